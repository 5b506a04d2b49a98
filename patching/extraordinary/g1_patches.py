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
#: The monotone step's QP has 6 n^2 unknowns and its change space an SVD of ~3 n^2 x 6 n^2
#: (``_change_space``): 0.2 s at valence 12, ~n^6 beyond (hours at the valence-64 poles of
#: tests/test_sharp_features.py).  Rings of higher valence keep the plain red operator.
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


def _stage2_unknowns(n: int, pinned: tuple, gap: int) -> np.ndarray:
    """Indices into x of stage 2's unknowns y = [f (present patches), q (spokes not pinned)]."""
    return np.array([1 + n + i for i in range(n) if i != gap] + [1 + 2 * n + i for i in range(n) if not pinned[i]])


def _bounded_least_change(metric: np.ndarray, bmat: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
    """argmin z^T metric z subject to lo <= bmat z <= hi (metric SPD), or None where z = 0
    already satisfies it or no feasible point is found.

    A simplified form of [GI83]'s dual active-set method (full steps: no partial step when a
    multiplier changes sign): z = 0 is the unconstrained minimum; the most violated bound joins
    the active set (as an equality), the equality problem is solved exactly
    (z = A^-1 G^T (G A^-1 G^T)^-1 r), and an active bound whose multiplier has the wrong sign
    (the solution would rather leave it) is dropped; it stops when no bound is violated, so a
    returned z always satisfies every bound (it may not be the exact minimiser).  A few dozen bounds, so a few dozen small solves; SciPy's SLSQP
    took about 40 ms a ring here, this about 1 ms.  Falls back to None after 4 m steps."""
    tol = 1e-12 * max(1.0, float(np.abs(np.concatenate([lo, hi])).max()))
    if np.all(lo <= tol) and np.all(hi >= -tol):
        return None
    a_inv = np.linalg.inv(metric)
    active: dict[int, bool] = {}  # bound -> True: at lo (bmat z >= lo), False: at hi
    z = np.zeros(metric.shape[0])
    for _ in range(4 * bmat.shape[0] + 4):
        value = bmat @ z
        excess = np.maximum(lo - value, value - hi)
        excess[list(active)] = -np.inf
        j = int(np.argmax(excess))
        if excess[j] <= tol:
            return z
        active[j] = bool(lo[j] - value[j] > value[j] - hi[j])
        while True:
            idx = list(active)
            g = bmat[idx]
            r = np.where([active[i] for i in idx], lo[idx], hi[idx])
            schur = g @ a_inv @ g.T
            mu = np.linalg.lstsq(schur, r, rcond=1e-13)[0]
            wrong = [k for k, i in enumerate(idx) if (mu[k] < 0) == active[i] and abs(mu[k]) > 1e-14 * max(1.0, np.abs(mu).max())]
            if not wrong or len(idx) == 1:
                break
            del active[idx[max(wrong, key=lambda k: abs(mu[k]))]]
        z = a_inv @ g.T @ mu
        if np.abs(g @ z - r).max() > 1e-9 * max(1.0, np.abs(r).max()):
            return None  # dependent active bounds that cannot all hold
    return None


@lru_cache(maxsize=4096)
def _change_space(n: int, key: tuple, pinned: tuple, skip: tuple):
    """(y, C_y, Z) of one ring configuration: stage 2's unknowns, G_1 over them, and a basis
    Z of the changes D of their rows (vec(D) row-major, D[r, j] at r (1 + 3n) + j) with
    C_y D = 0 and D 1 = 0; None without G_1 rows."""
    rows = _red_rows(n, key, skip)
    if not rows[1]:
        return None
    size = 1 + 3 * n
    y = _stage2_unknowns(n, pinned, -1)
    cy = np.vstack(rows[1])[:, y]
    fixed = np.vstack([np.kron(cy, np.eye(size)), np.kron(np.eye(y.size), np.ones((1, size)))])
    out = (y, cy, _null_space(fixed))
    for a in out:
        a.setflags(write=False)
    return out


def _monotone_red(
    n: int, key: tuple, pinned: tuple, skip: tuple, q_weight: float, k: np.ndarray,
    x: np.ndarray, bounds: list[tuple[int, int, float, float]],
) -> np.ndarray | None:
    """The red operator K of one closed ring, changed as little as possible so that the
    blending functions keep the monotone spoke curves the extraction gave them (module
    docstring, "monotone spoke curves"); None where no change inside G_1 can.

    ``x``: (1 + 3n, C) the blending functions of the C control points that reach the ring, at
    the red inputs x_hat (columns of the elevated extraction with the anchors folded in:
    topology and intervals only); after the solve they are K x.  ``bounds``: (column c,
    spoke i, lo, hi): the value of function c at q_i must lie in [lo, hi] (the bounds that
    make the black step's P30 lie between q_i and P40 and q_i between s_i and P30).  Stage 2's
    rows y = [f, q] of K change by D with C_y D = 0 (G_1 stays exact for every input), D 1 = 0
    (rows still sum to one: affine invariance), and (D x)[q_i, c] putting the value on the
    bound it broke (active set: a broken bound becomes an equality until none is broken), D
    least in the change of every function it touches, sum_rows w_r |D_r x|^2 (w: 1 on f,
    ``q_weight`` on q, stage 2's metric).  K + D stays linear in the control points."""
    system = _change_space(n, key, pinned, skip)
    if system is None:
        return None
    size = 1 + 3 * n
    y, cy, basis = system
    ny = y.size
    row_of = {int(j): r for r, j in enumerate(y.tolist())}
    w = np.where(y >= 1 + 2 * n, q_weight, 1.0)
    # x x^T is singular where the functions do not span the inputs: a change D with D x = 0
    # alters no function, and left free it lets the solver wander off to weights of 1e9 that
    # break G_1 in rounding; a small ridge (the weights' own size) pins those directions.
    gram = x @ x.T
    gram += (RIDGE * np.trace(gram) / size + 1e-300) * np.eye(size)
    v = k[y] @ x  # (ny, C)
    # D = reshape(Z z): Z a basis of the D that keep G_1 and the row sums; the bounds on
    # (D x)[q_i, c] are rows of B z.  Objective |M^(1/2) Z z|^2, M = W (x) (x x^T).
    metric = basis.T @ np.kron(np.diag(w), gram) @ basis
    b_rows, lo, hi = [], [], []
    for col, i, low, high in bounds:
        r = row_of[1 + 2 * n + i]
        pick = np.zeros(ny * size)
        pick[r * size : (r + 1) * size] = x[:, col]
        b_rows.append(pick @ basis)
        lo.append(low - v[r, col])
        hi.append(high - v[r, col])
    bmat, lo, hi = np.array(b_rows), np.array(lo), np.array(hi)
    z = _bounded_least_change(metric, bmat, lo, hi)
    if z is None:
        return None
    d = (basis @ z).reshape(ny, size)
    if np.abs(d).max() > MAX_CHANGE or np.abs(cy @ d).max() > 1e-12:
        return None
    out = k.copy()
    out[y] += d
    return out


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
    eqs = spoke_equations_batch(*spokes.T).reshape(g_count, n, 6, -1)
    rows = np.zeros((2, g_count, len(live), size))  # G_0 and G_1 rows of the constrained spokes
    for r, i in enumerate(live):
        slot_to_x = _spoke_slots(n, i)
        outside = np.delete(eqs[:, i, :2], list(slot_to_x), axis=-1)
        assert np.allclose(outside, 0.0), "G_0, G_1 reach beyond the red slots"
        for slot, col in slot_to_x.items():
            rows[:, :, r, col] += np.moveaxis(eqs[:, i, :2, slot], 1, 0)
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
        ref = self.reference(rows.ravel()).tocoo()
        ep = ref.row // per
        keys = ep * np.int64(ref.shape[1]) + ref.col
        uk, inv = np.unique(keys, return_inverse=True)
        starts = np.searchsorted(uk, np.arange(e_count, dtype=np.int64) * ref.shape[1])
        local = np.arange(uk.size) - starts[uk // ref.shape[1]]
        width = int(local.max(initial=-1)) + 1
        x = np.zeros((e_count, per, width))
        np.add.at(x, (ep, ref.row % per, local[inv]), ref.data)
        of_ep = np.zeros((e_count, width), dtype=bool)  # the column is an EP's function
        of_ep[uk // ref.shape[1], local] = self.is_ep[uk % ref.shape[1]]
        v = np.einsum("eij,ejc->eic", ops, x[:, :size])
        s_hat, q_hat = x[:, 1 : 1 + n], x[:, 1 + 2 * n : size]
        p30_hat, p40, p50 = x[:, size : size + n], x[:, size + n : size + 2 * n], x[:, size + 2 * n :]
        p00, s_new, q_new = v[:, :1], v[:, 1 : 1 + n], v[:, 1 + 2 * n :]
        tol = 1e-10
        steps = np.stack([s_hat - q_hat, q_hat - p30_hat, p30_hat - p40, p40 - p50])
        down = (steps >= -tol).all(axis=0) & (steps > tol).any(axis=0)
        up = (steps <= tol).all(axis=0) & (steps < -tol).any(axis=0)
        flat = 0.5 * (p40 + s_new) - 0.1 * (p00 - p50)  # q that puts P30 on P40
        lo = np.where(down, flat, np.where(up, s_new, np.nan))
        hi = np.where(down, s_new, np.where(up, flat, np.nan))
        free = (g.far < 0) & ~np.array(pinned, bool) & ~np.array(skip, bool)
        watch = (down | up) & free[:, :, None] & (lo <= hi) & of_ep[:, None, :]
        broken = watch & ((q_new < lo - 1e-12) | (q_new > hi + 1e-12))
        bad = np.flatnonzero(broken.any(axis=(1, 2)))
        if not bad.size:
            return ops
        ops = ops.copy()
        for e in bad.tolist():
            key = tuple(cache_key(r) for r in uniq[inverse[e]].reshape(n, 4))
            i_idx, c_idx = np.nonzero(watch[e])
            bounds = [(int(c), int(i), float(lo[e, i, c]), float(hi[e, i, c])) for i, c in zip(i_idx, c_idx)]
            fixed = _monotone_red(n, key, pinned, skip, Q_WEIGHT, ops[e], x[e, :size], bounds)
            if fixed is not None:
                ops[e] = fixed
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
