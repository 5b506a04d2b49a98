"""Blending functions of the EP on refined prism caps (a mesh family benchmarks/blending.py's
planar discs do not reach): the share of EP functions with a single local maximum.

    .venv/bin/python benchmarks/blending_prisms.py [--configs 8] [--samples 33] [--seed 0]

Meshes: the n-gonal prism (two n-gon caps, n side quads; n = 5, 6) refined by one
Catmull-Clark step (``subdivide``, uniform): each cap's centre is an EP of valence n (child
vertex 0 and 1: face points come first), its corners EPs of valence 3.  Every strip of the
refined mesh gets an interval drawn uniformly from [1, R] (``tests.helpers.with_random_intervals``,
no jitter of positions), R = 5 and 20.  For each configuration ``build_operator`` (defaults) and
``ep_quality`` on ``samples`` x ``samples`` grids per patch (maxima confirmed by Newton on the
patch polynomials) give the number of local maxima of the two cap EPs' blending functions and
the prominence of any second one (the dip between the two hills, relative to the peak).
Columns: configurations, EP functions with one maximum, the worst prominence, seconds per
configuration; then the configurations with a second maximum.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import patching  # noqa: E402
from patching.evaluation.sampling import ep_quality  # noqa: E402
from patching.subdivision import subdivide  # noqa: E402
from patching.topology.tables import Topology  # noqa: E402
from tests.helpers import lifted, prism, with_random_intervals  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=8)
    ap.add_argument("--samples", type=int, default=33)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"{args.configs} random configurations per row, {args.samples} x {args.samples} samples per patch")
    print(f"{'n':>2} {'ratio':>5} {'EP fns':>6} {'one max':>7} {'worst prom':>10} {'s/config':>8}")
    bad = []
    for ratio in (5.0, 20.0):
        for n in (5, 6):
            base = subdivide(prism(n), 1)
            ones, total, prom, times = 0, 0, 0.0, []
            for c in range(args.configs):
                mesh = with_random_intervals(base, ratio, seed=args.seed * 1000 + 97 * n + int(ratio) * 7 + c)
                topo = Topology(mesh)
                t0 = time.perf_counter()
                op = patching.build_operator(mesh, topology=topo)
                reports = ep_quality(op, lifted(mesh, seed=c), samples=args.samples, eps=[0, 1], topology=topo)
                times.append(time.perf_counter() - t0)
                for ep, q in zip((0, 1), reports):
                    total += 1
                    k = q.local_maxima[ep]
                    ones += k == 1
                    if k != 1:
                        prom = max(prom, q.prominence[ep])
                        bad.append((n, ratio, c, ep, k, round(q.prominence[ep], 4), round(q.second_maximum[ep], 4)))
            print(f"{n:>2} {ratio:>5.0f} {total:>6} {ones / total:>7.1%} {prom:>10.4f} {np.mean(times):>8.2f}")
    if bad:
        print("\nEP functions with more than one maximum (n, ratio, config, EP vertex, maxima, prominence, 2nd max):")
        for item in bad:
            print("  ", item)


if __name__ == "__main__":
    main()
