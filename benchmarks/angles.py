"""Time per angle-configuration solve ([FSLYJ] sec. 3.3), valence 3..8.

Random spoke intervals with max/min ratio <= 5 (the paper's Figs. 1, 13) and <= 20; every
configuration is new (the cache is bypassed).  Prints ms per solve for the optimized mode (the
default mode as the floor: the heuristic alone), the mean outer iterations, the share that
converged within N = 200, and the smallest optimized angle seen (degrees).

    .venv/bin/python benchmarks/angles.py [samples per cell, default 40]
"""

from __future__ import annotations

import sys
import time

import numpy as np

from patching.extraordinary import angle_configuration as ac


def solve(d, mode):
    ac._mapped.cache_clear()
    ac._cached.cache_clear()
    t = time.perf_counter()
    c = ac.angle_configuration(d, mode)
    return time.perf_counter() - t, c


def main(samples: int = 40) -> None:
    rng = np.random.default_rng(2024)
    print(f"{'n':>3} {'ratio':>5} {'opt ms':>8} {'default ms':>10} {'ratio':>6} {'iters':>6} {'converged':>9} {'min deg':>8}")
    for ratio in (5.0, 20.0):
        for n in range(3, 9):
            t_opt, t_def, its, conv, min_angle = [], [], [], 0, 180.0
            for _ in range(samples):
                d = rng.uniform(1.0, ratio, n)
                d[rng.integers(n)] = 1.0
                d[rng.integers(n)] = ratio  # make the ratio exact
                t, c = solve(d, "optimized")
                t_opt.append(t)
                its.append(c.iterations)
                conv += c.converged
                min_angle = min(min_angle, float(np.degrees(c.theta.min())))
                t_def.append(solve(d, "default")[0])
            o, f = 1e3 * np.median(t_opt), 1e3 * np.median(t_def)
            print(f"{n:>3} {ratio:>5.0f} {o:>8.2f} {f:>10.3f} {o / f:>6.0f} {np.mean(its):>6.1f} {conv / samples:>9.0%} {min_angle:>8.1f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
