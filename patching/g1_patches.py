"""Bi-quintic G1 patches around extraordinary points (seed 002, section 3.4), as row mixing.

Every coefficient of every patch is a row over the columns [control points | anchors] (see
``bezier_extraction``).  Irregular faces (faces with an EP corner) are degree-elevated to
bi-quintic, then their rows are recombined, EP by EP, spoke by spoke and face by face, by
small local solves that depend on intervals and connecting functions only.  Each step is a
sparse matrix T with new_rows = T @ old_rows (identity outside the rows it sets):

1. red (per EP): P00, the spoke points P^i[1,0], the face points P^i[1,1] and P^i[2,0];
   least squares towards the extraction under G_0 and G_1 of every spoke, with P00 kept at
   the extraction's vertex point (eq. 3, so the anchors fix it).
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
configurations, so here P^i[2,0] joins the least squares (one more difference, q_i - s_i) and
G_1 joins the constraints.  Where b_i is far from zero the result is the paper's up to the
weight of that one difference; where b_i = 0 it stays defined.  The differences do not see a
translation, so P00 is held at its extraction value; the solve uses the null space of the
constraints (G_0 has rank n - 2: the tangent plane), which tolerates the dependent rows.

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

__all__ = ["EPRing", "ep_rings", "local_index", "G1Assembly", "RowMixer", "blue_weights"]

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


@dataclass(frozen=True)
class EPRing:
    """One EP: vertex, spokes h[i] (outgoing half-edges, counter-clockwise), intervals d[i],
    faces[i] = face(h[i]) (patch i), corner[i] = corner of the EP in that face, far_ep[i] the
    EP at the far end of spoke i (-1 if regular) and far_spoke[i] its spoke index there."""

    vertex: int
    h: np.ndarray
    d: np.ndarray
    faces: np.ndarray
    corner: np.ndarray
    far_ep: np.ndarray
    far_spoke: np.ndarray

    @property
    def n(self) -> int:
        return int(self.h.size)


def ep_rings(topo: Topology, eps: np.ndarray) -> dict[int, EPRing]:
    """The local ring of every EP (a Python loop over EPs: small local problems)."""
    offsets = topo.mesh.face_offsets
    iv = topo.halfedge_interval
    rings = {}
    spoke_of: dict[int, tuple[int, int]] = {}
    raw = {}
    for v in eps.tolist():
        h = topo.one_ring(v)
        raw[v] = h
        for i, hh in enumerate(h.tolist()):
            spoke_of[hh] = (v, i)
    for v, h in raw.items():
        faces = topo.face[h]
        far = [spoke_of.get(int(t), (-1, -1)) for t in topo.twin[h]]
        rings[v] = EPRing(
            vertex=v,
            h=h,
            d=iv[h],
            faces=faces,
            corner=h - offsets[faces],
            far_ep=np.array([f[0] for f in far], dtype=np.int64),
            far_spoke=np.array([f[1] for f in far], dtype=np.int64),
        )
    return rings


class RowMixer:
    """Collects new_row[target] = sum_k w_k old_row[source_k] for one step; untouched rows copy."""

    def __init__(self, n_rows: int) -> None:
        self.n_rows = n_rows
        self.targets: list[np.ndarray] = []
        self.sources: list[np.ndarray] = []
        self.weights: list[np.ndarray] = []

    def set(self, targets: np.ndarray, sources: np.ndarray, weights: np.ndarray) -> None:
        """Every target row in ``targets`` (k,) becomes weights (k, m) @ rows ``sources`` (m,)."""
        targets = np.atleast_1d(np.asarray(targets, dtype=np.int64))
        sources = np.asarray(sources, dtype=np.int64)
        weights = np.asarray(weights, dtype=np.float64).reshape(targets.size, sources.size)
        self.targets.append(np.repeat(targets, sources.size))
        self.sources.append(np.tile(sources, targets.size))
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


def _null_space(a: np.ndarray, rtol: float = 1e-11) -> np.ndarray:
    u, s, vt = np.linalg.svd(a)
    rank = int(np.count_nonzero(s > rtol * max(1.0, s.max(initial=0.0))))
    return vt[rank:].T


@lru_cache(maxsize=4096)
def _red_operator(n: int, key: tuple) -> np.ndarray:
    """K with x = K x_hat for x = [P00, s_0..s_{n-1}, f_0..f_{n-1}, q_0..q_{n-1}].

    key = (alpha_a, alpha_b, b0, b1-or-None) per spoke, hashable."""
    size = 1 + 3 * n
    s = lambda i: 1 + (i % n)  # noqa: E731
    f = lambda i: 1 + n + (i % n)  # noqa: E731
    q = lambda i: 1 + 2 * n + (i % n)  # noqa: E731
    rows = []
    for i, (aa, ab, b0, b1) in enumerate(key):
        g = spoke_equations(aa, ab, b0, b1)
        # slot -> unknown: r0 = P00, r1 = s_i, r2 = q_i; A[0,1] = s_{i+1}, A[1,1] = f_i;
        # B[1,0] = s_{i-1}, B[1,1] = f_{i-1}.
        slot_to_x = {r_slot(0): 0, r_slot(1): s(i), r_slot(2): q(i), a_slot(0): s(i + 1),
                     a_slot(1): f(i), b_slot(0): s(i - 1), b_slot(1): f(i - 1)}
        for k in (0, 1):
            row = np.zeros(size)
            for slot, col in slot_to_x.items():
                row[col] += g[k, slot]
            assert np.allclose(np.delete(g[k], list(slot_to_x)), 0.0), "G_0, G_1 reach beyond the red slots"
            rows.append(row)
    pin = np.zeros(size)
    pin[0] = 1.0
    constraints = np.vstack(rows + [pin])
    # Differences D (and q_i - s_i).
    diffs = []
    for i in range(n):
        for a, b in ((s(i), 0), (f(i), s(i)), (s(i + 1), f(i)), (q(i), s(i))):
            row = np.zeros(size)
            row[a] += 1.0
            row[b] -= 1.0
            diffs.append(row)
    e = np.vstack(diffs)
    z = _null_space(constraints)
    # x = 1 x0_hat + Z (E Z)^+ E x_hat  (E annihilates constants).
    ez = e @ z
    k = z @ np.linalg.pinv(ez, rcond=1e-12) @ e
    k[:, 0] += 1.0 - k.sum(axis=1)  # exact affine invariance: the constant part goes to x0
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
    """Row bookkeeping of the quintic irregular patches and the four G1 steps."""

    def __init__(self, topo: Topology, rings: dict[int, EPRing], face_row: np.ndarray, angles: str) -> None:
        """face_row[f]: first row of face f's 36 quintic rows (-1 for faces that are not
        irregular).  angles: "optimized", "default" or "uniform" (angle_configuration mode)."""
        self.topo = topo
        self.rings = rings
        self.face_row = face_row
        self.angles = angles
        self.config = {v: self._connecting(r) for v, r in rings.items()}

    def _connecting(self, ring: EPRing):
        cfg = angle_configuration(ring.d, mode=self.angles)
        return -np.asarray(cfg.b)  # beta(0) per spoke (g1_constraints sign)

    def row(self, face: int, p: int, q: int) -> int:
        return int(self.face_row[face]) + 6 * p + q

    def local_row(self, ring: EPRing, patch: int, j: int, m: int) -> int:
        i = patch % ring.n
        p, q = local_index(int(ring.corner[i]), j, m)
        return self.row(int(ring.faces[i]), p, q)

    def spoke_key(self, ring: EPRing, i: int):
        n, d = ring.n, ring.d
        b0 = float(self.config[ring.vertex][i])
        far = int(ring.far_ep[i])
        b1 = None if far < 0 else float(self.config[far][int(ring.far_spoke[i])])
        return (float(d[i] * d[(i - 1) % n]), float(d[i] * d[(i + 1) % n]), b0, b1)

    def spoke_slots(self, ring: EPRing, i: int) -> np.ndarray:
        """(SLOTS,) rows: r_j = patch i [j,0]; A[j,1] = patch i [j,1]; B[1,j] = patch i-1 [1,j]."""
        r = [self.local_row(ring, i, j, 0) for j in range(6)]
        a = [self.local_row(ring, i, j, 1) for j in range(6)]
        b = [self.local_row(ring, i - 1, 1, j) for j in range(6)]
        return np.array(r + a + b, dtype=np.int64)

    # -- steps -------------------------------------------------------------------------------
    def red(self, mixer: RowMixer) -> None:
        for ring in self.rings.values():
            n = ring.n
            key = tuple(self.spoke_key(ring, i) for i in range(n))
            k = _red_operator(n, key)
            src = np.array(
                [self.local_row(ring, 0, 0, 0)]
                + [self.local_row(ring, i, 1, 0) for i in range(n)]
                + [self.local_row(ring, i, 1, 1) for i in range(n)]
                + [self.local_row(ring, i, 2, 0) for i in range(n)],
                dtype=np.int64,
            )
            for i in range(n):
                mixer.set(self.local_row(ring, i, 0, 0), src, k[0])
                mixer.set([self.local_row(ring, i, 1, 0), self.local_row(ring, i - 1, 0, 1)], src, np.vstack([k[1 + i]] * 2))
                mixer.set(self.local_row(ring, i, 1, 1), src, k[1 + n + i])
                mixer.set([self.local_row(ring, i, 2, 0), self.local_row(ring, i - 1, 0, 2)], src, np.vstack([k[1 + 2 * n + i]] * 2))

    def black(self, mixer: RowMixer) -> None:
        weights = np.array([0.1, -0.5, 1.0, 0.5, -0.1])  # P00, P10, P20, P40, P50
        for ring in self.rings.values():
            for i in range(ring.n):
                if ring.far_ep[i] >= 0:
                    continue
                src = [self.local_row(ring, i, j, 0) for j in (0, 1, 2, 4, 5)]
                targets = [self.local_row(ring, i, 3, 0), self.local_row(ring, i - 1, 0, 3)]
                mixer.set(targets, src, np.vstack([weights, weights]))

    def green(self, mixer: RowMixer) -> None:
        for ring in self.rings.values():
            for i in range(ring.n):
                far = int(ring.far_ep[i])
                if far >= 0 and far < ring.vertex:
                    continue  # a spoke between two EPs is solved once, from its lower-id end
                g = spoke_equations(*self.spoke_key(ring, i))
                slots = self.spoke_slots(ring, i)
                for k in (2, 3):
                    na, nb = g[k, a_slot(k)], g[k, b_slot(k)]
                    norm = na * na + nb * nb
                    # x = x_hat - n (n . x_hat + rest) / |n|^2 for x = (A[k,1], B[1,k]).
                    coeff = -g[k] / norm
                    wa = np.outer([na], coeff).ravel()
                    wb = np.outer([nb], coeff).ravel()
                    wa[a_slot(k)] += 1.0
                    wb[b_slot(k)] += 1.0
                    mixer.set(slots[a_slot(k)], slots, wa)
                    mixer.set(slots[b_slot(k)], slots, wb)
                    if ring.far_ep[i] >= 0:
                        # the same rows seen from the far EP are the same slots: nothing more
                        pass

    def blue(self, mixer: RowMixer, faces: np.ndarray) -> None:
        w = blue_weights()
        for f in faces.tolist():
            base = int(self.face_row[f])
            src = base + np.arange(36)
            targets = base + np.array([6 * 2 + 2, 6 * 3 + 2, 6 * 2 + 3, 6 * 3 + 3])
            mixer.set(targets, src, w)
