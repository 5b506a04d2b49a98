"""Bi-quintic G1 patches around extraordinary points ([FSLYJ] sec. 3.4), as row mixing.

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
4. blue (per irregular face): the four inner coefficients from f_1, f_2 (below); only with
   ``build_operator(interior="cubic-isocurves")``.  By default they keep the extraction's
   values (see ``operator.build_operator``: the seed's rule leaves ripples).

The local frame of an EP and the equations G_k are those of ``g1_constraints``.  EPs joined
by a spoke to another EP take steps 1-3 jointly instead, one fairing solve per cluster
(``cluster_fairing``, ``build_operator(g1_solve="joint")``, the default): the per-EP order
folds patches there that no per-EP rule can avoid.

Reconstruction of the red problem ([FSLYJ] text lost between "with linear constraints," and
"where M_vA"): minimise sum |D - D_hat|^2 over the differences D of the ring V_0 = P00,
spoke points and face points (D_{3i} = s_i - P00, D_{3i+1} = f_i - s_i, D_{3i+2} = s_{i+1} - f_i)
subject to G_0 of every spoke.  Deviation, said in the issue note: the paper then takes
P^i[2,0] from G_1 alone, dividing by 4 b_i; b_i vanishes at valence 4 and for symmetric
configurations, so here a second stage moves P^i[2,0] *and* P^i[1,1] as little as possible
(least squares, equal weights by default; below) to satisfy G_1, keeping P00 and the spoke points, hence the
tangent plane of section 3.5.  Where b_i = 0 it stays defined.  The differences do not see a
translation, so P00 is held at its extraction value; the solves use the null space of the
constraints and pseudo-inverses (G_0 has rank n - 2: the tangent plane), which tolerate the
dependent rows.

Spoke curves (ours).  G_0 makes the spoke legs s_i - P00 the image of the
characteristic fan, whose lengths follow the intervals (l_i about d_i), so where intervals
run against the control net's spacing stage 1 shortens or stretches a leg s_i a lot while
the far part of the spoke curve (P40, P50: the regular far end) stays.  Stage 2 then kept
q_i = P^i[2,0] at the extraction and the black step's P30 = q + P40/2 - s/2 + ... took the
whole mismatch: P30 overshot P40 and the patches beside the spoke folded (176 of the 15,360
patches of benchmarks/build.py's half-EP mesh, intervals 1, 2 and 5).  Stage 2's target for
q_i is therefore q_hat_i + (s_i - s_hat_i) / 2, the value that leaves P30 at the extraction's:
the curve bends back smoothly and no patch there folds (min cosine between neighbouring
normals 0.996).  At a spoke whose legs stage 1 does not move (uniform valence 4, any
extraction that is already G1) nothing changes.

Stage-2 weights (ours, measured, not used by default).  The G_1 residual left by stage 1 is
taken up by the least change of (f, q) in the metric |df|^2 + Q_WEIGHT |dq|^2.  With equal
weights q_i takes most of it (its coefficient in G_1 is the largest), and the black step passes
dq_i on to P30 as well, so the spoke curve P00..P50 can dip below its regular far end and rise
again: on refined prism caps with random strip intervals the cap EP's blending function gets a
second maximum (0.3% to 1% of its peak) in the patches of the valence-3 cap corners two faces
away (the spoke curve of the cap EP's function 6.1, 3.1, 0.8, 0.8, 2.3, 1.8 (x 1e-3) against
the extraction's 6.1, 4.6, 3.5, 2.8, 2.3, 1.8).  Found by switching one stage at a time.
Q_WEIGHT = 10 removes most of those tail maxima (docs/fidelity.md) but folds 72 of the 960
patches of tests/test_folds.py's EP-rich sphere (the face points take the correction and
overshoot), and 30 gives a prism cap function two maxima beside the EP; so the default stays 1
(G_1 is exact for every weight).  ``benchmarks/blending_families.py`` compares them.

Monotone spoke curves (ours, the default: ``MONOTONE_SPOKES``, at rings of valence up to
``MONOTONE_MAX_VALENCE``).  The tail maxima above are
the blending function of one EP (the prism cap centre) read along a spoke of another (the
valence-3 cap corner), where the extraction's spoke curve s, q, P30, P40, P50 of that function
falls monotonely and the red solve bends it back.  After stage 1 (P00, s_i fixed) the black
step's P30 = q_i + P40/2 - s_i/2 + P00/10 - P50/10 lies between q_i and P40 exactly when q_i
lies in [lo_i, hi_i] = [(P40 + s_i)/2 - (P00 - P50)/10, s_i] (for a falling curve; mirrored for
a rising one), bounds on the operator's weights, since every function's values at the red
inputs are its column x_c of the elevated extraction with the anchors folded in (topology and
intervals only, never positions).  Per EP ring and for every EP's function c whose extraction
spoke curve is monotone, the default operator K is checked; where it breaks a bound,
``_monotone_red`` takes K + D with D the least change (summed over all the functions it
touches at the red inputs, stage 2's weights) that keeps G_1 exact (C_y D = 0: the change
lies in the G_1 solution space for every input), keeps rows summing to one, and puts every
watched q_i back in its interval (a small QP).  Only EP functions are watched: watching all
functions asks for changes up to 14 times the functions' size (the bounds of neighbouring
vertices' functions conflict under G_1) and created maxima of 7% of the peak.  Rings where
the default already keeps the bounds get exactly the default operator.  Measured in
``benchmarks/blending_families.py`` (modes ``shipped`` and ``plain``) and docs/fidelity.md.

Blue coefficients (printed formulas garbled; reconstructed): a quintic that is a
degree-elevated cubic has q_2 = f_1(q_0, q_1, q_4, q_5) and q_3 = f_2(q_0, q_1, q_4, q_5) with
f_1 = -3/10 a + b + 1/2 c - 1/5 d and f_2 = -1/5 a + 1/2 b + c - 3/10 d (checked by elevating
cubics in the tests).  Each inner coefficient P[p, q] (p, q in {2, 3}) is the average of the
rule along its row and along its column: P[p,q] = 1/2 f_q(P[p,0], P[p,1], P[p,4], P[p,5]) +
1/2 f_p(P[0,q], P[1,q], P[4,q], P[5,q]), with f_2 := f_1 and f_3 := f_2.
"""

from __future__ import annotations

import copy
import hashlib
from collections.abc import Callable, Hashable
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from patching.extraordinary.angle_configuration import angle_configurations
from patching.topology.features import CORNER_SECTOR, CREASE_SECTOR, Features
from patching.extraordinary.g1_constraints import a_slot, b_slot, r_slot, spoke_equations, spoke_equations_batch
from patching.surface import CORNER_PARAMETERS
from patching.topology.tables import Topology
from patching.util.memo import batching, memo
from patching.util.solve_cache import lookup, lookup_many

__all__ = ["Q_WEIGHT", "MONOTONE_SPOKES", "MONOTONE_MAX_VALENCE", "EPGroup", "ep_groups", "local_index", "LOCAL_OFFSET", "G1Assembly", "RowMixer", "blue_weights", "cache_key"]

