"""Angle configuration of one extraordinary point: angles, lengths, connecting functions.

[FSLYJ] sec. 3.3 ("Constraints for G1 continuity"), with the sharp-feature rule of
section 4.2.  For an EP of valence n with spoke-edge knot intervals d_0..d_{n-1} this module
chooses the angles theta_i and spoke lengths l_i of a planar "characteristic" fan and from them
the constants b_i of the connecting functions used by the G1 constraints of section 3.4
(eqs. 8 and 9).  It depends on n, the intervals and the sharp tags only, never on positions.

Numbering (indices mod n; [FSLYJ] Figs. 9 and 10)::

                      spoke i+1
                         \\
            patch i+1     \\      patch i: its s-direction runs along spoke i,
                           \\              its t-direction along spoke i+1,
                            \\ theta_i     P^i_{j,0} = P^{i-1}_{0,j} (the shared spoke i)
                            EP ---------------- spoke i        (counter-clockwise = increasing i)
                            / theta_{i-1}
            patch i-2      /
                          /     patch i-1
                         /
                      spoke i-1

* Spoke i is the EP's i-th edge; d_i is its knot interval.  Patch (face) i lies between spoke
  i and spoke i+1, so its intervals are d_i (along s) and d_{i+1} (along t).
* theta_i is the angle of patch i at the EP, from spoke i to spoke i+1: the angle between
  A_s(0,0) and A_t(0,0) of Fig. 9 with A = patch i.  sum theta_i = 2 pi.
* l_i is the length of spoke i in the fan; v_i = l_i (cos phi_i, sin phi_i) with
  phi_i = theta_0 + ... + theta_{i-1} stands for the Bezier leg P^i_{1,0} - P^i_{0,0}.
* alpha_i = d_i d_{i-1} multiplies v_{i+1} (the far side of patch i) and gamma_i = d_i d_{i+1}
  multiplies v_{i-1} in the first row of eq. (8).  This assignment is the one for which the
  valence-4 (NURBS) case is C1: across spoke i the legs v_{i+1}/d_{i+1} and -v_{i-1}/d_{i-1} are
  equal derivatives.

The tangent-plane condition at the EP for spoke i, with the b_i returned here, is

    alpha_i v_{i+1} + gamma_i v_{i-1} + b_i v_i = 0.                              (*)

Crossing (*) with v_i gives the paper's eq. (5) (the unnumbered relation before Lemma 2),

    l_{i+1} sin(theta_i) / (l_{i-1} sin(theta_{i-1})) = d_{i+1} / d_{i-1},

and crossing with v_{i-1} gives b_i = -l_{i+1} d_{i-1} d_i sin(theta_{i-1} + theta_i) /
(l_i sin(theta_{i-1})), exactly as printed; uniform angles give b_i = -2 d_{i-1} d_{i+1}
cos(2 pi / n), the baseline of reference [SSEL13].  This confirms the convention above: with
theta_i measured from spoke i-1 instead, eq. (5) would carry other indices.

SIGN WARNING for whoever wires b into section 3.4: the printed eq. (8) (and Lemma 1, eq. 4,
"gamma A_t + alpha B_t - beta A_s = 0") group as alpha v_{i+1} + gamma v_{i-1} = b v_i, i.e.
they use the opposite sign: uniform valence 5 needs v_{i+1} + v_{i-1} = +2 cos(72 deg) v_i,
while the printed b formula and [SSEL13] give -2 d d cos(2 pi / n).  The paper is inconsistent
between its b formula and its eqs. (4), (8), (9); this module returns b as the b formula is
printed (the brief asked for that), so substitute -b for b in eqs. (8) and (9) as printed, or
equivalently use (*).  Valence 4 cannot tell the two apart (b = 0 there).

Reconstructions of garbled formulas (each checked in tests/test_angle_configuration.py):

* Even n, default angles.  Printed: theta_{n-1} = arctan(beta_2 sin beta_1 / (1 + beta_2 sin
  beta_1)).  From Lemma 2's condition (0, n-2) = (1, n-1) with theta_{n-2} + theta_{n-1} =
  beta_1 fixed: beta_2 sin(beta_1 - x) = sin x for x = theta_{n-1}, so tan x = beta_2 sin beta_1
  / (1 + beta_2 cos beta_1): cos, not sin, in the denominator; x = arg(1 + beta_2 e^{i beta_1})
  taken mod pi, which lies in (0, beta_1) whenever a solution with both angles in (0, pi)
  exists.  Test: the condition holds to round-off afterwards.
* Default lengths.  Printed: l_i = d_i + sum_{j=1}^{n-1} d_j (cos(sum_{k=0}^{j-i-1}
  theta_{i+k}))_+ with damaged indices.  Read with j the absolute spoke index i+1..i+n-1, the
  inner sum is the fan angle from spoke i to spoke j, so l_i = sum_j d_j (cos(phi_j - phi_i))_+
  (the j = i term is d_i).  This is the d_i^+ part of the eigen-polyhedron length of
  Li-Finnigan-Sederberg 2016 ([TLC], eq. 5) with the actual angles in place of 2 pi (i-j)/n.
  Tests: uniform intervals give equal lengths; valence 4 gives l_i proportional to d_i (NURBS).
* b_i is not garbled but see the sign warning above.

Choices the text leaves open (documented here, tested):

* Scale.  Intervals are divided by their mean before anything else, so angles do not change
  when all intervals are scaled (the surface does not either); lengths are returned in the
  units of the given intervals and alpha, gamma, b use the given intervals.
* Lengths from angles.  Eqs. (6) and (7) fix the lengths up to one factor (odd n) or two (even
  n: the even and the odd spokes form separate chains); the paper leaves l_0 (and l_1) free.
  Those factors are fitted to l-hat by linear least squares.  For even n, b_i depends on the
  ratio of the two factors (l_{i+1} / l_i crosses chains).  The "uniform" mode uses one common
  factor, l_i proportional to d_i, which is what makes b equal [SSEL13]'s formula.
* Labelling.  Every EP is solved in a canonical labelling (the lexicographically smallest
  rotation or reflection of its intervals and sharp set) and relabelled back, so results are
  exactly equivariant under rotation and reflection, and rotated or mirrored copies of an EP
  share one solve.  The paper's "last two angles" of the even-n perturbation are the last two
  of the canonical labelling.
* Optimisation target for even n.  The "default" mode returns the paper's perturbed angles; the
  "optimized" mode starts there but measures ||theta-hat - theta|| against the unperturbed
  heuristic angles (and l-hat from them), which do not depend on the labelling.  For odd n
  there is no difference.
* Symmetric intervals.  E can break symmetry: for intervals 10, 2, 1, 1, 2 it has a mirrored
  pair of asymmetric minima (E = 1.892) and only a saddle (E = 1.953) among symmetric angles.
  A symmetric mesh should not get an arbitrarily lopsided surface, so when the intervals (and
  sharp set) have a symmetry the optimisation is restricted to angles with that symmetry
  (stiff penalty rows, then an exact average and the Lemma 2 pair re-solved).
* Alternating scheme (section 3.3, Remark 2): the variables are the angles and the length
  factor(s) of the previous paragraph.  Step 1 fixes the factors and minimises E over the
  angles; step 2 refits the factors explicitly and recomputes l.  Each step lowers E =
  ||l-hat - l||^2 + omega ||theta-hat - theta||^2, so E decreases monotonically.  Each chain's
  shape is scaled to unit norm, so that angles change shape and factors change size (with l_0 =
  1 instead the blocks zig-zag: over 200 iterations at valence 16, against 4 to 10 now).  Step 1
  opens with the Levenberg-Marquardt rules of MINPACK's lmder ([Mor78], which earlier versions
  called through scipy.optimize: where E has several minima, the same rules from the same
  start end in the same one) and finishes with damped Newton steps.  The scheme stops when an outer
  iteration moves no angle by more than 1e-4 rad (or after max_iterations: then the current
  iterate is kept and ``converged`` is False); Newton steps on angles and factors together then
  take it to the stationary point of E, to ~1e-15 rad.  (The earlier MINPACK version stopped
  where E stopped decreasing in floating point, up to ~1e-7 rad short of it, typically 5e-10.)
  All configurations of one valence, sharp set and symmetry group are solved in one stacked
  computation (``angle_configurations``).  The constraints are built into a chart: in every
  sector all angles but the last are free and the last closes the sector's sum; when Lemma 2
  applies (even n) the last two angles of one sector come from the closed form above, so the
  condition holds exactly at every iterate.  Steps that leave (0, pi) are refused.
* Sharp spokes (section 4.2: "the sum of angles to each side of two continuous sharp edges must
  both be pi").  r sharp spokes split the n patches into r sectors; each sector's angles sum to
  2 pi / max(r, 1): r = 2 is the paper's rule (pi and pi), r = 1 (a dart) keeps 2 pi for the
  single sector so its angles are those of the smooth EP, r >= 3 (a corner) shares 2 pi equally
  (the geometric sector angles of [TLC]'s corner rule are not available to an operator that
  depends on topology and knots only).  Heuristic angles are normalised per sector.  There is
  no G1 constraint across a sharp spoke, so eq. (5) is not imposed there and b is NaN there;
  Lemma 2's condition is imposed only when a closed chain survives (n even and all sharp spokes
  of one parity, or none).  A sector of one patch gets the whole sector angle (pi for r = 2); no
  constraint uses it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from patching.errors import KnotError, TagError
from patching.options import ANGLES
from patching.util.memo import batching, memo
from patching.util.solve_cache import lookup_many

__all__ = ["AngleConfiguration", "angle_configuration", "angle_configurations", "MODES"]

#: The angle configurations: the choices of ``BuildOptions.angles``, defined in ``patching.options``.
MODES = ANGLES
_TWO_PI = 2.0 * math.pi
_OUTER_TOL = 1e-4  # the alternating scheme's stop (rad): its basin is settled; Newton on (u, s) finishes
_SYM_WEIGHT = 1e3  # weight of the rows keeping symmetric intervals' angles symmetric


@dataclass(frozen=True)
class AngleConfiguration:
    """Angles, lengths and connecting-function constants of one EP ([FSLYJ] sec. 3.3).

    All arrays are (n,) float64, read-only (results are cached and shared), indexed as in the
    module docstring: theta[i] is the angle of patch i (from spoke i to spoke i+1), lengths[i]
    the fan length of spoke i, and for spoke i
    alpha[i] = d_i d_{i-1}, gamma[i] = d_i d_{i+1},
    b[i] = -l_{i+1} d_{i-1} d_i sin(theta_{i-1} + theta_i) / (l_i sin theta_{i-1})
    (NaN on sharp spokes, which carry no G1 constraint), so that
    alpha_i v_{i+1} + gamma_i v_{i-1} + b_i v_i = 0 in the fan (see the sign warning).
    ``objective`` is E = ||l-hat - l||^2 + omega ||theta-hat - theta||^2 at this configuration
    (intervals scaled to mean 1), ``iterations`` the outer alternating iterations used.
    """

    theta: np.ndarray
    lengths: np.ndarray
    b: np.ndarray
    alpha: np.ndarray
    gamma: np.ndarray
    mode: str
    converged: bool
    iterations: int
    sharp_spokes: tuple[int, ...] = ()
    objective: float = 0.0


def angle_configuration(
    intervals: Sequence[float],
    mode: str = "optimized",
    omega: float = 2.0,
    max_iterations: int = 200,
    sharp_spokes: Sequence[int] = (),
) -> AngleConfiguration:
    """Angle configuration of an EP with spoke intervals ``intervals`` ([FSLYJ] sec. 3.3).

    intervals: (n,) knot intervals d_i of the spokes, counter-clockwise, n >= 3, d_i >= 0, at
    least one face (d_i d_{i+1} > 0) of nonzero area.
    mode: "optimized" (default angles, then the minimum of section 3.3's E with weight
    ``omega`` by the alternating scheme, at most ``max_iterations`` outer iterations, Remark 2;
    see the module docstring), "default" (the
    heuristic angles, perturbed for Lemma 2 when n is even) or "uniform" (theta = 2 pi / n, the
    baseline of [SSEL13]: b_i = -2 d_{i-1} d_{i+1} cos(2 pi / n)).
    sharp_spokes: indices of spokes that are sharp (C0) edges (section 4.2); see the module
    docstring for one, two and more sharp spokes.

    Results are cached by (intervals rounded to 12 significant digits, mode, omega,
    max_iterations, sharp spokes), so identical EPs are solved once; the computation uses the
    rounded intervals.  Raises KnotError for bad intervals, TagError for bad sharp spokes.
    """
    _validated_options(mode, omega, max_iterations)
    return _mapped(*_problem(intervals, mode, omega, max_iterations, sharp_spokes))


def angle_configurations(
    rows: Sequence[Sequence[float]],
    mode: str = "optimized",
    omega: float = 2.0,
    max_iterations: int = 200,
    sharp_spokes: Sequence[int] = (),
) -> list[AngleConfiguration]:
    """``angle_configuration`` of every row of ``rows`` (each an EP's spoke intervals), the
    same results; the configurations not solved yet whose canonical problems share a valence,
    sharp set and symmetry group are optimised together (one stacked solve), unless
    ``patching.util.memo.set_batching(False)`` asks for one at a time."""
    _validated_options(mode, omega, max_iterations)
    problems = [_problem(row, mode, omega, max_iterations, sharp_spokes) for row in rows]
    if batching():
        todo = []
        fresh = list(dict.fromkeys(args for args in problems if not _mapped.known(args)))
        _canonical_many([(args[0], args[4]) for args in fresh])
        for args in fresh:
            (dc, sharp_c), _, _ = _canonical(args[0], args[4])
            canonical = (dc, mode, float(omega), int(max_iterations), sharp_c)
            if not _cached.known(canonical):
                todo.append(canonical)
        todo = list(dict.fromkeys(todo))
        for args, config in zip(todo, _solve_canonical(todo) if todo else []):
            _cached.prime(args, config)
    return [_mapped(*args) for args in problems]


def _validated_options(mode: str, omega: float, max_iterations: int) -> None:
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, not {mode!r}")
    if not (math.isfinite(omega) and omega > 0):
        raise ValueError(f"omega must be a positive number, not {omega!r}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f"max_iterations must be a positive integer, not {max_iterations!r}")


def _problem(intervals, mode, omega, max_iterations, sharp_spokes) -> tuple:
    """The cache key of one EP: (intervals rounded to 12 significant digits, mode, omega,
    max_iterations, sharp spokes), validated."""
    d = _validated_intervals(intervals)
    sharp = _validated_sharp(sharp_spokes, d.size)
    key = tuple(float(f"{x:.12g}") for x in d)
    return key, mode, float(omega), int(max_iterations), sharp


def _dihedral(n: int):
    """The 2n relabellings of an EP: (spoke map g, patch map), spoke j of the relabelled EP
    being spoke g[j] of the original.  Rotation j -> j + k maps patch i to i + k; reflection
    j -> c - j maps patch i (spokes i, i+1) to patch c - i - 1."""
    j = np.arange(n)
    for c in range(n):
        yield (j + c) % n, (j + c) % n
    for c in range(n):
        yield (c - j) % n, (c - j - 1) % n


@lru_cache(maxsize=None)
def _relabellings(n: int, sharp: tuple[int, ...]):
    """The 2n relabellings of ``_dihedral`` as arrays (2n, n) (spoke maps, patch maps), each
    one's relabelled sharp set, and the rank of those sets in tuple order (equal sets, equal
    rank)."""
    maps = list(_dihedral(n))
    spokes = np.array([g for g, _ in maps])
    patches = np.array([gp for _, gp in maps])
    marked = set(sharp)
    sets = [tuple(j for j, x in enumerate(g.tolist()) if x in marked) for g in spokes]
    order = sorted(set(sets))
    return spokes, patches, sets, np.array([order.index(x) for x in sets])


@memo(maxsize=8192)
def _canonical(key: tuple[float, ...], sharp: tuple[int, ...]):
    """((intervals, sharp set) of the canonical relabelling, spoke map, patch map): the
    lexicographically smallest (intervals, then sharp set) over rotations and reflections, the
    first in ``_dihedral``'s order among equals."""
    spokes, patches, sets, _ = _relabellings(len(key), sharp)
    best = None
    for k, g in enumerate(spokes.tolist()):  # in plain Python; _canonical_many for many EPs at once
        cand = (tuple(key[j] for j in g), sets[k])
        if best is None or cand < best[0]:
            best = (cand, k)
    return best[0], spokes[best[1]], patches[best[1]]


