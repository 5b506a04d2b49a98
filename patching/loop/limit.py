"""Limit positions and normals of Loop surfaces: the true limit surface's.

[OSD]'s ``Far::PatchTable``/``Limit()`` treats semi-sharp features as sharp and its Loop limit
masks (``assignSmoothLimitMask``, ``assignCreaseLimitMask``, ``assignCornerLimitMask``) are
exact only where the 1-ring matrix is the one they were derived for.  Here:

1. the neighbourhood of semi-sharp features is refined until no semi-sharp tag is left in
   it (``decay_steps``: at most ceil of the largest finite sharpness; only the faces that
   touch the 1-ring of a vertex whose 1-ring matrix may still change, ``local``; the whole
   mesh with ``refine="global"``);
2. at that stationary level every vertex's limit point and per-region normal come from the
   eigenvectors of its own 1-ring matrix (``stationary``): [OSD]'s masks at smooth vertices
   (``(1 - n w) V + w sum E_i``, ``w = 1/(n + 3/(8 beta_n))``) and at crease vertices
   (``(1, 4, 1)/6`` along the crease) and corners (``V``), which the eigenvectors reproduce;
   the eigenvectors themselves at darts and for the normals of crease sides;
3. the masks are composed with the refinement operators, so that they are sparse rows over
   the input control points (``L @ P``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..mesh import ControlMesh
from ..topology import Topology
from .cache import topology_of
from .local import LocalScheme, local_limit
from .refine import LoopLevel, decay_steps, level_operator, loop_operator
from .stationary import StationaryMasks, corner_regions, evaluate_normals, level_rules, select_regions, stationary_masks

__all__ = ["LimitMasks", "loop_limit_masks", "loop_limit_points", "loop_limit_normals", "MAX_LIMIT_FACES"]

#: Largest refined mesh (faces) built on the way to the stationary level.
MAX_LIMIT_FACES = 4_000_000


@dataclass
class LimitMasks:
    """Limit masks over a mesh's own control points.

    position (v, v) CSR: limit points ``position @ P``.  region_of_corner (H,): the region
    (faces between sharp edges, [ZBK] sec. 3.4) of every face corner (half-edge) of the mesh;
    region_vertex (r,); ``normals(P)`` (r, 3) the unit limit normal of every region (regions
    that merge on the way to the stationary level, a semi-sharp crease that decays, share
    one).  ``stationary`` holds the masks over the input points, ``index`` maps the mesh's
    regions to them."""

    position: sp.csr_matrix
    region_of_corner: np.ndarray
    region_vertex: np.ndarray
    stationary: StationaryMasks
    index: np.ndarray

    def points(self, P: np.ndarray) -> np.ndarray:
        return self.position @ P

    def normals(self, P: np.ndarray) -> np.ndarray:
        return evaluate_normals(self.stationary, P)[self.index]

    def corner_normals(self, P: np.ndarray) -> np.ndarray:
        """(H, 3) unit limit normal at every face corner (its region's)."""
        return self.normals(P)[self.region_of_corner]


def _corner_child_loop(topo: Topology, corners: np.ndarray) -> np.ndarray:
    f = topo.face[corners]
    local = corners - 3 * f
    return 12 * f + 3 * local  # child face 4 f + local, the vertex at its corner 0


def loop_limit_masks(mesh: ControlMesh, crease_method: str | None = None, refine: str = "local") -> LimitMasks:
    """Limit masks of a triangle mesh under Loop subdivision (module docstring).

    refine: "local" (default: only the neighbourhood of semi-sharp features is refined until
    they have decayed, ``patching.loop.local``) or "global" (the whole mesh, the reference)."""
    crease_method = LoopLevel.of(mesh, crease_method).crease_method  # None: the mesh's
    k = decay_steps(mesh)
    if refine == "local":
        scheme = LocalScheme("loop", lambda m: loop_operator(m, crease_method))
        P, masks, index, label0, rv0 = local_limit(mesh, scheme, k)
        return LimitMasks(P, label0, rv0, masks, index)
    if mesh.n_faces * 4 ** (k + 1) > MAX_LIMIT_FACES:
        from ..errors import UnsupportedError

        raise UnsupportedError(
            f"the limit of sharpness {k} needs {k} refinement steps of {mesh.n_faces} faces, more than "
            f"{MAX_LIMIT_FACES:,} faces", mesh.name,
        )
    topo0 = topology_of(mesh)
    sharp0, _ = level_rules(mesh, topo0)
    label0, rv0 = corner_regions(topo0, sharp0)
    nv0 = mesh.n_vertices
    total = sp.identity(nv0, format="csr")
    cmap = np.arange(topo0.origin.size)
    cur, topo = mesh, topo0
    for _ in range(k):
        S, child = loop_operator(cur, crease_method)
        cmap = _corner_child_loop(topo, cmap)
        total = (S @ total).tocsr()
        cur = child
        topo = topology_of(cur)
    S = level_operator(cur, crease_method)
    masks = stationary_masks(cur, topo, S, "loop", targets=np.arange(nv0))
    first = np.zeros(rv0.size, np.int64)
    first[label0[::-1]] = np.arange(label0.size)[::-1]
    regions_k = masks.region_of_corner[cmap[first]]
    uniq, index = np.unique(regions_k, return_inverse=True)
    sub = select_regions(masks, uniq).compose(total)
    return LimitMasks(sub.position[:nv0].tocsr(), label0, rv0, sub, index)


def loop_limit_points(mesh: ControlMesh, crease_method: str | None = None) -> np.ndarray:
    """(v, 3) limit-surface point of every control vertex."""
    return loop_limit_masks(mesh, crease_method).points(mesh.vertices)


def loop_limit_normals(mesh: ControlMesh, crease_method: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(region_of_corner (H,), normals (r, 3)): the unit limit normal of every region."""
    m = loop_limit_masks(mesh, crease_method)
    return m.region_of_corner, m.normals(mesh.vertices)
