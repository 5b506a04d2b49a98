"""Subdivision speed (targets: >= 1M output faces/s for the sparse product S @ P, and
construction of S no slower than 200k faces/s).  Prints a small table.

Meshes: a 100 x 100 torus grid (10,000 quads) with uniform and with random non-uniform
intervals (regular: knot insertion), and catmark_pawn from the OpenSubdiv shapes subdivided to
about 10k faces (EPs, creases, boundaries) when the shapes folder is there.  The reference
time in the same run is one scipy CSR matrix-vector product of the same size (nnz), our floor.

Cold construction (every EP and tagged vertex a new configuration), output faces/s on this
machine: the bilinear face and edge solves of [TLC] eqs. 18-28 were one Python call per face
and edge of every vertex (cached by configuration); they are now one vectorised numpy call per
(valence) group of EPs and per (kind, shape) group of tagged vertices
(``eigen_polyhedron.bilinear_rule``):

    mesh                                   before     after
    pawn x2, random intervals (589 solves)  1.6e5     9.0e5
    icosphere x1, random (7682 EPs)         1.1e4     3.3e5   (target 2e5)

Each level's topology derived from the parent's and uniform quad steps written in CSR order
(``child_topology``, ``quad_rows``), 'S+mesh' output faces/s, one run each at load 8:

    mesh                                   before     after
    pawn x2, opensubdiv rules               3.8e5     3.4e6
    pawn x2 (seed rules, creases)           4.2e5     2.5e6
    torus 100x100 non-uniform               2.9e5     1.1e6

Run: .venv/bin/python benchmarks/subdivide.py [--report]  (--report adds the EP eigen-structure\nby interval ratio and [ZTL]'s blending-function maxima, standard vs modified angles)
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from patching.mesh.obj import read_obj  # noqa: E402
from patching.mesh.primitives import torus_grid  # noqa: E402
from patching.subdivision.catmark import _operator, subdivide, subdivision_operator  # noqa: E402
from patching.subdivision.context import _Context  # noqa: E402

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
    sphere = _ep_sphere()
    yield f"icosphere x1, random ({sphere[1]} EPs)", sphere[0]


def _ep_sphere():
    """A triangulated sphere (icosphere, 2562 vertices) refined once: 15,360 quads around 7,682
    EPs (valence 3 at the old face centres, 5 and 6 at the old vertices), then random
    intervals: every EP a new eigen-polyhedron configuration, the worst case for building S."""
    import trimesh

    from patching.mesh.control_mesh import from_arrays
    from patching.subdivision.context import _Context

    ico = trimesh.creation.icosphere(subdivisions=4)
    mesh = _random_intervals(subdivide(from_arrays(np.asarray(ico.vertices), np.asarray(ico.faces)), steps=1))
    ctx = _Context(mesh)
    return mesh, int(np.sum(ctx.valence != 4))


def _random_intervals(mesh, ratio=3.0, seed=0):
    """The same mesh with a random interval in [1, ratio] on every strip: every EP a new
    eigen-polyhedron configuration (no cache hits), the slow case."""
    from dataclasses import replace

    from patching.topology.tables import Topology

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
        from patching.rules import eigen_polyhedron

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




# ------------------------------------------------------------------------------------------
# Measurements for the report: not timings, but printed beside them.


def eigen_ratio_table(trials: int = 20) -> None:
    """For which spoke-interval ratios does the EP block of S have 1 > lambda = lambda >
    |others|?  S of a disk around one EP, level 1 (stationary); spoke intervals drawn as in
    benchmarks/eigen.py (one at 1, one at r, the others log-uniform: r is the true max/min) and
    judged by its criterion; also the largest difference between S's block and
    ``eigen_polyhedron.local_subdivision_matrix`` (the same matrix: see eigen.py's docstring
    for why the two benchmarks once disagreed)."""
    from eigen import LAWS, double_subdominant

    from patching.rules import eigen_polyhedron as eig
    from patching.errors import UnsupportedError
    from patching.mesh.control_mesh import from_arrays

    ratios = (2, 5, 20, 50, 100, 1000)
    draw = LAWS["1, r, log-uniform"]
    print(f"\nEP block of S: cases with 1 > lambda = lambda > |others| (of {trials} per cell, spoke "
          f"intervals 1, r, log-uniform); 'u' = rule undefined (UnsupportedError)")
    for angles in ("standard", "modified"):
        print(f"angles={angles}")
        print("  n  " + " ".join(f"{'r=' + str(r):>10}" for r in ratios))
        same = 0.0
        for n in [k for k in range(3, 17) if k != 4]:  # valence 4 is no EP
            cells = []
            for r in ratios:
                rng = np.random.default_rng(1000 * n + r)
                good = undefined = 0
                for _ in range(trials):
                    d = draw(rng, n, r)
                    try:
                        _, child = subdivision_operator(_blending_disk(d, from_arrays, rings=2), angles=angles)
                        S, _ = subdivision_operator(child, angles=angles)
                    except UnsupportedError:
                        undefined += 1
                        continue
                    block, ring_d = _ep_block(child, S)
                    same = max(same, np.abs(block - eig.local_subdivision_matrix(ring_d, angles=angles)).max())
                    good += double_subdominant(block, n)[0]
                cells.append(f"{good:>4d}" + (f" {undefined:>2d}u" if undefined else "    "))
            print(f"  {n:2d} " + " ".join(f"{c:>10}" for c in cells))
        print(f"  largest |S block - local_subdivision_matrix|: {same:.1e}")


def _ep_block(mesh, S):
    """S's rows and columns of the 1-ring [V, E_0.., F_0..] of the mesh's one EP, and its spoke
    intervals."""
    from patching.topology.tables import Topology

    t = Topology(mesh)
    v = int(np.flatnonzero((t.valence != 4) & ~t.vertex_is_boundary)[0])
    ring = t.one_ring(v)
    cols = np.concatenate([[v], t.dest[ring], t.dest[t.next[ring]]])
    rows = np.concatenate([[mesh.n_faces + t.n_edges + v], mesh.n_faces + t.edge_of[ring], t.face[ring]])
    return S[rows][:, cols].toarray(), t.halfedge_interval[ring]


def blending_maxima_table() -> None:
    """[ZTL]'s single-maximum claim, standard vs modified angles, on its figures' configurations
    (``benchmarks/modified_angles.py``, which also runs the paper's random test)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from modified_angles import figures_table

    figures_table()


def _blending_disk(d, from_arrays, rings: int = 3):
    """Polar disk of len(d) sectors of rings x rings quads; every strip crossing spoke i has
    interval d[i]; z = 1 at the EP, 0 elsewhere (the EP's blending function)."""
    n = len(d)
    ids, verts = {}, [(0.0, 0.0, 1.0)]

    def vid(i, p, q):
        i %= n
        if p == 0 and q == 0:
            return 0
        key = ("s", i, p) if q == 0 else ("s", (i + 1) % n, q) if p == 0 else ("in", i, p, q)
        if key not in ids:
            ids[key] = len(verts)
            a0, a1 = 2 * np.pi * i / n, 2 * np.pi * (i + 1) / n
            verts.append((p * np.cos(a0) + q * np.cos(a1), p * np.sin(a0) + q * np.sin(a1), 0.0))
        return ids[key]

    faces = [[vid(i, p, q), vid(i, p + 1, q), vid(i, p + 1, q + 1), vid(i, p, q + 1)]
             for i in range(n) for p in range(rings) for q in range(rings)]
    intervals = {(vid(i, p, 0), vid(i, p + 1, 0)): float(d[i]) for i in range(n) for p in range(rings)}
    return from_arrays(np.array(verts), faces, intervals=intervals)


if __name__ == "__main__":
    main()
    if "--report" in sys.argv:
        eigen_ratio_table()
        blending_maxima_table()
