"""Tests for patching/angle_configuration.py ([FSLYJ] sec. 3.3; sharp spokes: 4.2).

The references here are written again, slowly and literally from the paper: the heuristic of
section 3.3 in a loop, the reconstructed l-hat with its nested sums, the lengths of eqs. (6)
and (7) with the (i, j) products, and the objective; the optimum is compared with SLSQP on
the same constrained problem.  Tolerances: "round-off" is a few hundred ulps of the largest
quantity involved (products of up to 16 sines and ratios of intervals up to 20).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from scipy.optimize import approx_fprime, least_squares, minimize, root

from patching.extraordinary import angle_configuration as ac_module
from patching.extraordinary.angle_configuration import angle_configuration
from patching.options import ANGLES as MODES
from patching.errors import KnotError, NupatchError, TagError

TWO_PI = 2.0 * math.pi
FIG15 = (1.0, 4.0, 1.0, 4.0, 8.0)  # [FSLYJ], Fig. 15: valence 5, intervals 1, 4, 1, 4, 8

SMALL = settings(max_examples=25, deadline=None)  # 2 shared cores: keep runs small



def symmetric_even(d) -> bool:
    """Even valence and intervals invariant under a non-trivial rotation or reflection."""
    dd = np.array(d)
    n = len(dd)
    if n % 2:
        return False
    j = np.arange(n)
    return any(np.array_equal(dd[(j + k) % n], dd) for k in range(1, n)) or any(
        np.array_equal(dd[(k - j) % n], dd) for k in range(n)
    )

def knot(ratio=20.0):
    """An interval in [1, ratio] with 12 significant digits: the cache key's rounding, so the
    module computes with exactly the numbers the references see."""
    return st.floats(1.0, ratio).map(lambda x: float(f"{x:.12g}"))


def intervals_strategy(min_n=3, max_n=16, ratio=20.0):
    return st.integers(min_n, max_n).flatmap(lambda n: st.lists(knot(ratio), min_size=n, max_size=n))


# --------------------------------------------------------------------------------------------
# Slow references, literally from the paper


def paper_heuristic(d):
    """k_i, alpha_i and theta-hat_i of section 3.3, one index at a time (no perturbation)."""
    n = len(d)
    total = sum(d[j] * d[(j + 1) % n] for j in range(n))
    alpha = []
    for i in range(n):
        k = n * d[i] * d[(i + 1) % n] / total
        if k < 1:
            alpha.append(math.pi / 2 - (2 - 8 / n) * math.atan(k))
        else:
            alpha.append((8 - n) * math.pi / (2 * n) + (2 - 8 / n) * math.atan((1 + k) / 2))
    return np.array([TWO_PI * a / sum(alpha) for a in alpha])


def paper_lhat(d, theta):
    """l-hat_i = d_i + sum_{j=i+1}^{i+n-1} d_j (cos(sum_{k=0}^{j-i-1} theta_{i+k}))_+."""
    n = len(d)
    out = []
    for i in range(n):
        v = d[i]
        for j in range(i + 1, i + n):
            ang = sum(theta[(i + k) % n] for k in range(j - i))
            v += d[j % n] * max(math.cos(ang), 0.0)
        out.append(v)
    return np.array(out)


def pr(theta, i, j):
    """(i, j) = sin(theta_i) sin(theta_{i+2}) ... sin(theta_j); 1 when empty."""
    return math.prod(math.sin(theta[k]) for k in range(i, j + 1, 2))


def paper_lengths(d, theta, target):
    """Lengths of Lemma 2, eq. (6) (odd n) or (7) (even n), with l_0 (and l_1) fitted to
    ``target`` by least squares."""
    n = len(d)
    shapes = [np.zeros(n), np.zeros(n)]
    if n % 2:
        k = n // 2
        for i in range(k + 1):
            shapes[0][2 * i] = pr(theta, 0, 2 * i - 2) / pr(theta, 1, 2 * i - 1) * d[2 * i] / d[0]
        for i in range(k):
            shapes[0][2 * i + 1] = pr(theta, 2 * i + 2, 2 * k) / pr(theta, 2 * i + 1, 2 * k - 1) * d[2 * i + 1] / d[0]
        a = np.array([shapes[0]]).T
    else:
        for i in range(n // 2):
            shapes[0][2 * i] = pr(theta, 0, 2 * i - 2) / pr(theta, 1, 2 * i - 1) * d[2 * i] / d[0]
            shapes[1][2 * i + 1] = pr(theta, 1, 2 * i - 1) / pr(theta, 2, 2 * i) * d[2 * i + 1] / d[1]
        a = np.array(shapes).T
    coef = np.linalg.lstsq(a, target, rcond=None)[0]
    return a @ coef


def paper_objective(d, theta, omega=2.0):
    """E of section 3.3 for the given angles, intervals scaled to mean 1 (module docstring)."""
    dbar = np.asarray(d, float) / np.mean(d)
    theta_hat = paper_heuristic(dbar)
    l_hat = paper_lhat(dbar, theta_hat)
    lengths = paper_lengths(dbar, theta, l_hat)
    return float(np.sum((l_hat - lengths) ** 2) + omega * np.sum((theta_hat - theta) ** 2)), lengths


def lemma2_gap(theta):
    """(0, n-2) / (1, n-1) - 1 for even n."""
    n = len(theta)
    return pr(theta, 0, n - 2) / pr(theta, 1, n - 1) - 1.0


def relation5_residuals(c, d, sharp=()):
    """Eq. (5) cross-multiplied, l_{i+1} sin(theta_i) d_{i-1} - l_{i-1} sin(theta_{i-1}) d_{i+1},
    at every smooth spoke, relative to max(l) max(d)."""
    n = len(d)
    l, t = c.lengths, c.theta
    out = [
        l[(i + 1) % n] * math.sin(t[i]) * d[i - 1] - l[i - 1] * math.sin(t[i - 1]) * d[(i + 1) % n]
        for i in range(n)
        if i not in sharp
    ]
    return np.abs(out) / (l.max() * max(d))


def fan_identity_residuals(c, sharp=()):
    """alpha_i v_{i+1} + gamma_i v_{i-1} + b_i v_i (module docstring, (*)) in the fan v_j =
    l_j (cos phi_j, sin phi_j), relative to the size of its terms."""
    n = c.theta.size
    phi = np.concatenate([[0.0], np.cumsum(c.theta)[:-1]])
    v = c.lengths[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    out = []
    for i in range(n):
        if i in sharp:
            continue
        terms = [c.alpha[i] * v[(i + 1) % n], c.gamma[i] * v[i - 1], c.b[i] * v[i]]
        size = max(np.linalg.norm(x) for x in terms)
        out.append(np.linalg.norm(sum(terms)) / size if size > 0 else 0.0)
    return np.array(out)


# --------------------------------------------------------------------------------------------
# Uniform intervals and the baseline of [SSEL13]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("n", range(3, 17))
def test_uniform_intervals_give_uniform_angles_and_equal_lengths(n, mode):
    c = angle_configuration([2.5] * n, mode)
    assert np.array_equal(c.theta, np.full(n, TWO_PI / n))  # exactly, every mode
    # equal lengths to round-off of l-hat's cosines (differences of cumulative angles)
    np.testing.assert_allclose(c.lengths, c.lengths[0], rtol=1e-14)
    np.testing.assert_allclose(c.b, -2 * 2.5 * 2.5 * math.cos(TWO_PI / n), rtol=1e-13, atol=1e-14)
    assert c.converged


@given(intervals_strategy())
@SMALL
def test_uniform_mode_is_scott_baseline(d):
    """b_i = -2 d_{i-1} d_{i+1} cos(2 pi / n), reference [SSEL13], from the general b_i formula."""
    n = len(d)
    c = angle_configuration(d, "uniform")
    assert np.array_equal(c.theta, np.full(n, TWO_PI / n))
    expected = np.array([-2 * d[i - 1] * d[(i + 1) % n] * math.cos(TWO_PI / n) for i in range(n)])
    # sin(2 theta)/sin(theta) against 2 cos(theta): a few ulps of d^2 (absolute when cos ~ 0)
    np.testing.assert_allclose(c.b, expected, rtol=1e-13, atol=1e-13 * max(d) ** 2)


@pytest.mark.parametrize("mode", MODES)
def test_valence_four_is_the_nurbs_configuration(mode):
    d = [1.0, 3.0, 0.5, 7.0]
    c = angle_configuration(d, mode)
    np.testing.assert_allclose(c.theta, math.pi / 2, rtol=1e-15)
    np.testing.assert_allclose(c.b, 0.0, atol=1e-14 * 49)  # cos(pi/2) round-off times d^2
    np.testing.assert_allclose(c.lengths / np.array(d), c.lengths[0] / d[0], rtol=1e-14)


# --------------------------------------------------------------------------------------------
# Relations that must hold for every mode


@pytest.mark.parametrize("mode", MODES)
@given(d=intervals_strategy())
@SMALL
def test_relation5_and_fan_identity_hold(mode, d):
    c = angle_configuration(d, mode)
    # products of up to 16 sines: a few hundred ulps
    assert relation5_residuals(c, d).max() < 1e-13
    assert fan_identity_residuals(c).max() < 1e-13


@pytest.mark.parametrize("mode", MODES)
@given(d=intervals_strategy())
@SMALL
def test_angles_positive_below_pi_and_sum_to_two_pi(mode, d):
    c = angle_configuration(d, mode)
    assert np.all(c.theta > 0) and np.all(c.theta < math.pi)
    assert abs(c.theta.sum() - TWO_PI) < 1e-13  # n additions of numbers below pi
    assert np.all(c.lengths > 0)
    np.testing.assert_array_equal(c.alpha, np.array(d) * np.roll(d, 1))
    np.testing.assert_array_equal(c.gamma, np.array(d) * np.roll(d, -1))


@pytest.mark.parametrize("mode", ["default", "optimized"])
@given(d=intervals_strategy(min_n=4).filter(lambda d: len(d) % 2 == 0))
@SMALL
def test_even_valence_satisfies_lemma2(mode, d):
    c = angle_configuration(d, mode)
    assert abs(lemma2_gap(c.theta)) < 1e-13  # ratio of two products of n/2 sines


@given(d=intervals_strategy(min_n=4).filter(lambda d: len(d) % 2 == 0))
@SMALL
def test_default_is_the_perturbed_heuristic(d):
    """All but two adjacent default angles are the heuristic; those two keep their sum.  (The
    paper perturbs theta_{n-2}, theta_{n-1}: the last two in the canonical labelling.)"""
    n = len(d)
    # Symmetric even-n intervals take the symmetric optimum instead (module docstring): the
    # paper's two-angle perturbation would break the symmetry.
    assume(not symmetric_even(d))
    c = angle_configuration(d, "default")
    target = paper_heuristic(np.array(d) / np.mean(d))
    moved = np.flatnonzero(np.abs(c.theta - target) > 1e-13)
    assert len(moved) in (0, 2)
    if len(moved) == 2:
        assert (moved[1] - moved[0]) in (1, n - 1)
        assert abs(c.theta[moved].sum() - target[moved].sum()) < 1e-13


@given(d=intervals_strategy(max_n=15).filter(lambda d: len(d) % 2 == 1))
@SMALL
def test_default_odd_is_the_heuristic(d):
    c = angle_configuration(d, "default")
    np.testing.assert_allclose(c.theta, paper_heuristic(np.array(d) / np.mean(d)), rtol=1e-13)


def test_printed_even_formula_is_wrong_and_reconstruction_right():
    """theta_{n-1} = arctan(beta_2 sin beta_1 / (1 + beta_2 sin beta_1)) as printed misses the
    Lemma 2 condition; with cos beta_1 in the denominator it holds."""
    d = np.array([1.0, 3.0, 2.0, 5.0, 1.0, 4.0]) / 2.6666666666666665
    theta = paper_heuristic(d)
    n = theta.size
    beta1 = theta[n - 2] + theta[n - 1]
    beta2 = pr(theta, 0, n - 4) / pr(theta, 1, n - 3)
    for denominator, ok in ((1 + beta2 * math.sin(beta1), False), (1 + beta2 * math.cos(beta1), True)):
        t = theta.copy()
        t[n - 1] = math.atan(beta2 * math.sin(beta1) / denominator)
        t[n - 2] = beta1 - t[n - 1]
        assert (abs(lemma2_gap(t)) < 1e-14) is ok
    assert abs(lemma2_gap(theta)) > 1e-3  # the perturbation had something to do


# --------------------------------------------------------------------------------------------
# Default lengths (reconstructed l-hat) and lengths from angles (eqs. 6, 7)


@given(d=intervals_strategy(), data=st.data())
@SMALL
def test_lhat_matches_literal_formula(d, data):
    n = len(d)
    raw = np.array(data.draw(st.lists(st.floats(0.2, 1.0), min_size=n, max_size=n)))
    theta = TWO_PI * raw / raw.sum()
    np.testing.assert_allclose(ac_module._default_lengths(np.array(d), theta), paper_lhat(d, theta), rtol=1e-13)


@pytest.mark.parametrize("n", range(3, 17))
def test_lhat_equal_for_uniform_intervals(n):
    theta = np.full(n, TWO_PI / n)
    lh = paper_lhat([1.0] * n, theta)
    np.testing.assert_allclose(lh, lh[0], rtol=1e-14)
    np.testing.assert_allclose(ac_module._default_lengths(np.ones(n), theta), lh, rtol=1e-14)


@pytest.mark.parametrize("mode", MODES)
@given(d=intervals_strategy())
@SMALL
def test_lengths_are_eq6_eq7_fitted_to_lhat(mode, d):
    """The module's chains against eqs. (6)/(7) written with the (i, j) products."""
    c = angle_configuration(d, mode)
    mean = np.mean(d)
    _, lengths = paper_objective(d, c.theta)
    if mode == "uniform":  # [SSEL13]: l_i proportional to d_i, one factor fitted to l-hat
        dbar = np.array(d) / mean
        l_hat = paper_lhat(dbar, paper_heuristic(dbar))
        lengths = dbar * np.dot(dbar, l_hat) / np.dot(dbar, dbar)
    np.testing.assert_allclose(c.lengths / mean, lengths, rtol=1e-12)


