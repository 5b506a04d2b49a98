"""[FSLYJ]'s headline comparison reproduced: its construction against the T-spline baseline of
[SSEL13] (its [32]), ``build_operator(method="t-spline")`` (``patching.extraordinary.t_spline``).

    .venv/bin/python benchmarks/t_spline.py [--configs 40] [--samples 33] [--seed 2024] [--figures-only]
    .venv/bin/python benchmarks/t_spline.py --ablation --configs 20

Table: the random configurations of ``benchmarks/blending.py`` (the same draws: planar
``ep_disc`` of valence n = 5, 6, all 3n strips uniform in [1, R], ``default_rng([seed, n, R])``),
at R = 2, 5, 10, 20 ([FSLYJ] sec. 3.6: "200 random knot intervals, ratio 1 to 5"), three
builds per configuration: [FSLYJ] (defaults), [FSLYJ] with only its angles replaced by
[SSEL13]'s uniform ones (``angles="uniform"``, what the project offered before), and
[SSEL13]'s construction (``method="t-spline"``).  ``ep_quality`` counts the local maxima of
the 2n + 1 blending functions of the EP and its neighbours over their whole supports (confirmed
by Newton on the patch polynomials); columns: share with one maximum for the EP's own function,
for all 2n + 1, share of configurations where all have one, share of the functions whose other
maxima are all below 1% prominence ("<1%"), the worst second maximum relative to the peak, the
largest normal jump (degrees), seconds per configuration.

Figures (docs/figures/t_spline_*.png): [FSLYJ] Fig. 12 (valence 5, strips of the spokes 8, 4,
8, 1, 1: ``blending.FIG12_SPOKES``, our reading of its lost picture), and Figs. 1 and 13
(random intervals of ratio <= 5, valences 5 and 6): the first configurations of the table's
R = 5 draws where [SSEL13] gives a function with two maxima, that function drawn for both
methods (the paper does not say which function of which draw it shows).
"""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import patching  # noqa: E402
from patching.evaluation.sampling import ep_quality  # noqa: E402
from patching.topology.tables import Topology  # noqa: E402
from tests.helpers import ep_disc, lifted  # noqa: E402

FIGURES = ROOT / "docs" / "figures"
VISIBLE = 0.01
RATIOS = (2.0, 5.0, 10.0, 20.0)
MODES = {
    "fslyj": {},
    "uniform angles": {"angles": "uniform"},
    "t-spline": {"method": "t-spline"},
}


def draws(n: int, ratio: float, configs: int, seed: int):
    """blending.py's configurations: (configs, n, 3) strip intervals."""
    rng = np.random.default_rng([seed, n, int(ratio)])
    return [rng.uniform(1.0, ratio, (n, 3)) for _ in range(configs)]


def quality(d: np.ndarray, options: dict, samples: int, c: int):
    mesh = ep_disc(d.shape[0], d)
    topo = Topology(mesh)
    heights = lifted(mesh, seed=c)
    op = patching.build_operator(mesh, topology=topo, **options)
    (q,) = ep_quality(op, heights, samples=samples, topology=Topology(heights))
    return op, mesh, q


def table(configs: int, samples: int, seed: int) -> dict:
    head = f"{'n':>2} {'R':>3} {'method':>15} {'EP':>7} {'all 2n+1':>9} {'configs':>8} {'<1%':>7} {'2nd max':>8} {'jump deg':>9} {'s/config':>8}"
    print(f"{configs} random configurations per row (blending.py's draws, seed {seed}), {samples} x {samples} samples per patch")
    print(head)
    print("-" * len(head))
    bad = {}
    for ratio in RATIOS:
        for n in (5, 6):
            ds = draws(n, ratio, configs, seed)
            for name, options in MODES.items():
                ep, every, clean, visible, second, jump, secs = [], [], [], [], [], [], []
                for c, d in enumerate(ds):
                    t0 = time.perf_counter()
                    _, _, q = quality(d, options, samples, c)
                    secs.append(time.perf_counter() - t0)
                    ep.append(q.local_maxima[0] == 1)
                    every.extend(k == 1 for k in q.local_maxima.values())
                    clean.append(all(k == 1 for k in q.local_maxima.values()))
                    visible.extend(r < VISIBLE for r in q.prominence.values())
                    second.append(max(q.second_maximum.values()))
                    jump.append(q.max_normal_jump_deg)
                    if not clean[-1]:
                        bad.setdefault((n, ratio, name), []).append(_worst(c, q))
                print(f"{n:>2} {ratio:>3.0f} {name:>15} {np.mean(ep):>7.1%} {np.mean(every):>9.1%} {np.mean(clean):>8.1%} "
                      f"{np.mean(visible):>7.1%} {max(second):>8.3f} {max(jump):>9.1e} {np.mean(secs):>8.2f}", flush=True)
    return bad


