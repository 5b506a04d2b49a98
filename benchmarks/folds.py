"""Fold census: how often the surface folds over itself on OpenSubdiv's catmark shapes
with random strip intervals, and where.

    .venv/bin/python benchmarks/folds.py [--ratios 5 20] [--seeds 4] [--samples 17] [--g1-solve joint seed]
                                         [--modes shipped weighted extraction faired modified limit-fit]

For every shape of ../shared/opensubdiv-shapes (tags kept) and every ratio R, ``--seeds``
draws of strip intervals uniform in [1, R] (``tests.test_g1_patches.with_random_intervals``,
seeds 0, 1, ...) are built with the default rules (and each ``--g1-solve`` given, and each
``--modes`` of ``benchmarks/blending_families.py``: anchor rules, eigen-polyhedron angles, the
red solve's stage-2 weighting), and ``evaluation.normal_turning`` finds the
patches whose normal turns back inside them (smallest cosine between neighbouring samples < 0).
Folded patches are split by degree:

* bicubic: a face whose 4 x 4 stencil holds no EP, the exact B-spline of its control points and
  knots (tests/test_exactness.py), so the fold belongs to that spline: any NURBS system gives it;
* bi-quintic: a face at an EP, whose G1 construction ([FSLYJ] sec. 3.4) made the fold.

Shapes refused in one line (non-manifold input, random intervals around n-gons) are counted
apart.  Prints one line per shape that folds at some draw and a summary per ratio.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import patching  # noqa: E402
from patching.errors import NupatchError  # noqa: E402
from patching.evaluation.sampling import normal_turning  # noqa: E402
from tests.conftest import shape_files  # noqa: E402
from tests.helpers import with_random_intervals# noqa: E402


def folded_by_degree(surface: patching.BezierSurface, samples: int) -> dict[int, int]:
    """Number of folded patches per degree."""
    _, worst = normal_turning(surface, samples=samples)  # patches in group order
    ends = np.cumsum([len(g.faces) for g in surface.groups])
    out: dict[int, int] = {}
    for g, part in zip(surface.groups, np.split(worst, ends[:-1])):
        out[g.degree] = out.get(g.degree, 0) + int(np.count_nonzero(part < 0.0))
    return out


def census(ratio: float, seeds: int, samples: int, g1_solve: str = "joint", mode: str = "shipped") -> None:
    from blending_families import MODES, stage_settings

    fields, overrides = MODES[mode]
    builds = refused = folding = 0
    patches = {3: 0, 5: 0}
    folded = {3: 0, 5: 0}
    start = time.perf_counter()
    for path in shape_files("catmark_"):
        row = []
        for seed in range(seeds):
            try:
                mesh = with_random_intervals(patching.read_mesh(path), ratio, seed=seed)
                with stage_settings(overrides):
                    surface = patching.build(mesh, g1_solve=g1_solve, **fields)
            except NupatchError:
                refused += 1
                row.append("refused")
                continue
            builds += 1
            counts = folded_by_degree(surface, samples)
            for g in surface.groups:
                patches[g.degree] = patches.get(g.degree, 0) + len(g.faces)
            for d, k in counts.items():
                folded[d] = folded.get(d, 0) + k
            folding += any(counts.values())
            row.append(f"{counts.get(3, 0)}+{counts.get(5, 0)}")
        if any(r not in ("refused", "0+0") for r in row):
            print(f"  {path.stem:32s} folded bicubic+quintic per seed: {', '.join(row)}")
    print(
        f"{g1_solve}, {mode}, ratio {ratio:g}: {builds} builds ({refused} refused), {folding} with a fold; folded patches: "
        f"bicubic {folded[3]} of {patches[3]}, bi-quintic {folded[5]} of {patches[5]} "
        f"({time.perf_counter() - start:.0f} s)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ratios", type=float, nargs="+", default=[5.0, 20.0])
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--samples", type=int, default=17)
    parser.add_argument("--g1-solve", nargs="+", default=["joint"], choices=patching.G1_SOLVES)
    parser.add_argument("--modes", nargs="+", default=["shipped"])
    args = parser.parse_args()
    if not shape_files("catmark_"):
        sys.exit("../shared/opensubdiv-shapes is absent")
    warnings.simplefilter("ignore")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    for g1_solve in args.g1_solve:
        for ratio in args.ratios:
            for mode in args.modes:
                census(ratio, args.seeds, args.samples, g1_solve, mode)


if __name__ == "__main__":
    main()
