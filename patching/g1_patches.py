"""Bi-quintic G1 patches around extraordinary points (seed 002, section 3.4), as row mixing.

Every coefficient of every patch is a row over the columns [control points | anchors] (see
``bezier_extraction``).  Irregular faces (faces with an EP corner) are degree-elevated to
bi-quintic, then their rows are recombined, EP by EP, spoke by spoke and face by face, by
small local solves that depend on intervals and connecting functions only.  Each step is a
sparse matrix T with new_rows = T @ old_rows (identity outside the rows it sets):

1. red (per EP): P00, the spoke points P^i[1,0], the face points P^i[1,1] and P^i[2,0]:
   least squares towards the extraction under G_0 (then G_1) of every spoke, with P00 kept
   at the extraction's vertex point (eq. 3, so the anchors fix it).
2. black (per spoke with a regular far end): P^i[3,0] from the fifth difference (eq. 8, last
   row: P30 = P20 + P40/2 - P10/2 + P00/10 - P50/10).
3. green (per spoke): A[k,1], B[1,k] for k = 2, 3, nearest to the extraction under G_2, G_3.
4. blue (per irregular face): the four inner coefficients from f_1, f_2 (below).

The local frame of an EP and the equations G_k are those of ``g1_constraints``.

Reconstruction of the red problem (seed 002 text lost between "with linear constraints," and
"where M_vA"): minimise sum |D - D_hat|^2 over the differences D of the ring V_0 = P00,
spoke points and face points (D_{3i} = s_i - P00, D_{3i+1} = f_i - s_i, D_{3i+2} = s_{i+1} - f_i)
subject to G_0 of every spoke.  Deviation, said in the issue note: the paper then takes
P^i[2,0] from G_1 alone, dividing by 4 b_i; b_i vanishes at valence 4 and for symmetric
configurations, so here a second stage moves P^i[2,0] *and* P^i[1,1] as little as possible
(least squares, equal weights) to satisfy G_1, keeping P00 and the spoke points, hence the
tangent plane of section 3.5.  Where b_i = 0 it stays defined.  The differences do not see a
translation, so P00 is held at its extraction value; the solves use the null space of the
constraints and pseudo-inverses (G_0 has rank n - 2: the tangent plane), which tolerate the
dependent rows.

Blue coefficients (printed formulas garbled; reconstructed): a quintic that is a
degree-elevated cubic has q_2 = f_1(q_0, q_1, q_4, q_5) and q_3 = f_2(q_0, q_1, q_4, q_5) with
f_1 = -3/10 a + b + 1/2 c - 1/5 d and f_2 = -1/5 a + 1/2 b + c - 3/10 d (checked by elevating
cubics in the tests).  Each inner coefficient P[p, q] (p, q in {2, 3}) is the average of the
rule along its row and along its column: P[p,q] = 1/2 f_q(P[p,0], P[p,1], P[p,4], P[p,5]) +
1/2 f_p(P[0,q], P[1,q], P[4,q], P[5,q]), with f_2 := f_1 and f_3 := f_2.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from .angle_configuration import angle_configuration
from .g1_constraints import a_slot, b_slot, r_slot, spoke_equations
from .surface import CORNER_PARAMETERS
from .topology import Topology

__all__ = ["EPGroup", "ep_groups", "local_index", "LOCAL_OFFSET", "G1Assembly", "RowMixer", "blue_weights"]

QUINTIC = 5
_CORNERS = CORNER_PARAMETERS.astype(np.int64)


def local_index(corner: int, j: int, m: int, degree: int = QUINTIC) -> tuple[int, int]:
    """Net index (p, q) in the face's own frame of local (j, m) of the patch whose EP sits at
    face corner ``corner``: j runs towards corner+1, m towards corner-1."""
    c0 = _CORNERS[corner]
    u = _CORNERS[(corner + 1) % 4] - c0
    w = _CORNERS[(corner + 3) % 4] - c0
    p, q = degree * c0 + j * u + m * w
    return int(p), int(q)


#: LOCAL_OFFSET[corner, j, m] = 6 p + q: the row offset of local (j, m) inside a face's 36 rows.
LOCAL_OFFSET = np.array(
    [[[6 * local_index(c, j, m)[0] + local_index(c, j, m)[1] for m in range(6)] for j in range(6)] for c in range(4)],
    dtype=np.int64,
)


@dataclass(frozen=True)
class EPGroup:
    """All EPs of one valence n, as (E, n) arrays in counter-clockwise spoke order.

    h: spokes (outgoing half-edges); d: their intervals; faces: patch i = face(h_i); corner:
    the EP's corner in that face; far: the vertex at the far end of each spoke if it is an EP
    (else -1); far_spoke: that spoke's index in the far EP's ring."""

    n: int
    vertices: np.ndarray
    h: np.ndarray
    d: np.ndarray
    faces: np.ndarray
    corner: np.ndarray
    far: np.ndarray
    far_spoke: np.ndarray


def ep_groups(topo: Topology, eps: np.ndarray) -> list[EPGroup]:
    """The rings of all EPs, grouped by valence, without a Python loop over EPs."""
    eps = np.asarray(eps, dtype=np.int64)
    valence = topo.valence[eps]
    spoke_index = np.full(topo.origin.size, -1, dtype=np.int64)
    is_ep = np.zeros(topo.n_vertices, dtype=bool)
    is_ep[eps] = True
    raw = []
    for n in np.unique(valence).tolist():
        vs = eps[valence == n]
        h = np.empty((vs.size, n), dtype=np.int64)
        h[:, 0] = topo.outgoing[vs]
        for i in range(1, n):
            h[:, i] = topo.rotate(h[:, i - 1])
        spoke_index[h] = np.arange(n)[None, :]
        raw.append((n, vs, h))
    groups = []
    offsets = topo.mesh.face_offsets
    for n, vs, h in raw:
        faces = topo.face[h]
        ends = topo.dest[h]
        far = np.where(is_ep[ends], ends, -1)
        groups.append(
            EPGroup(n, vs, h, topo.halfedge_interval[h], faces, h - offsets[faces], far, np.where(far >= 0, spoke_index[topo.twin[h]], -1))
        )
    return groups


class RowMixer:
    """Collects new_row[target] = sum_k w_k old_row[source_k] for one step; untouched rows copy."""

    def __init__(self, n_rows: int) -> None:
        self.n_rows = n_rows
        self.targets: list[np.ndarray] = []
        self.sources: list[np.ndarray] = []
        self.weights: list[np.ndarray] = []

    def set(self, targets: np.ndarray, sources: np.ndarray, weights: np.ndarray) -> None:
        """Batched: targets (E, T) rows become weights (T, S) (or (E, T, S)) @ rows sources (E, S)."""
        targets = np.asarray(targets, dtype=np.int64)
        sources = np.asarray(sources, dtype=np.int64)
        if targets.ndim == 1:
            targets, sources = targets[None], sources[None]
        e, t = targets.shape
        s = sources.shape[1]
        weights = np.broadcast_to(np.asarray(weights, dtype=np.float64), (e, t, s))
        self.targets.append(np.broadcast_to(targets[:, :, None], (e, t, s)).ravel())
        self.sources.append(np.broadcast_to(sources[:, None, :], (e, t, s)).ravel())
        self.weights.append(weights.ravel())

    def matrix(self) -> sp.csr_matrix:
        if not self.targets:
            return sp.identity(self.n_rows, format="csr")
        t = np.concatenate(self.targets)
        s = np.concatenate(self.sources)
        w = np.concatenate(self.weights)
        keep = np.ones(self.n_rows, dtype=bool)
        keep[t] = False
        ident = np.flatnonzero(keep)
        rows = np.concatenate([t, ident])
        cols = np.concatenate([s, ident])
        vals = np.concatenate([w, np.ones(ident.size)])
        out = sp.csr_matrix((vals, (rows, cols)), shape=(self.n_rows, self.n_rows))
        out.sum_duplicates()
        return out


def _unique_rows(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of a float array (NaN-safe) and the inverse index."""
    key = np.where(np.isnan(a), np.inf, a)
    uniq, inverse = np.unique(key, axis=0, return_inverse=True)
    uniq = np.where(np.isinf(uniq), np.nan, uniq)
    return uniq, inverse.ravel()


