"""Surface queries for tool paths: one common degree, point-wise evaluation with second
derivatives, closest points by Newton's method, and a drop-cutter for a ball-end mill.

All patches are raised to one degree (exact Bernstein degree elevation), so that every query
is one vectorised contraction over ``(N, d+1, d+1, 3)`` nets gathered per point.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from ..bernstein import bernstein, bernstein_derivatives

__all__ = ["SurfaceIndex", "evaluate_points", "unit_normals"]

CHUNK = 8192


def evaluate_points(nets: np.ndarray, s: np.ndarray, t: np.ndarray, order: int = 1) -> tuple[np.ndarray, ...]:
    """Point, first (and with order=2 second) derivatives of net k at (s_k, t_k), one net per
    point: nets (N, d+1, d+1, 3), s, t (N,).  Returns (S, S_s, S_t[, S_ss, S_st, S_tt]), (N, 3) each.

    One batched product: the tensor-product weights B_i(s) B_j(t) (and their derivatives) of
    every point, (N, q, (d+1)^2), times its net, (N, (d+1)^2, 3)."""
    d = nets.shape[1] - 1
    bs, dbs, ddbs = bernstein_derivatives(d, s)
    bt, dbt, ddbt = bernstein_derivatives(d, t)
    if order >= 2:
        ws, wt = np.stack([bs, dbs, bs, ddbs, dbs, bs], 1), np.stack([bt, bt, dbt, bt, dbt, ddbt], 1)
    elif order == 1:
        ws, wt = np.stack([bs, dbs, bs], 1), np.stack([bt, bt, dbt], 1)
    else:
        ws, wt = bs[:, None], bt[:, None]
    w = (ws[:, :, :, None] * wt[:, :, None, :]).reshape(len(bs), ws.shape[1], (d + 1) ** 2)
    out = np.matmul(w, nets.reshape(len(bs), (d + 1) ** 2, 3))
    return tuple(out[:, k] for k in range(out.shape[1]))


def unit_normals(su: np.ndarray, sv: np.ndarray) -> np.ndarray:
    """(N, 3) unit normals S_u x S_v / |S_u x S_v| (zero where the Jacobian vanishes)."""
    n = np.cross(su, sv)
    size = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(size > 1e-300, n / np.maximum(size, 1e-300), 0.0)


@dataclass
class SurfaceIndex:
    """Dense samples of the whole surface with KD-trees, for closest points and drop-cutting.

    nets: (p, d+1, d+1, 3) all patches; spacing: the largest distance between neighbouring
    samples along a patch's grid lines (each patch gets its own n x n grid)."""

    nets: np.ndarray
    spacing: float

    @cached_property
    def samples(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(points (m, 3), patch (m,), st (m, 2))."""
        nets = self.nets
        # Patch extent along its grid lines from the control net (an upper bound of the curves).
        ext_s = np.linalg.norm(np.diff(nets, axis=1), axis=-1).sum(axis=1).max(axis=1)
        ext_t = np.linalg.norm(np.diff(nets, axis=2), axis=-1).sum(axis=2).max(axis=1)
        n = np.clip(np.ceil(np.maximum(ext_s, ext_t) / self.spacing).astype(int) + 1, 4, 160)
        pts, rows, sts = [], [], []
        for m in np.unique(n):
            ks = np.flatnonzero(n == m)
            u = np.linspace(0.0, 1.0, m)
            s, t = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
            bs, bt = bernstein(nets.shape[1] - 1, s), bernstein(nets.shape[1] - 1, t)
            p = np.einsum("mi,mj,kijc->kmc", bs, bt, nets[ks], optimize=True)
            pts.append(p.reshape(-1, 3))
            rows.append(np.repeat(ks, s.size))
            sts.append(np.tile(np.stack([s, t], axis=1), (ks.size, 1)))
        return np.concatenate(pts), np.concatenate(rows), np.concatenate(sts)

    @cached_property
    def tree(self) -> cKDTree:
        return cKDTree(self.samples[0])

    @cached_property
    def tree_xy(self) -> cKDTree:
        return cKDTree(self.samples[0][:, :2])

    def closest(self, c: np.ndarray, k: int = 3, iterations: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest surface points to c (N, 3): (distance (N,), foot points (N, 3), patch (N,)).

        Newton's method on |S(s, t) - c|^2 / 2 in the patches of the k nearest samples, from
        those samples, clamped to the unit square (a foot on a patch side is then the closest
        point of that patch; the neighbour's own start covers the other side)."""
        c = np.asarray(c, dtype=np.float64).reshape(-1, 3)
        pts, rows, sts = self.samples
        best_d = np.full(len(c), np.inf)
        best_p = np.zeros((len(c), 3))
        best_r = np.zeros(len(c), dtype=np.int64)
        for lo in range(0, len(c), CHUNK):
            cc = c[lo : lo + CHUNK]
            _, idx = self.tree.query(cc, k=min(k, len(pts)))
            idx = idx.reshape(len(cc), -1)
            rep = np.repeat(cc, idx.shape[1], axis=0)
            flat = idx.ravel()
            row = rows[flat]
            st = sts[flat].copy()
            nets = self.nets[row]
            for _ in range(iterations):
                s, su, sv, suu, suv, svv = evaluate_points(nets, st[:, 0], st[:, 1], order=2)
                r = s - rep
                g = np.stack([np.einsum("nc,nc->n", su, r), np.einsum("nc,nc->n", sv, r)], axis=1)
                a = np.einsum("nc,nc->n", su, su) + np.einsum("nc,nc->n", suu, r)
                b = np.einsum("nc,nc->n", su, sv) + np.einsum("nc,nc->n", suv, r)
                e = np.einsum("nc,nc->n", sv, sv) + np.einsum("nc,nc->n", svv, r)
                det = a * e - b * b
                ok = (det > 1e-14 * (a * a + e * e + 1e-300)) & (a > 0)
                step = np.where(
                    ok[:, None],
                    np.stack([e * g[:, 0] - b * g[:, 1], a * g[:, 1] - b * g[:, 0]], axis=1) / np.where(ok, det, 1.0)[:, None],
                    g / np.maximum(np.stack([a, e], axis=1), 1e-12) * 0.5,  # damped gradient where not convex
                )
                st = np.clip(st - np.clip(step, -0.25, 0.25), 0.0, 1.0)
            p = evaluate_points(nets, st[:, 0], st[:, 1], order=0)[0]
            dist = np.linalg.norm(p - rep, axis=1).reshape(len(cc), -1)
            # A sample itself is a surface point: never report more than the nearest sample.
            sample_d = np.linalg.norm(pts[flat] - rep, axis=1).reshape(len(cc), -1)
            use_sample = sample_d < dist
            dist = np.where(use_sample, sample_d, dist)
            p = np.where(use_sample.ravel()[:, None], pts[flat], p).reshape(len(cc), -1, 3)
            j = np.argmin(dist, axis=1)
            ar = np.arange(len(cc))
            best_d[lo : lo + CHUNK] = dist[ar, j]
            best_p[lo : lo + CHUNK] = p[ar, j]
            best_r[lo : lo + CHUNK] = row.reshape(len(cc), -1)[ar, j]
        return best_d, best_p, best_r

    def drop(self, c: np.ndarray, radius: float, rounds: int = 8) -> np.ndarray:
        """Ball centres lifted along +z until the ball of the given radius clears the surface.

        A ball at centre c touches no sample q with |q_xy - c_xy| < R as long as
        c_z >= q_z + sqrt(R^2 - |q_xy - c_xy|^2) (drop-cutter; this also clears the shank above
        the ball); then Newton closest points refine it: where the distance d < R, the centre
        rises by dz with |c + dz z - p| = R for the foot p.  Centres that clear already stay."""
        c = np.array(c, dtype=np.float64).reshape(-1, 3)
        pts = self.samples[0]
        for lo in range(0, len(c), CHUNK):
            cc = c[lo : lo + CHUNK]
            pairs = cKDTree(cc[:, :2]).sparse_distance_matrix(
                self.tree_xy, radius * (1.0 - 1e-12), output_type="ndarray"
            )
            if pairs.size:
                owner, idx, dxy = pairs["i"], pairs["j"], pairs["v"]
                need = pts[idx, 2] + np.sqrt(np.maximum(radius * radius - dxy * dxy, 0.0))
                np.maximum.at(cc[:, 2], owner, need)
        active = np.arange(len(c))
        for _ in range(rounds):
            d, p, _ = self.closest(c[active])
            low = d < radius * (1.0 - 1e-9)
            if not low.any():
                break
            active, p = active[low], p[low]
            v = c[active] - p
            rxy2 = np.sum(v[:, :2] ** 2, axis=1)
            dz = np.sqrt(np.maximum(radius * radius - rxy2, 0.0)) - v[:, 2]
            c[active, 2] += np.maximum(dz, 0.0) + 1e-9 * radius
        return c
