"""Crease rules solved from S M = M T ([KSD] sec. 3) and the semi-sharp cubic of OpenSubdiv.

References: the matrices printed in [KSD] (3), (5), (8), (9) and M_4, T_4 (typed in here
from the paper as fractions); uniform subdivision of the polygon extended by odd reflection
(ghost points, written again below); an independent re-implementation of Pixar's semi-sharp
curve rules ([DKT98], OpenSubdiv's crease rule on a curve).
"""

from __future__ import annotations

import math
from fractions import Fraction as F

import numpy as np
import pytest

from patching.curves import runs
from patching.curves.creases import crease_scheme, half_line_subdivision
from patching.curves.curve import Curve
from patching.curves.runs import CREASE, FREE

# [KSD] eq. (3), (5), (8), (9) and the M_4, T_4 display of sec. 3.2.3: leading rows/columns
PAPER = {
    3: dict(M=[[1, 0], [F(2, 3), F(1, 3)], [0, 1]], T=[[8, 0], [4, 4]], scale=8),
    4: dict(
        M=[[1, 0, 0], [F(2, 3), F(1, 4), F(1, 12)], [0, F(3, 4), F(1, 4)], [0, 0, 1]],
        T=[[16, 0, 0, 0], [10, 5, 1, 0], [2, 9, 5, 0], [0, 5, 10, 1]],
        scale=16,
    ),
    5: dict(
        M=[[1, 0, 0], [F(49, 60), F(1, 6), F(1, 60)], [F(9, 20), F(1, 2), F(1, 20)], [0, F(4, 5), F(1, 5)], [0, 0, 1]],
        T=[[32, 0, 0, 0], [17, 14, 1, 0], [6, 20, 6, 0], [1, 15, 15, 1]],
        scale=32,
    ),
    7: dict(
        M=[
            [1, 0, 0, 0],
            [F(1109, 1260), F(7, 72), F(1, 45), F(1, 2520)],
            [F(269, 420), F(7, 24), F(1, 15), F(1, 840)],
            [F(32, 105), F(113, 210), F(16, 105), F(1, 210)],
            [0, F(25, 42), F(8, 21), F(1, 42)],
            [0, 0, F(6, 7), F(1, 7)],
            [0, 0, 0, 1],
        ],
        T=[[128, 0, 0, 0, 0], [72, 48, 8, 0, 0], [30, 69, 28, 1, 0], [8, 56, 56, 8, 0], [1, 28, 70, 28, 1]],
        scale=128,
    ),
}


@pytest.mark.parametrize("d", sorted(PAPER))
def test_solved_scheme_reproduces_the_paper(d):
    s = crease_scheme(d)
    M = np.array(PAPER[d]["M"], dtype=float)
    T = np.array(PAPER[d]["T"], dtype=float) / PAPER[d]["scale"]
    rows, cols = M.shape
    # round-off of a least-squares solve with entries <= 1: 1e-13
    assert np.abs(s.M_full[:rows, :cols] - M).max() < 1e-13
    assert np.abs(s.T_full[: T.shape[0], : T.shape[1]] - T).max() < 1e-13