QUINTIC = 5
#: Weight of the spoke-curve points q_i = P^i[2,0] against the face points f_i = P^i[1,1] in
#: the red solve's stage 2, the least weighted change that satisfies G_1 (``_red_operator``;
#: module docstring, "stage-2 weights").  1: the unweighted least change (the default).
Q_WEIGHT = 1.0
#: Keep the spoke curves of every EP's own blending function monotone where the red solve's
#: least change would make them dip and rise (``_monotone_red``; module docstring, "monotone
#: spoke curves").  False: the plain least change everywhere (for comparisons).
MONOTONE_SPOKES = True
#: The monotone step runs at rings of valence up to this; the others keep the plain red
#: operator.  Set when the monotone step built a
#: basis of its changes (an SVD of ~3 n^2 x 6 n^2: 0.2 s at valence 12, ~n^6 beyond, hours at
#: the valence-64 poles of tests/test_sharp_features.py); ``_monotone_red`` no longer needs
#: one, but the cap stays where it was, so the operator of every mesh stays the same.
MONOTONE_MAX_VALENCE = 12
#: ``_monotone_red``: ridge on the change of the weights themselves (relative to the functions'
#: Gram matrix), and the largest change of a weight it accepts (else the default stays).
RIDGE = 1e-6
MAX_CHANGE = 1.0
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
    """EPs of one valence n and one sharp-spoke pattern, as (E, n) arrays in spoke order.

    h: spokes (outgoing half-edges; on a boundary ring the last spoke is the incoming boundary
    half-edge); d: their intervals; faces: patch i = face(h_i) (-1 for a boundary ring's gap,
    patch n - 1); corner: the EP's corner in that face; far: the vertex at the far end of each
    spoke if it is an EP (else -1); far_spoke: that spoke's index in the far EP's ring.
    sharp: (n,) the pattern of sharp spokes ([FSLYJ] sec. 4.2: sectors, no G1 across them);
    boundary: the ring is an open fan; theta: (n,) fixed sector angles per patch for rings with
    sharp spokes or an interpolated vertex (``features``), None where the angles come from
    ``angle_configuration``."""

    n: int
    vertices: np.ndarray
    h: np.ndarray
    d: np.ndarray
    faces: np.ndarray
    corner: np.ndarray
    far: np.ndarray
    far_spoke: np.ndarray
    sharp: np.ndarray = None  # type: ignore[assignment]
    boundary: bool = False
    theta: np.ndarray | None = None

    @property
    def gap(self) -> int:
        """The missing patch of a boundary ring (n - 1), or -1."""
        return self.n - 1 if self.boundary else -1

    @property
    def unconstrained(self) -> np.ndarray:
        """(n,) spokes without G1 constraint: the sharp ones."""
        return np.zeros(self.n, dtype=bool) if self.sharp is None else self.sharp

    @property
    def pinned(self) -> np.ndarray:
        """(n,) spokes that keep the crease curve: the sharp ones, except a dart's."""
        if self.sharp is None or self.is_dart:
            return np.zeros(self.n, dtype=bool)
        return self.sharp

    @property
    def is_dart(self) -> bool:
        return self.sharp is not None and not self.boundary and int(self.sharp.sum()) == 1

    @property
    def outgoing(self) -> np.ndarray:
        """(E, k) the spokes that leave the EP (all but a boundary ring's last)."""
        return self.h[:, :-1] if self.boundary else self.h

    @property
    def patches(self) -> list[int]:
        return [i for i in range(self.n) if i != self.gap]


#: The fan of an interpolated (corner-tagged) smooth vertex of valence 4.  Every closed fan of
#: valence 4 (Lemma 2) has beta = 0 on two opposite spokes; with equal angles on all four, the
#: G_1 equations at the vertex lose every q_i and become a cyclic system in the face points
#: that is singular, and a spoke to another EP breaks its solvability condition.  This fan,
#: (pi/2 + delta, pi/2 + delta, pi/2 - delta, pi/2 - delta), keeps beta != 0 on spokes 1 and 3
#: (their q_i take up the condition) and sin(theta_{i-1}) = sin(theta_i) at every spoke, so
#: lengths l_i = d_i satisfy eq. (5).  delta = pi / 12: a mild skew.
FOUR_FAN = np.pi / 2 + np.array([1.0, 1.0, -1.0, -1.0]) * np.pi / 12
FOUR_FAN.setflags(write=False)


def _sector_angles(sharp: np.ndarray, boundary: bool, interpolated: bool) -> np.ndarray:
    """(n,) angle of every patch of a ring with sharp spokes (``features``): each sector's sum
    (pi at a crease vertex, ``corner_sector_angle`` at a corner; 2 pi when an interpolated
    vertex has no sharp spoke) shared equally by its patches; NaN for a boundary ring's gap."""
    n = sharp.size
    theta = np.full(n, np.nan)
    if not sharp.any() and n == 4:  # an interpolated smooth valence-4 vertex: a skewed fan
        return FOUR_FAN.copy()
    if not sharp.any() or (not boundary and sharp.sum() == 1):  # no sector ends, or a dart
        theta[:] = 2 * np.pi / n
        return theta
    start = int(np.flatnonzero(sharp)[0])
    sector: list[int] = []
    for step in range(1, n + 1):
        patch = (start + step - 1) % n
        sector.append(patch)
        if sharp[(start + step) % n]:
            if not (boundary and sector == [n - 1]):
                theta[sector] = (corner_sector_angle(len(sector)) if interpolated else CREASE_SECTOR) / len(sector)
            sector = []
    return theta


def corner_sector_angle(faces: int) -> float:
    """The angle of a corner sector of ``faces`` quads: the topological angle faces * pi / 2
    ([TLC]'s corner rules as ``subdivision`` reads them: a concave sector of three quads,
    an L's inner corner, spans 3 pi / 2) where that is not a multiple of pi; pi / 2 for two
    quads and 3 pi / 2 for four or more.  A multiple of pi would make the fan's two crease
    spokes parallel, and G_0 would then need the pinned crease legs parallel too, which at a
    corner they are not.  Measured: pi / 2 for a three-quad concave sector folds the patches
    near the corner (a negative Jacobian on 1% of their area on models/machined_bracket.obj)."""
    return CORNER_SECTOR if faces <= 2 else 3 * CORNER_SECTOR


def ep_groups(topo: Topology, eps: np.ndarray, feats: Features | None = None) -> list[EPGroup]:
    """The rings of all EPs, grouped by valence (and sharp pattern), without a Python loop over
    EPs.  With ``feats``, EPs that are sector vertices (sharp spokes, boundary fans, corners)
    carry their sharp spokes and fixed sector angles."""
    eps = np.asarray(eps, dtype=np.int64)
    spoke_index = np.full(topo.origin.size, -1, dtype=np.int64)
    is_ep = np.zeros(topo.n_vertices, dtype=bool)
    is_ep[eps] = True
    sector = feats.sector_vertex[eps] if feats is not None else np.zeros(eps.size, dtype=bool)
    boundary = topo.vertex_is_boundary[eps]
    raw = []
    for b in (False, True):
        for sec in (False, True):
            sel = (boundary == b) & (sector == sec)
            for ring, _ in topo.fans(eps[sel]):
                vs = topo.origin[ring[:, 0]]
                n = ring.shape[1] + b
                # a boundary fan is closed by its incoming boundary half-edge, spoke n - 1
                h = np.concatenate([ring, topo.prev[ring[:, -1:]]], axis=1) if b else ring
                spoke_index[h[:, : n - b]] = np.arange(n - b)[None, :]
                if not sec:
                    raw.append((n, vs, h, None, b, None))
                    continue
                pattern = feats.sharp[topo.edge_of[h]]
                interpolated = feats.corner[vs]
                key = np.concatenate([pattern, interpolated[:, None]], axis=1)
                uniq, inverse = np.unique(key, axis=0, return_inverse=True)
                for u, row in enumerate(uniq):
                    pick = inverse.ravel() == u
                    raw.append((n, vs[pick], h[pick], row[:n].copy(), b, _sector_angles(row[:n], b, bool(row[n]))))
    groups = []
    offsets = topo.mesh.face_offsets
    for n, vs, h, sharp, b, theta in raw:
        faces = topo.face[h]
        ends = topo.dest[h]
        far = np.where(is_ep[ends], ends, -1)
        far_spoke = np.where(far >= 0, spoke_index[np.maximum(topo.twin[h], 0)], -1)
        if b:
            faces[:, -1] = -1
            ends[:, -1] = topo.origin[h[:, -1]]
            far[:, -1] = -1
            far_spoke[:, -1] = -1
        corner = np.where(faces >= 0, h - offsets[np.maximum(faces, 0)], 0)
        if sharp is not None:  # no G1 across sharp spokes: nothing to share with their far end
            far[:, sharp] = -1
            far_spoke[:, sharp] = -1
        groups.append(EPGroup(n, vs, h, topo.halfedge_interval[h], faces, corner, far, far_spoke, sharp, bool(b), theta))
    return groups


