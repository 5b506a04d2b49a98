"""Subdivision speed (issue 7 targets: >= 1M output faces/s for the sparse product S @ P, and
construction of S no slower than 200k faces/s).  Prints a small table.

Meshes: a 100 x 100 torus grid (10,000 quads) with uniform and with random non-uniform
intervals (regular: knot insertion), and catmark_pawn from the OpenSubdiv shapes subdivided to
about 10k faces (EPs, creases, boundaries) when the shapes folder is there.  The reference
time in the same run is one scipy CSR matrix-vector product of the same size (nnz), our floor.

Run: .venv/bin/python benchmarks/subdivide.py
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from patching.obj import read_obj  # noqa: E402
from patching.primitives import torus_grid  # noqa: E402
from patching.subdivision import _Context, _operator, subdivide, subdivision_operator  # noqa: E402

SHAPES = Path(__file__).resolve().parent.parent.parent / "shared" / "opensubdiv-shapes"


def best(fn, repeat=3):
    times = []
    out = None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def meshes():
    rng = np.random.default_rng(0)
    yield "torus 100x100 uniform", torus_grid(100, 100)
    yield "torus 100x100 non-uniform", torus_grid(100, 100, rng.uniform(1, 5, 100), rng.uniform(1, 5, 100))
    pawn = SHAPES / "catmark_pawn.obj"
    if pawn.exists():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mesh = read_obj(pawn)
        mesh = subdivide(mesh, steps=2, rules="seed")  # 588 faces -> ~9.4k quads
        yield f"pawn x2 ({mesh.n_faces} faces, creases)", mesh
        yield "pawn x2, opensubdiv rules", (mesh, "opensubdiv")
        yield "pawn x2, random intervals (EP solves)", _random_intervals(mesh)


def _random_intervals(mesh, ratio=3.0, seed=0):
    """The same mesh with a random interval in [1, ratio] on every strip: every EP a new
    eigen-polyhedron configuration (no cache hits), the slow case."""
    from dataclasses import replace

    from patching.topology import Topology

    t = Topology(mesh)
    rng = np.random.default_rng(seed)
    first = np.full(t.n_strips, -1)
    first[t.edge_strip[::-1]] = np.arange(t.n_edges)[::-1]
    return replace(mesh, intervals={tuple(map(int, t.edges[e])): float(rng.uniform(1, ratio)) for e in first})


def main() -> None:
    rows = []
    for name, mesh in meshes():
        rules = "seed"
        if isinstance(mesh, tuple):
            mesh, rules = mesh
        from patching import eigen_polyhedron

        eigen_polyhedron._solve.cache_clear()  # cold: every EP configuration solved afresh
        t_cold, _ = best(lambda: _operator(_Context(mesh), rules, "standard"), repeat=1)
        t_s, _ = best(lambda: _operator(_Context(mesh), rules, "standard"))
        t_all, (S, child) = best(lambda: subdivision_operator(mesh, rules=rules))
        P = mesh.vertices
        t_prod, _ = best(lambda: S @ P, repeat=20)
        # floor: a CSR product with the same nnz and shape, one column at a time as we do
        t_floor, _ = best(lambda: S.dot(P[:, 0]), repeat=20)
        out_faces = child.n_faces
        rows.append((name, mesh.n_faces, out_faces, S.nnz, out_faces / t_cold, out_faces / t_s, out_faces / t_all, out_faces / t_prod, 3 * t_floor / t_prod))
    head = f"{'mesh':38} {'faces':>7} {'out':>7} {'nnz':>8} {'S cold f/s':>11} {'S faces/s':>11} {'S+mesh f/s':>11} {'S@P faces/s':>12} {'floor/ours':>10}"
    print(head)
    print("-" * len(head))
    for name, nf, of, nnz, fc, fs, fa, fp, ratio in rows:
        print(f"{name:38} {nf:7d} {of:7d} {nnz:8d} {fc:11.3g} {fs:11.3g} {fa:11.3g} {fp:12.3g} {ratio:10.2f}")
    print("\ntargets: S@P >= 1e6 output faces/s; construction >= 2e5 faces/s "
          "('S cold' = S alone, eigen-polyhedron cache emptied first; 'S faces/s' = S alone, best of 3; 'S+mesh' = S and the refined mesh with its tags);\n"
          "floor/ours = 3 one-column CSR products over our (n, 3) product (1 = as fast as scipy allows).")


if __name__ == "__main__":
    main()
