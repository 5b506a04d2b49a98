"""Foot points: the parameters (patch, s, t) of the nearest surface point to each data point.

[FSLYJ] sec. 4.1 "re-parameterises the triangle mesh locally" onto the patches.  Here: a start
from the nearest samples of a grid on every patch (a k-d tree over all samples, several
candidate patches per point), then Newton's method on the squared distance
f(s, t) = |S(s, t) - x|^2 of the patch polynomial, with gradient (S_s . r, S_t . r) and Hessian
[[S_s.S_s + S_ss.r, S_s.S_t + S_st.r], [., S_t.S_t + S_tt.r]] (r = S - x), the Gauss-Newton
matrix where that Hessian is not positive definite, steps clamped to the parameter square and
halved while they do not lower f.  The best candidate wins; a previous foot point is kept
where it is still nearer (so an update never increases a distance).

Patches are numbered as the rows of ``SurfaceOperator.groups`` concatenated (``PatchLayout``);
the coefficient net of patch p is rows ``row[p] + i (d+1) + j`` of M @ P (``surface``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

#: A foot point farther than this many RMS distances is searched for again (``project``).
OUTLIER = 3.0

__all__ = ["PatchLayout", "FootPoints", "basis_derivatives", "evaluate", "project"]


@dataclass(frozen=True)
class PatchLayout:
    """Where each patch's coefficients sit in M's rows.

    degree: (p,) int64; row: (p,) int64, first row of the patch's (d+1)^2 coefficient rows;
    face: (p,) int64, the control mesh face the patch covers."""

    degree: np.ndarray
    row: np.ndarray
    face: np.ndarray

    @classmethod
    def of(cls, operator) -> "PatchLayout":
        degree, row, face = [], [], []
        for g in operator.groups:
            k = len(g.faces)
            degree.append(np.full(k, g.degree, dtype=np.int64))
            row.append(g.row_offset + (g.degree + 1) ** 2 * np.arange(k, dtype=np.int64))
            face.append(np.asarray(g.faces, dtype=np.int64))
        return cls(np.concatenate(degree), np.concatenate(row), np.concatenate(face))

    @property
    def n_patches(self) -> int:
        return int(self.degree.size)

    @cached_property
    def degrees(self) -> tuple[int, ...]:
        return tuple(int(d) for d in np.unique(self.degree))

    def nets(self, coefficients: np.ndarray, patches: np.ndarray, d: int) -> np.ndarray:
        """(k, d+1, d+1, 3) nets of ``patches`` (all of degree d)."""
        rows = self.row[patches][:, None] + np.arange((d + 1) ** 2)[None, :]
        return coefficients[rows].reshape(-1, d + 1, d + 1, coefficients.shape[1])


@dataclass
class FootPoints:
    """patch: (m,) int64; s, t: (m,) float64 in [0, 1]; distance: (m,) |S(s, t) - x|."""

    patch: np.ndarray
    s: np.ndarray
    t: np.ndarray
    distance: np.ndarray


def _bernstein(d: int, x: np.ndarray) -> np.ndarray:
    """(m, d+1) B_i^d(x) by the triangular recurrence B_i^k = (1-x) B_i^{k-1} + x B_{i-1}^{k-1}
    (cheaper than the powers of ``bernstein.bernstein``, the same values to round-off),
    computed on contiguous rows of a (d+1, m) array and returned transposed."""
    out = np.zeros((d + 1, x.size))
    out[0] = 1.0
    u = 1.0 - x
    for k in range(1, d + 1):
        out[k] = x * out[k - 1]
        for i in range(k - 1, 0, -1):
            out[i] = u * out[i] + x * out[i - 1]
        out[0] *= u
    return out.T


def basis_derivatives(d: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(m, d+1) Bernstein values B_i^d(x) and their first and second derivatives:
    B' = d (B_{i-1}^{d-1} - B_i^{d-1}), B'' = d (d-1) (B_{i-2}^{d-2} - 2 B_{i-1}^{d-2} + B_i^{d-2})."""
    m = x.size
    b = _bernstein(d, x)
    low = np.zeros((m, d + 2))
    low[:, 1:-1] = _bernstein(d - 1, x)
    db = d * (low[:, :-1] - low[:, 1:])
    low2 = np.zeros((m, d + 3))
    if d >= 2:
        low2[:, 2:-2] = _bernstein(d - 2, x)
    ddb = d * (d - 1) * (low2[:, :-2] - 2 * low2[:, 1:-1] + low2[:, 2:])
    return b, db, ddb


