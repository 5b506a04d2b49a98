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
  factor(s) of the previous paragraph.  Step 1 fixes the factors and runs Levenberg-Marquardt
  (scipy.optimize.least_squares, method "lm", analytic Jacobian) on the angles; step 2 refits
  the factors explicitly and recomputes l.  Each step lowers E = ||l-hat - l||^2 + omega
  ||theta-hat - theta||^2, so E decreases monotonically.  Each chain's shape is scaled to unit
  norm, so that angles change shape and factors change size (with l_0 = 1 instead the blocks
  zig-zag: over 200 iterations at valence 16, against 4 to 10 now).  Stop when the largest
  angle change of an outer iteration is below 1e-11 rad or E stops decreasing in floating
  point, or after max_iterations (then the current iterate is kept and ``converged`` is False).
  Near a minimum with a large residual E is flat to round-off over ~sqrt(eps) in the angles,
  so the minimiser is located to ~1e-8 rad there (Gauss-Newton polishing does better where
  the residual is small).  The constraints are built into a chart: in every sector
  all angles but the last are free and the last closes the sector's sum; when Lemma 2 applies
  (even n) the last two angles of one sector come from the closed form above, so the condition
  holds exactly at every iterate.  Steps that leave (0, pi) are rejected by a large residual.
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
from patching.util.solve_cache import lookup

__all__ = ["AngleConfiguration", "angle_configuration", "MODES"]

