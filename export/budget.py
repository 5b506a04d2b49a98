"""Resource budgets checked before the work starts: tessellation size, patch count, --tolerance.

Tessellation (``stl``, ``glb``, ``obj`` and ``render``): OpenCASCADE's ``BRepMesh`` refines a
face until its chords are within the linear deflection ``tol``.  A polynomial curve c(s) with
|c''| <= K deviates from its chord of parameter length h by at most K h^2 / 8, and for a
Bezier net of degree d, |S_ss| <= d (d - 1) max |second difference of the net in s|
(the hodograph of the hodograph; Farin, *Curves and Surfaces for CAGD*, sec. 5.3).  So a patch
needs about n_s = ceil(sqrt(K_s / (8 tol))) segments in s (likewise t).  BRepMesh makes more
than the 2 n_s n_t triangles of that grid (it also refines for the angular deflection, along
the edges, and puts at least a few nodes inside every face); ``estimate_triangles`` takes
4 (n_s + 1)(n_t + 1) per patch, a factor calibrated on 2026-12-01 against OpenCASCADE's counts:
cube 0.52 to 0.88 of them, torus 30 x 30 1.2 to 1.6, pawn (93k patches) 1.0 to 1.7 at
tolerances 1e-2 to 1e-4 of the size (tests/test_faults.py checks the cube and a torus).

Above ``MAX_TRIANGLES`` (documented in docs/limits.md) the tessellation is refused up front
with an OutputError that names ``--tolerance`` and the smallest tolerance that fits; at
``WARN_TRIANGLES`` a warning says how large the output will be.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from patching.errors import NupatchError
from patching.mesh import NupatchWarning

from export.tolerances import check_tolerance  # noqa: F401  (the one check, re-exported for the writers)

__all__ = [
    "MAX_TRIANGLES",
    "WARN_TRIANGLES",
    "MANY_PATCHES",
    "estimate_triangles",
    "check_tessellation_budget",
    "warn_many_patches",
    "estimate_shape_triangles",
    "check_shape_budget",
]

#: Most triangles a tessellation may have: OpenCASCADE's mesh data structures take several
#: hundred bytes per triangle while meshing (a cube at 1e-6 reached 7.5 GB), then our points,
#: normals, uv and indices; a 250 MB STL.  Refused above, with the tolerance that would fit.
MAX_TRIANGLES = 5_000_000
#: Triangles from which a warning gives the expected size.
WARN_TRIANGLES = 1_000_000
#: Patches from which a build warns, when the mesh has far fewer faces (refinement of tags).
MANY_PATCHES = 50_000


def _segments(groups, tolerance: float) -> np.ndarray:
    """(patches, 2) segment counts (n_s, n_t) per patch, in row order."""
    parts = []
    for g in groups:
        d = g.degree
        nets = np.asarray(g.coefficients)  # (k, d+1, d+1, 3)
        if d < 2 or len(nets) == 0:
            parts.append(np.ones((len(nets), 2)))
            continue
        ss = np.linalg.norm(nets[:, 2:] - 2 * nets[:, 1:-1] + nets[:, :-2], axis=-1).max(axis=(1, 2))
        tt = np.linalg.norm(nets[:, :, 2:] - 2 * nets[:, :, 1:-1] + nets[:, :, :-2], axis=-1).max(axis=(1, 2))
        k = d * (d - 1) * np.stack([ss, tt], axis=1)
        parts.append(np.maximum(1.0, np.ceil(np.sqrt(k / (8.0 * tolerance)))))
    return np.concatenate(parts) if parts else np.zeros((0, 2))


def estimate_triangles(surface, tolerance: float) -> int:
    """Triangles a tessellation of ``surface`` within ``tolerance`` needs (module docstring)."""
    n = _segments(surface.groups, float(tolerance))
    return int((4.0 * (n[:, 0] + 1) * (n[:, 1] + 1)).sum())


def _judge(estimate: int, tolerance: float, option: str) -> int:
    """Refuse an estimate above MAX_TRIANGLES (naming ``option`` and the tolerance that fits),
    warn above WARN_TRIANGLES; returns the estimate."""
    if estimate > MAX_TRIANGLES:
        # triangles scale as 1 / tolerance: the tolerance that fits, rounded up to 2 digits
        fits = float(f"{tolerance * estimate / MAX_TRIANGLES * 1.01:.2g}")
        raise NupatchError(
            f"tolerance {tolerance:g} would make about {estimate:.3g} triangles, more than the budget of "
            f"{MAX_TRIANGLES:.3g} (docs/limits.md); use a tolerance of at least {fits:g}",
            option,
        )
    if estimate > WARN_TRIANGLES:
        warnings.warn(NupatchWarning(f"tolerance {tolerance:g} makes about {estimate:.3g} triangles (a large output)"))
    return estimate


def check_tessellation_budget(surface, tolerance: float, option: str = "--tolerance") -> int:
    """Refuse (NupatchError naming ``option``) a tessellation estimated above MAX_TRIANGLES,
    warn above WARN_TRIANGLES; returns the estimate.  Runs before BRepMesh is called."""
    estimate = estimate_triangles(surface, tolerance)
    return _judge(estimate, tolerance, option)


def warn_many_patches(mesh, surface) -> None:
    """A NupatchWarning when a build makes more than MANY_PATCHES patches from a mesh of fewer
    than MANY_PATCHES / 10 faces: refinement of semi-sharp tags did it; the tags are named."""
    if surface.n_patches <= MANY_PATCHES or mesh.n_faces * 10 > MANY_PATCHES:
        return
    semi = sorted(((s, e) for e, s in mesh.creases.items() if 0 < s < 10), reverse=True)
    corners = sorted(((s, v) for v, s in mesh.corners.items() if 0 < s < 10), reverse=True)
    named = [f"crease {a}-{b} s={s:g} ({mesh.where('crease', (a, b))})" for s, (a, b) in semi[:3]]
    named += [f"corner {v} s={s:g} ({mesh.where('corner', v)})" for s, v in corners[:2]]
    cause = ", ".join(named) if named else "the subdivision the mesh needs"
    warnings.warn(
        NupatchWarning(
            f"{surface.n_patches} patches from {mesh.n_faces} faces: semi-sharp tags are refined step by step; "
            f"the highest: {cause}"
        )
    )


def estimate_shape_triangles(shape, tolerance: float) -> int:
    """``estimate_triangles`` for an OpenCASCADE shape (a STEP file given to ``render``): the
    same bound per knot span of every B-spline or Bezier face, read from its poles (each span
    taken as one patch of the face's degree); other faces count as a few triangles."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_BezierSurface, GeomAbs_BSplineSurface
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from export.ocp_compat import TopoDS

    total = 0
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        adaptor = BRepAdaptor_Surface(TopoDS.Face_s(explorer.Current()))
        kind = adaptor.GetType()
        if kind in (GeomAbs_BSplineSurface, GeomAbs_BezierSurface):
            geom = adaptor.BSpline() if kind == GeomAbs_BSplineSurface else adaptor.Bezier()
            nu, nv = geom.NbUPoles(), geom.NbVPoles()
            poles = np.array([[geom.Pole(i, j).Coord() for j in range(1, nv + 1)] for i in range(1, nu + 1)])
            du, dv = geom.UDegree(), geom.VDegree()
            spans_u = geom.NbUKnots() - 1 if kind == GeomAbs_BSplineSurface else 1
            spans_v = geom.NbVKnots() - 1 if kind == GeomAbs_BSplineSurface else 1
            ss = np.linalg.norm(poles[2:] - 2 * poles[1:-1] + poles[:-2], axis=-1).max() if nu > 2 else 0.0
            tt = np.linalg.norm(poles[:, 2:] - 2 * poles[:, 1:-1] + poles[:, :-2], axis=-1).max() if nv > 2 else 0.0
            # each span as a Bezier patch whose net has the poles' second differences
            n_s = math.ceil(math.sqrt(max(du * (du - 1), 0) * ss / (8.0 * tolerance))) if ss > 0 else 1
            n_t = math.ceil(math.sqrt(max(dv * (dv - 1), 0) * tt / (8.0 * tolerance))) if tt > 0 else 1
            total += int(4 * spans_u * spans_v * (max(n_s, 1) + 1) * (max(n_t, 1) + 1))
        else:
            total += 8
        explorer.Next()
    return total


def check_shape_budget(shape, tolerance: float, option: str = "--tolerance") -> int:
    """``check_tessellation_budget`` for an OpenCASCADE shape (``estimate_shape_triangles``)."""
    estimate = estimate_shape_triangles(shape, tolerance)
    return _judge(estimate, tolerance, option)