def _evaluate_nets(nets: np.ndarray, s: np.ndarray, t: np.ndarray, order: int):
    """Points (order 0), with S_s, S_t (1), and S_ss, S_st, S_tt (2) of per-point nets
    (m, d+1, d+1, 3): two batched matrix products, first over i with the s-bases stacked,
    then over j with the t-bases stacked (an einsum over four indices is several times slower)."""
    m, d = nets.shape[0], nets.shape[1] - 1
    flat = nets.reshape(m, d + 1, 3 * (d + 1))
    if order == 0:
        along = np.matmul(_bernstein(d, s)[:, None, :], flat).reshape(m, d + 1, 3)
        return (np.matmul(_bernstein(d, t)[:, None, :], along)[:, 0],)
    k = order + 1
    bs = np.stack(basis_derivatives(d, s)[:k], axis=1)  # (m, k, d+1): B, B', B''
    bt = np.stack(basis_derivatives(d, t)[:k], axis=1)
    along = np.matmul(bs, flat).reshape(m, k, d + 1, 3).transpose(0, 2, 1, 3).reshape(m, d + 1, 3 * k)
    both = np.matmul(bt, along).reshape(m, k, k, 3)  # [m, t-derivative, s-derivative, c]
    out = (both[:, 0, 0], both[:, 0, 1], both[:, 1, 0])
    if order == 1:
        return out
    return out + (both[:, 0, 2], both[:, 1, 1], both[:, 2, 0])


def evaluate(layout: PatchLayout, coefficients: np.ndarray, patch: np.ndarray, s: np.ndarray, t: np.ndarray, order: int = 0):
    """Surface points at (patch, s, t) pairs: (m, 3); with order=2 also S_s, S_t, S_ss, S_st,
    S_tt (each (m, 3)); with order=1 S_s and S_t."""
    m = patch.size
    out = [np.empty((m, 3)) for _ in range((1, 3, 6)[order])]
    for d in layout.degrees:
        sel = np.flatnonzero(layout.degree[patch] == d)
        if sel.size == 0:
            continue
        nets = layout.nets(coefficients, patch[sel], d)
        for target, value in zip(out, _evaluate_nets(nets, s[sel], t[sel], order)):
            target[sel] = value
    return out[0] if order == 0 else tuple(out)


def _samples(layout: PatchLayout, coefficients: np.ndarray, n: int):
    """An n x n grid on every patch: (patch, s, t, points)."""
    u = (np.arange(n) + 0.5) / n
    s, t = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    p = np.repeat(np.arange(layout.n_patches), s.size)
    ss, tt = np.tile(s, layout.n_patches), np.tile(t, layout.n_patches)
    return p, ss, tt, evaluate(layout, coefficients, p, ss, tt)