# --------------------------------------------------------------------------------------------
# The optimisation


@given(d=intervals_strategy(ratio=20.0).filter(lambda d: len(d) != 4 and max(d) > 1.01 * min(d)))
@SMALL
def test_optimisation_lowers_objective(d):
    opt = angle_configuration(d, "optimized")
    default = angle_configuration(d, "default")
    e_opt, _ = paper_objective(d, opt.theta)
    e_def, _ = paper_objective(d, default.theta)
    assert opt.converged
    if symmetric_even(d):  # the default mode is the symmetric optimum there (module docstring)
        assert e_opt == e_def
    else:
        assert e_opt < e_def
    assert abs(opt.objective - e_opt) <= 1e-12 * max(1.0, e_opt)  # same E in both codes


@pytest.mark.parametrize("d", [FIG15, (1.0, 2.0, 3.0), (1.0, 3.0, 2.0, 5.0, 1.0, 4.0), (2.0, 9.0, 1.0, 1.0, 5.0, 3.0, 7.0)])
def test_optimum_matches_slsqp(d):
    """A second solver on the same constrained problem finds no lower objective."""
    n = len(d)
    opt = angle_configuration(d, "optimized")
    cons = [{"type": "eq", "fun": lambda t: t.sum() - TWO_PI}]
    if n % 2 == 0:
        cons.append({"type": "eq", "fun": lambda t: lemma2_gap(t)})
    start = angle_configuration(d, "default").theta
    res = minimize(
        lambda t: paper_objective(d, t)[0], start, method="SLSQP", constraints=cons,
        bounds=[(1e-3, math.pi - 1e-3)] * n, options={"ftol": 1e-14, "maxiter": 500},
    )
    assert res.success
    assert opt.objective <= res.fun + 1e-9  # SLSQP's own accuracy
    np.testing.assert_allclose(opt.theta, res.x, atol=1e-4)  # SLSQP stops at ~sqrt(ftol)