class RowMixer:
    """Collects new_row[target] = sum_k w_k old_row[source_k] for one step; untouched rows copy."""

    def __init__(self, n_rows: int) -> None:
        self.n_rows = n_rows
        self.blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def set(self, targets: np.ndarray, sources: np.ndarray, weights: np.ndarray) -> None:
        """Batched: targets (E, T) rows become weights (T, S) (or (E, T, S)) @ rows sources (E, S)."""
        targets = np.asarray(targets, dtype=np.int64)
        sources = np.asarray(sources, dtype=np.int64)
        if targets.ndim == 1:
            targets, sources = targets[None], sources[None]
        e, t = targets.shape
        s = sources.shape[1]
        weights = np.broadcast_to(np.asarray(weights, dtype=np.float64), (e, t, s))
        self.blocks.append((targets, sources, weights))

    def matrix(self) -> sp.csr_matrix:
        """The step as a CSR matrix, written straight into CSR arrays when every target row is
        set once (each step's rule: one solve owns a row); a row set twice sums its rules.
        Repeated sources in a row stay repeated entries (sparse products add them)."""
        n = self.n_rows
        if not self.blocks:
            return sp.identity(n, format="csr")
        targets = np.concatenate([t.ravel() for t, _, _ in self.blocks])
        if targets.min() < 0 or np.bincount(targets, minlength=n).max() > 1:
            return self._summed()
        counts = np.ones(n, dtype=np.int64)
        for t, src, _ in self.blocks:
            counts[t] = src.shape[1]
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(counts, out=indptr[1:])
        indices = np.empty(indptr[-1], dtype=np.int64)
        data = np.empty(indptr[-1], dtype=np.float64)
        untouched = np.ones(n, dtype=bool)
        untouched[targets] = False
        ident = np.flatnonzero(untouched)
        indices[indptr[ident]] = ident
        data[indptr[ident]] = 1.0
        for t, src, w in self.blocks:
            pos = indptr[t][:, :, None] + np.arange(src.shape[1])  # (E, T, S)
            indices[pos] = src[:, None, :]
            data[pos] = w
        return sp.csr_matrix((data, indices, indptr), shape=(n, n))

    def _summed(self) -> sp.csr_matrix:
        """The general path: triplets, duplicates summed."""
        t = np.concatenate([np.broadcast_to(t[:, :, None], w.shape).ravel() for t, _, w in self.blocks])
        s = np.concatenate([np.broadcast_to(src[:, None, :], w.shape).ravel() for _, src, w in self.blocks])
        w = np.concatenate([w.ravel() for _, _, w in self.blocks])
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


def cache_key(row: np.ndarray) -> tuple:
    """A cache key of a float row: NaN (no value) becomes None, since NaN != NaN and its hash
    is per object, so a key holding NaN never hits an lru_cache."""
    return tuple(None if x != x else x for x in row.tolist())


def _null_space(a: np.ndarray, rtol: float = 1e-11) -> np.ndarray:
    u, s, vt = np.linalg.svd(a)
    rank = int(np.count_nonzero(s > rtol * max(1.0, s.max(initial=0.0))))
    return vt[rank:].T


def _red_valid(args: tuple, arrays: list[np.ndarray]) -> bool:
    """A cache entry of ``_red_operator(*args)`` is trusted if it is (1 + 3n) x (1 + 3n) with
    rows summing to 1."""
    size = 1 + 3 * args[0]
    (k,) = arrays
    return k.shape == (size, size) and bool(np.all(np.abs(k.sum(axis=1) - 1.0) <= 1e-9))


@memo(4096)
def _red_operator(
    n: int, key: tuple, pinned: tuple = (), gap: int = -1, skip: tuple = (), q_weight: float = 1.0
) -> np.ndarray:
    """``_red_solve`` through the persistent cache of ``patching.util.solve_cache`` (when one is
    installed; ``_red_valid`` judges an entry)."""
    args = (n, key, pinned, gap, skip, q_weight)
    (k,) = lookup("red_operator", args, 1, lambda: [_red_solve(*args)], lambda a: _red_valid(args, a))
    k.setflags(write=False)
    return k


def _red_operators(n: int, keys: list[tuple], pinned: tuple, gap: int, skip: tuple, q_weight: float) -> np.ndarray:
    """``_red_operator`` of many spoke keys of one group (same valence, pinned, gap, skip):
    (len(keys), 1 + 3n, 1 + 3n).  Keys not solved before in this process are read from the
    persistent cache or solved together (``_red_solve_batch``)."""
    configs = [(n, key, pinned, gap, skip, q_weight) for key in keys]
    if batching():
        todo = list(dict.fromkeys(a for a in configs if not _red_operator.known(a)))
        if todo:
            solve_many = lambda args_list: [[k] for k in _red_solve_batch(n, [a[1] for a in args_list], pinned, gap, skip, q_weight)]  # noqa: E731
            for args, (k,) in zip(todo, lookup_many("red_operator", todo, 1, solve_many, _red_valid)):
                k.setflags(write=False)
                _red_operator.prime(args, k)
    return np.array([_red_operator(*a) for a in configs]).reshape(len(keys), 1 + 3 * n, 1 + 3 * n)


def _stage1_structure(n: int, pinned: tuple, gap: int):
    """Stage 1 of the red solve on x1 = [P00, s, f]: (n1, free, E, H, F) with the held
    components (P00, pinned spokes, a gap's face point), the differences D over present
    patches as rows E, H keeping the held components and F putting the free ones.  Then
    x1 = H x1_hat + F u, C0 x1 = 0, min |E x1 - E x1_hat|: u = U0 x1_hat + Z w, U0 the
    least-norm solution of C0 F u = -C0 H x1_hat, Z = null(C0 F)."""
    s = lambda i: 1 + (i % n)  # noqa: E731
    f = lambda i: 1 + n + (i % n)  # noqa: E731
    n1 = 1 + 2 * n
    held = [0] + [s(i) for i in range(n) if pinned[i]] + ([f(gap)] if gap >= 0 else [])
    free = [c for c in range(n1) if c not in held]
    diffs = []
    for i in range(n):
        pairs = [(s(i), 0)] + ([] if i == gap else [(f(i), s(i)), (s(i + 1), f(i))])
        for a, b in pairs:
            row = np.zeros(n1)
            row[a] += 1.0
            row[b] -= 1.0
            diffs.append(row)
    hold = np.zeros((n1, n1))
    hold[held, held] = 1.0
    put = np.zeros((n1, len(free)))
    put[free, np.arange(len(free))] = 1.0
    return n1, free, np.vstack(diffs), hold, put


def _spoke_slots(n: int, i: int) -> dict[int, int]:
    """Slot of spoke i's G_0/G_1 equations -> red unknown in x = [P00, s_0..s_{n-1},
    f_0..f_{n-1}, q_0..q_{n-1}]: r0 = P00, r1 = s_i, r2 = q_i; A[0,1] = s_{i+1},
    A[1,1] = f_i; B[1,0] = s_{i-1}, B[1,1] = f_{i-1}."""
    s = lambda j: 1 + (j % n)  # noqa: E731
    f = lambda j: 1 + n + (j % n)  # noqa: E731
    return {r_slot(0): 0, r_slot(1): s(i), r_slot(2): 1 + 2 * n + (i % n), a_slot(0): s(i + 1),
            a_slot(1): f(i), b_slot(0): s(i - 1), b_slot(1): f(i - 1)}


def _red_rows(n: int, key: tuple, skip: tuple) -> dict[int, list[np.ndarray]]:
    """G_0 (rows[0]) and G_1 (rows[1]) of every spoke not in ``skip`` as rows over the red
    unknowns x = [P00, s_0..s_{n-1}, f_0..f_{n-1}, q_0..q_{n-1}] (``_red_solve``)."""
    size = 1 + 3 * n
    rows: dict[int, list[np.ndarray]] = {0: [], 1: []}
    for i, (aa, ab, b0, b1) in enumerate(key):
        if skip[i]:
            continue
        g = spoke_equations(aa, ab, b0, b1)
        slot_to_x = _spoke_slots(n, i)
        for k in (0, 1):
            row = np.zeros(size)
            for slot, col in slot_to_x.items():
                row[col] += g[k, slot]
            assert np.allclose(np.delete(g[k], list(slot_to_x)), 0.0), "G_0, G_1 reach beyond the red slots"
            rows[k].append(row)
    return rows


def _red_rows_batch(n: int, spokes: np.ndarray, live: list[int]) -> np.ndarray:
    """``_red_rows`` of g configurations at once: spokes (g, n, 4) = (alpha_a, alpha_b, b0, b1)
    per spoke (b1 NaN for a regular far end) -> (2, g, len(live), 1 + 3n), G_0 and G_1 of the
    spokes ``live`` (the constrained ones), by the same operations as ``_red_rows``."""
    g_count = spokes.shape[0]
    eqs = spoke_equations_batch(*spokes.reshape(-1, 4).T).reshape(g_count, n, 6, -1)
    rows = np.zeros((2, g_count, len(live), 1 + 3 * n))
    for r, i in enumerate(live):
        slot_to_x = _spoke_slots(n, i)
        outside = np.delete(eqs[:, i, :2], list(slot_to_x), axis=-1)
        assert np.allclose(outside, 0.0), "G_0, G_1 reach beyond the red slots"
        for slot, col in slot_to_x.items():
            rows[:, :, r, col] += np.moveaxis(eqs[:, i, :2, slot], 1, 0)
    return rows