def _canonical_many(problems: list[tuple[tuple[float, ...], tuple[int, ...]]]) -> None:
    """``_canonical`` of many (intervals, sharp set) pairs, vectorised over those of one valence
    and sharp set, put into its memo: the relabelled intervals (g, 2n, n) narrowed column by
    column to the candidates equal to the smallest, then by the sharp sets' rank, then the
    first; the same choice as the one-problem loop."""
    groups: dict[tuple[int, tuple[int, ...]], list[tuple]] = {}
    for key, sharp in problems:
        if not _canonical.known((key, sharp)):
            groups.setdefault((len(key), sharp), []).append(key)
    for (n, sharp), keys in groups.items():
        spokes, patches, sets, rank = _relabellings(n, sharp)
        cand = np.array(keys)[:, spokes]  # (g, 2n, n)
        alive = np.ones(cand.shape[:2], dtype=bool)
        for col in range(n):
            v = np.where(alive, cand[:, :, col], np.inf)
            alive &= cand[:, :, col] == v.min(axis=1)[:, None]
        r = np.where(alive, rank[None, :], rank.size)
        alive &= r == r.min(axis=1)[:, None]
        first = np.argmax(alive, axis=1)
        for key, k, c in zip(keys, first.tolist(), cand[np.arange(len(keys)), first].tolist()):
            _canonical.prime((key, sharp), ((tuple(c), sets[k]), spokes[k], patches[k]))


