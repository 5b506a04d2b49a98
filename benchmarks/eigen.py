"""Where do the local eigen-polyhedron rules keep their promises?  Prints small tables.

For valences n and random spoke intervals with max/min ratio r (one spoke at 1, one at r, the
others uniform, then log-uniform, in [1, r]) it counts, per (options, n, r):
  eig   configurations with 1 > lambda = lambda > |others| (the G1 necessary condition),
  conv  configurations whose face and edge coefficients all lie in [0, 1] (convex rule),
  fail  configurations where the bilinear solves had no admissible root (ValueError),
  gap   the worst |mu| / lambda over the configurations (mu: 4th eigenvalue; < 1 needed),
and the time per matrix (uncached).

    .venv/bin/python benchmarks/eigen.py [samples]        (default 40 per cell; 2 cores: small)

Why two helpers disagreed: this table found 1 > lambda = lambda > |others| failing
for some draws at n = 5, 8, 12, 16 from r = 50 up, while ``benchmarks/subdivide.py --report``
found it holding up to "ratio 1000".  Both measured the same matrix: subdivide.py took
``local_subdivision_matrix`` itself, and S's block on an EP's 1-ring is that matrix to 1e-14
(tests/test_subdivision.py::test_ep_rows_are_the_eigen_polyhedron_matrix; subdivide.py's
report now measures S's own block on a mesh, with the draws and the criterion of this file).  They differed in what "ratio r" meant: subdivide.py
drew every spoke uniformly in [1, r], whose max/min is only about n + 1 (median 6 for n = 5,
24 for n = 16 at r = 1000), so it never reached the large true ratios where the rule fails;
here r is the true max/min (one spoke at 1, one at r).  With the same intervals the two give
the same eigenvalues.  The answer: the eigen-structure holds for true spoke ratios up to 20 at
every valence; from 50 up it fails for some draws at n = 5, 7, 8, 11, 12, 16 (n = 3, 6, 9, 10,
13-15 held in every draw), mostly with log-uniform intervals: at r = 1000 from 2% (n = 7) to
40% (n = 5) of them, as this table says (measured: 40 draws per cell, standard angles).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from patching.rules import eigen_polyhedron as ep

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


def double_subdominant(matrix: np.ndarray, n: int) -> tuple[bool, float]:
    """(1 > lambda = lambda > |others| holds, |mu| / lambda) for a local subdivision matrix of
    valence n, mu its fourth eigenvalue by modulus; the one criterion of both benchmarks."""
    lam = ep.characteristic_scale(n).lam
    ev = np.linalg.eigvals(matrix)
    ev = ev[np.lexsort((-ev.real, -np.round(np.abs(ev), 12)))]
    mods = np.abs(ev)
    ok = abs(ev[0] - 1) < 1e-9 and np.allclose(ev[1:3], lam, atol=1e-9) and mods[3] < lam
    return bool(ok), float(mods[3] / lam)


def cell(rng, n, ratio, angles, lengths, samples, law):
    eig = conv = fail = 0
    worst = 0.0
    t0 = time.perf_counter()
    for _ in range(samples):
        d = intervals(rng, n, ratio, law) * (1.0 + 1e-9 * rng.random())  # defeat the cache
        try:
            c = ep.rule_coefficients(d, angles=angles, lengths=lengths)
            m = ep.local_subdivision_matrix(d, angles=angles, lengths=lengths)
        except ValueError:
            fail += 1
            continue
        coef = np.concatenate([c.alpha.ravel(), c.beta.ravel()])
        conv += bool(np.all((coef >= 0) & (coef <= 1)))
        ok, gap = double_subdominant(m, n)
        eig += ok
        worst = max(worst, gap)
    dt = (time.perf_counter() - t0) / samples
    return eig, conv, fail, worst, dt


def main(samples: int = 40) -> None:
    rng = np.random.default_rng(2016)
    for (angles, lengths), law in [(o, law) for law in ("uniform", "log") for o in OPTIONS]:
        print(
            f"\nangles={angles} lengths={lengths} intervals 1, r and the others {law} in [1, r]"
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


LAWS = {
    "uniform in [1, r]": lambda rng, n, r: rng.uniform(1.0, r, n),  # subdivide.py's old draw
    "1, r, uniform": lambda rng, n, r: intervals(rng, n, r, "uniform"),
    "1, r, log-uniform": lambda rng, n, r: intervals(rng, n, r, "log"),
}


def sampling_table(samples: int = 40) -> None:
    """The disagreement explained: pass counts and the median true ratio max/min of the
    intervals under subdivide.py's old draw and this file's two, the same matrices."""
    print(f"\nWhat 'ratio r' means: eig ok / {samples} samples (u: rule undefined) and the median "
          f"true ratio max/min, per way of drawing the spoke intervals")
    print("   n      r " + "".join(f"{name:>28}" for name in LAWS))
    for n in (5, 8, 12, 16):
        for r in (50, 1000):
            rng = np.random.default_rng(100 * n + r)
            cells = []
            for draw in LAWS.values():
                good = undefined = 0
                ratios = []
                for _ in range(samples):
                    d = draw(rng, n, r)
                    ratios.append(d.max() / d.min())
                    try:
                        good += double_subdominant(ep.local_subdivision_matrices(d[None])[0], n)[0]
                    except ValueError:
                        undefined += 1
                cells.append(f"{good:>3} ok {undefined:>2} u  median {np.median(ratios):6.0f}")
            print(f"{n:>4} {r:>6g} " + "".join(f"{c:>28}" for c in cells))
    print("  -> the old draw never reaches the true ratios at which the rule fails; the matrices are the same.")


if __name__ == "__main__":
    cache_timing()
    sampling_table()
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
