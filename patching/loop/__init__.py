"""Loop subdivision as [OSD] defines it: masks (``rules``), one refinement step as a sparse
operator with the child topology and tags (``refine``), limit positions and normals of the
true limit surface (``limit``)."""

from .refine import CREASE_METHODS, loop_operator, loop_subdivide

__all__ = ["CREASE_METHODS", "loop_operator", "loop_subdivide"]