@memo(maxsize=4096)
def _mapped(key, mode, omega, max_iterations, sharp) -> AngleConfiguration:
    """Solve on the canonical relabelling (lexicographically smallest intervals and sharp set
    over rotations and reflections), then relabel back: results are exactly equivariant, and
    rotated or mirrored copies of one EP share one solve."""
    d = np.array(key)
    n = d.size
    (dc, sharp_c), g, gp = _canonical(key, sharp)
    c = _cached(dc, mode, omega, max_iterations, sharp_c)
    theta, lengths, b = (np.empty(n) for _ in range(3))
    theta[gp] = c.theta
    lengths[g] = c.lengths
    b[g] = c.b  # b multiplies the middle leg of (*): unchanged by a reflection (by eq. 5)
    arrays = {"theta": theta, "lengths": lengths, "b": b, "alpha": d * np.roll(d, 1), "gamma": d * np.roll(d, -1)}
    for v in arrays.values():
        v.setflags(write=False)
    return AngleConfiguration(
        mode=mode, converged=c.converged, iterations=c.iterations, sharp_spokes=sharp, objective=c.objective, **arrays
    )


# --------------------------------------------------------------------------------------------
# Validation


def _where(n: int) -> str:
    return f"spokes of a valence-{n} extraordinary point"