def minpack_minimum(dc, sharp, theta0, omega=2.0):
    """The minimum of E for the canonical intervals ``dc`` by MINPACK, converged as far as it
    goes: Levenberg-Marquardt (lmder) from the angles theta0 on the residuals of E
    with the lengths eliminated (each chain's factor fitted in closed form: variable projection,
    not the module's joint angles-and-factors problem), then Powell's hybrid method (hybrd) on
    the stationarity equations J^T r = 0, which does not stop where E stops decreasing in
    floating point.  Derivatives by complex steps (exact to round-off); the chart (free angles,
    the last of each sector closing it, Lemma 2's pair by arctan) is written again here."""
    n = len(dc)
    struct = ac_module._structure(n, sharp)
    dbar = np.array(dc) / np.mean(dc)
    target = ac_module._default_angles(dbar, struct)[0]
    l_hat = ac_module._default_lengths(dbar, target)
    sectors = [list(s) for s in struct.sectors]
    pair = struct.pair
    free = [j for s in sectors if len(s) > 1 for j in s[: -(2 if pair and s[-1] == pair[1] else 1)]]

    def angles(u):
        theta = np.zeros(n, dtype=u.dtype)
        theta[free] = u
        order = sorted(zip(sectors, struct.sums), key=lambda x: bool(pair) and x[0][-1] == pair[1])  # the pair last
        for sec, total in order:
            if len(sec) == 1:
                theta[sec[0]] = total
            elif pair and sec[-1] == pair[1]:
                a, b = pair
                beta1 = total - theta[sec[:-2]].sum()
                others = [j for j in range(n) if j not in pair]
                log_sin = np.log(np.sin(theta[others]))
                beta2 = np.exp(sum(ls if j % 2 == a % 2 else -ls for j, ls in zip(others, log_sin)))
                x = np.arctan(beta2 * np.sin(beta1) / (1 + beta2 * np.cos(beta1)))
                theta[b] = x + math.pi if x.real <= 0 else x
                theta[a] = beta1 - theta[b]
            else:
                theta[sec[-1]] = total - theta[sec[:-1]].sum()
        return theta

    def residual(u):
        theta = angles(u)
        moving = theta[[j for sec in sectors if len(sec) > 1 for j in sec]].real  # a lone patch keeps pi
        if not np.all((moving > 0) & (moving < math.pi)):
            return np.full(2 * n, 1e6, dtype=u.dtype)  # a step out of (0, pi): refused
        q = dbar * np.exp(struct.exponents @ np.log(np.sin(theta)))
        lengths = np.zeros(n, dtype=q.dtype)
        for c in range(struct.n_components):
            on = struct.component == c
            if np.any(q[on] != 0):  # a chain of zero intervals keeps zero lengths
                lengths[on] = q[on] * (q[on] @ l_hat[on]) / (q[on] @ q[on])
        return np.concatenate([l_hat - lengths, math.sqrt(omega) * (target - theta)])

    def jac(u):
        return np.array([residual(u + 1e-30j * e).imag / 1e-30 for e in np.eye(u.size)]).T

    def grad(u):
        return jac(u).T @ residual(u).real

    if not free:
        return angles(np.zeros(0)), float(np.sum(residual(np.zeros(0)).real ** 2)), 0.0
    sol = least_squares(lambda u: residual(u).real, np.asarray(theta0)[free], jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    ref = root(grad, sol.x, method="hybr", options={"xtol": 1e-15})
    return angles(ref.x), float(np.sum(residual(ref.x).real ** 2)), np.abs(grad(ref.x)).max()


def symmetric(d, sharp) -> bool:
    dd, n = np.array(d), len(d)
    j = np.arange(n)
    maps = [(j + k) % n for k in range(1, n)] + [(k - j) % n for k in range(n)]
    return any(np.array_equal(dd[g], dd) and set(g[list(sharp)].tolist()) == set(sharp) for g in maps)


@st.composite
def minimum_cases(draw):
    """Valence 3..12, intervals with ratios up to 20, now and then zero intervals (a gap in the
    fan, as at a boundary) and sharp spokes."""
    n = draw(st.integers(3, 12))
    d = draw(st.lists(knot(draw(st.sampled_from([2.0, 5.0, 20.0]))), min_size=n, max_size=n))
    for i in draw(st.lists(st.integers(0, n - 1), max_size=2, unique=True)):
        d[i] = 0.0
    sharp = tuple(sorted(draw(st.lists(st.integers(0, n - 1), max_size=3, unique=True))))
    return d, sharp


@given(case=minimum_cases())
@example(case=([0.0, 0.0, 1.0, 4.0, 1.0, 2.0, 1.0], ()))  # the scheme stopped at a saddle of E here
@settings(max_examples=40, deadline=None)
def test_optimum_is_minpacks_minimum(case):
    """MINPACK, on another formulation of E, started 1e-4 rad away from the module's minimum
    (the alternating scheme with damped Newton steps, then Newton on angles and factors), goes
    back to it to ~1e-12 rad; E is no larger there.  (Which minimum the scheme ends in from the
    paper's start, where E has several, is compared with the MINPACK scheme of earlier versions
    in docs/speed.md.)"""
    d, sharp = case
    assume(any(d[i] * d[(i + 1) % len(d)] > 0 for i in range(len(d))) and len(d) != 4 and not symmetric(d, sharp))
    key = tuple(float(x) for x in d)
    (dc, sharp_c), _, gp = ac_module._canonical(key, sharp)
    config = angle_configuration(d, sharp_spokes=sharp)
    assert config.converged
    kick = 1e-4 * np.cos(np.arange(len(d)) + 1.0)  # away from the minimum, in no special direction
    theta_ref, e_ref, grad_ref = minpack_minimum(dc, sharp_c, config.theta[gp] + kick)
    assert grad_ref < 1e-11  # MINPACK really converged
    np.testing.assert_allclose(config.theta[gp], theta_ref, rtol=0, atol=1e-12)
    assert config.objective <= e_ref * (1 + 1e-12) + 1e-26  # no larger, to the round-off of two formulas of E


def test_fig15_configuration_converges():
    c = angle_configuration(FIG15)
    assert c.converged and 1 <= c.iterations < 200
    assert np.abs(c.theta - TWO_PI / 5).max() > 0.05  # really moved away from uniform
    assert c.objective < angle_configuration(FIG15, "default").objective
    assert c.objective < angle_configuration(FIG15, "uniform").objective


def test_remark2_keeps_current_iterate_when_not_converged():
    c1 = angle_configuration(FIG15, max_iterations=1)
    assert not c1.converged and c1.iterations == 1
    assert relation5_residuals(c1, FIG15).max() < 1e-13  # still a valid configuration
    full = angle_configuration(FIG15)
    assert full.objective <= c1.objective < angle_configuration(FIG15, "default").objective


@pytest.mark.parametrize("n,sharp", [(5, ()), (6, ()), (8, ()), (6, (0, 2)), (7, (1, 4)), (6, (3,)), (9, (0, 3, 5))])
def test_explicit_jacobians_match_finite_differences(n, sharp):
    rng = np.random.default_rng(n)
    d = rng.uniform(1, 5, n)
    d /= d.mean()
    struct = ac_module._structure(n, sharp)
    target, start = ac_module._default_angles(d, struct)
    prob = ac_module._BatchProblem(d[None], struct, target[None], ac_module._default_lengths(d, target)[None], 2.0)
    one = np.zeros(1, dtype=np.int64)
    x = np.concatenate([start[prob.chart.free], 1.1 * prob.factors(start[None], one)[0]])
    theta, r = prob.residual(x[None], one)
    np.testing.assert_allclose(theta[0], start, atol=1e-15)  # the chart gives the start back
    num = np.array([approx_fprime(x, lambda v: prob.residual(v[None], one)[1][0, k], 1e-7) for k in range(2 * n)])
    np.testing.assert_allclose(prob.jacobian(x[None], theta, one)[0], num, atol=2e-6)  # forward differences
    grad = lambda v: prob.gradient(v[None], prob.residual(v[None], one)[0], prob.residual(v[None], one)[1], one)[0]
    hess = np.array([approx_fprime(x, lambda v: grad(v)[k], 1e-7) for k in range(x.size)])
    np.testing.assert_allclose(prob.hessian(x[None], one, x.size)[0], 0.5 * (hess + hess.T), atol=2e-5)


# --------------------------------------------------------------------------------------------
# Symmetry


@pytest.mark.parametrize("mode", MODES)
@given(d=intervals_strategy(), k=st.integers(1, 15))
@SMALL
def test_rotation_rotates_theta(mode, d, k):
    c = angle_configuration(d, mode)
    r = angle_configuration(np.roll(d, -k), mode)
    # both are relabellings of one canonical solve: exact, except for intervals with a
    # symmetry, whose angles are symmetric only to the round-off of the averaging
    np.testing.assert_allclose(r.theta, np.roll(c.theta, -k), rtol=0, atol=1e-14)
    np.testing.assert_allclose(r.b, np.roll(c.b, -k), rtol=1e-13)
    np.testing.assert_allclose(r.lengths, np.roll(c.lengths, -k), rtol=1e-13)


@pytest.mark.parametrize("mode", MODES)
@given(d=intervals_strategy())
@SMALL
def test_reversal_mirrors_theta(mode, d):
    """Spoke i -> spoke -i maps patch i (spokes i, i+1) to patch -i-1: theta reverses; b and
    the lengths stay on their spokes; alpha and gamma swap."""
    c = angle_configuration(d, mode)
    m = angle_configuration(np.roll(np.array(d)[::-1], 1), mode)
    # exact up to the symmetrisation round-off (see the rotation test)
    np.testing.assert_allclose(m.theta, c.theta[::-1], rtol=0, atol=1e-14)
    np.testing.assert_allclose(m.b, np.roll(c.b[::-1], 1), rtol=1e-13)
    np.testing.assert_array_equal(m.alpha, np.roll(c.gamma[::-1], 1))
    assert fan_identity_residuals(m).max() < 1e-13


@pytest.mark.parametrize("mode", MODES)
@given(half=st.lists(knot(), min_size=2, max_size=8), odd=st.booleans())
@SMALL
def test_symmetric_intervals_give_symmetric_angles(mode, half, odd):
    d = np.array(half + half[-2 if odd else -1 : 0 : -1])  # d_i = d_{-i}
    n = d.size
    if n < 3 or (mode == "default" and n % 2 == 0):
        return  # the paper's Lemma 2 perturbation of one pair is not symmetric
    c = angle_configuration(d, mode)
    # averaged over the symmetry, then at most the Lemma 2 pair is re-solved: round-off
    np.testing.assert_allclose(c.theta, c.theta[(-np.arange(n) - 1) % n], atol=1e-12)
    assert relation5_residuals(c, d).max() < 1e-13
    if n % 2 == 0:
        assert abs(lemma2_gap(c.theta)) < 1e-13


def test_symmetric_case_where_the_objective_breaks_symmetry():
    """Intervals 10, 2, 1, 1, 2: E has a mirrored pair of lower, asymmetric minima (found here
    by SLSQP); the module returns the best symmetric configuration instead (module docstring)."""
    d = (10.0, 2.0, 1.0, 1.0, 2.0)
    c = angle_configuration(d)
    np.testing.assert_allclose(c.theta, c.theta[[4, 3, 2, 1, 0]], atol=1e-12)
    start = np.array([1.4, 0.6, 1.5, 1.3, 1.4])
    start *= TWO_PI / start.sum()
    res = minimize(
        lambda t: paper_objective(d, t)[0], start, method="SLSQP",
        constraints=[{"type": "eq", "fun": lambda t: t.sum() - TWO_PI}], bounds=[(1e-3, 3.1)] * 5,
        options={"ftol": 1e-14, "maxiter": 500},
    )
    assert res.fun < c.objective - 0.01
    assert np.abs(res.x - res.x[[4, 3, 2, 1, 0]]).max() > 0.1


def test_scaling_intervals_keeps_angles():
    d = np.array([1.0, 3.0, 2.0, 5.0, 1.5, 4.0, 2.0])
    for mode in MODES:
        c, c7 = angle_configuration(d, mode), angle_configuration(7 * d, mode)
        np.testing.assert_allclose(c7.theta, c.theta, atol=1e-10)
        np.testing.assert_allclose(c7.b, 49 * c.b, rtol=1e-9)
        np.testing.assert_allclose(c7.lengths, 7 * c.lengths, rtol=1e-9)


@pytest.mark.parametrize("n", range(3, 11))
@pytest.mark.parametrize("mode", ["default", "optimized"])
def test_one_tiny_interval_opens_its_two_angles_towards_right_angles(n, mode):
    """[FSLYJ]: if d_i is tiny, theta_{i-1} and theta_i should tend to pi/2."""
    d = np.ones(n)
    i = 2
    d[i] = 1e-9
    c = angle_configuration(d, mode)
    adjacent = c.theta[[i - 1, i]]
    assert abs(adjacent[0] - adjacent[1]) < 1e-9  # mirror symmetry about spoke i
    if n == 4:
        np.testing.assert_allclose(adjacent, math.pi / 2, rtol=1e-15)
        return
    assert np.all(np.abs(adjacent - math.pi / 2) < abs(TWO_PI / n - math.pi / 2))
    if n >= 5:
        others = np.delete(c.theta, [i - 1, i])
        assert adjacent.min() > others.max()
    assert relation5_residuals(c, d).max() < 1e-13


def test_zero_interval_gives_zero_length_and_finite_b():
    d = [0.0, 1.0, 2.0, 1.0, 3.0]
    for mode in MODES:
        c = angle_configuration(d, mode)
        assert c.lengths[0] == 0 and np.all(c.lengths[1:] > 0)
        assert np.all(np.isfinite(c.b))
        assert fan_identity_residuals(c).max() < 1e-13


# --------------------------------------------------------------------------------------------
# Sharp spokes (section 4.2)


def sector_sums(theta, sharp):
    n = theta.size
    sharp = sorted(sharp)
    return [sum(theta[p % n] for p in range(a, a + ((b - a - 1) % n) + 1)) for a, b in zip(sharp, sharp[1:] + sharp[:1])]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize(
    "d,sharp",
    [(FIG15, (0, 2)), (FIG15, (1, 3)), ((1.0, 2.0, 5.0, 1.0, 3.0, 2.0), (0, 3)), ((1.0, 2.0, 5.0, 1.0, 3.0, 2.0), (1, 5)),
     ((3.0, 1.0, 1.0, 7.0), (0, 2)), ((2.0, 1.0, 6.0), (0, 1))],
)
def test_two_sharp_spokes_split_into_two_half_turns(mode, d, sharp):
    c = angle_configuration(d, mode, sharp_spokes=sharp)
    np.testing.assert_allclose(sector_sums(c.theta, sharp), [math.pi, math.pi], rtol=1e-14)
    assert np.all(np.isnan(c.b[list(sharp)]))
    smooth = [i for i in range(len(d)) if i not in sharp]
    assert np.all(np.isfinite(c.b[smooth]))
    assert relation5_residuals(c, d, sharp).max() < 1e-13
    assert fan_identity_residuals(c, sharp).max() < 1e-13
    assert c.converged and c.sharp_spokes == tuple(sorted(sharp))
    n = len(d)
    if n % 2 == 0 and len({s % 2 for s in sharp}) == 1:  # a closed chain survives
        assert abs(lemma2_gap(c.theta)) < 1e-13


def test_one_face_sector_gets_a_half_turn():
    c = angle_configuration((2.0, 1.0, 6.0, 1.0, 1.0), sharp_spokes=(1, 2))
    assert c.theta[1] == math.pi
    assert np.all(c.theta[[0, 2, 3, 4]] < math.pi)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("d", [FIG15, (1.0, 2.0, 5.0, 1.0, 3.0, 2.0)])
@pytest.mark.parametrize("spoke", [0, 3])
def test_dart_keeps_smooth_angles_and_drops_its_constraint(mode, d, spoke):
    """One sharp spoke: one sector of 2 pi, the smooth EP's angles; its b is NaN."""
    smooth = angle_configuration(d, mode)
    dart = angle_configuration(d, mode, sharp_spokes=(spoke,))
    others = [i for i in range(len(d)) if i != spoke]
    assert np.isnan(dart.b[spoke]) and np.all(np.isfinite(dart.b[others]))
    if mode != "default" or spoke == 0 or len(d) % 2:
        # (default, even n: the paper's perturbed pair is the sector's last two patches,
        # which sit before the dart instead of at n-2, n-1)
        # two solves in different charts: a minimum of a large-residual least-squares problem
        # is located to ~sqrt(eps) (E is flat to round-off there); b amplifies that
        np.testing.assert_allclose(dart.theta, smooth.theta, atol=1e-7)
        np.testing.assert_allclose(dart.b[others], smooth.b[others], rtol=1e-6)
    assert relation5_residuals(dart, d, (spoke,)).max() < 1e-13
    if len(d) % 2 == 0:  # the other chain still closes: Lemma 2 still needed
        assert abs(lemma2_gap(dart.theta)) < 1e-13


@pytest.mark.parametrize("mode", MODES)
def test_corner_shares_the_turn_equally(mode):
    d = (1.0, 2.0, 5.0, 1.0, 3.0, 2.0, 4.0)
    sharp = (0, 2, 5)
    c = angle_configuration(d, mode, sharp_spokes=sharp)
    np.testing.assert_allclose(sector_sums(c.theta, sharp), [TWO_PI / 3] * 3, rtol=1e-14)
    assert relation5_residuals(c, d, sharp).max() < 1e-13
    assert fan_identity_residuals(c, sharp).max() < 1e-13
    assert np.all(np.isnan(c.b[list(sharp)]))


@given(
    case=st.integers(3, 12).flatmap(
        lambda n: st.tuples(
            st.lists(st.lists(st.sampled_from([0.0, 1.0, 2.0, 2.5]), min_size=n, max_size=n), min_size=1, max_size=30),
            st.lists(st.integers(0, n - 1), max_size=3, unique=True),
        )
    )
)
@SMALL
def test_canonical_labelling_vectorised_is_the_loop(case):
    """``_canonical_many`` (all EPs of one valence at once) picks the same relabelling as the
    one-EP loop, ties (repeated intervals, symmetric patterns) included."""
    rows, sharp = case
    sharp = tuple(sorted(sharp))
    keys = [tuple(r) for r in rows]
    ac_module._canonical.cache_clear()
    ac_module._canonical_many([(k, sharp) for k in keys])
    for k in keys:
        assert ac_module._canonical.known((k, sharp))
        (dc, sc), g, gp = ac_module._canonical(k, sharp)
        (dl, sl), gl, gpl = ac_module._canonical.__wrapped__(k, sharp)
        assert dc == dl and sc == sl
        np.testing.assert_array_equal(g, gl)
        np.testing.assert_array_equal(gp, gpl)


def test_sharp_rotation_equivariance():
    d = np.array([1.0, 2.0, 5.0, 1.0, 3.0, 2.0, 4.0])
    c = angle_configuration(d, sharp_spokes=(1, 4))
    r = angle_configuration(np.roll(d, -2), sharp_spokes=(6, 2))
    np.testing.assert_allclose(r.theta, np.roll(c.theta, -2), atol=1e-10)


# --------------------------------------------------------------------------------------------
# Input, cache


@pytest.mark.parametrize(
    "d", [[1.0, 1.0], [], [1.0, -1.0, 1.0], [1.0, math.nan, 1.0], [1.0, math.inf, 1.0], [0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 1.0, 0.0], [[1.0, 1.0, 1.0]], ["a", 1, 1]]
)
def test_bad_intervals_raise_knot_error(d):
    with pytest.raises(KnotError) as info:
        angle_configuration(d)
    assert isinstance(info.value, NupatchError) and isinstance(info.value, ValueError)


@pytest.mark.parametrize("sharp", [(5,), (-1,), (1.5,), (True,)])
def test_bad_sharp_spokes_raise_tag_error(sharp):
    with pytest.raises(TagError):
        angle_configuration(FIG15, sharp_spokes=sharp)


@pytest.mark.parametrize("kwargs", [{"mode": "modified"}, {"omega": -1.0}, {"omega": math.nan}, {"max_iterations": 0}])
def test_bad_options_raise_value_error(kwargs):
    with pytest.raises(ValueError):
        angle_configuration(FIG15, **kwargs)


def test_cache_shares_one_solve_per_kind():
    a = angle_configuration([1.0, 2.0, 3.0, 4.0, 5.0])
    b = angle_configuration((1.0 + 1e-14, 2.0, 3.0, 4.0, 5.0 - 1e-14))  # same to 12 digits
    assert a is b
    assert angle_configuration([1.0, 2.0, 3.0, 4.0, 5.0 + 1e-9]) is not a
    with pytest.raises(ValueError):
        a.theta[0] = 1.0  # cached arrays are read-only


@pytest.mark.parametrize("n", [3, 5, 6, 7])
def test_printed_eq8_first_row_needs_minus_b(n):
    """The sign warning of the module docstring, made concrete for the G1 solve: put the fan
    into the first row of eq. (8) as printed (P_00 = 0, P^i_10 = v_i, P^i_01 = v_{i+1},
    P^{i-1}_10 = v_{i-1}); it holds with beta = -b and fails with beta = b."""
    d = np.array([1.0, 2.0, 1.5, 3.0, 1.0, 2.5, 1.2][:n])
    c = angle_configuration(d)
    phi = np.concatenate([[0.0], np.cumsum(c.theta)[:-1]])
    v = c.lengths[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    for i in range(n):
        dm, dp = d[i - 1], d[(i + 1) % n]

        def row(beta):
            return -d[i] * dm * v[(i + 1) % n] - d[i] * dp * v[i - 1] + beta * v[i]

        scale = np.abs(d[i] * dm * v[(i + 1) % n]).max()
        assert np.abs(row(-c.b[i])).max() < 1e-13 * scale
        assert np.abs(row(c.b[i])).max() > 1e-3 * scale