def _stage2_unknowns(n: int, pinned: tuple, gap: int) -> np.ndarray:
    """Indices into x of stage 2's unknowns y = [f (present patches), q (spokes not pinned)]."""
    return np.array([1 + n + i for i in range(n) if i != gap] + [1 + 2 * n + i for i in range(n) if not pinned[i]])


#: ``_active_set_batch`` looks for problems that cycle (and would run into the step limit)
#: from this step on; most stop within a dozen steps (on the half-EP mesh 10 of 2,364 rings of
#: valence 6 cycled, and ran 290 steps each before this).
CYCLE_CHECK_AFTER = 16


def _active_set_batch(
    gram: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, valid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """argmin z^T A z subject to lo <= B z <= hi (A SPD) for E problems at once, in the dual:
    (ok (E,), order (E, K), mu (E, K)), z = A^-1 B^T mu over the active bounds ``order`` (-1:
    none) where ok; not ok where z = 0 already satisfies the bounds or no feasible point is
    found.

    ``gram(e, a, b)``: entries [a, b] of problem e's H = B A^-1 B^T (e (L,), a (L, I), b (L, J)
    -> (L, I, J)); lo, hi (E, m); valid (E, m) (bounds past a problem's own count are padding).

    A simplified form of [GI83]'s dual active-set method (full steps: no partial step when a
    multiplier changes sign), in terms of H alone (B z = H[:, active] mu): z = 0 is the
    unconstrained minimum; the most violated bound joins the active set (as an equality); the
    equality problem is solved for the active multipliers (least squares, cut-off 1e-13 of the
    largest singular value: ``np.linalg.pinv``), and an active bound whose multiplier has the
    wrong sign (the solution would rather leave it; the largest first) is dropped; a problem
    stops when no bound is violated (so a returned z satisfies every bound, though it may not
    be the exact minimiser), when the active bounds cannot all hold, or after 4 m + 4 steps
    (as does one whose active set repeats: ``CYCLE_CHECK_AFTER``).  All problems step in
    lockstep, the solves grouped by the active set's size, so that each matrix is factored
    alone and a problem's numbers do not depend on the others in its batch."""
    e_count, m = lo.shape
    lo = np.where(valid, lo, -np.inf)
    hi = np.where(valid, hi, np.inf)
    tol = 1e-12 * np.maximum(1.0, np.where(valid, np.maximum(np.abs(lo), np.abs(hi)), 0.0).max(axis=1, initial=0.0))
    ok = np.zeros(e_count, dtype=bool)
    done = (lo <= tol[:, None]).all(axis=1) & (hi >= -tol[:, None]).all(axis=1)  # z = 0 holds: None
    limit = 4 * valid.sum(axis=1) + 4
    order = np.full((e_count, m + 1), -1, dtype=np.int64)  # the active bounds in the order they joined
    mu = np.zeros((e_count, m + 1))  # their multipliers
    count = np.zeros(e_count, dtype=np.int64)
    is_active = np.zeros((e_count, m), dtype=bool)
    at_lo = np.zeros((e_count, m), dtype=bool)
    every = np.arange(m)
    seen: dict[int, set[bytes]] = {}
    for step in range(int(limit.max(initial=0))):
        done |= step >= limit
        live = np.flatnonzero(~done)
        if not live.size:
            break
        if step >= CYCLE_CHECK_AFTER:
            # A problem whose active set (in order, with its sides) repeats one it had at an
            # earlier step repeats the same steps (each is a function of that state alone) and
            # so runs into the step limit: it stops now with the limit's outcome (None).
            for e in live.tolist():
                state = order[e, : count[e]].tobytes() + at_lo[e, order[e, : count[e]]].tobytes()
                if state in seen.setdefault(e, set()):
                    done[e] = True
                seen[e].add(state)
            live = np.flatnonzero(~done)
            if not live.size:
                break
        value = np.zeros((live.size, m))
        for c, sub in _by_count(count[live]):
            if c:
                e = live[sub]
                value[sub] = (gram(e, np.broadcast_to(every, (e.size, m)), order[e, :c]) @ mu[e, :c, None])[:, :, 0]
        excess = np.maximum(lo[live] - value, value - hi[live])
        excess[is_active[live]] = -np.inf
        rows = np.arange(live.size)
        j = np.argmax(excess, axis=1)
        met = excess[rows, j] <= tol[live]
        ok[live[met]] = True
        done[live[met]] = True
        grow, j, rows = live[~met], j[~met], rows[~met]
        at_lo[grow, j] = lo[grow, j] - value[rows, j] > value[rows, j] - hi[grow, j]
        is_active[grow, j] = True
        order[grow, count[grow]] = j
        count[grow] += 1
        inner = grow
        while inner.size:
            again = []
            for c, sub in _by_count(count[inner]):
                e = inner[sub]
                idx = order[e, :c]
                block = gram(e, idx, idx)
                lower = at_lo[e[:, None], idx]
                r = np.where(lower, lo[e[:, None], idx], hi[e[:, None], idx])
                m_act = (np.linalg.pinv(block, rcond=1e-13) @ r[:, :, None])[:, :, 0]
                size = np.abs(m_act)
                wrong = ((m_act < 0) == lower) & (size > 1e-14 * np.maximum(1.0, size.max(axis=1, keepdims=True)))
                stop = ~wrong.any(axis=1) | (c == 1)
                fin = e[stop]
                residual = np.abs((block[stop] @ m_act[stop][:, :, None])[:, :, 0] - r[stop]).max(axis=1, initial=0.0)
                done[fin[residual > 1e-9 * np.maximum(1.0, np.abs(r[stop]).max(axis=1, initial=0.0))]] = True  # cannot all hold
                mu[fin, :c] = m_act[stop]
                drop = e[~stop]
                if drop.size:
                    p = np.argmax(np.where(wrong[~stop], size[~stop], -1.0), axis=1)
                    left = idx[~stop]
                    is_active[drop, left[np.arange(drop.size), p]] = False
                    order[drop, : c - 1] = left[every[None, :c] != p[:, None]].reshape(drop.size, c - 1)  # the others, in order
                    order[drop, c - 1] = -1
                    count[drop] -= 1
                    again.append(drop)
            inner = np.concatenate(again) if again else grow[:0]
    k_max = int(count.max(initial=0))
    return ok, order[:, :k_max], np.where(order[:, :k_max] >= 0, mu[:, :k_max], 0.0)


def _by_count(counts: np.ndarray):
    """(c, positions with counts == c) for each distinct c, ascending: the active-set solves
    run per size, each matrix alone as it would be in a batch of one."""
    for c in np.unique(counts).tolist():
        yield c, np.flatnonzero(counts == c)


def _monotone_red(
    n: int, configs: np.ndarray, inverse: np.ndarray, pinned: tuple, skip: tuple, q_weight: float,
    k: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray, watch: np.ndarray, width: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The red operators K of E closed rings of one group, each changed as little as possible
    so that the blending functions keep the monotone spoke curves the extraction gave them
    (module docstring, "monotone spoke curves"): (ok (E,), d (E, ny, 1 + 3n)), K + d on stage
    2's rows y where ok, K unchanged where no change inside G_1 can.

    configs (g, n, 4) the distinct spoke keys (alpha_a, alpha_b, b0, b1; NaN for no b1), ring
    e's is configs[inverse[e]]; k (E, 1 + 3n, 1 + 3n) the red operators; x (E, 1 + 3n, W) the
    blending functions of the control points that reach the ring at the red inputs x_hat
    (columns of the elevated extraction with the anchors folded in: topology and intervals
    only; zero columns pad), after the solve K x; lo, hi (E, n, W): where watch[e, i, c], the
    value of function c at q_i must lie in [lo, hi] (the bounds that put the black step's P30
    between q_i and P40 and q_i between s_i and P30; ``G1Assembly._monotone``).  ``width``:
    the number of watched functions to allow for (default: the batch's most).

    The QP: stage 2's rows y = [f, q] of K change by D with C_y D = 0 (G_1 stays exact for
    every input), D 1 = 0 (rows still sum to one: affine invariance), and (D x)[q_i, c] put on
    the bound it broke (active set: a broken bound becomes an equality until none is broken),
    D least in the change of every function it touches plus a ridge on the weights,
    sum_r w_r D_r G D_r^T with G = x x^T + RIDGE tr(x x^T) / (1 + 3n) I (w: 1 on f,
    ``q_weight`` on q, stage 2's metric).  K + D stays linear in the control points.

    Solved without a basis of the changes.  The D with C_y D = 0 and D 1 = 0 are exactly
    N A P^T, N a basis of null(C_y) and P one of the vectors orthogonal to 1, and the metric
    is W (x) G on vec(D); so its inverse on that space, Z (Z^T M Z)^-1 Z^T for any basis Z, is
    S1 (x) S2 with S1 = N (N^T W N)^-1 N^T (ny x ny, from the configuration alone: W^(-1/2)
    times the projector onto null(C_y W^(-1/2)), an SVD of C_y) and
    S2 = P (P^T G P)^-1 P^T = G^-1 - G^-1 1 1^T G^-1 / (1^T G^-1 1) (one solve per ring).  A
    bound on (D x)[q_i, c] is the row e_{q_i} (x) x_c, so the bounds' Gram matrix is
    H[k, l] = S1[q_k, q_l] (x_{c_k}^T S2 x_{c_l}) and the solution
    D = sum_k mu_k (S1 e_{q_k}) (S2 x_{c_k})^T: the active-set steps run on H alone
    (``_active_set_batch``, every ring in lockstep).  The first version built Z (an SVD of
    ~3 n^2 x 6 n^2 per configuration) and the (6 n^2)^2 metric per ring; it took the same
    steps in exact arithmetic, and in floating point differs by what the QP makes of round-off
    (docs/speed.md; ``tests.helpers.monotone_red_primal`` keeps it as the tests' reference).
    The same checks close it: |D| <= MAX_CHANGE and |C_y D| <= 1e-12, else the ring keeps K."""
    size = 1 + 3 * n
    e_count = k.shape[0]
    live = [i for i in range(n) if not skip[i]]
    y = _stage2_unknowns(n, pinned, -1)
    ny = y.size
    ok = np.zeros(e_count, dtype=bool)
    d = np.zeros((e_count, ny, size))
    if not live or not e_count:
        return ok, d
    cy = _red_rows_batch(n, configs, live)[1][:, :, y]  # (g, L, ny)
    root = 1.0 / np.sqrt(np.where(y >= 1 + 2 * n, q_weight, 1.0))
    _, sv, vt = np.linalg.svd(cy * root, full_matrices=True)
    rank = np.count_nonzero(sv > 1e-11 * np.maximum(1.0, sv.max(axis=1, initial=0.0))[:, None], axis=1)
    null = np.arange(ny)[None, :] >= rank[:, None]
    s1 = (root[:, None] * ((np.swapaxes(vt, 1, 2) * null[:, None, :]) @ vt) * root[None, :])[inverse]  # (E, ny, ny)
    q_row = np.full(n, -1, dtype=np.int64)
    for r, j in enumerate(y.tolist()):
        if j >= 1 + 2 * n:
            q_row[j - 1 - 2 * n] = r
    # the functions each ring watches, and its bounds (spoke-major)
    watched = watch.any(axis=1)  # (E, W)
    width = int(watched.sum(axis=1).max(initial=0)) if width is None else width
    position = np.cumsum(watched, axis=1) - 1
    we, wc = np.nonzero(watched)
    cols = np.zeros((e_count, width), dtype=np.int64)
    cols[we, position[we, wc]] = wc
    col_ok = np.zeros((e_count, width), dtype=bool)
    col_ok[we, position[we, wc]] = True
    be, bi, bc = np.nonzero(watch)
    m_e = np.bincount(be, minlength=e_count)
    bk = np.arange(be.size) - np.concatenate([[0], np.cumsum(m_e)[:-1]])[be]
    m = int(m_e.max(initial=0))
    v = k[:, y] @ x  # (E, ny, W): stage 2's rows of every function after the red solve
    gram = x @ np.swapaxes(x, 1, 2)
    gram += (RIDGE * np.trace(gram, axis1=1, axis2=2) / size + 1e-300)[:, None, None] * np.eye(size)
    xw = np.take_along_axis(x, cols[:, None, :], axis=2) * col_ok[:, None, :]
    # G^-1 of the watched functions and of 1 in one solve.  LAPACK's and BLAS's results for a
    # column depend on how many columns they take at once, so the width is the batch's
    # (``width``: a caller solving one ring of a batch passes the batch's): a ring's numbers
    # are then the same in a batch of one.
    solved = np.linalg.solve(gram, np.concatenate([xw, np.ones((e_count, size, 1))], axis=2))
    g_x = solved[:, :, :-1]
    g_one = solved[:, :, -1:]
    s2x = g_x - g_one * (g_x.sum(axis=1, keepdims=True) / g_one.sum(axis=1, keepdims=True))
    q = np.swapaxes(xw, 1, 2) @ s2x  # (E, width, width): x_c^T S2 x_c'
    valid = np.zeros((e_count, m), dtype=bool)
    valid[be, bk] = True
    b_row = np.zeros((e_count, m), dtype=np.int64)
    b_row[be, bk] = q_row[bi]
    b_col = np.zeros((e_count, m), dtype=np.int64)
    b_col[be, bk] = position[be, bc]
    b_lo = np.zeros((e_count, m))
    b_hi = np.zeros((e_count, m))
    b_lo[be, bk] = lo[be, bi, bc] - v[be, q_row[bi], bc]
    b_hi[be, bk] = hi[be, bi, bc] - v[be, q_row[bi], bc]

    # H[e, a, b] = S1[e, row_a, row_b] Q[e, col_a, col_b], read from the flat arrays
    s1_at = b_row * ny + (np.arange(e_count) * ny * ny)[:, None]
    q_at = b_col * width + (np.arange(e_count) * width * width)[:, None]
    s1_flat, q_flat = s1.ravel(), q.ravel()

    def h_entries(e: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        s1_a, s1_b = np.take_along_axis(s1_at[e], a, 1), np.take_along_axis(b_row[e], b, 1)
        q_a, q_b = np.take_along_axis(q_at[e], a, 1), np.take_along_axis(b_col[e], b, 1)
        return s1_flat[s1_a[:, :, None] + s1_b[:, None, :]] * q_flat[q_a[:, :, None] + q_b[:, None, :]]

    solved_ok, order, mu = _active_set_batch(h_entries, b_lo, b_hi, valid)
    change = np.zeros((e_count, ny, size))
    for c, e in _by_count((order >= 0).sum(axis=1)):
        if c:
            u = np.take_along_axis(s1[e], np.take_along_axis(b_row[e], order[e, :c], 1)[:, None, :], axis=2)  # (., ny, c)
            w = np.take_along_axis(s2x[e], np.take_along_axis(b_col[e], order[e, :c], 1)[:, None, :], axis=2)  # (., size, c)
            change[e] = (u * mu[e, None, :c]) @ np.swapaxes(w, 1, 2)
    exact = np.abs(cy[inverse] @ change).max(axis=(1, 2), initial=0.0) <= 1e-12
    small = np.abs(change).max(axis=(1, 2), initial=0.0) <= MAX_CHANGE
    ok = solved_ok & exact & small
    d[ok] = change[ok]
    return ok, d


@memo(16)
def _monotone_memo(*args: Hashable) -> None:
    """The in-process store of ``_monotone_changes`` (filled with ``prime``; a few groups)."""
    return None


def _monotone_changes(
    n: int, configs: np.ndarray, inverse: np.ndarray, pinned: tuple, skip: tuple, q_weight: float,
    k: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray, watch: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``_monotone_red`` through the in-process memo and the persistent cache
    (``patching.util.solve_cache``), one entry per group of rings.

    A ring's QP depends on its blending functions x and bounds, which follow from the intervals
    of a wider neighbourhood than its configuration: on the half-EP mesh no two of its 6,820
    QPs have the same inputs (nor after sorting each ring's functions), so an entry per ring
    would be read once, by this mesh.  The key is therefore a SHA-256 of the exact bytes of
    everything the solve reads (configurations, red operators, functions, bounds, watched
    pairs, with their shapes) and the settings (valence, pinned and sharp spokes, q weight,
    ``RIDGE``, ``MAX_CHANGE``); the store adds the source digest.  The entry holds which rings
    changed (1.0 / 0.0) and their changes D, float64 bit for bit.  Read back it is trusted only
    if ``_monotone_valid`` accepts it (shapes, |D| <= MAX_CHANGE, D 1 = 0, C_y D = 0, and every
    watched bound held by K + D), else it is solved afresh and rewritten.  With batching off
    (``patching.util.memo.set_batching``) the rings are solved one at a time, by the same
    arithmetic (a ring's numbers do not depend on its batch), so both paths share entries."""
    e_count, ny, size = k.shape[0], _stage2_unknowns(n, pinned, -1).size, 1 + 3 * n
    digest = hashlib.sha256()
    for a in (configs, inverse, k, x, lo, hi, watch):
        a = np.ascontiguousarray(a)  # the same bytes as ``a.tobytes()``, without its copy
        digest.update(repr((a.dtype.str, a.shape)).encode())
        digest.update(a.reshape(-1).view(np.uint8))
    args = (n, pinned, skip, float(q_weight), RIDGE, MAX_CHANGE, digest.hexdigest())
    if _monotone_memo.known(args):
        return _monotone_memo(*args)

    def solve() -> list[np.ndarray]:
        if batching():
            ok, d = _monotone_red(n, configs, inverse, pinned, skip, q_weight, k, x, lo, hi, watch)
        else:  # ring by ring, at the batch's width (the reference path of the batched solves)
            width = int(watch.any(axis=1).sum(axis=1).max(initial=0))
            one = [
                _monotone_red(n, configs[inverse[e : e + 1]], np.zeros(1, dtype=np.int64), pinned, skip, q_weight,
                                    k[e : e + 1], x[e : e + 1], lo[e : e + 1], hi[e : e + 1], watch[e : e + 1], width)
                for e in range(e_count)
            ]
            ok = np.array([o[0] for o, _ in one], dtype=bool).reshape(e_count)
            d = np.concatenate([c for _, c in one]) if one else np.zeros((0, ny, size))
        return [ok.astype(np.float64), d[ok]]

    def valid(arrays: list[np.ndarray]) -> bool:
        return _monotone_valid(n, configs, inverse, pinned, skip, k, x, lo, hi, watch, arrays)

    flags, changes = lookup("monotone_red", args, 2, solve, valid)
    ok = flags == 1.0
    d = np.zeros((e_count, ny, size))
    d[ok] = changes
    for a in (ok, d):
        a.setflags(write=False)
    _monotone_memo.prime(args, (ok, d))
    return ok, d


def _monotone_valid(
    n: int, configs: np.ndarray, inverse: np.ndarray, pinned: tuple, skip: tuple,
    k: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray, watch: np.ndarray, arrays: list[np.ndarray],
) -> bool:
    """A cache entry (flags, changes) of ``_monotone_changes`` is trusted if the flags are 0 or
    1 per ring, the changes fit the changed rings, and each change is one the solve could
    return: |D| <= MAX_CHANGE, rows summing to 0 (1e-9), C_y D = 0 (1e-12, the solve's own
    test), and every watched bound of the ring held by K + D (1e-9 of the bounds' size)."""
    flags, changes = arrays
    y = _stage2_unknowns(n, pinned, -1)
    size = 1 + 3 * n
    if flags.shape != (k.shape[0],) or not np.isin(flags, (0.0, 1.0)).all():
        return False
    ok = flags == 1.0
    if changes.shape != (int(ok.sum()), y.size, size):
        return False
    if not changes.size:
        return True
    live = [i for i in range(n) if not skip[i]]
    if not live or np.abs(changes).max() > MAX_CHANGE or np.abs(changes.sum(axis=2)).max() > 1e-9:
        return False
    cy = _red_rows_batch(n, configs, live)[1][:, :, y]
    if np.abs(cy[inverse[ok]] @ changes).max() > 1e-12:
        return False
    q_rows = [r for r, j in enumerate(y.tolist()) if j >= 1 + 2 * n]
    spokes = [j - 1 - 2 * n for j in y.tolist() if j >= 1 + 2 * n]
    value = ((k[ok][:, y] + changes) @ x[ok])[:, q_rows]  # (E_ok, spokes, W): q_i of every function
    w = watch[ok][:, spokes]
    low, high = lo[ok][:, spokes][w], hi[ok][:, spokes][w]
    scale = 1e-9 * max(1.0, float(np.abs(np.concatenate([low, high])).max(initial=0.0)))
    return bool(np.all(value[w] >= low - scale) and np.all(value[w] <= high + scale))


def _red_solve(
    n: int, key: tuple, pinned: tuple = (), gap: int = -1, skip: tuple = (), q_weight: float = 1.0
) -> np.ndarray:
    """K with x = K x_hat for x = [P00, s_0..s_{n-1}, f_0..f_{n-1}, q_0..q_{n-1}].

    key = (alpha_a, alpha_b, b0, b1) per spoke, hashable; b1 None for a regular far end.
    Stage 1 ([FSLYJ] sec. 3.4): P00 held, spoke points s and face points f nearest to the
    extraction's differences D under G_0; every input is then in the anchors' plane, so the
    tangent plane is section 3.5's.  Stage 2: f and q (= P^i[2,0]) nearest to their targets
    under G_1, with P00 and s kept: f from stage 1, q_hat + (s - s_hat) / 2 (module docstring,
    "spoke curves").  The paper takes q from G_1 alone, dividing by 4 b_i, which vanishes at
    valence 4 and in symmetric configurations.

    Sharp features (section 4.2): ``skip[i]`` marks a sharp spoke, which has no G1 constraint;
    ``pinned[i]`` one that also keeps its extraction values s_i, q_i (the crease curve; all
    sharp spokes but a dart's); ``gap`` is the missing patch of a boundary fan (its face point
    is neither read nor set)."""
    pinned = tuple(pinned) or (False,) * n
    skip = tuple(skip) or pinned
    size = 1 + 3 * n
    s = lambda i: 1 + (i % n)  # noqa: E731
    q = lambda i: 1 + 2 * n + (i % n)  # noqa: E731
    rows = _red_rows(n, key, skip)
    n1, free, e, hold, put = _stage1_structure(n, pinned, gap)
    c0 = np.vstack([r[:n1] for r in rows[0]]) if rows[0] else np.zeros((0, n1))
    cf = c0 @ put
    u0 = -np.linalg.pinv(cf, rcond=1e-12) @ c0 @ hold if cf.size else np.zeros((len(free), n1))
    z = _null_space(cf) if cf.size else np.eye(len(free))
    ez = e @ put @ z
    w = np.linalg.pinv(ez, rcond=1e-12) @ (e - e @ hold - e @ put @ u0)
    k1 = hold + put @ (u0 + z @ w)
    k1[:, 0] += 1.0 - k1.sum(axis=1)
    stage1 = np.zeros((size, size))
    stage1[:n1, :n1] = k1
    stage1[n1:, n1:] = np.eye(n)  # q keeps its extraction value for now
    k = stage1
    if rows[1]:
        # Stage 2: y = [f, q] nearest to stage 1 under G_1, P00 and s fixed (and held ones).
        c = np.vstack(rows[1])
        y = _stage2_unknowns(n, pinned, gap)
        cy = c[:, y]
        # The target of q_i is not its extraction value but q_hat_i + (s_i - s_hat_i) / 2: the
        # black step's P30 = q + P40/2 - s/2 + P00/10 - P50/10 then starts from its extraction
        # value (module docstring, "spoke curves").
        target = stage1.copy()
        for i in range(n):
            if not pinned[i] and not skip[i]:
                target[q(i)] += 0.5 * stage1[s(i)]
                target[q(i), s(i)] -= 0.5
        # least change |W^(1/2) dy| (W: 1 on f, q_weight on q) with C (y + dy) = 0
        inv_w = np.where(y >= q(0), 1.0 / q_weight, 1.0)
        correction = np.zeros((size, size))
        correction[np.ix_(y, np.arange(size))] = -(inv_w[:, None] * cy.T) @ np.linalg.pinv((cy * inv_w) @ cy.T, rcond=1e-12) @ c
        k = (np.eye(size) + correction) @ target
    k[:, 0] += 1.0 - k.sum(axis=1)  # exact affine invariance: the constant part goes to P00
    k.setflags(write=False)
    return k


def _red_solve_batch(
    n: int, keys: list[tuple], pinned: tuple = (), gap: int = -1, skip: tuple = (), q_weight: float = 1.0
) -> np.ndarray:
    """``_red_solve`` of g spoke keys sharing (n, pinned, gap, skip): (g, 1 + 3n, 1 + 3n).

    The held and free components, the difference rows D and stage 2's unknowns depend on those
    alone, so only the G1 rows differ between the configurations: they are built for all at
    once (``spoke_equations_batch``) and the least-squares steps run as stacked LAPACK calls
    (``np.linalg.pinv``, ``svd`` on (g, rows, columns)), each matrix through the same routine
    and cut-off as alone.  The null space of C0 F can differ in dimension between
    configurations: they are split by its rank.  Groups without G1 rows (every spoke sharp)
    take the one-key path."""
    pinned = tuple(pinned) or (False,) * n
    skip = tuple(skip) or pinned
    size = 1 + 3 * n
    live = [i for i in range(n) if not skip[i]]
    if not live or not keys:
        return np.array([_red_solve(n, key, pinned, gap, skip, q_weight) for key in keys]).reshape(len(keys), size, size)
    s = lambda i: 1 + (i % n)  # noqa: E731
    q = lambda i: 1 + 2 * n + (i % n)  # noqa: E731
    g_count = len(keys)
    spokes = np.array([[np.nan if x is None else x for x in spoke] for key in keys for spoke in key], dtype=np.float64)
    rows = _red_rows_batch(n, spokes.reshape(g_count, n, 4), live)
    n1, free, e, hold, put = _stage1_structure(n, pinned, gap)
    c0 = rows[0][:, :, :n1]
    cf = c0 @ put
    if cf.shape[1] == 0 or cf.shape[2] == 0:
        return np.array([_red_solve(n, key, pinned, gap, skip, q_weight) for key in keys]).reshape(g_count, size, size)
    u0 = -np.linalg.pinv(cf, rcond=1e-12) @ c0 @ hold
    _, sv, vt = np.linalg.svd(cf)  # _null_space, for all at once
    rank = np.count_nonzero(sv > 1e-11 * np.maximum(1.0, sv.max(axis=1, initial=0.0))[:, None], axis=1)
    ep = e @ put
    residual = e - e @ hold - ep @ u0
    k1 = np.empty((g_count, n1, n1))
    for r in np.unique(rank):
        sel = np.flatnonzero(rank == r)
        z = np.swapaxes(vt[sel, r:], 1, 2)
        w = np.linalg.pinv(ep @ z, rcond=1e-12) @ residual[sel]
        k1[sel] = hold + put @ (u0[sel] + z @ w)
    k1[:, :, 0] += 1.0 - k1.sum(axis=2)
    stage1 = np.zeros((g_count, size, size))
    stage1[:, :n1, :n1] = k1
    stage1[:, n1:, n1:] = np.eye(n)
    c = rows[1]
    y = _stage2_unknowns(n, pinned, gap)
    cy = c[:, :, y]
    target = stage1.copy()
    for i in range(n):
        if not pinned[i] and not skip[i]:
            target[:, q(i)] += 0.5 * stage1[:, s(i)]
            target[:, q(i), s(i)] -= 0.5
    inv_w = np.where(y >= q(0), 1.0 / q_weight, 1.0)
    correction = np.zeros((g_count, size, size))
    cyt = np.swapaxes(cy, 1, 2)
    correction[:, y, :] = -(inv_w[:, None] * cyt) @ np.linalg.pinv((cy * inv_w) @ cyt, rcond=1e-12) @ c
    k = (np.eye(size) + correction) @ target
    k[:, :, 0] += 1.0 - k.sum(axis=2)
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


#: ``_ring_blocks`` numbers each ring's columns in a (rings x columns) table of this many rings
#: at a time: small enough to stay in the cache and in the allocator's reused memory (for 15k
#: control points, 16 rings are 1 MB; 256 rings were a 31 MB table of fresh pages per valence).
RING_TABLE = 16


def _ring_blocks(ref: sp.csr_matrix, e_count: int, per: int) -> tuple[np.ndarray, np.ndarray]:
    """The rows of ``ref`` (e_count rings of ``per`` consecutive rows) as dense blocks over
    the columns each ring reaches: (x (e_count, per, W), columns (e_count, W)), ring e's
    columns in the order of their last entry in its rows, then -1 (zero columns of x) up to
    the widest ring's W.  ``ref`` is put in canonical form (in place).  No sort: each ring's
    columns are numbered through a table indexed by (ring, column), filled for
    ``RING_TABLE`` rings at a time (an entry's number is written before it is read, so the table is never
    cleared)."""
    ref.sum_duplicates()  # one entry per (row, column), so x is written, not accumulated
    counts = np.diff(ref.indptr)
    wide = ref.shape[1]
    ring_ptr = ref.indptr[:: per] if ref.shape[0] else np.zeros(1, dtype=np.int64)
    table = np.empty(min(RING_TABLE, max(e_count, 1)) * wide, dtype=np.int32)
    ring = np.repeat(np.arange(ref.shape[0]) // per, counts)
    slot = np.empty(ref.nnz, dtype=np.int64)
    owners, slots, cols = [], [], []
    for first in range(0, e_count, RING_TABLE):
        last = min(first + RING_TABLE, e_count)
        span = slice(int(ring_ptr[first]), int(ring_ptr[last]))
        key = (ring[span] - first) * wide + ref.indices[span]
        order = np.arange(key.size)
        table[key] = order
        own = table[key] == order  # one entry of each (ring, column): its last
        ring_own = ring[span][own]
        number = np.arange(ring_own.size) - np.searchsorted(ring_own, ring_own)
        table[key[own]] = number
        slot[span] = table[key]
        owners.append(ring_own)
        slots.append(number)
        cols.append(ref.indices[span][own])
    owner = np.concatenate(owners) if owners else np.zeros(0, dtype=np.int64)
    number = np.concatenate(slots) if slots else np.zeros(0, dtype=np.int64)
    width = int(number.max(initial=-1)) + 1
    columns = np.full((e_count, width), -1, dtype=np.int64)
    columns[owner, number] = np.concatenate(cols) if cols else number
    x = np.zeros((e_count, per, width))
    x[ring, np.repeat(np.arange(ref.shape[0]) % per, counts), slot] = ref.data
    return x, columns


def _monotone_runs(values: tuple[np.ndarray, ...], tol: float) -> tuple[np.ndarray, np.ndarray]:
    """(down, up) of a control polygon given as equal-shape arrays of its consecutive values:
    down where every step values[j] - values[j + 1] is >= -tol and one is > tol (monotone
    decreasing, not flat), up the same way round.  The steps are taken one at a time (no
    stacked (steps, ...) array: on the half-EP mesh that stack and its four comparisons were
    ~40 MB of fresh memory per valence, and first touches dominate a cold build's system time)."""
    down = up = any_down = any_up = None
    for a, b in zip(values[:-1], values[1:]):
        step = a - b
        d, u, sd, su = step >= -tol, step <= tol, step > tol, step < -tol
        if down is None:
            down, up, any_down, any_up = d, u, sd, su
        else:
            down &= d
            up &= u
            any_down |= sd
            any_up |= su
    return down & any_down, up & any_up


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
            if g.theta is None:
                uniq, inverse = _unique_rows(g.d)
                b = np.array([-np.asarray(c.b) for c in angle_configurations(uniq, mode=angles)])
                b0 = b[inverse].reshape(g.d.shape)  # beta(0) per spoke (g1_constraints sign)
            else:
                b0 = _sector_beta(g)
            beta0[g.outgoing] = b0[:, : g.outgoing.shape[1]]
            self.beta0.append(b0)
        self.beta1 = [np.where(g.far >= 0, beta0[topo.twin[g.h]], np.nan) for g in groups]
        #: rows -> those rows of the elevated extraction over the control points, anchors
        #: folded in: every blending function before the G1 steps (``MONOTONE_SPOKES``);
        #: None: the plain red solve.
        self.reference = None
        self.is_ep = np.zeros(topo.n_vertices, dtype=bool)
        for g in groups:
            self.is_ep[g.vertices] = True

    def without(self, inside: list[np.ndarray]) -> "G1Assembly":
        """The same assembly over the EPs not marked in ``inside`` ((E,) bool per group); groups
        left empty are dropped."""
        out = copy.copy(self)
        keep = [(k, ~m) for k, m in enumerate(inside) if (~m).any()]
        out.groups = [_subset(self.groups[k], m) for k, m in keep]
        out.beta0 = [self.beta0[k][m] for k, m in keep]
        out.beta1 = [self.beta1[k][m] for k, m in keep]
        return out

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
            pinned = tuple(bool(x) for x in g.pinned)
            keys = self.spoke_keys(k).reshape(len(g.vertices), 4 * n)
            uniq, inverse = _unique_rows(keys)
            skip = tuple(bool(x) for x in g.unconstrained)
            ops = _red_operators(n, [tuple(cache_key(r) for r in row.reshape(n, 4)) for row in uniq], pinned, g.gap, skip, Q_WEIGHT)
            present = g.patches

            def source(i: int, j: int, m: int, mirror: tuple[int, int]) -> np.ndarray:
                # slot (j, m) of patch i, read from patch i - 1 at ``mirror`` across a gap
                return self.rows(g, i, j, m) if i != g.gap else self.rows(g, i - 1, *mirror)

            src = np.stack(
                [self.rows(g, present[0], 0, 0)]
                + [source(i, 1, 0, (0, 1)) for i in range(n)]
                + [source(i, 1, 1, (0, 0)) for i in range(n)]  # a gap's face point: unused
                + [source(i, 2, 0, (0, 2)) for i in range(n)],
                axis=1,
            )
            # targets and the unknown each takes; sharp spokes keep the crease curve
            tgt, unknown = [], []
            for ii in present:
                tgt += [self.rows(g, ii, 0, 0), self.rows(g, ii, 1, 1)]
                unknown += [0, 1 + n + ii]
            for ii in range(n):
                if pinned[ii]:
                    continue
                tgt += [self.rows(g, ii, 1, 0), self.rows(g, ii - 1, 0, 1), self.rows(g, ii, 2, 0), self.rows(g, ii - 1, 0, 2)]
                unknown += [1 + ii, 1 + ii, 1 + 2 * n + ii, 1 + 2 * n + ii]
            ops_e = ops[inverse]
            if MONOTONE_SPOKES and n <= MONOTONE_MAX_VALENCE and self.reference is not None and g.gap < 0:
                ops_e = self._monotone(g, ops_e, src, uniq, inverse, pinned, skip)
            weights = ops_e[:, unknown, :]  # (E, T, S)
            mixer.set(np.stack(tgt, 1), src, weights)

    def _monotone(self, g: EPGroup, ops: np.ndarray, src: np.ndarray, uniq, inverse, pinned, skip) -> np.ndarray:
        """ops (E, 1 + 3n, 1 + 3n) with ``_monotone_red`` applied where the default red
        operator bends back a spoke curve that the extraction gave monotone.  Per spoke i with
        a regular far end (not pinned, not sharp) and per function c: with the extraction's
        s, q, P30, P40, P50 of c monotone (either way), the solve's q_i must lie between s_i
        and the value that puts P30 on P40, (P40 + s_i)/2 - (P00 - P50)/10 (black step); the
        test runs over all EPs at once, the solves only at the EPs that break a bound."""
        n = g.n
        size = 1 + 3 * n
        spoke = lambda j, m: np.stack([self.rows(g, i, j, m) for i in range(n)], 1)  # noqa: E731
        rows = np.concatenate([src, spoke(3, 0), spoke(4, 0), spoke(5, 0)], axis=1)  # (E, size + 3n)
        e_count, per = rows.shape
        x, reached = _ring_blocks(sp.csr_matrix(self.reference(rows.ravel())), e_count, per)
        of_ep = self.is_ep[reached] & (reached >= 0)  # the column is an EP's function
        # the solve's P00, s and q of every function (its face points f are not read here)
        read = np.r_[0 : 1 + n, 1 + 2 * n : size]
        v = np.einsum("eij,ejc->eic", ops[:, read], x[:, :size])
        s_hat, q_hat = x[:, 1 : 1 + n], x[:, 1 + 2 * n : size]
        p30_hat, p40, p50 = x[:, size : size + n], x[:, size + n : size + 2 * n], x[:, size + 2 * n :]
        p00, s_new, q_new = v[:, :1], v[:, 1 : 1 + n], v[:, 1 + n :]
        tol = 1e-10
        down, up = _monotone_runs((s_hat, q_hat, p30_hat, p40, p50), tol)
        flat = 0.5 * (p40 + s_new) - 0.1 * (p00 - p50)  # q that puts P30 on P40
        lo = np.where(down, flat, np.where(up, s_new, np.nan))
        hi = np.where(down, s_new, np.where(up, flat, np.nan))
        free = (g.far < 0) & ~np.array(pinned, bool) & ~np.array(skip, bool)
        watch = (down | up) & free[:, :, None] & (lo <= hi) & of_ep[:, None, :]
        broken = watch & ((q_new < lo - 1e-12) | (q_new > hi + 1e-12))
        bad = np.flatnonzero(broken.any(axis=(1, 2)))
        if not bad.size:
            return ops
        used, of_ring = np.unique(inverse[bad], return_inverse=True)
        ok, change = _monotone_changes(
            n, uniq[used].reshape(-1, n, 4), of_ring.ravel(), pinned, skip, Q_WEIGHT, ops[bad], x[bad, :size], lo[bad], hi[bad], watch[bad]
        )
        ops = ops.copy()
        fixed = bad[ok]
        ops[fixed[:, None], _stage2_unknowns(n, pinned, -1)[None, :]] += change[ok]
        return ops

    def black(self, mixer: RowMixer) -> None:
        weights = np.array([[0.1, -0.5, 1.0, 0.5, -0.1]] * 2)  # P00, P10, P20, P40, P50
        for g in self.groups:
            for i in range(g.n):
                sel = (g.far[:, i] < 0) & ~g.pinned[i]
                if not sel.any():
                    continue
                src = np.stack([self.rows(g, i, j, 0)[sel] for j in (0, 1, 2, 4, 5)], 1)
                tgt = np.stack([self.rows(g, i, 3, 0)[sel], self.rows(g, i - 1, 0, 3)[sel]], 1)
                mixer.set(tgt, src, weights)

    def green(self, mixer: RowMixer) -> None:
        for k, g in enumerate(self.groups):
            keys = self.spoke_keys(k)
            for i in range(g.n):
                if g.unconstrained[i]:
                    continue
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
                weights = np.array([_green_weights(*cache_key(row)) for row in uniq])[inverse]  # (E, 4, 18)
                tgt = slots[:, [a_slot(2), b_slot(2), a_slot(3), b_slot(3)]]
                mixer.set(tgt, slots, weights)

    def blue(self, mixer: RowMixer) -> None:
        base = self.face_row[self.face_row >= 0]
        src = base[:, None] + np.arange(36)[None, :]
        tgt = base[:, None] + np.array([6 * 2 + 2, 6 * 3 + 2, 6 * 2 + 3, 6 * 3 + 3])[None, :]
        mixer.set(tgt, src, blue_weights())


def _subset(g: EPGroup, keep: np.ndarray) -> EPGroup:
    """The EPs ``keep`` of a group."""
    per_ep = ("vertices", "h", "d", "faces", "corner", "far", "far_spoke")
    return replace(g, **{name: getattr(g, name)[keep] for name in per_ep})


def _sector_beta(g: EPGroup) -> np.ndarray:
    """(E, n) beta(0) of every spoke of a ring with fixed sector angles; NaN on sharp spokes.

    The fan v_i = d_i (cos phi_i, sin phi_i) satisfies [FSLYJ]'s eq. (5) with l_i = d_i
    wherever sin(theta_{i-1}) = sin(theta_i) (equal angles inside a sector; FOUR_FAN), and
    then alpha_i v_{i+1} + gamma_i v_{i-1} = beta_i v_i with
    beta_i(0) = d_{i-1} d_{i+1} sin(theta_{i-1} + theta_i) / sin(theta_{i-1}) (the printed b of
    ``angle_configuration`` with the g1_constraints sign; 2 d_{i-1} d_{i+1} cos(theta) for
    equal angles, [SSEL13]'s uniform rule per sector).  With these lengths the two crease legs of
    a sector of angle pi come out in the ratio of their intervals, the ratio in which the
    crease B-spline's Bezier legs stand, so G_0 of the inner spokes is consistent with both
    pinned crease legs (a fitted fan need not be)."""
    theta_before = np.roll(g.theta, 1)
    ratio = np.sin(theta_before + g.theta) / np.sin(theta_before)
    beta = np.roll(g.d, 1, axis=1) * np.roll(g.d, -1, axis=1) * ratio[None, :]
    beta[:, g.unconstrained] = np.nan
    smooth = ~g.unconstrained
    assert np.allclose(np.sin(theta_before[smooth]), np.sin(g.theta[smooth])), "eq. (5) needs l_i != d_i here"
    return beta


@lru_cache(maxsize=65536)
def _green_weights(alpha_a: float, alpha_b: float, b0: float, b1: float | None) -> np.ndarray:
    """(4, SLOTS): A[2,1], B[1,2], A[3,1], B[1,3] nearest to their extraction values under
    G_2, G_3: x = x_hat - n (n . x_hat + rest) / |n|^2 for x = (A[k,1], B[1,k])."""
    g = spoke_equations(alpha_a, alpha_b, b0, b1)
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
