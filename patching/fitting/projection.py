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
    (cheaper than the powers of ``bernstein.bernstein``, the same values to round-off)."""
    out = np.zeros((x.size, d + 1))
    out[:, 0] = 1.0
    u = 1.0 - x
    for k in range(1, d + 1):
        out[:, k] = x * out[:, k - 1]
        for i in range(k - 1, 0, -1):
            out[:, i] = u * out[:, i] + x * out[:, i - 1]
        out[:, 0] = u * out[:, 0]
    return out


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


def _apply(u: np.ndarray, v: np.ndarray, nets: np.ndarray) -> np.ndarray:
    """sum_ij u[m, i] v[m, j] nets[m, i, j, c] -> (m, c)."""
    return np.einsum("mj,mjc->mc", v, np.einsum("mi,mijc->mjc", u, nets))


def _evaluate_nets(nets: np.ndarray, s: np.ndarray, t: np.ndarray, order: int):
    d = nets.shape[1] - 1
    if order == 0:
        return (_apply(_bernstein(d, s), _bernstein(d, t), nets),)
    bs, dbs, ddbs = basis_derivatives(d, s)
    bt, dbt, ddbt = basis_derivatives(d, t)
    pairs = [(bs, bt), (dbs, bt), (bs, dbt), (ddbs, bt), (dbs, dbt), (bs, ddbt)][: (1, 3, 6)[order]]
    return tuple(_apply(u, v, nets) for u, v in pairs)


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
    ``candidates`` nearest grid samples; with ``previous``, from the nearest sample and from
    the previous foot point, keeping the nearer."""
    x = np.asarray(points, dtype=np.float64)
    sp_, ss, st, spts = _samples(layout, coefficients, grid)
    k = min(candidates, sp_.size)
    _, idx = cKDTree(spts).query(x, k=k)
    idx = idx.reshape(x.shape[0], k)
    patch = sp_[idx].T.ravel()
    s, t = ss[idx].T.ravel().copy(), st[idx].T.ravel().copy()
    xs = np.tile(x, (k, 1))
    if previous is not None:
        patch = np.concatenate([patch, previous.patch])
        s, t = np.concatenate([s, previous.s]), np.concatenate([t, previous.t])
        xs = np.concatenate([xs, x])
    f = np.empty(s.size)
    for d in layout.degrees:
        sel = np.flatnonzero(layout.degree[patch] == d)
        if sel.size:
            nets = layout.nets(coefficients, patch[sel], d)
            s[sel], t[sel], f[sel] = _newton(nets, xs[sel], s[sel], t[sel], iterations)
    rounds = f.size // x.shape[0]
    f = f.reshape(rounds, -1)
    best = np.argmin(f, axis=0)
    pick = best * x.shape[0] + np.arange(x.shape[0])
    return FootPoints(patch[pick], s[pick], t[pick], np.sqrt(f.ravel()[pick]))