def _contours(ax, op, mesh, column: int, samples: int, levels, title: str) -> None:
    from blending import draw_edges, ep_patches, mesh_edges, zoom

    patches = ep_patches(op, mesh, column, samples, 1.0)
    for x, y, v, _ in patches:
        ax.contourf(x, y, v, levels=levels, cmap="viridis", extend="min")
        ax.contour(x, y, v, levels=levels, colors="k", linewidths=0.3)
    draw_edges(ax, mesh_edges(mesh, Topology(mesh)))
    ax.set_aspect("equal")
    ax.set_xlim(*zoom(patches, 0)), ax.set_ylim(*zoom(patches, 1))
    ax.set_xticks([]), ax.set_yticks([])
    ax.set_title(title, fontsize=9)


def _compare(rows, stem: str, suptitle: str, samples: int = 41) -> None:
    """rows: [(intervals (n, 3), column, label, config index)]; one row of two panels each:
    t-spline | fslyj, the same contour levels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(rows), 2, figsize=(9, 4.3 * len(rows)), constrained_layout=True, squeeze=False)
    for (d, column, label, c), pair in zip(rows, axes):
        built = {m: quality(d, MODES[m], 33, c) for m in ("t-spline", "fslyj")}
        top = max(float(op.matrix[:, column].max()) for op, _, _ in built.values())
        levels = np.linspace(0.0, top, 21)
        for ax, m in zip(pair, ("t-spline", "fslyj")):
            op, mesh, q = built[m]
            k = q.local_maxima[column]
            name = "[SSEL13] (t-spline)" if m == "t-spline" else "[FSLYJ]"
            _contours(ax, op, mesh, column, samples, levels, f"{name}: {label}, {k} maxim{'um' if k == 1 else 'a'}")
            print(f"{stem}: {label} {m}: {k} maxima, 2nd max {q.second_maximum[column]:.3f}, prominence {q.prominence[column]:.3f}")
    fig.suptitle(suptitle)
    FIGURES.mkdir(parents=True, exist_ok=True)
    path = FIGURES / f"{stem}.png"
    fig.savefig(path, dpi=70)
    plt.close(fig)
    print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size / 1024:.0f} KB)")


def _worst(c: int, q):
    """(config, control point, maxima, 2nd max / peak) of the function whose second maximum is
    highest among those with more than one."""
    multi = [k for k, v in q.local_maxima.items() if v != 1]
    k = max(multi, key=lambda k: q.second_maximum[k])
    return c, int(k), q.local_maxima[k], q.second_maximum[k]


def _label(column: int, mesh) -> str:
    from patching.evaluation.sampling import neighbourhood

    if column == 0:
        return "the EP's function"
    edge, _ = neighbourhood(Topology(mesh), 0)
    return f"{'edge' if column in set(np.asarray(edge).tolist()) else 'diagonal'} neighbour {column}"


def figures(bad: dict, seed: int) -> None:
    from blending import FIG12_SPOKES

    d12 = np.ones((5, 3))
    d12[:, 0] = FIG12_SPOKES
    _compare([(d12, 0, "the EP's function", 0)], "t_spline_fig12",
             "[FSLYJ] Fig. 12 (our reading): valence 5, spoke strips 8, 4, 8, 1, 1, others 1")
    picks = {}
    for n in (5, 6):
        ds = draws(n, 5.0, 200, seed)
        found = list(bad.get((n, 5.0, "t-spline"), []))
        if not found:  # only the figures: search the first draws
            for c in range(40):
                _, _, q = quality(ds[c], MODES["t-spline"], 33, c)
                if any(k != 1 for k in q.local_maxima.values()):
                    found.append(_worst(c, q))
        found.sort(key=lambda item: -item[3])  # the most visible second maxima first
        picks[n] = [(ds[c], col, f"n={n} draw {c}, {_label(col, ep_disc(n, ds[c]))}", c) for c, col, _, _ in found[:3]]
    _compare([picks[5][0], picks[6][0]] if picks[5] and picks[6] else picks[5] + picks[6], "t_spline_fig1",
             "[FSLYJ] Fig. 1: random intervals, ratio <= 5, valences 5 and 6")
    rest = picks[5][1:3] + picks[6][1:3]
    if rest:
        _compare(rest, "t_spline_fig13", "[FSLYJ] Fig. 13: more random intervals, ratio <= 5")


@contextmanager
def _variant(angles: str, local_g1: bool):
    """[SSEL13]'s build with one of its three parts swapped back (module docstring of
    ``patching.extraordinary.t_spline``): the angles, and/or the per-EP fairing replaced by
    [FSLYJ]'s local steps (clusters of one EP dropped)."""
    from patching.extraordinary.cluster_fairing import ep_clusters
    from patching.operator import assembly

    saved = assembly.T_SPLINE_ANGLES, assembly.t_spline_clusters
    assembly.T_SPLINE_ANGLES = angles
    if local_g1:
        assembly.t_spline_clusters = ep_clusters
    try:
        yield
    finally:
        assembly.T_SPLINE_ANGLES, assembly.t_spline_clusters = saved