def _null_space(a: np.ndarray, rtol: float = 1e-11) -> np.ndarray:
    u, s, vt = np.linalg.svd(a)
    rank = int(np.count_nonzero(s > rtol * max(1.0, s.max(initial=0.0))))
    return vt[rank:].T


@lru_cache(maxsize=4096)
def _red_operator(n: int, key: tuple) -> np.ndarray:
    """K with x = K x_hat for x = [P00, s_0..s_{n-1}, f_0..f_{n-1}, q_0..q_{n-1}].

    key = (alpha_a, alpha_b, b0, b1) per spoke, hashable; b1 NaN for a regular far end.
    Stage 1 (seed 002 section 3.4): P00 held, spoke points s and face points f nearest to the
    extraction's differences D under G_0; every input is then in the anchors' plane, so the
    tangent plane is section 3.5's.  Stage 2: f and q (= P^i[2,0]) nearest to stage 1 and the
    extraction under G_1, with P00 and s kept (the paper takes q from G_1 alone, dividing by
    4 b_i, which vanishes at valence 4 and in symmetric configurations)."""
    size = 1 + 3 * n
    s = lambda i: 1 + (i % n)  # noqa: E731
    f = lambda i: 1 + n + (i % n)  # noqa: E731
    q = lambda i: 1 + 2 * n + (i % n)  # noqa: E731
    rows = {0: [], 1: []}
    for i, (aa, ab, b0, b1) in enumerate(key):
        g = spoke_equations(aa, ab, b0, None if np.isnan(b1) else b1)
        # slot -> unknown: r0 = P00, r1 = s_i, r2 = q_i; A[0,1] = s_{i+1}, A[1,1] = f_i;
        # B[1,0] = s_{i-1}, B[1,1] = f_{i-1}.
        slot_to_x = {r_slot(0): 0, r_slot(1): s(i), r_slot(2): q(i), a_slot(0): s(i + 1),
                     a_slot(1): f(i), b_slot(0): s(i - 1), b_slot(1): f(i - 1)}
        for k in (0, 1):
            row = np.zeros(size)
            for slot, col in slot_to_x.items():
                row[col] += g[k, slot]
            assert np.allclose(np.delete(g[k], list(slot_to_x)), 0.0), "G_0, G_1 reach beyond the red slots"
            rows[k].append(row)
    # Stage 1 on x1 = [P00, s, f].
    n1 = 1 + 2 * n
    pin = np.zeros(n1)
    pin[0] = 1.0
    c1 = np.vstack([r[:n1] for r in rows[0]] + [pin])
    diffs = []
    for i in range(n):
        for a, b in ((s(i), 0), (f(i), s(i)), (s(i + 1), f(i))):
            row = np.zeros(n1)
            row[a] += 1.0
            row[b] -= 1.0
            diffs.append(row)
    e = np.vstack(diffs)
    z = _null_space(c1)
    # x1 = 1 x0_hat + Z (E Z)^+ E x1_hat  (E annihilates constants).
    k1 = z @ np.linalg.pinv(e @ z, rcond=1e-12) @ e
    k1[:, 0] += 1.0 - k1.sum(axis=1)
    stage1 = np.zeros((size, size))
    stage1[:n1, :n1] = k1
    stage1[n1:, n1:] = np.eye(n)  # q keeps its extraction value for now
    # Stage 2: y = [f, q] nearest to stage 1 under G_1, P00 and s fixed.
    c = np.vstack(rows[1])  # (n, size)
    y = np.arange(1 + n, size)
    cy = c[:, y]
    correction = np.zeros((size, size))
    correction[np.ix_(y, np.arange(size))] = -cy.T @ np.linalg.pinv(cy @ cy.T, rcond=1e-12) @ c
    k = (np.eye(size) + correction) @ stage1
    k[:, 0] += 1.0 - k.sum(axis=1)  # exact affine invariance: the constant part goes to P00
    k.setflags(write=False)
    return k


