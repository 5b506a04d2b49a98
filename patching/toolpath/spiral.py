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
* All of this is laid out in pass coordinates (X, Y) = (G_u(u), G_v(v)), where the contours
  are the rectangles [q, N_u - q] x [q, N_v - q] and the spiral is a polyline with a vertex at
  every quarter turn (the levels change linearly in between), and only then mapped to (u, v)
  by the piecewise linear inverses of G_u, G_v, with a vertex wherever a segment crosses a knot
  of those maps (between knots they are affine), so the polyline in (u, v) is the exact image.
  (Placing the points along each side linearly in (u, v) instead, as a first version did,
  shears neighbouring arms against each other where the density jumps: 0.54 passes uncovered
  for a 6x jump into a narrow third.)
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


def _ring_points(q: np.ndarray, theta: np.ndarray, nu_pass: float, nv_pass: float) -> np.ndarray:
    """(N, 2) points in pass coordinates (X, Y) at levels q and angles theta: the contour at
    level q is the rectangle [q, N_u - q] x [q, N_v - q] there, whatever the densities."""
    x0, x1 = q, nu_pass - q
    y0, y1 = q, nv_pass - q
    corners = np.stack(
        [np.stack([x0, y0], 1), np.stack([x1, y0], 1), np.stack([x1, y1], 1), np.stack([x0, y1], 1)], axis=1
    )
    th = np.mod(theta, 1.0) * 4.0
    k = np.minimum(np.floor(th).astype(int), 3)
    f = (th - k)[:, None]
    a = corners[np.arange(len(q)), k]
    b = corners[np.arange(len(q)), (k + 1) % 4]
    return a + f * (b - a)


def _crossings(x: np.ndarray, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the polyline's coordinate x (N,) crosses a knot strictly inside a segment:
    (segment index, fraction in (0, 1)) of every crossing."""
    a, b = x[:-1], x[1:]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    first = np.searchsorted(knots, lo, side="right")
    count = np.maximum(np.searchsorted(knots, hi, side="left") - first, 0)
    seg = np.repeat(np.arange(a.size), count)
    rank = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    k = knots[first[seg] + rank]
    return seg, (k - a[seg]) / (b[seg] - a[seg])


def pass_map_polyline(xy: np.ndarray, cu: np.ndarray, u_grid: np.ndarray, cv: np.ndarray, v_grid: np.ndarray) -> np.ndarray:
    """The exact image in (u, v) of a polyline in pass coordinates under the piecewise linear
    maps u = G_u^-1(X), v = G_v^-1(Y) (``np.interp`` over the knots cu, cv): between knots
    the map is affine, so with a vertex added wherever a segment crosses a knot the image is
    again a polyline, and a simple one if the pass polyline is simple (a homeomorphism)."""
    su, fu = _crossings(xy[:, 0], cu)
    sv, fv = _crossings(xy[:, 1], cv)
    seg = np.concatenate([np.arange(len(xy)), su, sv])
    frac = np.concatenate([np.zeros(len(xy)), fu, fv])
    order = np.lexsort((frac, seg))
    seg, frac = seg[order], frac[order]
    nxt = np.minimum(seg + 1, len(xy) - 1)
    p = xy[seg] + frac[:, None] * (xy[nxt] - xy[seg])
    return np.stack([np.interp(p[:, 0], cu, u_grid), np.interp(p[:, 1], cv, v_grid)], axis=1)


def fermat_spiral(
    u_grid: np.ndarray, density_u: np.ndarray, v_grid: np.ndarray, density_v: np.ndarray, samples_per_turn: int = 8
) -> np.ndarray:
    """The connected Fermat spiral of [0, u_grid[-1]] x [0, v_grid[-1]] as a parameter polyline
    (N, 2), from the corner (0, 0) to the opposite corner.

    density_u: passes per unit u at u_grid (g_u >= 0), density_v likewise.  In pass coordinates
    the spiral is a polyline with a vertex at every corner of every turn (the levels change
    linearly between them); its exact image in (u, v) (``pass_map_polyline``) is returned, with
    at least ``samples_per_turn`` vertices per turn."""
    cu = CORNER * np.concatenate([[0.0], np.cumsum(0.5 * (density_u[1:] + density_u[:-1]) * np.diff(u_grid))])
    cv = CORNER * np.concatenate([[0.0], np.cumsum(0.5 * (density_v[1:] + density_v[:-1]) * np.diff(v_grid))])
    # Strictly increasing maps so that their inverses are functions.
    cu = cu + 1e-9 * np.arange(cu.size) / cu.size
    cv = cv + 1e-9 * np.arange(cv.size) / cv.size
    nu_pass, nv_pass = cu[-1], cv[-1]

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
    pin = _ring_points(level(2 * phi_in), phi_in, nu_pass, nv_pass)
    phi_out = arm(half, 0.5) if half > 0.5 else np.array([0.5])
    pout = _ring_points(level(2 * phi_out - 1), phi_out, nu_pass, nv_pass)
    xy = np.concatenate([pin, pout])  # the link: one straight segment in pass space
    keep = np.concatenate([[True], np.any(np.abs(np.diff(xy, axis=0)) > 1e-12 * (nu_pass + nv_pass), axis=1)])
    path = pass_map_polyline(xy[keep], cu, u_grid, cv, v_grid)
    scale = float(u_grid[-1] + v_grid[-1])
    keep = np.concatenate([[True], np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-9 * scale])
    out = path[keep]
    out[-1] = path[-1]  # the far corner exactly
    return out
