"""A connected Fermat spiral over a rectangle, with pass spacing given by a density.

Zhao et al. ("Connected Fermat spirals for layered fabrication", SIGGRAPH 2016; [FSLYJ]
sec. 4.3 uses the same idea through its reference [ZZX18]) turn the nested iso-contours of a
region into one curve that spirals in along every other contour and back out along the
contours in between, so that it enters and leaves at the boundary and never crosses itself.
For a rectangle the contours are nested rectangles.  We write the construction in closed form:

* A *level* q measures the distance from the boundary in passes: q = G_u(u) from the left side,
  N_u - G_u(u) from the right, G_v(v) from the bottom, N_v - G_v(v) from the top, where
  G_u(u) = int_0^u g_u is the number of passes needed across [0, u] (g_u = largest
  |S_u| / w over the column, w the allowed pass spacing on the surface).  The contour at level q
  is the rectangle [G_u^-1(q), G_u^-1(N_u - q)] x [G_v^-1(q), G_v^-1(N_v - q)]; the centre
  Lambda = min(N_u, N_v) / 2 is a segment (or a point).
* Contours sit at levels lambda_0 = 0 (the boundary), 0.5, then steps <= 1 up to
  Lambda - 0.5, then Lambda - 0.25 and Lambda; lambda(rho) interpolates them linearly over
  the contour index rho in [0, m].
* On each contour an angle theta in [0, 1) runs counter-clockwise from the lower-left corner,
  the four corners at theta = 0, 1/4, 1/2, 3/4.  The inward arm is rho = 2 phi, theta = phi mod 1
  (phi in [0, m/2]); the outward arm is rho = 2 phi - 1, traversed from phi = m/2 back to 1/2,
  where it reaches the boundary at the corner opposite the entry.  At a given theta the arms
  sit at rho = 2 theta + 2k and 2 theta + 2k + 1: never equal, so the curve is simple, and
  neighbouring passes are one contour index apart, at most one allowed spacing.  A radial link at
  theta = (m/2) mod 1 joins the arms' inner ends (rho = m to m - 1: nothing lies between them).
* Corners: a point on the diagonal between the corners of two contours one pass apart lies
  sqrt(2) / (1 + sqrt(2)) = 0.586 passes from both (nearer the outer contour's sides than the
  inner contour's corner), not 0.5; so the densities are scaled by CORNER = 2 sqrt(2) /
  (1 + sqrt(2)) = 1.172, which brings it to half a pass.  (Found by the scallop check on the
  flat tops of the machined bracket: 0.0216 for H = 0.02 before, exactly the ratio 0.586^2/0.5^2.)
* Coverage: every point lies within half a spacing of a pass: between passes by the one-index
  gap; at the boundary because lambda_1 = 0.5; at the centre because the inward arm's last
  turn keeps every angle at rho >= m - 2, i.e. within Lambda - lambda_{m-2} = 0.5 of the centre
  from both sides.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CORNER", "fermat_spiral", "levels"]

#: density factor that keeps a contour corner's diagonal within half a pass (module docstring).
CORNER = 2.0 * np.sqrt(2.0) / (1.0 + np.sqrt(2.0))


def levels(centre: float) -> np.ndarray:
    """Contour levels lambda_0..lambda_m in passes for a centre at level Lambda (module docstring)."""
    lam = float(centre)
    if lam <= 0.5:
        return np.array([0.0, lam / 2, lam]) if lam > 0 else np.array([0.0])
    inner = [lam - 0.5, lam - 0.25, lam]
    if lam - 0.5 <= 0.5:
        return np.array([0.0, *inner])
    n = int(np.ceil((lam - 1.0) - 1e-12))
    return np.concatenate([[0.0], np.linspace(0.5, lam - 0.5, n + 1), inner[1:]])


def _ring_points(q: np.ndarray, theta: np.ndarray, gu, gv, nu_pass: float, nv_pass: float) -> np.ndarray:
    """(N, 2) parameter points at levels q and angles theta (gu, gv: inverse pass maps)."""
    x0, x1 = gu(q), gu(nu_pass - q)
    y0, y1 = gv(q), gv(nv_pass - q)
    corners = np.stack(
        [np.stack([x0, y0], 1), np.stack([x1, y0], 1), np.stack([x1, y1], 1), np.stack([x0, y1], 1)], axis=1
    )
    th = np.mod(theta, 1.0) * 4.0
    k = np.minimum(np.floor(th).astype(int), 3)
    f = (th - k)[:, None]
    a = corners[np.arange(len(q)), k]
    b = corners[np.arange(len(q)), (k + 1) % 4]
    return a + f * (b - a)


def fermat_spiral(
    u_grid: np.ndarray, density_u: np.ndarray, v_grid: np.ndarray, density_v: np.ndarray, samples_per_turn: int = 400
) -> np.ndarray:
    """The connected Fermat spiral of [0, u_grid[-1]] x [0, v_grid[-1]] as a parameter polyline
    (N, 2), from the corner (0, 0) to the opposite corner.

    density_u: passes per unit u at u_grid (g_u >= 0), density_v likewise; every sample of
    the four corners of each turn is included, so the polyline follows the contours exactly
    there and interpolates between."""
    cu = CORNER * np.concatenate([[0.0], np.cumsum(0.5 * (density_u[1:] + density_u[:-1]) * np.diff(u_grid))])
    cv = CORNER * np.concatenate([[0.0], np.cumsum(0.5 * (density_v[1:] + density_v[:-1]) * np.diff(v_grid))])
    # Strictly increasing maps so that their inverses are functions.
    cu = cu + 1e-9 * np.arange(cu.size) / cu.size
    cv = cv + 1e-9 * np.arange(cv.size) / cv.size
    nu_pass, nv_pass = cu[-1], cv[-1]

    def gu(q):
        return np.interp(q, cu, u_grid)

    def gv(q):
        return np.interp(q, cv, v_grid)

    lam = levels(min(nu_pass, nv_pass) / 2)
    m = lam.size - 1
    if m == 0:
        return np.array([[0.0, 0.0], [u_grid[-1], v_grid[-1]]])
    index = np.arange(m + 1, dtype=np.float64)

    def level(rho):
        return np.interp(rho, index, lam)

    def arm(phi0: float, phi1: float) -> np.ndarray:
        n = max(int(np.ceil(abs(phi1 - phi0) * samples_per_turn)), 2)
        phi = np.linspace(phi0, phi1, n + 1)
        quarter = np.arange(np.ceil(min(phi0, phi1) * 4), np.floor(max(phi0, phi1) * 4) + 1) / 4
        phi = np.unique(np.concatenate([phi, quarter]))
        return phi if phi1 >= phi0 else phi[::-1]

    half = m / 2
    phi_in = arm(0.0, half)
    pin = _ring_points(level(2 * phi_in), phi_in, gu, gv, nu_pass, nv_pass)
    rho_link = np.linspace(m, m - 1, 9)[1:-1]
    plink = _ring_points(level(rho_link), np.full(rho_link.size, half), gu, gv, nu_pass, nv_pass)
    phi_out = arm(half, 0.5) if half > 0.5 else np.array([0.5])
    pout = _ring_points(level(2 * phi_out - 1), phi_out, gu, gv, nu_pass, nv_pass)
    path = np.concatenate([pin, plink, pout])
    keep = np.concatenate([[True], np.any(np.abs(np.diff(path, axis=0)) > 1e-13, axis=1)])
    return path[keep]
