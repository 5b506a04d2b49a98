"""Where do the local eigen-polyhedron rules keep their promises?  Prints small tables.

For valences n and random spoke intervals with max/min ratio r (one spoke at 1, one at r, the
others uniform, then log-uniform, in [1, r]) it counts, per (options, n, r):
  eig   configurations with 1 > lambda = lambda > |others| (the G1 necessary condition),
  conv  configurations whose face and edge coefficients all lie in [0, 1] (convex rule),
  fail  configurations where the bilinear solves had no admissible root (ValueError),
  gap   the worst |mu| / lambda over the configurations (mu: 4th eigenvalue; < 1 needed),
and the time per matrix (uncached).

    .venv/bin/python benchmarks/eigen.py [samples]        (default 40 per cell; 2 cores: small)
"""

from __future__ import annotations

import sys
import time

import numpy as np

from patching import eigen_polyhedron as ep

VALENCES = [3, 5, 6, 7, 8, 10, 12, 16]
RATIOS = [2, 5, 10, 20, 50, 100, 1e3, 1e4]
OPTIONS = [("standard", "appendix"), ("standard", "fourier"), ("modified", "fourier")]


def intervals(rng, n, ratio, law="uniform"):
    """One spoke at 1, one at ratio, the others uniform (or log-uniform) in [1, ratio]."""
    if law == "log":
        d = 10.0 ** rng.uniform(0.0, np.log10(ratio), size=n)
    else:
        d = rng.uniform(1.0, ratio, size=n)
    k = rng.permutation(n)[:2]
    d[k[0]], d[k[1]] = 1.0, ratio
    return d


def cell(rng, n, ratio, angles, lengths, samples, law):
    eig = conv = fail = 0
    worst = 0.0
    lam = ep.characteristic_scale(n).lam
    t0 = time.perf_counter()
    for _ in range(samples):
        d = intervals(rng, n, ratio, law) * (1.0 + 1e-9 * rng.random())  # defeat the cache
        try:
            c = ep.rule_coefficients(d, angles=angles, lengths=lengths)
            ev = ep.subdivision_eigenvalues(d, angles=angles, lengths=lengths)
        except ValueError:
            fail += 1
            continue
        coef = np.concatenate([c.alpha.ravel(), c.beta.ravel()])
        conv += bool(np.all((coef >= 0) & (coef <= 1)))
        mods = np.abs(ev)
        ok = abs(ev[0] - 1) < 1e-9 and np.allclose(ev[1:3], lam, atol=1e-9) and mods[3] < lam
        eig += bool(ok)
        worst = max(worst, mods[3] / lam)
    dt = (time.perf_counter() - t0) / samples
    return eig, conv, fail, worst, dt


def main(samples: int = 40) -> None:
    rng = np.random.default_rng(2016)
    for (angles, lengths), law in [(o, law) for law in ("uniform", "log") for o in OPTIONS]:
        print(
            f"\nangles={angles} lengths={lengths} intervals {law} in [1, r]"
            f"  ({samples} samples per cell: eig/conv/fail gap)"
        )
        print("   n " + "".join(f"{'r=' + format(r, 'g'):>22}" for r in RATIOS))
        for n in VALENCES:
            row, times = [], []
            for r in RATIOS:
                eig, conv, fail, worst, dt = cell(rng, n, r, angles, lengths, samples, law)
                row.append(f"{eig:>3}/{conv:>3}/{fail:>2} {worst:6.3f}")
                times.append(dt)
            cells = "".join(f"{x:>22}" for x in row)
            print(f"{n:>4} {cells}   {1e3 * np.mean(times):.2f} ms/vertex")


def cache_timing() -> None:
    """One valence-5 vertex: solve (uncached) versus lookup (cached), the ratio the cache buys."""
    d = [1.0, 2.0, 3.0, 1.5, 4.0]
    ep._solve.cache_clear()
    ep._eigen.cache_clear()
    t0 = time.perf_counter()
    ep.tangent_weights(d)
    solve = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(1000):
        ep.tangent_weights(d)
    lookup = (time.perf_counter() - t0) / 1000
    print(f"\nvalence 5: solve {1e3 * solve:.2f} ms, cached lookup {1e6 * lookup:.1f} us, "
          f"ratio {solve / lookup:.0f}")


if __name__ == "__main__":
    cache_timing()
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