def _newton(nets: np.ndarray, x: np.ndarray, s: np.ndarray, t: np.ndarray, iterations: int):
    """Newton on |S(s, t) - x|^2 inside each point's patch (nets (m, d+1, d+1, 3) gathered
    once), clamped to [0, 1]^2, steps halved while they do not lower f (module docstring)."""
    (pts,) = _evaluate_nets(nets, s, t, 0)
    f = np.einsum("ij,ij->i", pts - x, pts - x)
    active = np.arange(s.size)
    for _ in range(iterations):
        if active.size == 0:
            break
        sa, ta, xa, na = s[active], t[active], x[active], nets[active]
        p, su, sv, suu, suv, svv = _evaluate_nets(na, sa, ta, 2)
        r = p - xa
        g0, g1 = np.einsum("ij,ij->i", su, r), np.einsum("ij,ij->i", sv, r)
        a = np.einsum("ij,ij->i", su, su)
        b = np.einsum("ij,ij->i", su, sv)
        c = np.einsum("ij,ij->i", sv, sv)
        ha, hb, hc = a + np.einsum("ij,ij->i", suu, r), b + np.einsum("ij,ij->i", suv, r), c + np.einsum("ij,ij->i", svv, r)
        det = ha * hc - hb * hb
        bad = (det <= 1e-12 * (a * c + 1e-300)) | (ha <= 0)
        ha, hb, hc = np.where(bad, a, ha), np.where(bad, b, hb), np.where(bad, c, hc)
        det = ha * hc - hb * hb
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        ds = -(hc * g0 - hb * g1) / det
        dt = -(ha * g1 - hb * g0) / det
        scale = np.minimum(1.0, 0.5 / np.maximum(np.maximum(np.abs(ds), np.abs(dt)), 1e-300))
        ds, dt = ds * scale, dt * scale
        moved = np.zeros(active.size, dtype=bool)
        small = np.zeros(active.size, dtype=bool)
        for step in (1.0, 0.5, 0.25):
            todo = np.flatnonzero(~moved)
            ns = np.clip(sa[todo] + step * ds[todo], 0.0, 1.0)
            nt = np.clip(ta[todo] + step * dt[todo], 0.0, 1.0)
            (q,) = _evaluate_nets(na[todo], ns, nt, 0)
            fq = np.einsum("ij,ij->i", q - xa[todo], q - xa[todo])
            better = fq < f[active[todo]]
            hit = todo[better]
            shift = np.maximum(np.abs(ns[better] - sa[hit]), np.abs(nt[better] - ta[hit]))
            small[hit] = shift < 1e-13
            idx = active[hit]
            s[idx], t[idx], f[idx] = ns[better], nt[better], fq[better]
            moved[hit] = True
            if moved.all():
                break
        active = active[moved & ~small]
    return s, t, f


def _refine(layout, coefficients, x, patch, s, t, iterations):
    """Newton from (patch, s, t) for every point, per degree group: (s, t, squared distance)."""
    f = np.empty(s.size)
    for d in layout.degrees:
        sel = np.flatnonzero(layout.degree[patch] == d)
        if sel.size:
            nets = layout.nets(coefficients, patch[sel], d)
            s[sel], t[sel], f[sel] = _newton(nets, x[sel], s[sel], t[sel], iterations)
    return s, t, f


def project(
    layout: PatchLayout,
    coefficients: np.ndarray,
    points: np.ndarray,
    previous: FootPoints | None = None,
    candidates: int = 3,
    grid: int = 6,
    iterations: int = 8,
) -> FootPoints:
    """Foot points of (m, 3) ``points`` on the patches (module docstring): Newton from the
    ``candidates`` nearest grid samples.  With ``previous``: Newton from the previous foot
    points first, and the candidate search only for the points whose foot stopped on a patch
    side (where the nearest point may lie on the neighbour); the nearest found is kept."""
    x = np.asarray(points, dtype=np.float64)
    m = x.shape[0]
    if previous is not None:
        s, t = previous.s.copy(), previous.t.copy()
        s, t, f = _refine(layout, coefficients, x, previous.patch, s, t, iterations)
        feet = FootPoints(previous.patch.copy(), s, t, np.sqrt(f))
        # search again where the foot stopped on a patch side (the nearest point may be on
        # the neighbour) or lies far beyond the others (a foot left on a wrong patch)
        d = feet.distance
        far = d > OUTLIER * np.sqrt(np.mean(d**2))
        side = np.flatnonzero((s <= 0.0) | (s >= 1.0) | (t <= 0.0) | (t >= 1.0) | far)
        if side.size == 0:
            return feet
        again = project(layout, coefficients, x[side], None, candidates, grid, iterations)
        better = again.distance < feet.distance[side]
        idx = side[better]
        feet.patch[idx], feet.s[idx], feet.t[idx], feet.distance[idx] = (
            again.patch[better], again.s[better], again.t[better], again.distance[better])
        return feet
    sp_, ss, st, spts = _samples(layout, coefficients, grid)
    k = min(candidates, sp_.size)
    dist, idx = cKDTree(spts).query(x, k=k)
    dist, idx = dist.reshape(m, k), idx.reshape(m, k)
    # Candidates: the patches of the k nearest samples, each patch once, and only those that
    # can hold the nearest point.  Every point of patch p lies within h_p (its largest
    # distance between neighbouring samples) of a sample of p, so if p holds the foot y,
    # its nearest sample is within |x - y| + h_p <= dist_0 + h_p of x (dist_0: the nearest
    # sample's distance, itself a surface point's).
    grid_pts = spts.reshape(layout.n_patches, grid, grid, 3)
    spacing = np.maximum(
        np.linalg.norm(np.diff(grid_pts, axis=1), axis=-1).max(axis=(1, 2)),
        np.linalg.norm(np.diff(grid_pts, axis=2), axis=-1).max(axis=(1, 2)),
    )
    cand = sp_[idx]
    keep = dist <= dist[:, :1] + spacing[cand]
    for j in range(1, k):
        keep[:, j] &= (cand[:, j : j + 1] != cand[:, :j]).all(axis=1)
    keep[:, 0] = True
    row, col = np.nonzero(keep)
    patch = cand[row, col]
    s, t = ss[idx[row, col]].copy(), st[idx[row, col]].copy()
    s, t, f = _refine(layout, coefficients, x[row], patch, s, t, iterations)
    # the best candidate per point (rows come sorted by point)
    order = np.lexsort((f, row))
    first = order[np.r_[True, row[order][1:] != row[order][:-1]]]
    return FootPoints(patch[first], s[first], t[first], np.sqrt(f[first]))