#: The angle configurations: the choices of ``BuildOptions.angles``, defined in ``patching.options``.
MODES = ANGLES
_TWO_PI = 2.0 * math.pi
_ANGLE_TOL = 1e-11  # outer-iteration stop: largest angle change (rad)
_BAD = 1e6  # residual for a rejected step (an angle outside (0, pi))
_SYM_WEIGHT = 1e3  # weight of the rows keeping symmetric intervals' angles symmetric
_EPS = 4 * np.finfo(float).eps  # least_squares("lm") tolerances: near the smallest MINPACK allows


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
    mode: "optimized" (default angles, then the alternating least-squares of section 3.3 with
    weight ``omega`` and at most ``max_iterations`` outer iterations, Remark 2), "default" (the
    heuristic angles, perturbed for Lemma 2 when n is even) or "uniform" (theta = 2 pi / n, the
    baseline of [SSEL13]: b_i = -2 d_{i-1} d_{i+1} cos(2 pi / n)).
    sharp_spokes: indices of spokes that are sharp (C0) edges (section 4.2); see the module
    docstring for one, two and more sharp spokes.

    Results are cached by (intervals rounded to 12 significant digits, mode, omega,
    max_iterations, sharp spokes), so identical EPs are solved once; the computation uses the
    rounded intervals.  Raises KnotError for bad intervals, TagError for bad sharp spokes.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, not {mode!r}")
    if not (math.isfinite(omega) and omega > 0):
        raise ValueError(f"omega must be a positive number, not {omega!r}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f"max_iterations must be a positive integer, not {max_iterations!r}")
    d = _validated_intervals(intervals)
    sharp = _validated_sharp(sharp_spokes, d.size)
    key = tuple(float(f"{x:.12g}") for x in d)
    return _mapped(key, mode, float(omega), int(max_iterations), sharp)


def _dihedral(n: int):
    """The 2n relabellings of an EP: (spoke map g, patch map), spoke j of the relabelled EP
    being spoke g[j] of the original.  Rotation j -> j + k maps patch i to i + k; reflection
    j -> c - j maps patch i (spokes i, i+1) to patch c - i - 1."""
    j = np.arange(n)
    for c in range(n):
        yield (j + c) % n, (j + c) % n
    for c in range(n):
        yield (c - j) % n, (c - j - 1) % n


@lru_cache(maxsize=4096)
def _mapped(key, mode, omega, max_iterations, sharp) -> AngleConfiguration:
    """Solve on the canonical relabelling (lexicographically smallest intervals and sharp set
    over rotations and reflections), then relabel back: results are exactly equivariant, and
    rotated or mirrored copies of one EP share one solve."""
    d = np.array(key)
    n = d.size
    best = None
    marked = set(sharp)
    for g, gp in _dihedral(n):  # in plain Python: a build meets hundreds of EPs, 2n relabellings each
        gl = g.tolist()
        cand = (tuple(key[j] for j in gl), tuple(j for j, x in enumerate(gl) if x in marked))
        if best is None or cand < best[0]:
            best = (cand, g, gp)
    (dc, sharp_c), g, gp = best
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
    """theta(u) for the free angles u, and its Jacobian (n, f)."""

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
        self.column = {int(j): c for c, j in enumerate(self.free)}

    def theta(self, u: np.ndarray) -> np.ndarray:
        st = self.st
        theta = np.zeros(st.n)
        theta[self.free] = u
        for j, total in self.fixed:
            theta[j] = total
        for j, others, total in self.last:
            theta[j] = total - theta[others].sum()
        if st.pair is not None:
            a, b = st.pair
            others, total = self.pair_sector
            beta1 = total - theta[others].sum()
            theta[a] = 0.5 * math.pi  # placeholders, excluded from beta_2
            theta[b] = 0.5 * math.pi
            v = theta[self.variable]
            if not (0 < beta1 < _TWO_PI) or np.any(v <= 0) or np.any(v >= math.pi):
                theta[b] = math.nan
            else:
                x = _pair_angle(beta1, _pair_beta2(theta, a, b))
                theta[b] = x
                theta[a] = beta1 - x
        return theta

    def valid(self, theta: np.ndarray) -> bool:
        v = theta[self.variable]
        return bool(np.all(np.isfinite(v)) and np.all(v > 0) and np.all(v < math.pi))

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        st = self.st
        jac = np.zeros((st.n, self.free.size))
        jac[self.free, np.arange(self.free.size)] = 1.0
        for j, others, _ in self.last:
            jac[j] = -jac[others].sum(axis=0)
        if st.pair is not None:
            a, b = st.pair
            others, _ = self.pair_sector
            beta1 = theta[a] + theta[b]
            sign = np.where(np.arange(st.n) % 2 == a % 2, 1.0, -1.0)
            sign[[a, b]] = 0.0
            beta2 = _pair_beta2(theta, a, b)
            dbeta2 = beta2 * ((sign / np.tan(theta)) @ jac)
            dbeta1 = -jac[others].sum(axis=0)
            e = complex(math.cos(beta1), math.sin(beta1))
            w = 1.0 + beta2 * e
            # x = arg w: dx = Im(dw / w), dw = e^{i beta1} (d beta2 + i beta2 d beta1)
            jac[b] = ((e / w) * (dbeta2 + 1j * beta2 * dbeta1)).imag
            jac[a] = dbeta1 - jac[b]
        return jac


# --------------------------------------------------------------------------------------------
# Solve


def _objective(theta, lengths, theta_hat, l_hat, omega) -> float:
    return float(np.sum((l_hat - lengths) ** 2) + omega * np.sum((theta_hat - theta) ** 2))


def _unit_shapes(dbar: np.ndarray, theta: np.ndarray, st: _Structure) -> tuple[np.ndarray, np.ndarray]:
    """q = dbar m scaled to unit norm on every length chain, and the chain norms (n,)."""
    q = dbar * _relative_lengths(theta, st)
    norm = np.sqrt(np.bincount(st.component, q * q, st.n_components))[st.component]
    return q / np.where(norm > 0, norm, 1.0), norm


class _Problem:
    """E = ||l-hat - l||^2 + omega ||theta-hat - theta||^2 as least-squares residuals of the
    free angles u, with l = s_c q_c(theta(u)) and the chain factors s fixed (the angle step)."""

    def __init__(self, dbar, st, theta_hat, l_hat, omega, symmetries=()) -> None:
        self.dbar, self.st, self.theta_hat, self.l_hat = dbar, st, theta_hat, l_hat
        self.sqrt_w = math.sqrt(omega)
        self.chart = _Chart(st)
        self.same = st.component[:, None] == st.component[None, :]
        # theta[i] = theta[perm[i]] for each symmetry of the intervals: stiff penalty rows
        self.symmetries = [np.asarray(p) for p in symmetries]
        self.n_rows = 2 * st.n + st.n * len(self.symmetries)

    def factors(self, theta: np.ndarray) -> np.ndarray:
        """The length step: s_c = <q_c, l-hat_c> (q_c of unit norm), per spoke."""
        st = self.st
        q, _ = _unit_shapes(self.dbar, theta, st)
        return np.bincount(st.component, q * self.l_hat, st.n_components)[st.component]

    def residual(self, u: np.ndarray, s: np.ndarray) -> np.ndarray:
        th = self.chart.theta(u)
        if not self.chart.valid(th):
            return np.full(self.n_rows, _BAD)
        q, _ = _unit_shapes(self.dbar, th, self.st)
        sym = [_SYM_WEIGHT * (th - th[p]) for p in self.symmetries]
        return np.concatenate([self.l_hat - s * q, self.sqrt_w * (self.theta_hat - th), *sym])

    def jacobian(self, u: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Explicit Jacobian: d log m / d theta = E cot(theta), chained through the chart."""
        th = self.chart.theta(u)
        p = self.chart.jacobian(th)
        q, _ = _unit_shapes(self.dbar, th, self.st)
        cot = np.cos(th) / np.sin(th)
        dq = q[:, None] * ((self.st.exponents * cot[None, :]) @ p)  # d q_raw / du over |q_raw|
        # d(q_raw / |q_raw|) = (I - q q^T) d q_raw / |q_raw|, chain by chain
        proj = np.eye(self.st.n) - np.where(self.same, np.outer(q, q), 0.0)
        sym = [_SYM_WEIGHT * (p - p[perm]) for perm in self.symmetries]
        return np.vstack([-(s[:, None] * (proj @ dq)), -self.sqrt_w * p, *sym])


def _optimise(dbar, st, theta0, theta_hat, l_hat, omega, max_iterations, symmetries=()):
    """Alternating scheme of section 3.3: LM on the angles with the chain factors fixed, then
    the factors (and so l) explicitly; returns (theta, iterations, converged).

    Lengths are written l = s_c q_c(theta) with q_c the chain's shape from eqs. (6)/(7) scaled
    to unit norm, so the angle step changes only the shape of every chain and the length step
    only its size.  (With the paper's l_0 = 1 normalisation instead, the two blocks are
    strongly coupled and the alternation zig-zags: valence 16 needed more than 200 iterations;
    now 4 to 10 are typical.)
    """
    from scipy.optimize import least_squares  # here: importing scipy.optimize costs a small build ~0.4 s

    prob = _Problem(dbar, st, theta_hat, l_hat, omega, symmetries)
    chart = prob.chart
    if chart.free.size == 0:
        return theta0, 0, True
    theta = theta0
    s = prob.factors(theta)
    cost = float(np.sum(prob.residual(theta[chart.free], s) ** 2))
    if cost < 1e-24 * st.n:
        return theta, 0, True  # already optimal (valence 4: the NURBS configuration)
    for it in range(1, max_iterations + 1):
        sol = least_squares(
            prob.residual, theta[chart.free], jac=prob.jacobian, args=(s,), method="lm", xtol=_EPS, ftol=_EPS, gtol=_EPS
        )
        u, step_cost = sol.x, 2 * sol.cost
        for _ in range(3):  # Gauss-Newton polish: LM stops on cost reduction, with u known to
            # ~sqrt(eps) only; J du = -r goes further while it still lowers the cost.
            du = np.linalg.lstsq(prob.jacobian(u, s), -prob.residual(u, s), rcond=None)[0]
            trial = float(np.sum(prob.residual(u + du, s) ** 2))
            if not trial < step_cost:
                break
            u, step_cost = u + du, trial
        new = chart.theta(u)
        if not chart.valid(new):  # pragma: no cover - LM returns its best accepted point
            break
        step = float(np.max(np.abs(new - theta)))
        theta = new
        s = prob.factors(theta)
        new_cost = float(np.sum(prob.residual(theta[chart.free], s) ** 2))
        # Stop on a small angle step (the paper's rule), or when an outer iteration no longer
        # lowers E in floating point (a large-residual minimum is located to ~sqrt(eps) only).
        if step < _ANGLE_TOL or not new_cost < cost * (1 - 4 * np.finfo(float).eps):
            return theta, it, True
        cost = new_cost
    return theta, max_iterations, False  # Remark 2: keep the current iterate


def _optimise_cached(problem: tuple, dbar, st, *args):
    """``_optimise`` through the persistent cache of ``patching.util.solve_cache`` (when one is
    installed): an entry is trusted only if its angles are in (0, pi) and close every sector."""

    def solve():
        theta, iterations, converged = _optimise(dbar, st, *args)
        return theta, np.array([iterations, float(converged)])

    def valid(arrays) -> bool:
        theta, info = arrays
        return (
            theta.shape == (st.n,) and info.shape == (2,) and bool(np.all((theta > 0) & (theta < math.pi)))
            and all(abs(theta[list(sector)].sum() - total) <= 1e-12 for sector, total in zip(st.sectors, st.sums))
        )

    theta, info = lookup("angle_configuration", problem, 2, solve, valid)
    return theta, int(info[0]), bool(info[1])


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


@lru_cache(maxsize=4096)
def _cached(key: tuple[float, ...], mode: str, omega: float, max_iterations: int, sharp: tuple[int, ...]) -> AngleConfiguration:
    d = np.array(key)
    n = d.size
    st = _structure(n, sharp)
    mean = d.mean()
    dbar = d / mean
    theta_hat, theta_default = _default_angles(dbar, st)
    l_hat = _default_lengths(dbar, theta_hat)
    iterations, converged = 0, True
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
        symmetries = [
            gp for g, gp in _dihedral(n)
            if np.any(g != np.arange(n)) and np.array_equal(d[g], d) and set(g[list(sharp)].tolist()) == set(sharp)
        ]
        if mode == "default" and not (symmetries and st.pair is not None):
            theta = theta_default
        else:
            theta, iterations, converged = _optimise_cached(
                (key, mode, omega, max_iterations, sharp), dbar, st, theta_default, theta_hat, l_hat, omega, max_iterations, symmetries
            )
        if symmetries:
            theta = _symmetrised(theta, symmetries, st)
    m = _relative_lengths(theta, st)
    if mode == "uniform":
        # [SSEL13]: one factor for every chain, l_i proportional to d_i (m = 1 without sharp spokes)
        q = dbar * m
        s = np.full(n, np.dot(q, l_hat) / np.dot(q, q))
    else:
        s = _fit_factors(dbar * m, l_hat, st)
    lengths = s * dbar * m
    objective = _objective(theta, lengths, theta_hat, l_hat, omega)
    arrays = {
        "theta": theta,
        "lengths": lengths * mean,
        "b": _connecting_b(d, theta, s * m, st),
        "alpha": d * np.roll(d, 1),
        "gamma": d * np.roll(d, -1),
    }
    for v in arrays.values():
        v.setflags(write=False)
    return AngleConfiguration(
        mode=mode, converged=converged, iterations=iterations, sharp_spokes=sharp, objective=objective, **arrays
    )
