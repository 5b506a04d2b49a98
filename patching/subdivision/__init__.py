"""Subdivision as sparse operators: one refinement step (positions of the child mesh =
S @ parent positions), the child mesh with its tags, and limit masks.  ``catmark``:
non-uniform Catmull-Clark with sharp and semi-sharp features ([TLC], [ZTL], or OpenSubdiv's
uniform rules)."""

from patching.subdivision.catmark import subdivide, subdivision_operator
from patching.subdivision.limit import limit_operator, limit_points, limit_tangents

__all__ = ["subdivide", "subdivision_operator", "limit_operator", "limit_points", "limit_tangents"]