def ablation(configs: int, samples: int, seed: int) -> None:
    """Which of [SSEL13]'s three parts makes the extra maxima: the same draws, R = 5 and 20."""
    variants = {
        "t-spline": ("uniform", False),
        "t-spline, local G1": ("uniform", True),
        "first-ring anchors only": ("optimized", True),
    }
    print(f"\nablation: {configs} configurations per row; [SSEL13] with its parts swapped back to [FSLYJ]'s")
    head = f"{'n':>2} {'R':>3} {'variant':>24} {'EP':>7} {'all 2n+1':>9} {'configs':>8} {'<1%':>7} {'2nd max':>8} {'jump deg':>9}"
    print(head)
    print("-" * len(head))
    for ratio in (5.0, 20.0):
        for n in (5, 6):
            ds = draws(n, ratio, configs, seed)
            for name, (angles, local) in variants.items():
                ep, every, clean, visible, second, jump = [], [], [], [], [], []
                with _variant(angles, local):
                    for c, d in enumerate(ds):
                        _, _, q = quality(d, MODES["t-spline"], samples, c)
                        ep.append(q.local_maxima[0] == 1)
                        every.extend(k == 1 for k in q.local_maxima.values())
                        clean.append(all(k == 1 for k in q.local_maxima.values()))
                        visible.extend(r < VISIBLE for r in q.prominence.values())
                        second.append(max(q.second_maximum.values()))
                        jump.append(q.max_normal_jump_deg)
                print(f"{n:>2} {ratio:>3.0f} {name:>24} {np.mean(ep):>7.1%} {np.mean(every):>9.1%} {np.mean(clean):>8.1%} "
                      f"{np.mean(visible):>7.1%} {max(second):>8.3f} {max(jump):>9.1e}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=40)
    ap.add_argument("--samples", type=int, default=33)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--figures-only", action="store_true")
    ap.add_argument("--ablation", action="store_true", help="only the table of [SSEL13]'s parts swapped back")
    args = ap.parse_args()
    if args.ablation:
        ablation(args.configs, args.samples, args.seed)
        return
    bad = {} if args.figures_only else table(args.configs, args.samples, args.seed)
    figures(bad, args.seed)


if __name__ == "__main__":
    main()