@lru_cache(maxsize=None)
def blue_weights() -> np.ndarray:
    """(4, 36) weights of the inner coefficients (2,2), (3,2), (2,3), (3,3) over a 6x6 net."""
    f1 = np.array([-0.3, 1.0, 0.5, -0.2])
    f2 = np.array([-0.2, 0.5, 1.0, -0.3])
    rule = {2: f1, 3: f2}
    outer = (0, 1, 4, 5)
    out = np.zeros((4, 36))
    for r, (p, q) in enumerate(((2, 2), (3, 2), (2, 3), (3, 3))):
        for w, m in zip(rule[q], outer):
            out[r, 6 * p + m] += 0.5 * w
        for w, m in zip(rule[p], outer):
            out[r, 6 * m + q] += 0.5 * w
    out.setflags(write=False)
    return out


class G1Assembly:
    """Row bookkeeping of the quintic irregular patches and the four G1 steps, vectorised over
    the EPs of one valence; local solves are computed once per distinct configuration."""

    def __init__(self, topo: Topology, groups: list[EPGroup], face_row: np.ndarray, angles: str) -> None:
        """face_row[f]: first row of face f's 36 quintic rows (-1 for faces that are not
        irregular).  angles: "optimized", "default" or "uniform" (angle_configuration mode)."""
        self.topo = topo
        self.groups = groups
        self.face_row = face_row
        beta0 = np.full(topo.origin.size, np.nan)
        self.beta0 = []
        for g in groups:
            uniq, inverse = _unique_rows(g.d)
            b = np.array([-np.asarray(angle_configuration(row, mode=angles).b) for row in uniq])
            b0 = b[inverse].reshape(g.d.shape)  # beta(0) per spoke (g1_constraints sign)
            beta0[g.h] = b0
            self.beta0.append(b0)
        self.beta1 = [np.where(g.far >= 0, beta0[topo.twin[g.h]], np.nan) for g in groups]

    def rows(self, g: EPGroup, patch: np.ndarray | int, j: int, m: int) -> np.ndarray:
        """(E,) rows of local (j, m) of patch i (mod n) of every EP of the group."""
        i = np.asarray(patch) % g.n
        return self.face_row[g.faces[:, i]] + LOCAL_OFFSET[g.corner[:, i], j, m]

    def spoke_keys(self, k: int) -> np.ndarray:
        """(E, n, 4): (alpha_A, alpha_B, b0, b1) of every spoke of group k."""
        g = self.groups[k]
        return np.stack(
            [g.d * np.roll(g.d, 1, axis=1), g.d * np.roll(g.d, -1, axis=1), self.beta0[k], self.beta1[k]], axis=-1
        )

    # -- steps -------------------------------------------------------------------------------
    def red(self, mixer: RowMixer) -> None:
        for k, g in enumerate(self.groups):
            n = g.n
            keys = self.spoke_keys(k).reshape(len(g.vertices), 4 * n)
            uniq, inverse = _unique_rows(keys)
            ops = np.array([_red_operator(n, tuple(map(tuple, row.reshape(n, 4).tolist()))) for row in uniq])
            i = np.arange(n)
            src = np.concatenate(
                [self.rows(g, 0, 0, 0)[:, None]]
                + [np.stack([self.rows(g, ii, a, b) for ii in i], 1) for a, b in ((1, 0), (1, 1), (2, 0))],
                axis=1,
            )
            # targets and the unknown each takes
            tgt, unknown = [], []
            for ii in range(n):
                tgt += [self.rows(g, ii, 0, 0), self.rows(g, ii, 1, 0), self.rows(g, ii - 1, 0, 1),
                        self.rows(g, ii, 1, 1), self.rows(g, ii, 2, 0), self.rows(g, ii - 1, 0, 2)]
                unknown += [0, 1 + ii, 1 + ii, 1 + n + ii, 1 + 2 * n + ii, 1 + 2 * n + ii]
            weights = ops[inverse][:, unknown, :]  # (E, T, S)
            mixer.set(np.stack(tgt, 1), src, weights)

    def black(self, mixer: RowMixer) -> None:
        weights = np.array([[0.1, -0.5, 1.0, 0.5, -0.1]] * 2)  # P00, P10, P20, P40, P50
        for g in self.groups:
            for i in range(g.n):
                sel = g.far[:, i] < 0
                if not sel.any():
                    continue
                src = np.stack([self.rows(g, i, j, 0)[sel] for j in (0, 1, 2, 4, 5)], 1)
                tgt = np.stack([self.rows(g, i, 3, 0)[sel], self.rows(g, i - 1, 0, 3)[sel]], 1)
                mixer.set(tgt, src, weights)

    def green(self, mixer: RowMixer) -> None:
        for k, g in enumerate(self.groups):
            keys = self.spoke_keys(k)
            for i in range(g.n):
                # a spoke between two EPs is solved once, from its lower-id end
                sel = (g.far[:, i] < 0) | (g.far[:, i] > g.vertices)
                if not sel.any():
                    continue
                slots = np.stack(
                    [self.rows(g, i, j, 0) for j in range(6)]
                    + [self.rows(g, i, j, 1) for j in range(6)]
                    + [self.rows(g, i - 1, 1, j) for j in range(6)],
                    axis=1,
                )[sel]
                uniq, inverse = _unique_rows(keys[sel, i])
                weights = np.array([_green_weights(*row) for row in uniq])[inverse]  # (E, 4, 18)
                tgt = slots[:, [a_slot(2), b_slot(2), a_slot(3), b_slot(3)]]
                mixer.set(tgt, slots, weights)

    def blue(self, mixer: RowMixer) -> None:
        base = self.face_row[self.face_row >= 0]
        src = base[:, None] + np.arange(36)[None, :]
        tgt = base[:, None] + np.array([6 * 2 + 2, 6 * 3 + 2, 6 * 2 + 3, 6 * 3 + 3])[None, :]
        mixer.set(tgt, src, blue_weights())


@lru_cache(maxsize=65536)
def _green_weights(alpha_a: float, alpha_b: float, b0: float, b1: float) -> np.ndarray:
    """(4, SLOTS): A[2,1], B[1,2], A[3,1], B[1,3] nearest to their extraction values under
    G_2, G_3: x = x_hat - n (n . x_hat + rest) / |n|^2 for x = (A[k,1], B[1,k])."""
    g = spoke_equations(alpha_a, alpha_b, b0, None if np.isnan(b1) else b1)
    out = np.zeros((4, g.shape[1]))
    for r, k in enumerate((2, 3)):
        na, nb = g[k, a_slot(k)], g[k, b_slot(k)]
        coeff = -g[k] / (na * na + nb * nb)
        out[2 * r] = na * coeff
        out[2 * r, a_slot(k)] += 1.0
        out[2 * r + 1] = nb * coeff
        out[2 * r + 1, b_slot(k)] += 1.0
    out.setflags(write=False)
    return out