def boundary_sides(operator) -> np.ndarray:
    """(k, 2) int64 (patch, side) of the patch sides on the surface's open boundary (sides
    whose B-rep edge only one side uses; ``surface.PatchTopology``), rows in layout order."""
    topo = operator.topology
    pieces = topo.pieces
    open_edge = topo.edge_use_count == 1
    sides = np.flatnonzero(np.add.reduceat(open_edge[pieces.edge].astype(np.int64), pieces.indptr[:-1]) > 0)
    return np.stack([sides // 4, sides % 4], axis=1).astype(np.int64)


def _side_parameters(side: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(s, t, ds/du, dt/du) along side k of the square (``surface``: side k runs from corner
    k to corner k+1)."""
    s = np.select([side == 0, side == 1, side == 2], [u, np.ones_like(u), 1.0 - u], np.zeros_like(u))
    t = np.select([side == 0, side == 1, side == 2], [np.zeros_like(u), u, np.ones_like(u)], 1.0 - u)
    ds = np.select([side == 0, side == 2], [np.ones_like(u), -np.ones_like(u)], np.zeros_like(u))
    dt = np.select([side == 1, side == 3], [np.ones_like(u), -np.ones_like(u)], np.zeros_like(u))
    return s, t, ds, dt


def project_to_boundary(
    layout: PatchLayout, coefficients: np.ndarray, points: np.ndarray, sides: np.ndarray,
    previous: FootPoints | None = None, samples: int = 16, iterations: int = 8,
) -> FootPoints:
    """Foot points of (m, 3) points on the surface's open boundary (the ``sides`` of
    ``boundary_sides``): nearest of ``samples`` points per side, then Gauss-Newton along the
    side, u clamped to [0, 1]; with ``previous`` (feet on those sides), the nearer is kept."""
    x = np.asarray(points, dtype=np.float64)
    u0 = (np.arange(samples) + 0.5) / samples
    sp_ = np.repeat(sides[:, 0], samples)
    sd = np.repeat(sides[:, 1], samples)
    uu = np.tile(u0, sides.shape[0])
    s, t, _, _ = _side_parameters(sd, uu)
    _, idx = cKDTree(evaluate(layout, coefficients, sp_, s, t)).query(x)
    patch, side, u = sp_[idx], sd[idx], uu[idx].copy()
    for _ in range(iterations):
        s, t, ds, dt = _side_parameters(side, u)
        p, su, sv = evaluate(layout, coefficients, patch, s, t, order=1)
        tangent = su * ds[:, None] + sv * dt[:, None]
        step = -np.einsum("ij,ij->i", tangent, p - x) / np.maximum(np.einsum("ij,ij->i", tangent, tangent), 1e-300)
        u = np.clip(u + np.clip(step, -0.5, 0.5), 0.0, 1.0)
    s, t, _, _ = _side_parameters(side, u)
    dist = np.linalg.norm(evaluate(layout, coefficients, patch, s, t) - x, axis=1)
    feet = FootPoints(patch, s, t, dist)
    if previous is not None:
        old = np.linalg.norm(evaluate(layout, coefficients, previous.patch, previous.s, previous.t) - x, axis=1)
        keep = old < dist
        feet.patch[keep], feet.s[keep], feet.t[keep], feet.distance[keep] = (
            previous.patch[keep], previous.s[keep], previous.t[keep], old[keep])
    return feet
