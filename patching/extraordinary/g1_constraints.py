"""G1 constraints across a spoke edge of an extraordinary point ([FSLYJ] sec. 3.3-3.4).

Local frame of an EP of valence n (counter-clockwise spokes i = 0..n-1, patch i between spoke i
and spoke i+1; the same numbering as ``angle_configuration``).  Patch i is a bi-quintic net
P^i[j, m] with the EP at P^i[0, 0], j running along spoke i and m along spoke i+1, so that
P^i[j, 0] = P^{i-1}[0, j] (the shared spoke i):

            spoke i+1
              m ^
                |  patch i
                |  P^i[j, m]
     patch i-1  +-----------> j   spoke i
     P^{i-1}    EP

Across spoke i, with A = patch i (A_s along the spoke, A_t into patch i) and B = patch i-1
(B_t = its derivative across spoke i, into patch i-1), Lemma 1 (eq. 4) with the connecting
functions of section 3.3 reads

    alpha_A A_t(s, 0) + alpha_B B_t(s, 0) - beta(s) A_s(s, 0) = 0,
    alpha_A = d_i d_{i-1},  alpha_B = d_i d_{i+1},

(the width of the *other* patch weighs each cross derivative: for a valence-4 NURBS the
condition is C1 with beta = 0, which fixes this assignment), and

    beta(s) = b0 (1 - s)^2        if the spoke's far end is a regular vertex,
    beta(s) = b0 (1 - s) - b1 s   if it is another EP (b1 that EP's own constant).

Sign: b0 here is beta(0), the coefficient with alpha v_{i+1} + gamma v_{i-1} = b0 v_i in the
characteristic fan; ``angle_configuration`` returns the paper's printed b, which is -b0 (see
its sign warning).  With a far EP Y, the same condition written in Y's frame gives
beta(1) = -b_Y, hence the minus sign in front of b1.

Equations.  A_t = 5 sum_j (A[j,1] - A[j,0]) B^5_j, B_t likewise with B[1,j] - B[0,j], and
A_s = r'(s) for the spoke curve r_j = A[j,0].  With a regular far end the spoke curve is kept
of degree 4 (the fifth difference vanishes: the last row of eq. 8), so beta r' has degree 5;
with the quartic coefficients rho of r (recovered by the triangular recursion
rho_0 = r_0, rho_j = (5 r_j - j rho_{j-1}) / (5 - j), exact when the fifth difference
vanishes), (1-s)^2 r' = sum_{k<=3} 4 (rho_{k+1} - rho_k) C(3,k)/C(5,k) B^5_k.  With a far EP,
beta r' = 5 sum_k [b0 C(4,k)/C(5,k) dr_k - b1 C(4,k-1)/C(5,k) dr_{k-1}] B^5_k.  The G1
condition is then six linear equations G_0..G_5 (Bernstein coefficients of degree 5).  G_0 is
the first row of eq. (8)/(9) and G_1 its second row, letter for letter (checked in the tests);
the printed third and fourth rows differ from G_2, G_3 by multiples of earlier rows and of the
fifth-difference condition, and the printed last row of (9) has one sign wrong
(``+5 d_i d_{i+1} P^{i-1}_{1,3}``): substituting a C1 valence-4 configuration shows it, and
the tests do that substitution here.  G_4, G_5 vanish for a regular far end: they are the C1
conditions there, which the extraction satisfies (beta has a double root at s = 1).
"""

from __future__ import annotations

from math import comb

import numpy as np

__all__ = ["SLOTS", "spoke_equations", "spoke_equations_batch", "r_slot", "a_slot", "b_slot", "fifth_difference"]

#: Slot vector of one spoke: r_0..r_5 = A[j, 0], then A[j, 1] (j = 0..5), then B[1, j].
SLOTS = 18


def r_slot(j: int) -> int:
    return j


def a_slot(j: int) -> int:
    return 6 + j


def b_slot(j: int) -> int:
    return 12 + j


def _quartic_recursion() -> np.ndarray:
    """(5, 6) weights rho = W r of the degree-4 coefficients of a degree-reducible quintic."""
    w = np.zeros((5, 6))
    w[0, 0] = 1.0
    for j in range(1, 5):
        w[j] = -j * w[j - 1]
        w[j, j] += 5.0
        w[j] /= 5.0 - j
    return w


_RHO = _quartic_recursion()

#: Fifth difference of a quintic: zero iff its degree is at most 4 (eq. 8, last row).
fifth_difference = np.array([-1.0, 5.0, -10.0, 10.0, -5.0, 1.0])


def spoke_equations(alpha_a: float, alpha_b: float, b0: float, b1: float | None) -> np.ndarray:
    """(6, SLOTS) coefficients of G_0..G_5 over the spoke's slot vector (module docstring).

    b1 None: the far end is a regular vertex (beta = b0 (1-s)^2, quartic spoke curve).
    """
    g = np.zeros((6, SLOTS))
    for k in range(6):
        g[k, a_slot(k)] += 5.0 * alpha_a
        g[k, b_slot(k)] += 5.0 * alpha_b
        g[k, r_slot(k)] -= 5.0 * (alpha_a + alpha_b)
    if b1 is None:
        for k in range(4):
            weight = 4.0 * b0 * comb(3, k) / comb(5, k)
            g[k, :6] -= weight * (_RHO[k + 1] - _RHO[k])
    else:
        for k in range(6):
            if k <= 4:
                w = 5.0 * b0 * comb(4, k) / comb(5, k)
                g[k, r_slot(k + 1)] -= w
                g[k, r_slot(k)] += w
            if k >= 1:
                w = 5.0 * b1 * comb(4, k - 1) / comb(5, k)
                g[k, r_slot(k)] += w
                g[k, r_slot(k - 1)] -= w
    return g


def spoke_equations_batch(alpha_a: np.ndarray, alpha_b: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """:func:`spoke_equations` of m spokes at once: (m,) arrays -> (m, 6, SLOTS), b1 NaN for a
    regular far end; every coefficient by the same floating-point operations as alone."""
    alpha_a, alpha_b, b0, b1 = (np.asarray(x, dtype=np.float64) for x in (alpha_a, alpha_b, b0, b1))
    g = np.zeros((alpha_a.size, 6, SLOTS))
    for k in range(6):
        g[:, k, a_slot(k)] += 5.0 * alpha_a
        g[:, k, b_slot(k)] += 5.0 * alpha_b
        g[:, k, r_slot(k)] -= 5.0 * (alpha_a + alpha_b)
    regular = np.isnan(b1)
    if regular.any():
        for k in range(4):
            weight = 4.0 * b0[regular] * comb(3, k) / comb(5, k)
            g[regular, k, :6] -= weight[:, None] * (_RHO[k + 1] - _RHO[k])
    far = ~regular
    if far.any():
        c0, c1 = b0[far], b1[far]
        for k in range(6):
            if k <= 4:
                w = 5.0 * c0 * comb(4, k) / comb(5, k)
                g[far, k, r_slot(k + 1)] -= w
                g[far, k, r_slot(k)] += w
            if k >= 1:
                w = 5.0 * c1 * comb(4, k - 1) / comb(5, k)
                g[far, k, r_slot(k)] += w
                g[far, k, r_slot(k - 1)] -= w
    return g
