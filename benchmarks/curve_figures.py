"""[KSD] Figs. 1-4 as PNGs under docs/figures/, and the time of the curve operators.

    PYTHONPATH=. python benchmarks/curve_figures.py [--out docs/figures]

Fig. 1: a letter G of the quintic crease scheme T_5 (sharp vertices green, the polygon after
one step grey).  Fig. 2: a quintic with three semi-sharp vertices at s = 0, 1, 2, 3, inf (grey
to red) and the three basis functions at the middle crease for each s.  Fig. 3: quintic end
conditions: the T_5 end (blue) against the smooth curve (grey), the tangent at P_0 and the
displayed point P~1 = (10 P_1 + P_2) / 11 ([KSD] sec. 3.2.1); the red curve of [KSD14b] (29)
is not reproduced.  Fig. 4: the modified quintic T~5 (eq. (7)) at the same sharpness values,
by refinement (it has no exact B-spline form).  Then a table: polygon size, degree, seconds for
``Curve.limit()`` (exact) and ``refine(5)``.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.interpolate import BSpline  # noqa: E402

from patching.curves.creases import modified_quintic_step  # noqa: E402
from patching.curves.curve import Curve  # noqa: E402

SHARPNESS = [0, 1, 2, 3, math.inf]
COLOURS = ["0.6", "#f4a582", "#d6604d", "#b2182b", "#67001f"]


def _plot_curve(ax, curve: Curve, **kw):
    lim = curve.limit()
    t = np.linspace(*lim.domain, 2000)
    p = lim.evaluate(t)
    ax.plot(p[:, 0], p[:, 1], **kw)


def figure_1(out: Path) -> None:
    P = np.array([[4.2, 4.3], [3.2, 5], [1, 5], [0, 3.8], [0, 1.2], [1, 0], [3.2, 0], [4.2, 0.9], [4.2, 2.3],
                  [2.6, 2.3], [2.6, 1.7]])
    sharp = {0: math.inf, 7: math.inf, 8: math.inf, 9: math.inf, 10: math.inf}
    c = Curve(P, 5, corners=sharp)
    fig, ax = plt.subplots(figsize=(5, 5.5))
    ax.plot(P[:, 0], P[:, 1], "o-", color="0.3", lw=0.8, ms=4)
    r = c.refine(1).points
    ax.plot(r[:, 0], r[:, 1], ".-", color="0.7", lw=0.6, ms=3)
    _plot_curve(ax, c, color="k", lw=2)
    idx = sorted(sharp)
    ax.plot(P[idx, 0], P[idx, 1], "o", color="green", ms=7)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title("[KSD] Fig. 1: letter G, quintic T_5 (sharp: green)")
    fig.savefig(out / "curves_fig1_letter_g.png", dpi=120, bbox_inches="tight")
    plt.close(fig)


def _zigzag() -> np.ndarray:
    x = np.arange(11.0)
    y = np.array([0, 2, 0, 2, 0, 2, 0, 2, 0, 2, 0], dtype=float)
    return np.c_[x, y]


def figure_2(out: Path) -> None:
    P = _zigzag()
    n = len(P)
    inner = [3, 5, 7]
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
    ax.plot(P[:, 0], P[:, 1], "o-", color="0.3", lw=0.8, ms=4)
    ax.plot(P[inner, 0], P[inner, 1], "o", color="green", ms=7)
    for s, col in zip(SHARPNESS, COLOURS):
        corners = {0: math.inf, n - 1: math.inf, **{v: s for v in inner if s}}
        c = Curve(P, 5, corners=corners)
        _plot_curve(ax, c, color=col, lw=1.5, label=f"s = {s}")
        knots, W, _ = c.limit_operator()
        t = np.linspace(3.0, 7.0, 800)
        for j in (4, 5, 6):
            bx.plot(t, BSpline(knots, W.toarray()[:, j], 5)(t), color=col, lw=1.2)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    ax.set_title("[KSD] Fig. 2: quintic T_5, semi-sharp vertices 3, 5, 7")
    bx.set_title("basis functions of P_4, P_5, P_6 (crease at 5)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "curves_fig2_semi_sharp_quintic.png", dpi=120)
    plt.close(fig)


def figure_3(out: Path) -> None:
    P = np.array([[0, 0], [1, 2], [3, 2.5], [5, 1], [6, 3], [8, 3], [9, 1.0]])
    n = len(P)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(P[:, 0], P[:, 1], "o-", color="0.3", lw=0.8, ms=4)
    _plot_curve(ax, Curve(P, 5), color="0.6", lw=1.5, label="smooth (uniform, n - d spans)")
    c = Curve(P, 5, corners={0: math.inf, n - 1: math.inf})
    _plot_curve(ax, c, color="tab:blue", lw=1.8, label="T_5 end conditions")
    # c'(0) = (-11 P0 + 10 P1 + P2) / 12 ([KSD] eq. (6)): compare with the exact limit
    lim = c.limit()
    d1 = BSpline(lim.knots, lim.poles, 5).derivative()(0.0)
    expected = (-11 * P[0] + 10 * P[1] + P[2]) / 12
    assert np.allclose(d1, expected, atol=1e-12), (d1, expected)
    tan = P[0] + np.outer([0, 2.0], d1 / np.linalg.norm(d1))
    ax.plot(tan[:, 0], tan[:, 1], "--", color="tab:blue", lw=1)
    shown = (10 * P[1] + P[2]) / 11
    ax.plot(*shown, "s", color="tab:blue", ms=7, label="P~1 = (10 P1 + P2)/11")
    ax.legend(fontsize=8)
    ax.set_aspect("equal")
    ax.set_title("[KSD] Fig. 3: quintic end conditions, tangent at P_0 through P~1")
    fig.savefig(out / "curves_fig3_quintic_end.png", dpi=120, bbox_inches="tight")
    plt.close(fig)


def figure_4(out: Path) -> None:
    P = _zigzag()
    n = len(P)
    inner = [3, 5, 7]
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(P[:, 0], P[:, 1], "o-", color="0.3", lw=0.8, ms=4)
    ax.plot(P[inner, 0], P[inner, 1], "o", color="green", ms=7)
    for s, col in zip(SHARPNESS, COLOURS):
        sharp = np.zeros(n)
        sharp[inner] = s
        Q = P
        for _ in range(7):
            A, sharp = modified_quintic_step(len(Q), False, sharp)
            Q = A @ Q
        ax.plot(Q[:, 0], Q[:, 1], color=col, lw=1.5, label=f"s = {s}")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    ax.set_title("[KSD] Fig. 4: modified quintic T~5 (7 refinement steps)")
    fig.savefig(out / "curves_fig4_modified_quintic.png", dpi=120, bbox_inches="tight")
    plt.close(fig)


def timings() -> None:
    print(f"{'n':>6} {'d':>2} {'limit() s':>10} {'refine(5) s':>12} {'poles':>7}")
    rng = np.random.default_rng(0)
    for n in (100, 300):
        for d in (3, 5, 7):
            P = rng.normal(size=(n, 3))
            corners = {v: (2.5 if d % 2 else 2.0) for v in range(10, n - 10, 25)}
            c = Curve(P, d, corners=corners)
            t0 = time.perf_counter()
            lim = c.limit()
            t1 = time.perf_counter()
            c.refine(5)
            t2 = time.perf_counter()
            print(f"{n:>6} {d:>2} {t1 - t0:>10.3f} {t2 - t1:>12.3f} {len(lim.poles):>7}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/figures")
    parser.add_argument("--no-timings", action="store_true")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for f in (figure_1, figure_2, figure_3, figure_4):
        f(out)
        print(f"wrote {f.__name__}")
    if not args.no_timings:
        timings()


if __name__ == "__main__":
    main()
