"""What pictures draw, sampled from the exact patches: grids on every Bézier patch with points,
unit normals and curvatures, the grid's triangles, and the patches' edge lines.

Curvature from the patch polynomials, not from a tessellation: at every sample the first and
second derivatives of the net give the fundamental forms
E = S_s.S_s, F = S_s.S_t, G = S_t.S_t and L = S_ss.n, M = S_st.n, N = S_tt.n (n the unit
normal S_s x S_t / |S_s x S_t|, outward: ``patching.surface``), and

    K = (L N - M^2) / (E G - F^2),   H = -(E N - 2 F M + G L) / (2 (E G - F^2)),
    k1, k2 = H +- sqrt(max(H^2 - K, 0))   (k1 >= k2),

signed so that a convex part (a sphere seen from outside) has H, k1, k2 > 0 (the minus in H:
with the outward normal L, M, N are negative there).  Check: a sphere of radius r gives
H = k1 = k2 = 1/r and K = 1/r^2 (``tests/test_render.py``).

Resolution from the picture, not the model tolerance: every patch gets the same m x m grid
(so neighbouring grids meet sample for sample and leave no cracks), m chosen so that the
longest control-polygon line of any patch (an upper bound of its curves' lengths) is cut into
pieces of at most ``EDGE_PIXELS`` pixels, and so that the chord error is below a third of a
pixel (``second difference bound``), within a vertex budget.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from patching.surface import BezierSurface
from patching.bernstein import bernstein_derivatives, common_nets

__all__ = ["EDGE_PIXELS", "MAX_SAMPLES", "MAX_VERTICES", "PatchSamples", "grid_size", "grid_triangles", "sample_patches"]

#: Largest triangle side in pixels of the final image (stripes are interpolated per pixel
#: inside a triangle: smaller triangles keep them smooth where the surface is).
EDGE_PIXELS = 6.0
#: Samples per patch side: bounds.
MIN_SAMPLES, MAX_SAMPLES = 5, 129
#: Vertex budget of a picture's tessellation (a few hundred MB of arrays at most).
MAX_VERTICES = 2_500_000


@dataclass(frozen=True)
class PatchSamples:
    """m x m samples on each of p patches (row order of ``BezierSurface.groups``), sample
    (a, b) at (s, t) = (a, b) / (m - 1).

    points, normals: (p, m, m, 3); area: (p, m, m) |S_s x S_t| (the area element, weights of
    statistics); mean, gaussian, k1, k2: (p, m, m) (module docstring); faces: (p,) mesh faces.
    """

    points: np.ndarray
    normals: np.ndarray
    area: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    faces: np.ndarray

    @property
    def m(self) -> int:
        return int(self.points.shape[1])

    def edge_lines(self) -> np.ndarray:
        """(l, 2, 3) segments along the four sides of every patch (the patch edges)."""
        p = self.points
        sides = [p[:, :, 0], p[:, -1, :], p[:, :, -1], p[:, 0, :]]
        segs = [np.stack([s[:, :-1], s[:, 1:]], axis=2).reshape(-1, 2, 3) for s in sides]
        return np.concatenate(segs)

    def edge_normals(self) -> np.ndarray:
        """(l, 3) unit normal at the midpoint of each ``edge_lines`` segment (visibility)."""
        n = self.normals
        sides = [n[:, :, 0], n[:, -1, :], n[:, :, -1], n[:, 0, :]]
        out = [(0.5 * (s[:, :-1] + s[:, 1:])).reshape(-1, 3) for s in sides]
        return np.concatenate(out)


def grid_size(surface: BezierSurface, pixel: float, edge_pixels: float = EDGE_PIXELS) -> int:
    """Samples per patch side for a picture whose pixel is ``pixel`` model units (module
    docstring): the same for every patch, within [MIN_SAMPLES, MAX_SAMPLES] and MAX_VERTICES."""
    worst_length, worst_bend = 0.0, 0.0
    for g in surface.groups:
        c = np.asarray(g.coefficients, dtype=np.float64)
        along = [np.linalg.norm(np.diff(c, axis=ax), axis=-1).sum(axis=ax) for ax in (1, 2)]
        worst_length = max(worst_length, max(float(a.max()) for a in along))
        if g.degree >= 2:  # |S''| <= d (d-1) max |second difference|; chord error <= h^2 |S''| / 8
            bend = [np.linalg.norm(np.diff(c, 2, axis=ax), axis=-1).max() for ax in (1, 2)]
            worst_bend = max(worst_bend, g.degree * (g.degree - 1) * float(max(bend)))
    pixel = max(float(pixel), 1e-300)
    by_length = worst_length / (edge_pixels * pixel)
    by_chord = np.sqrt(worst_bend / (8.0 * pixel / 3.0))
    m = int(np.ceil(max(by_length, by_chord))) + 1
    budget = int(np.sqrt(MAX_VERTICES / max(surface.n_patches, 1)))
    return int(np.clip(m, MIN_SAMPLES, max(MIN_SAMPLES, min(MAX_SAMPLES, budget))))


def sample_patches(surface: BezierSurface, m: int) -> PatchSamples:
    """Points, normals and curvatures on the m x m grid of every patch (module docstring)."""
    faces, nets, d = common_nets(surface)  # every patch raised to the largest degree (exact)
    u = np.linspace(0.0, 1.0, m)
    b, db, ddb = bernstein_derivatives(d, u)

    def grid(bs, bt):  # sum_ij bs[a, i] bt[b, j] nets[k, i, j, c] -> (k, a, b, c)
        return np.einsum("ai,kijc,bj->kabc", bs, nets, bt, optimize=True)

    s_s, s_t = grid(db, b), grid(b, db)
    s_ss, s_st, s_tt = grid(ddb, b), grid(db, db), grid(b, ddb)
    points = grid(b, b)
    cross = np.cross(s_s, s_t)
    area = np.linalg.norm(cross, axis=-1)
    normals = cross / np.maximum(area, 1e-300)[..., None]
    e, f, g = (np.einsum("...c,...c->...", x, y) for x, y in ((s_s, s_s), (s_s, s_t), (s_t, s_t)))
    ll, mm, nn = (np.einsum("...c,...c->...", x, normals) for x in (s_ss, s_st, s_tt))
    det = e * g - f * f
    ok = det > 1e-24 * np.maximum(e * g, 1e-300)  # a degenerate corner has no curvature
    with np.errstate(divide="ignore", invalid="ignore"):
        gauss = np.where(ok, (ll * nn - mm * mm) / det, np.nan)
        mean = np.where(ok, -(e * nn - 2 * f * mm + g * ll) / (2 * det), np.nan)
    root = np.sqrt(np.maximum(mean * mean - gauss, 0.0))
    _fill_degenerate(normals, area)
    return PatchSamples(points, normals, area, mean, gauss, mean + root, mean - root, faces)


def _fill_degenerate(normals: np.ndarray, area: np.ndarray) -> None:
    """Where S_s x S_t vanishes (a collapsed corner) take the grid neighbour's normal."""
    bad = area <= 1e-14 * max(float(area.max()), 1e-300)
    if not bad.any():
        return
    k, a, b = np.nonzero(bad)
    m = normals.shape[1]
    a2 = np.where(a == 0, 1, np.where(a == m - 1, m - 2, a))
    b2 = np.where(b == 0, 1, np.where(b == m - 1, m - 2, b))
    normals[k, a, b] = normals[k, a2, b2]


def grid_triangles(p: int, m: int) -> np.ndarray:
    """(2 p (m-1)^2, 3) int64 triangles of p row-major m x m grids, counter-clockwise in (s, t)
    (so outward with the patches' normals); flattened vertex k m^2 + a m + b."""
    a, b = np.meshgrid(np.arange(m - 1), np.arange(m - 1), indexing="ij")
    v00 = (a * m + b).ravel()
    v10, v01, v11 = v00 + m, v00 + 1, v00 + m + 1
    cell = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    return (cell[None, :, :] + (np.arange(p) * m * m)[:, None, None]).reshape(-1, 3).astype(np.int64)