@pytest.mark.parametrize("d", range(2, 8))
def test_S_M_equals_M_T_and_spectrum(d):
    s = crease_scheme(d)
    K = s.M_full.shape[0]
    S = half_line_subdivision(d, K)
    R = S @ s.M_full - s.M_full @ s.T_full
    assert np.abs(R[: K - 2 * d, : s.M_full.shape[1] - d]).max() < 1e-13
    # natural configuration linear: eigenvalues 1, 1/2 then 1/8, 1/32, ... (no 1/4: c'' = 0)
    block = s.T_full[: 2 * d, : 2 * d]
    ev = np.sort(np.abs(np.linalg.eigvals(block)))[::-1]
    expected = [1.0, 0.5] + [0.5 ** (2 * k + 1) for k in range(1, (d - 1) // 2 + 1)]
    if d % 2 == 0:
        expected.append(0.5**d)  # even d: the top power t^d is kept ([KSD] T_4: 1/16)
    assert np.allclose(ev[: len(expected)], expected, atol=1e-12)
    assert np.all(ev[len(expected) :] < 1e-6)


def _ghost_step(P: np.ndarray, d: int) -> np.ndarray:
    """Independent ghost rule between two crease ends: extend the run by odd reflection
    (P_(-i) = 2 P_0 - P_i, P_(n-1+i) = 2 P_(n-1) - P_(n-1-i), repeated for short runs),
    apply Lane-Riesenfeld (double every point, average neighbours d times), keep the new
    points whose centres lie between the two ends."""
    n = len(P)

    def point(i):
        if 0 <= i < n:
            return P[i]
        if i < 0:
            return 2 * P[0] - point(-i)
        return 2 * P[n - 1] - point(2 * (n - 1) - i)

    g = (d + 1) // 2 + 1
    idx = np.arange(-g, n + g)
    R = np.repeat(np.array([point(i) for i in idx]), 2, axis=0)
    for _ in range(d):
        R = (R[:-1] + R[1:]) / 2
    centres = idx[0] + (np.arange(len(R)) + (d + 1) / 2) / 2 - 0.5  # d = 1: R[0] at idx[0]
    return R[(centres > -1e-9) & (centres < n - 1 + 1e-9)]


@pytest.mark.parametrize("d", [3, 5, 7])
@pytest.mark.parametrize("n", [2, 3, 4, 5, 8, 13, 17, 21])
def test_odd_crease_rule_is_odd_reflection(d, n):
    """The solved crease stencils (assembled) = uniform subdivision of the reflected run."""
    rng = np.random.default_rng(n + d)
    P = rng.normal(size=(n, 2))
    ours = runs.run_refinement(n, d, CREASE, CREASE).toarray() @ P
    ref = _ghost_step(P, d)
    assert ours.shape == ref.shape
    assert np.abs(ours - ref).max() < 1e-14
    if n >= 2 * d + 2:
        assembled = runs.run_refinement(n, d, CREASE, CREASE, method="assembled").toarray() @ P
        assert np.abs(assembled - ref).max() < 1e-14
        for ends in [(CREASE, FREE), (FREE, CREASE)]:
            a = runs.run_refinement(n, d, *ends, method="assembled").toarray()
            g = runs.run_refinement(n, d, *ends, method="ghost").toarray()
            assert np.abs(a - g).max() < 1e-15


@pytest.mark.parametrize("d", [2, 4, 6])
@pytest.mark.parametrize("ends", [(CREASE, CREASE), (CREASE, FREE), (FREE, CREASE), (FREE, FREE)])
def test_even_assembled_rule_solves_the_run(d, ends):
    """Even d: the stencils assembled from the solved T equal the dense solve of the run's
    spline spaces M_fine T_run = S M (which exists only if the subspace is refinable)."""
    for n in range(2 * d + 2, 3 * d + 4):
        a = runs.run_refinement(n, d, *ends, method="assembled").toarray()
        s = runs.run_refinement(n, d, *ends, method="solved").toarray()
        assert np.abs(a - s).max() < 1e-11  # dense lstsq of ~40 unknowns


def test_adjacent_quintic_creases_give_the_16_16_rule():
    """[KSD] sec. 3.2.1: between two adjacent crease points the new point is [16, 16]/32."""
    T = runs.run_refinement(2, 5, CREASE, CREASE).toarray()
    assert np.allclose(T, [[1, 0], [0.5, 0.5], [0, 1]], atol=1e-15)


# --------------------------------------------------------------- OpenSubdiv cubic reference
def _pixar_step(P: np.ndarray, s: np.ndarray, closed: bool):
    """Pixar / OpenSubdiv semi-sharp cubic curve rule, written independently:
    edge point (P_i + P_i+1)/2; vertex point (P_i-1 + 6 P_i + P_i+1)/8 when smooth, P_i when
    s >= 1, s P_i + (1 - s) smooth when 0 < s < 1; the child gets max(s - 1, 0)."""
    n = len(P)
    out, sharp = [], []
    for i in range(n):
        if not closed and i in (0, n - 1):
            vp = P[i]  # end vertices: the sharp (end) rule
        else:
            smooth = (P[i - 1] + 6 * P[i] + P[(i + 1) % n]) / 8
            if s[i] >= 1:
                vp = P[i]
            elif s[i] > 0:
                vp = s[i] * P[i] + (1 - s[i]) * smooth
            else:
                vp = smooth
        out.append(vp)
        sharp.append(s[i] - 1 if s[i] >= 1 else 0.0)
        if closed or i < n - 1:
            out.append((P[i] + P[(i + 1) % n]) / 2)
            sharp.append(0.0)
    if not closed:
        sharp[0] = sharp[-1] = math.inf
    return np.array(out), np.array(sharp)


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("s", [1.0, 2.0, 2.5, math.inf, 0.3])
def test_cubic_equals_opensubdiv_semi_sharp_rules(s, closed):
    rng = np.random.default_rng(7)
    n = 9
    P = rng.normal(size=(n, 3)) * 10
    sharp = np.zeros(n)
    sharp[3] = s
    sharp[5] = 1.5
    corners = {3: s, 5: 1.5}
    if not closed:
        sharp[[0, n - 1]] = math.inf
        corners.update({0: math.inf, n - 1: math.inf})
    curve = Curve(P, 3, closed, corners=corners)
    Q, q = P, sharp
    for k in range(1, 5):
        Q, q = _pixar_step(Q, q, closed)
        ours = curve.refine(k)
        assert ours.points.shape == Q.shape
        assert np.abs(ours.points - Q).max() < 1e-12 * 10
    # the exact limit against the reference's limit points after 4 steps: cubic limit stencil
    # (P_i-1 + 4 P_i + P_i+1)/6 at smooth vertices, P_i at infinitely sharp ones
    m = len(Q)
    if not closed:
        lim_ref = np.array(
            [Q[i] if (q[i] == math.inf) else (Q[i - 1] + 4 * Q[i] + Q[i + 1]) / 6 for i in range(m)]
        )
        t = np.arange(m) / 16.0  # vertex i of level 4 sits at parameter i / 2^4
        assert np.abs(curve.evaluate(t) - lim_ref).max() < 1e-12 * 10


@pytest.mark.parametrize(
    "d, weights, denominator",
    [(5, [-11, 10, 1], 12), (7, [-302, 245, 56, 1], 360)],  # [KSD] eq. (6) and (10)
)
def test_end_conditions_of_the_paper(d, weights, denominator):
    """c(0) = P_0, c'(0) as printed, c''(0) = 0 at a sharp end (unit knot spacing)."""
    from scipy.interpolate import BSpline

    rng = np.random.default_rng(d)
    P = rng.normal(size=(3 * d, 2))
    lim = Curve(P, d, corners={0: math.inf, len(P) - 1: math.inf}).limit()
    spline = BSpline(lim.knots, lim.poles, d)
    assert np.allclose(spline(0.0), P[0], atol=1e-14)
    expected = sum(w * P[k] for k, w in enumerate(weights)) / denominator
    assert np.allclose(spline.derivative()(0.0), expected, atol=1e-12)
    assert np.allclose(spline.derivative(2)(0.0), 0.0, atol=1e-11)


def test_modified_quintic_rows_are_eq_7():
    from patching.curves.creases import modified_quintic_step

    n = 9
    s = np.zeros(n)
    s[4] = math.inf
    A, child = modified_quintic_step(n, False, s)
    rows = A[8:13] * 32  # vertex 4 is row 8: then the edge, vertex, edge, vertex rows after it
    expected = np.zeros((5, n))
    expected[0, 4] = 32
    expected[1, [4, 5]] = 16
    expected[2, [4, 5, 6]] = [6, 20, 6]
    expected[3, [4, 5, 6, 7]] = [1, 15, 15, 1]
    expected[4, [5, 6, 7]] = [6, 20, 6]
    assert np.allclose(rows, expected, atol=1e-13)
    assert child[8] == math.inf and np.allclose(A.sum(axis=1), 1.0)
