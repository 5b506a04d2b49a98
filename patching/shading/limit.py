"""Limit points and per-region limit normals N_L for both schemes: Loop (``patching.loop``) and
Catmull-Clark (``patching.subdivision``'s operator), through the same stationary-level
eigen-analysis (``patching.loop.stationary``).

Catmull-Clark: the neighbourhood of semi-sharp features and of faces that are not quads is
refined locally (``patching.loop.local``); with ``refine="global"`` the whole mesh is refined until no semi-sharp tag is left (ceil of the largest finite
sharpness; at least one step where a face is not a quad), keeping track of each input vertex
(child id ``n_faces + n_edges + v``) and of each face corner (corner h becomes corner 0 of
child face h, half-edge ``4 h``); then the 1-ring blocks of that level's operator.  Uniform
knots only (the 1-ring blocks of plain vertices are shared by valence).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from ..errors import KnotError, UnsupportedError
from ..mesh import INFINITELY_SHARP, ControlMesh
from ..loop.cache import topology_of
from ..loop.limit import LimitMasks, loop_limit_masks
from ..loop.local import LocalScheme, local_limit
from ..loop.stationary import corner_regions, level_rules, select_regions, stationary_masks
from ..rules.crease import crease_method_of

__all__ = ["limit_masks", "SCHEMES"]

SCHEMES = ("catmark", "loop")
MAX_LIMIT_FACES = 4_000_000


def _catmark_decay(mesh: ControlMesh) -> int:
    finite = [float(x) for x in list(mesh.creases.values()) + list(mesh.corners.values()) if 0 < x < INFINITELY_SHARP]
    steps = int(math.ceil(max(finite, default=0.0)))
    if not mesh.is_quad_mesh:
        steps = max(steps, 1)
    return steps


def check_uniform_catmark(mesh: ControlMesh) -> None:
    """Uniform knots: one interval on every strip, else a KnotError naming two values."""
    si = topology_of(mesh).strip_interval
    if si.size and not np.all(si == si[0]):
        raise KnotError(
            f"normals take uniform knots only: strip intervals {float(si.min()):g} and {float(si.max()):g}", mesh.name
        )


def catmark_limit_masks(mesh: ControlMesh, rules: str = "opensubdiv", crease_method: str | None = None,
                        refine: str = "local") -> LimitMasks:
    """Limit masks of a mesh under Catmull-Clark (rules as ``patching.subdivision``); refine
    "local" (default) or "global" as ``patching.loop.limit.loop_limit_masks``; crease_method None:
    the mesh's."""
    from ..subdivision import subdivision_operator

    crease_method = crease_method_of(mesh, crease_method)

    check_uniform_catmark(mesh)
    k = _catmark_decay(mesh)
    if refine == "local":
        scheme = LocalScheme("catmark", lambda m: subdivision_operator(m, rules=rules, crease_method=crease_method))
        P, masks, index, label0, rv0 = local_limit(mesh, scheme, k)
        return LimitMasks(P, label0, rv0, masks, index)
    if int(mesh.face_sizes.sum()) * 4 ** (k + 1) > MAX_LIMIT_FACES:
        raise UnsupportedError(f"the limit needs {k} refinement steps of {mesh.n_faces} faces, too many", mesh.name)
    topo0 = topology_of(mesh)
    sharp0, _ = level_rules(mesh, topo0)
    label0, rv0 = corner_regions(topo0, sharp0)
    nv0 = mesh.n_vertices
    ids = np.arange(nv0)
    cmap = np.arange(topo0.origin.size)
    total = sp.identity(nv0, format="csr")
    cur, topo = mesh, topo0
    for _ in range(k):
        S, child = subdivision_operator(cur, rules=rules, crease_method=crease_method)
        ids = topo.n_faces + topo.n_edges + ids
        cmap = 4 * cmap
        total = (S @ total).tocsr()
        cur = child
        topo = topology_of(cur)
    S, _ = subdivision_operator(cur, rules=rules, crease_method=crease_method)
    masks = stationary_masks(cur, topo, S, "catmark", targets=ids)
    first = np.zeros(rv0.size, np.int64)
    first[label0[::-1]] = np.arange(label0.size)[::-1]
    regions_k = masks.region_of_corner[cmap[first]]
    uniq, index = np.unique(regions_k, return_inverse=True)
    sub = select_regions(masks, uniq).compose(total)
    return LimitMasks(sub.position[ids].tocsr(), label0, rv0, sub, index)


def limit_masks(mesh: ControlMesh, scheme: str, rules: str = "opensubdiv", crease_method: str | None = None,
                refine: str = "local") -> LimitMasks:
    """Limit masks (points, per-region normals) of ``mesh`` under ``scheme``; refine "local"
    (default) or "global" (``patching.loop.limit.loop_limit_masks``)."""
    if scheme == "loop":
        return loop_limit_masks(mesh, crease_method, refine)
    if scheme == "catmark":
        return catmark_limit_masks(mesh, rules, crease_method, refine)
    raise UnsupportedError(f"scheme must be one of {', '.join(SCHEMES)}, got '{scheme}'")