def _validated_intervals(intervals: Sequence[float]) -> np.ndarray:
    try:
        d = np.asarray(intervals, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise KnotError(f"knot intervals are not numbers: {intervals!r}") from exc
    if d.ndim != 1:
        raise KnotError(f"knot intervals must be a flat list, got shape {d.shape}")
    n = d.size
    if n < 3:
        raise KnotError(f"an extraordinary point needs valence >= 3, got {n} intervals", _where(n))
    bad = np.flatnonzero(~np.isfinite(d))
    if bad.size:
        raise KnotError(f"knot interval d_{bad[0]} = {d[bad[0]]} is not finite", _where(n))
    bad = np.flatnonzero(d < 0)
    if bad.size:
        raise KnotError(f"knot interval d_{bad[0]} = {d[bad[0]]} is negative", _where(n))
    if not np.any(d * np.roll(d, -1) > 0):
        raise KnotError("every face around the point has a zero knot interval", _where(n))
    return d


def _validated_sharp(sharp_spokes: Sequence[int], n: int) -> tuple[int, ...]:
    out = set()
    for s in sharp_spokes:
        if isinstance(s, bool) or int(s) != s or not 0 <= int(s) < n:
            raise TagError(f"sharp spoke {s!r} is not a spoke index 0..{n - 1}", _where(n))
        out.add(int(s))
    return tuple(sorted(out))


# --------------------------------------------------------------------------------------------
# Structure: sectors, the length chains, the Lemma 2 pair


@dataclass(frozen=True)
class _Structure:
    n: int
    sharp: tuple[int, ...]
    sectors: tuple[tuple[int, ...], ...]  # patch indices of each sector, counter-clockwise
    sums: tuple[float, ...]  # angle sum of each sector
    exponents: np.ndarray  # (n, n) int: log m_j = sum_k E[j, k] log sin theta_k
    component: np.ndarray  # (n,) int: length chain of each spoke (one free factor each)
    n_components: int
    pair: tuple[int, int] | None  # (a, b): theta_b from Lemma 2's closed form, or None


@lru_cache(maxsize=None)
def _structure(n: int, sharp: tuple[int, ...]) -> _Structure:
    r = len(sharp)
    if r == 0:
        sectors = (tuple(range(n)),)
    else:
        sectors = tuple(
            tuple(p % n for p in range(sharp[k], sharp[k] + ((sharp[(k + 1) % r] - sharp[k] - 1) % n) + 1))
            for k in range(r)
        )
    sums = tuple(_TWO_PI / max(r, 1) for _ in sectors)
    # Length chains: a smooth spoke i links spokes i-1 and i+1 by eq. (5),
    # m_{i+1} sin(theta_i) = m_{i-1} sin(theta_{i-1}) with m_j = l_j / d_j.
    smooth = [i for i in range(n) if i not in sharp]
    exponents = np.zeros((n, n), dtype=np.int64)
    component = np.full(n, -1, dtype=np.int64)
    n_components = 0
    for root in range(n):
        if component[root] >= 0:
            continue
        component[root] = n_components
        stack = [root]
        while stack:
            p = stack.pop()
            for i in smooth:
                lo, hi = (i - 1) % n, (i + 1) % n
                if p == lo:
                    q, sign = hi, 1
                elif p == hi:
                    q, sign = lo, -1
                else:
                    continue
                if component[q] >= 0:
                    continue  # closing a chain: consistent by Lemma 2
                component[q] = n_components
                exponents[q] = exponents[p]
                exponents[q, (i - 1) % n] += sign
                exponents[q, i] -= sign
                stack.append(q)
        n_components += 1
    # Lemma 2's condition is needed when a closed chain survives: n even and all sharp spokes
    # of one parity (an odd closed chain closes by itself).
    pair = None
    if n % 2 == 0 and len({s % 2 for s in sharp}) <= 1:
        sizes = [len(s) for s in sectors]
        best = max(range(len(sectors)), key=lambda k: (sizes[k], k))
        if sizes[best] >= 2:
            pair = (sectors[best][-2], sectors[best][-1])
    return _Structure(n, sharp, sectors, sums, exponents, component, n_components, pair)


# --------------------------------------------------------------------------------------------
# The heuristic ([FSLYJ] sec. 3.3)


def _heuristic_weights(d: np.ndarray) -> np.ndarray:
    """alpha_i of the default-angle heuristic: k_i = n d_i d_{i+1} / sum_j d_j d_{j+1},
    alpha_i = pi/2 - (2 - 8/n) arctan k_i for k_i < 1, (8 - n) pi / (2n) + (2 - 8/n)
    arctan((1 + k_i)/2) otherwise (continuous at k = 1, value 2 pi / n; pi/2 as k -> 0)."""
    n = d.size
    area = d * np.roll(d, -1)
    k = n * area / area.sum()
    c = 2.0 - 8.0 / n
    return np.where(k < 1, 0.5 * math.pi - c * np.arctan(k), (8 - n) * math.pi / (2 * n) + c * np.arctan(0.5 * (1 + k)))


def _heuristic_angles(d: np.ndarray, st: _Structure) -> np.ndarray:
    """theta-hat_i = S alpha_i / sum(alpha over the sector), S the sector sum (2 pi if smooth)."""
    w = _heuristic_weights(d)
    theta = np.empty(st.n)
    for sector, total in zip(st.sectors, st.sums):
        idx = list(sector)
        theta[idx] = total * w[idx] / w[idx].sum()
    return theta


def _lemma2_residual(theta: np.ndarray) -> float:
    """log((0, n-2) / (1, n-1)) = sum log sin theta_even - sum log sin theta_odd (n even)."""
    ls = np.log(np.sin(theta))
    return float(ls[0::2].sum() - ls[1::2].sum())


def _pair_beta2(theta: np.ndarray, a: int, b: int) -> float:
    """beta_2 = product of sin theta_j, j != a, b, with j of a's parity over those of b's."""
    ls = np.log(np.sin(theta))
    sign = np.where(np.arange(theta.size) % 2 == a % 2, 1.0, -1.0)
    sign[[a, b]] = 0.0
    return float(np.exp(np.dot(sign, ls)))


def _pair_angle(beta1: float, beta2: float) -> float:
    """x in (0, beta1) with beta2 sin(beta1 - x) = sin x (reconstructed closed form):
    tan x = beta2 sin beta1 / (1 + beta2 cos beta1), i.e. x = arg(1 + beta2 e^{i beta1}) mod pi.
    Returns NaN when no solution keeps both angles in (0, pi)."""
    x = math.atan2(beta2 * math.sin(beta1), 1.0 + beta2 * math.cos(beta1))
    if x <= 0:
        x += math.pi
    if not (0 < x < math.pi and 0 < beta1 - x < math.pi):
        return math.nan
    return x


def _default_angles(d: np.ndarray, st: _Structure) -> tuple[np.ndarray, np.ndarray]:
    """(unperturbed heuristic, paper's default): the latter has its Lemma 2 pair perturbed."""
    target = _heuristic_angles(d, st)
    theta = target.copy()
    if st.pair is not None and abs(_lemma2_residual(theta)) > 1e-13:
        a, b = st.pair
        beta1 = theta[a] + theta[b]
        x = _pair_angle(beta1, _pair_beta2(theta, a, b))
        if not math.isfinite(x):  # pragma: no cover - cannot happen for heuristic angles
            raise ArithmeticError("Lemma 2 perturbation has no solution")
        theta[b] = x
        theta[a] = beta1 - x
    return target, theta


def _default_lengths(d: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """l-hat_i = sum_j d_j (cos(phi_j - phi_i))_+, phi the fan angle of each spoke
    (reconstructed; the j = i term is d_i, see the module docstring)."""
    phi = np.concatenate([[0.0], np.cumsum(theta)[:-1]])
    c = np.cos(phi[None, :] - phi[:, None])
    return np.maximum(c, 0.0) @ d


# --------------------------------------------------------------------------------------------
# Lengths from angles (Lemma 2, eqs. 6 and 7) and b


def _relative_lengths(theta: np.ndarray, st: _Structure) -> np.ndarray:
    """m_j = l_j / d_j up to one factor per chain: eqs. (6)/(7) as a product of sine ratios."""
    return np.exp(st.exponents @ np.log(np.abs(np.sin(theta))))


def _fit_factors(q: np.ndarray, target: np.ndarray, st: _Structure) -> np.ndarray:
    """Least-squares factor s_c per chain so that s_c q_j matches target_j; s per spoke."""
    num = np.bincount(st.component, q * target, st.n_components)
    den = np.bincount(st.component, q * q, st.n_components)
    s = np.where(den > 0, num / np.where(den > 0, den, 1.0), 1.0)
    return s[st.component]


def _connecting_b(d: np.ndarray, theta: np.ndarray, mu: np.ndarray, st: _Structure) -> np.ndarray:
    """b_i = -l_{i+1} d_{i-1} d_i sin(theta_{i-1} + theta_i) / (l_i sin theta_{i-1}), written with
    l_j = d_j mu_j as -d_{i-1} d_{i+1} (mu_{i+1} / mu_i) sin(theta_{i-1} + theta_i) /
    sin(theta_{i-1}) so that zero intervals do not give 0/0.  For even n, l_{i+1} / l_i is a
    ratio between the two chains, so b depends on both chain factors."""
    tm = np.roll(theta, 1)
    b = -np.roll(d, 1) * np.roll(d, -1) * (np.roll(mu, -1) / mu) * np.sin(tm + theta) / np.sin(tm)
    if st.sharp:
        b[list(st.sharp)] = np.nan
    return b


# --------------------------------------------------------------------------------------------
# The chart: free angles -> all angles, with the sums and Lemma 2 built in


class _Chart:
    """Which angles are free (u), which close a sector, which are fixed (one-patch sectors) and
    which sector holds the Lemma 2 pair; ``_BatchProblem`` evaluates theta(u) and its Jacobian."""

    def __init__(self, st: _Structure) -> None:
        self.st = st
        free, last, fixed = [], [], []
        for sector, total in zip(st.sectors, st.sums):
            if len(sector) == 1:
                fixed.append((sector[0], total))
                continue
            n_dep = 2 if st.pair is not None and sector[-1] == st.pair[1] else 1
            free.extend(sector[:-n_dep])
            if n_dep == 1:
                last.append((sector[-1], list(sector[:-1]), total))
            else:
                self.pair_sector = (list(sector[:-2]), total)
        self.free = np.array(free, dtype=np.int64)
        self.variable = np.setdiff1d(np.arange(st.n), [j for j, _ in fixed])
        self.last = last
        self.fixed = fixed


# --------------------------------------------------------------------------------------------
# Solve


def _objective(theta, lengths, theta_hat, l_hat, omega) -> float:
    return float(np.sum((l_hat - lengths) ** 2) + omega * np.sum((theta_hat - theta) ** 2))


# --------------------------------------------------------------------------------------------
# The batched solver: damped Gauss-Newton on the angles and the chain factors together


class _BatchProblem:
    """E = ||l-hat - l||^2 + omega ||theta-hat - theta||^2 for g configurations of one
    structure at once, as least-squares residuals of x = (u, s): the free angles u (the chart)
    and the chain factors s, l = s_c q_c(theta(u)) with q_c each chain's shape (eqs. 6/7) of
    unit norm; with symmetries, stiff rows 1e3 (theta - theta[p]) (module docstring).
    Residuals (g, R), Jacobians (g, R, f + C); the analytic Jacobian uses
    d log m / d theta = E cot(theta), chained through the chart."""

    def __init__(self, dbar, st, theta_hat, l_hat, omega, symmetries=()) -> None:
        self.st, self.dbar, self.theta_hat, self.l_hat = st, dbar, theta_hat, l_hat
        self.sqrt_w = math.sqrt(omega)
        self.chart = _Chart(st)
        self.f = self.chart.free.size
        self.symmetries = [np.asarray(p) for p in symmetries]
        self.chains = (st.component[:, None] == np.arange(st.n_components)[None, :]).astype(float)  # (n, C)
        self.same = (st.component[:, None] == st.component[None, :]).astype(float)
        self.exponents = st.exponents.astype(float)
        self.lemma = None
        if st.pair is not None:
            a, b = st.pair
            sign = np.where(np.arange(st.n) % 2 == a % 2, 1.0, -1.0)
            sign[[a, b]] = 0.0
            self.lemma = (a, b, sign, list(self.chart.pair_sector[0]), self.chart.pair_sector[1])

    def theta(self, u: np.ndarray) -> np.ndarray:
        """theta(u) (g, n) through the chart; a row is NaN where it leaves (0, pi)."""
        chart, st = self.chart, self.st
        theta = np.zeros((u.shape[0], st.n))
        theta[:, chart.free] = u
        for j, total in chart.fixed:
            theta[:, j] = total
        for j, others, total in chart.last:
            theta[:, j] = total - theta[:, others].sum(axis=1)
        if self.lemma is not None:
            a, b, sign, others, total = self.lemma
            beta1 = total - theta[:, others].sum(axis=1)
            theta[:, [a, b]] = 0.5 * math.pi  # placeholders: excluded from beta_2
            with np.errstate(invalid="ignore", divide="ignore"):
                beta2 = np.exp(np.log(np.abs(np.sin(theta))) @ sign)
                x = np.arctan2(beta2 * np.sin(beta1), 1.0 + beta2 * np.cos(beta1))  # _pair_angle
            x = np.where(x <= 0, x + math.pi, x)
            ok = (0 < x) & (x < math.pi) & (0 < beta1 - x) & (beta1 - x < math.pi) & (0 < beta1) & (beta1 < _TWO_PI)
            theta[:, b] = np.where(ok, x, math.nan)
            theta[:, a] = beta1 - theta[:, b]
        v = theta[:, chart.variable]
        bad = ~np.all(np.isfinite(v) & (v > 0) & (v < math.pi), axis=1)
        theta[bad] = math.nan
        return theta

    def shapes(self, theta: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """q = dbar m of unit norm on every chain (``_unit_shapes``), (g, n); idx: the rows'
        configurations."""
        q = self.dbar[idx] * np.exp(np.log(np.abs(np.sin(theta))) @ self.exponents.T)
        norm = np.sqrt((q * q) @ self.chains)[:, self.st.component]
        return q / np.where(norm > 0, norm, 1.0)

    def factors(self, theta: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """The best chain factors for these angles, s_c = <q_c, l-hat_c>, (g, C)."""
        return (self.shapes(theta, idx) * self.l_hat[idx]) @ self.chains

    def residual(self, x: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(theta, residuals) at x (g, p) of configurations idx; the rows of an invalid x are NaN."""
        th = self.theta(x[:, : self.f])
        q = self.shapes(th, idx)
        rows = [self.l_hat[idx] - x[:, self.f :][:, self.st.component] * q, self.sqrt_w * (self.theta_hat[idx] - th)]
        rows += [_SYM_WEIGHT * (th - th[:, p]) for p in self.symmetries]
        return th, np.concatenate(rows, axis=1)

    def chart_jacobian(self, theta: np.ndarray) -> np.ndarray:
        """d theta / d u, (g, n, f)."""
        chart = self.chart
        g = theta.shape[0]
        jac = np.zeros((g, self.st.n, self.f))
        jac[:, chart.free, np.arange(self.f)] = 1.0
        for j, others, _ in chart.last:
            jac[:, j] = -jac[:, others].sum(axis=1)
        if self.lemma is not None:
            a, b, sign, others, _ = self.lemma
            beta1 = theta[:, a] + theta[:, b]
            beta2 = np.exp(np.log(np.abs(np.sin(theta))) @ sign)
            cot = np.cos(theta) / np.sin(theta)
            dbeta2 = beta2[:, None] * np.einsum("gn,gnf->gf", sign * cot, jac)
            dbeta1 = -jac[:, others].sum(axis=1)
            e = np.exp(1j * beta1)
            w = 1.0 + beta2 * e
            jac[:, b] = ((e / w)[:, None] * (dbeta2 + 1j * beta2[:, None] * dbeta1)).imag
            jac[:, a] = dbeta1 - jac[:, b]
        return jac

    def jacobian(self, x: np.ndarray, theta: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """d residual / dx (g, R, p) at x with angles theta, configurations idx."""
        st = self.st
        p = self.chart_jacobian(theta)
        q = self.shapes(theta, idx)
        s = x[:, self.f :][:, st.component]
        cot = np.cos(theta) / np.sin(theta)
        dq = q[:, :, None] * ((self.exponents[None] * cot[:, None, :]) @ p)  # d q_raw / du over |q_raw|
        proj = np.eye(st.n)[None] - self.same[None] * (q[:, :, None] * q[:, None, :])
        top = np.concatenate([-(s[:, :, None] * (proj @ dq)), -(q[:, :, None] * self.chains[None])], axis=2)
        rows = [top, np.concatenate([-self.sqrt_w * p, np.zeros((p.shape[0], st.n, st.n_components))], axis=2)]
        rows += [np.concatenate([_SYM_WEIGHT * (p - p[:, perm]), np.zeros((p.shape[0], st.n, st.n_components))], axis=2) for perm in self.symmetries]
        return np.concatenate(rows, axis=1)

    def gradient(self, x: np.ndarray, theta: np.ndarray, r: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """J^T r, half the gradient of E, (g, p)."""
        return np.einsum("grp,gr->gp", self.jacobian(x, theta, idx), r)

    def hessian(self, x: np.ndarray, idx: np.ndarray, k: int) -> np.ndarray:
        """Half the Hessian of E in the first k variables, by central differences of
        ``gradient``, symmetrised, (g, k, k)."""
        g, p = x.shape
        h = 1e-5 * np.maximum(1.0, np.abs(x[:, :k]))
        step = np.zeros((g, k, p))
        step[:, np.arange(k), np.arange(k)] = h
        both = np.concatenate([x[:, None, :] + step, x[:, None, :] - step], axis=1).reshape(2 * g * k, p)
        rows = np.repeat(idx, 2 * k)
        theta, r = self.residual(both, rows)
        grad = self.gradient(both, theta, r, rows)[:, :k].reshape(g, 2, k, k)
        hess = (grad[:, 0] - grad[:, 1]) / (2 * h[:, :, None])
        return 0.5 * (hess + hess.transpose(0, 2, 1))


def _trust_region(prob: _BatchProblem, x, theta, r, todo: np.ndarray, k: int, limit: int) -> None:
    """The opening of the angle step, in place: Levenberg-Marquardt as MINPACK's lmder takes
    it ([Mor78], the scheme scipy's ``least_squares(method="lm")`` runs), for the first k
    variables of the configurations ``todo``: variables scaled by the running maximum of the
    Jacobian's column norms, a trust region of radius delta (first 100 times the scaled x, then
    at most the first step), the step the Gauss-Newton one when it fits, else the
    Levenberg-Marquardt step of scaled length delta (lambda by bisection on the SVD of the
    scaled Jacobian, where lmpar iterates to 10%), taken when it gains at least 1e-4 of the
    predicted reduction, and lmder's updates of delta and lambda.  Where E has several minima,
    the same rules from the same start head for the same one; this stops once a taken step is
    below 1e-4 of the scaled x (the damped Newton steps of ``_damped_newton`` finish), or after
    ``limit`` evaluations."""
    g, p = x.shape
    a = np.asarray(todo)
    if a.size == 0:
        return
    fnorm = np.sqrt(np.sum(r[a] ** 2, axis=1))
    jac = prob.jacobian(x[a], theta[a], a)[:, :, :k]
    diag = np.sqrt(np.sum(jac**2, axis=1))
    diag[diag == 0] = 1.0
    xnorm = np.sqrt(np.sum((diag * x[a, :k]) ** 2, axis=1))
    delta = np.where(xnorm > 0, 100.0 * xnorm, 100.0)
    par = np.zeros(a.size)
    first = np.ones(a.size, dtype=bool)
    live = np.ones(a.size, dtype=bool)
    fresh = np.ones(a.size, dtype=bool)
    sv = np.zeros((a.size, k))
    vt = np.zeros((a.size, k, k))
    cc = np.zeros((a.size, k))
    evaluations = 0
    while np.any(live) and evaluations < limit:
        evaluations += 1
        f = np.flatnonzero(live & fresh)
        if f.size:
            u, sv[f], vt[f] = np.linalg.svd(jac[f] / diag[f, None, :], full_matrices=False)
            cc[f] = np.einsum("grk,gr->gk", u, r[a[f]])
            fresh[f] = False
        w = np.flatnonzero(live)
        s_, c_, d_ = sv[w], cc[w], delta[w]
        with np.errstate(divide="ignore", invalid="ignore"):
            gn = np.sqrt(np.sum((c_ / s_) ** 2, axis=1))
        lam = np.zeros(w.size)
        need = ~(gn <= 1.1 * d_)
        if np.any(need):  # ||D p(lambda)|| = delta: decreasing in lambda; bisection in log lambda
            lo = np.full(need.sum(), -40.0)
            hi = np.log(np.maximum(np.sqrt(np.sum((s_[need] * c_[need]) ** 2, axis=1)) / d_[need], 1e-300)) + 1.0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                norm = np.sqrt(np.sum((s_[need] * c_[need] / (s_[need] ** 2 + np.exp(mid)[:, None])) ** 2, axis=1))
                big = norm > d_[need]
                lo, hi = np.where(big, mid, lo), np.where(big, hi, mid)
            lam[need] = np.exp(0.5 * (lo + hi))
        ps = -np.einsum("gkq,gk->gq", vt[w], s_ * c_ / (s_**2 + lam[:, None]))
        step = np.zeros((w.size, p))
        step[:, :k] = ps / diag[w]
        pnorm = np.sqrt(np.sum(ps**2, axis=1))
        delta[w] = np.where(first[w], np.minimum(delta[w], pnorm), delta[w])
        first[w] = False
        trial_theta, trial_r = prob.residual(x[a[w]] + step, a[w])
        fnorm1 = np.sqrt(np.sum(trial_r**2, axis=1))
        fnorm1 = np.where(np.isfinite(fnorm1), fnorm1, np.inf)  # out of (0, pi): lmder's huge residual
        fn = fnorm[w]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            actred = np.where(0.1 * fnorm1 < fn, 1.0 - (fnorm1 / fn) ** 2, -1.0)
            t1 = np.sqrt(np.sum(np.einsum("grk,gk->gr", jac[w], step[:, :k]) ** 2, axis=1)) / fn
            t2 = np.sqrt(lam) * pnorm / fn
            prered = t1**2 + t2**2 / 0.5
            dirder = -(t1**2 + t2**2)
            ratio = np.where(prered != 0, actred / np.where(prered != 0, prered, 1.0), 0.0)
            temp = np.where(actred >= 0, 0.5, 0.5 * dirder / (dirder + 0.5 * actred))
        temp = np.where((0.1 * fnorm1 >= fn) | ~(temp >= 0.1), 0.1, temp)
        shrink = ratio <= 0.25
        grow = ~shrink & ((lam == 0) | (ratio >= 0.75))
        delta[w] = np.where(shrink, temp * np.minimum(delta[w], pnorm / 0.1), np.where(grow, pnorm / 0.5, delta[w]))
        par[w] = np.where(shrink, lam / temp, np.where(grow, 0.5 * lam, lam))
        take = ratio >= 1e-4
        t = a[w[take]]
        x[t] += step[take]
        theta[t], r[t] = trial_theta[take], trial_r[take]
        fnorm[w[take]] = fnorm1[take]
        if np.any(take):
            wt = w[take]
            jac[wt] = prob.jacobian(x[t], theta[t], t)[:, :, :k]
            diag[wt] = np.maximum(diag[wt], np.sqrt(np.sum(jac[wt] ** 2, axis=1)))
            xnorm[wt] = np.sqrt(np.sum((diag[wt] * x[t, :k]) ** 2, axis=1))
            fresh[wt] = True
        settled = take & (pnorm <= 1e-4 * xnorm[w])
        stuck = delta[w] <= 1e-12 * np.maximum(xnorm[w], 1e-300)
        live[w[settled | stuck]] = False


def _damped_newton(prob: _BatchProblem, x, theta, r, todo: np.ndarray, k: int, limit: int, tol: float) -> None:
    """Minimise E over the first k variables of x for the configurations ``todo``, the others
    fixed, in place, Levenberg-Marquardt fashion: steps solve (H + lambda I) dx = -J^T r, a step
    is taken when it lowers E, lambda per configuration (0 at first, as MINPACK's first step is
    the Gauss-Newton step when its trust region holds it).  H is J^T J (Gauss-Newton, as in
    MINPACK's lmder, so that the iterates head for the same minimum) until a step of at most
    1e-3 has been taken, then the Hessian of E (central differences of the analytic gradient),
    which converges fast where the residual is large.  Until a step of at most ``tol`` with
    little damping, or ``limit`` steps."""
    g, p = x.shape
    cost = np.sum(r * r, axis=1)
    grad = np.zeros((g, k))
    hess = np.zeros((g, k, k))
    lam = np.zeros(g)
    scale = np.ones(g)
    newton = np.zeros(g, dtype=bool)  # near the minimum: the Hessian of E instead of J^T J
    fresh = np.zeros(g, dtype=bool)
    fresh[todo] = True
    active = fresh.copy()
    steps = np.zeros(g, dtype=np.int64)
    while np.any(active):
        idx = np.flatnonzero(active & fresh)
        if idx.size:
            jac = prob.jacobian(x[idx], theta[idx], idx)[:, :, :k]
            grad[idx] = np.einsum("grp,gr->gp", jac, r[idx])
            hess[idx] = np.einsum("grp,grq->gpq", jac, jac)
            near = idx[newton[idx]]
            if near.size:
                hess[near] = prob.hessian(x[near], near, k)
            scale[idx] = np.maximum(np.max(np.abs(np.diagonal(hess[idx], axis1=1, axis2=2)), axis=1), 1e-300)
            fresh[idx] = False
        a = np.flatnonzero(active)
        damped = hess[a] + lam[a, None, None] * np.eye(k)
        definite = np.linalg.eigvalsh(damped)[:, 0] > 0
        dx = np.zeros((a.size, p))
        dx[definite, :k] = -np.linalg.solve(damped[definite], grad[a[definite]][:, :, None])[:, :, 0]
        trial_theta, trial_r = prob.residual(x[a] + dx, a)
        trial = np.sum(trial_r * trial_r, axis=1)
        ok = definite & (trial < cost[a])  # NaN (a step out of (0, pi)) is never taken
        size = np.where(definite, np.max(np.abs(dx), axis=1), np.inf)
        take = a[ok]
        x[take] += dx[ok]
        theta[take], r[take], cost[take] = trial_theta[ok], trial_r[ok], trial[ok]
        steps[a] += 1
        done = ((size <= tol) & (lam[a] < 1e-2 * scale[a])) | (steps[a] >= limit)  # a small step, not a small damped one
        newton[take[size[ok] <= 1e-3]] = True
        lam[take] *= 0.1
        fresh[take] = True
        lam[a[~ok]] = np.maximum(10.0 * lam[a[~ok]], 1e-3 * scale[a[~ok]])
        active[a[done]] = False


def _optimise_batch(dbar, st, theta0, theta_hat, l_hat, omega, max_iterations, symmetries=()):
    """The minimum of section 3.3's E for g configurations of one structure (valence, sharp
    spokes, symmetries) at once; arrays (g, n).  Returns (theta (g, n), outer iterations (g,),
    converged (g,)).

    The alternating scheme of Remark 2, with the lengths l = s_c q_c(theta) (q_c each chain's
    shape from eqs. (6)/(7), of unit norm; s_c its factor): the angle step minimises E over the
    free angles u with the factors fixed (damped Newton, ``_damped_newton``), the length step
    sets s_c = <q_c, l-hat_c>; until an outer iteration moves no angle by more than 1e-9 rad
    (or after max_iterations: then the current iterate is kept and ``converged`` is False).
    It starts from the default angles as the paper's scheme does, so it ends in the same
    minimum.  The scheme stops where E is stationary in u with s fixed and in s with u fixed,
    i.e. at a stationary point of E(u, s); Newton steps on (u, s) together then take the
    iterate to that point, taken while they shrink and without the cost test: near a minimum
    with a large residual E is flat to round-off over ~sqrt(eps) in the angles, but the Newton
    step (from J^T r, not from differences of E) still points at the stationary point, so the
    angles are located to ~1e-15 rad instead of stopping ~1e-8 away where E stops decreasing.
    Every step is one stacked computation over the g configurations (Jacobians, Hessians by
    central differences of the analytic gradient, eigenvalue tests, solves).
    """
    g, n = theta0.shape
    prob = _BatchProblem(dbar, st, theta_hat, l_hat, omega, symmetries)
    f = prob.f
    iterations = np.zeros(g, dtype=np.int64)
    converged = np.ones(g, dtype=bool)
    if f == 0:
        return theta0.copy(), iterations, converged
    every = np.arange(g)
    x = np.concatenate([theta0[:, prob.chart.free], prob.factors(theta0, every)], axis=1)
    theta, r = prob.residual(x, every)
    rows = np.flatnonzero(~(np.sum(r * r, axis=1) < 1e-24 * n))  # else optimal (valence 4: the NURBS configuration)
    _descend(prob, x, theta, r, rows, iterations, converged, max_iterations)
    rows = rows[converged[rows] & (iterations[rows] > 0)]
    _polish(prob, x, theta, r, rows)
    # A saddle of E(u, s): pushed off it, then descended in (u, s) together (damped Newton
    # steps lower E, so they leave the saddle; Newton alone would go back to it).
    p = x.shape[1]
    for _ in range(_SADDLE_ROUNDS):
        rows = _leave_saddles(prob, x, theta, r, rows)
        if rows.size == 0:
            break
        _damped_newton(prob, x, theta, r, rows, p, 200, 1e-12)
        iterations[rows] += 1
        _polish(prob, x, theta, r, rows)
    else:
        converged[_leave_saddles(prob, x, theta, r, rows, push=False)] = False  # still a saddle: say so
    return theta, iterations, converged


#: How many times a configuration that ended at a saddle of E is pushed off it and descended
#: again (``_leave_saddles``); one was enough in every case seen.
_SADDLE_ROUNDS = 4
#: Length of the push off a saddle along the Hessian's direction of negative curvature (rad
#: or factor units): large beside the Newton steps' 1e-15, small beside the angles.
_SADDLE_PUSH = 1e-3


def _descend(prob: _BatchProblem, x, theta, r, rows: np.ndarray, iterations, converged, max_iterations: int) -> None:
    """``_optimise_batch``'s alternating scheme for the configurations ``rows``, in place,
    until an outer iteration moves no angle by more than ``_OUTER_TOL`` (or max_iterations:
    ``converged`` False)."""
    f = prob.f
    active = np.zeros(x.shape[0], dtype=bool)
    active[rows] = True
    while np.any(active):
        a = np.flatnonzero(active)
        before = theta[a].copy()
        _trust_region(prob, x, theta, r, a, f, 100)  # the angle step: lmder's path to its minimum,
        _damped_newton(prob, x, theta, r, a, f, 100, _OUTER_TOL)  # then Newton steps to it
        x[a, f:] = prob.factors(theta[a], a)  # the length step
        theta[a], r[a] = prob.residual(x[a], a)
        iterations[a] += 1
        done = np.max(np.abs(theta[a] - before), axis=1) < _OUTER_TOL
        over = (iterations[a] >= max_iterations) & ~done
        converged[a[over]] = False
        active[a[done | over]] = False


def _polish(prob: _BatchProblem, x, theta, r, polish: np.ndarray) -> None:
    """Newton on (u, s) to the stationary point of the configurations ``polish``, in place,
    while the steps shrink (``_optimise_batch``)."""
    last = np.full(x.shape[0], np.inf)
    p = x.shape[1]
    for _ in range(8):
        if polish.size == 0:
            break
        grad = prob.gradient(x[polish], theta[polish], r[polish], polish)
        hess = prob.hessian(x[polish], polish, p)
        # pinv: a chain of zero intervals leaves E unchanged by its factor (no step there)
        dx = -np.einsum("gpq,gq->gp", np.linalg.pinv(hess, rcond=1e-13, hermitian=True), grad)
        size = np.max(np.abs(dx), axis=1)
        trial_theta, trial_r = prob.residual(x[polish] + dx, polish)
        ok = (size < 0.5 * last[polish]) & np.all(np.isfinite(trial_r), axis=1)
        take = polish[ok]
        x[take] += dx[ok]
        theta[take], r[take] = trial_theta[ok], trial_r[ok]
        last[take] = size[ok]
        polish = take[size[ok] > 1e-15]


def _leave_saddles(prob: _BatchProblem, x, theta, r, rows: np.ndarray, push: bool = True) -> np.ndarray:
    """The configurations of ``rows`` whose stationary point is a saddle of E(u, s), each
    pushed, in place, ``_SADDLE_PUSH`` along the Hessian's eigenvector of its most negative
    eigenvalue, to the side where E is lower.  The alternating scheme stops where E is least in
    u for fixed s and in s for fixed u, which a saddle of E(u, s) can be: with intervals
    (0, 0, 1, 4, 1, 2, 1) it stopped at E = 1.637953 with two angles equal, where MINPACK,
    started 1e-6 away, went down to E = 1.636716, 0.13 rad away (tests/test_angle_configuration.py,
    ``test_optimum_is_minpacks_minimum``).  Negative means below -1e-7 of the Hessian's largest
    diagonal entry, far beyond the central differences' error (~1e-10 of it).  push False:
    only find them."""
    if rows.size == 0:
        return rows
    hess = prob.hessian(x[rows], rows, x.shape[1])
    values, vectors = np.linalg.eigh(hess)
    scale = np.max(np.abs(np.diagonal(hess, axis1=1, axis2=2)), axis=1)
    saddle = values[:, 0] < -1e-7 * scale
    if not np.any(saddle) or not push:
        return rows[saddle]
    out = rows[saddle]
    step = vectors[saddle][:, :, 0]
    step *= _SADDLE_PUSH / np.max(np.abs(step), axis=1, keepdims=True)
    best = np.sum(r[out] ** 2, axis=1)
    new_x, new_theta, new_r = x[out].copy(), theta[out].copy(), r[out].copy()
    for sign in (1.0, -1.0):
        trial_theta, trial_r = prob.residual(x[out] + sign * step, out)
        cost = np.sum(trial_r**2, axis=1)
        lower = cost < best  # NaN (out of (0, pi)) never is
        new_x[lower] = x[out][lower] + sign * step[lower]
        new_theta[lower], new_r[lower], best[lower] = trial_theta[lower], trial_r[lower], cost[lower]
    x[out], theta[out], r[out] = new_x, new_theta, new_r
    return out


def _symmetrised(theta: np.ndarray, symmetries, st: _Structure) -> np.ndarray:
    """Average over the symmetry group (removes the penalty's ~1e-9 asymmetry; sector sums are
    kept since symmetries map sectors to sectors), then restore Lemma 2 on the pair if needed."""
    theta = np.mean([theta] + [theta[p] for p in symmetries], axis=0)
    if st.pair is not None and abs(_lemma2_residual(theta)) > 1e-15:
        a, b = st.pair
        beta1 = theta[a] + theta[b]
        theta[b] = _pair_angle(beta1, _pair_beta2(theta, a, b))
        theta[a] = beta1 - theta[b]
    return theta


def _symmetries(d: np.ndarray, sharp: tuple[int, ...]) -> list[np.ndarray]:
    """The patch maps of the non-trivial rotations and reflections that keep the intervals and
    the sharp set."""
    n = d.size
    return [
        gp for g, gp in _dihedral(n)
        if np.any(g != np.arange(n)) and np.array_equal(d[g], d) and set(g[list(sharp)].tolist()) == set(sharp)
    ]


@dataclass
class _Prepared:
    """One canonical configuration before its optimisation: what ``_finish`` needs, and
    whether the angles still have to be optimised (``theta`` None)."""

    d: np.ndarray
    st: _Structure
    dbar: np.ndarray
    theta_hat: np.ndarray
    theta_default: np.ndarray
    l_hat: np.ndarray
    symmetries: list
    theta: np.ndarray | None


def _prepare(key: tuple[float, ...], mode: str, sharp: tuple[int, ...]) -> _Prepared:
    d = np.array(key)
    n = d.size
    st = _structure(n, sharp)
    dbar = d / d.mean()
    theta_hat, theta_default = _default_angles(dbar, st)
    l_hat = _default_lengths(dbar, theta_hat)
    symmetries, theta = [], None
    if mode == "uniform" or (len(sharp) <= 1 and np.all(d == d[0])):
        # [SSEL13]; and for equal intervals every mode: the heuristic gives equal angles, equal
        # l-hat, and E = 0 there, so 2 pi / n exactly (within each sector if sharp).
        theta = np.empty(n)
        for sector, total in zip(st.sectors, st.sums):
            theta[list(sector)] = total / len(sector)
    else:
        # Symmetric intervals (and sharp set) keep symmetric angles: the objective can have a
        # mirrored pair of minima there (e.g. 10, 2, 1, 1, 2) and a symmetric mesh must not get
        # an arbitrarily broken surface; we take the best symmetric configuration instead.  The
        # default mode's even-n perturbation of "the last two angles" breaks a symmetry too
        # (e.g. 1, 1, 1, 1, 2, 2), and averaging it breaks Lemma 2: for symmetric intervals
        # with a Lemma 2 pair the default mode takes the symmetric optimum instead.
        symmetries = _symmetries(d, sharp)
        if mode == "default" and not (symmetries and st.pair is not None):
            theta = theta_default
    return _Prepared(d, st, dbar, theta_hat, theta_default, l_hat, symmetries, theta)


def _finish(prep: _Prepared, theta: np.ndarray, mode: str, omega: float, iterations: int, converged: bool) -> AngleConfiguration:
    d, st, dbar, l_hat = prep.d, prep.st, prep.dbar, prep.l_hat
    n = d.size
    if prep.symmetries:
        theta = _symmetrised(theta, prep.symmetries, st)
    m = _relative_lengths(theta, st)
    if mode == "uniform":
        # [SSEL13]: one factor for every chain, l_i proportional to d_i (m = 1 without sharp spokes)
        q = dbar * m
        s = np.full(n, np.dot(q, l_hat) / np.dot(q, q))
    else:
        s = _fit_factors(dbar * m, l_hat, st)
    lengths = s * dbar * m
    objective = _objective(theta, lengths, prep.theta_hat, l_hat, omega)
    arrays = {
        "theta": theta,
        "lengths": lengths * d.mean(),
        "b": _connecting_b(d, theta, s * m, st),
        "alpha": d * np.roll(d, 1),
        "gamma": d * np.roll(d, -1),
    }
    for v in arrays.values():
        v.setflags(write=False)
    return AngleConfiguration(
        mode=mode, converged=converged, iterations=iterations, sharp_spokes=st.sharp, objective=objective, **arrays
    )


def _angles_valid(args: tuple, arrays: list[np.ndarray]) -> bool:
    """A stored optimisation is trusted only if its angles are in (0, pi) and close every sector."""
    key, _, _, _, sharp = args
    st = _structure(len(key), sharp)
    theta, info = arrays
    return (
        theta.shape == (st.n,) and info.shape == (2,) and bool(np.all((theta > 0) & (theta < math.pi)))
        and all(abs(theta[list(sector)].sum() - total) <= 1e-12 for sector, total in zip(st.sectors, st.sums))
    )


def _solve_canonical(args_list: list[tuple]) -> list[AngleConfiguration]:
    """The configurations of canonical problems (key, mode, omega, max_iterations, sharp): the
    optimisations of one structure and symmetry group solved together (``_optimise_batch``),
    through the persistent cache of ``patching.util.solve_cache`` when one is installed."""
    prepared = [_prepare(key, mode, sharp) for key, mode, _, _, sharp in args_list]
    groups: dict[tuple, list[int]] = {}
    for i, prep in enumerate(prepared):
        if prep.theta is None:
            shape = (prep.st.n, prep.st.sharp, tuple(tuple(p.tolist()) for p in prep.symmetries))
            groups.setdefault(shape, []).append(i)
    solved: dict[int, tuple[np.ndarray, int, bool]] = {}
    for members in groups.values():
        first = prepared[members[0]]

        def solve_many(todo: list[tuple], members=members, first=first) -> list[list[np.ndarray]]:
            index = {args_list[i]: i for i in members}
            preps = [prepared[index[args]] for args in todo]
            _, _, omega, max_iterations, _ = todo[0]
            theta, iterations, converged = _optimise_batch(
                np.array([p.dbar for p in preps]), first.st, np.array([p.theta_default for p in preps]),
                np.array([p.theta_hat for p in preps]), np.array([p.l_hat for p in preps]), omega, max_iterations,
                first.symmetries,
            )
            return [[t, np.array([k, float(c)])] for t, k, c in zip(theta, iterations, converged)]

        todo = [args_list[i] for i in members]
        for i, (theta, info) in zip(members, lookup_many("angle_configuration", todo, 2, solve_many, _angles_valid)):
            solved[i] = (theta, int(info[0]), bool(info[1]))
    out = []
    for i, (prep, (_, mode, omega, _, _)) in enumerate(zip(prepared, args_list)):
        theta, iterations, converged = solved.get(i, (prep.theta, 0, True))
        out.append(_finish(prep, theta, mode, omega, iterations, converged))
    return out


@memo(maxsize=4096)
def _cached(key: tuple[float, ...], mode: str, omega: float, max_iterations: int, sharp: tuple[int, ...]) -> AngleConfiguration:
    return _solve_canonical([(key, mode, omega, max_iterations, sharp)])[0]
