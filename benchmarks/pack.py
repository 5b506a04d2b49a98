"""Packed (multi-span B-spline) faces against one Bézier face a patch: faces, STEP size, times.

    .venv/bin/python benchmarks/pack.py [--size 100] [--ep-divisions 16]

Models: the 100 x 100 regular torus of benchmarks/build.py (intervals 1 to 20) and an
L-shaped polycube (EPs of valence 3 and 5, non-uniform intervals) with each cube face divided
into D x D quads.  Times: B-rep (``to_shape`` or ``to_packed_shape``), STEP write, and both.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

import patching
from export.brep import to_shape
from export.pack import patch_spans, to_packed_shape
from export.step import write_step
from patching.mesh.primitives import polycube, torus_grid


def ell(divisions: int) -> patching.ControlMesh:
    cube = polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0)], divisions, name="ell")
    topo = patching.Topology(cube)
    intervals = {}
    for strip in range(topo.n_strips):
        a, b = topo.edges[int(np.flatnonzero(topo.edge_strip == strip)[0])]
        intervals[(int(a), int(b))] = (1, 2, 0.5, 3, 1.5)[strip % 5]
    faces = [list(cube.face(f)) for f in range(cube.n_faces)]
    return patching.from_arrays(cube.vertices, faces, intervals=intervals, name="ell")


def measure(name: str, mesh: patching.ControlMesh) -> None:
    surface = patching.build(mesh)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for packed in (False, True):
            start = time.perf_counter()
            if packed:
                shape, report = to_packed_shape(surface, patch_spans(surface, mesh))
                faces = report.faces
            else:
                shape, faces = to_shape(surface), surface.n_patches
            t_brep = time.perf_counter() - start
            path = Path(tmp) / "out.step"
            start = time.perf_counter()
            write_step(shape, path, name, check=False)
            t_write = time.perf_counter() - start
            rows.append((packed, faces, os.path.getsize(path) / 1e6, t_brep, t_write))
    print(f"{name}: {mesh.n_faces} mesh faces, {surface.n_patches} patches")
    print(f"  {'':9} {'faces':>6} {'STEP MB':>8} {'B-rep s':>8} {'write s':>8} {'total s':>8}")
    for packed, faces, size, t_brep, t_write in rows:
        print(f"  {'packed' if packed else 'one/patch':9} {faces:6d} {size:8.1f} {t_brep:8.2f} {t_write:8.2f} {t_brep + t_write:8.2f}")
    (_, f0, s0, b0, w0), (_, f1, s1, b1, w1) = rows
    print(f"  ratio     {f0 / f1:6.0f}x {s0 / s1:7.1f}x {b0 / b1:7.1f}x {w0 / w1:7.1f}x {(b0 + w0) / (b1 + w1):7.1f}x")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--size", type=int, default=100)
    parser.add_argument("--ep-divisions", type=int, default=16)
    args = parser.parse_args()
    n = args.size
    rng = np.random.default_rng(0)
    du, dv = rng.integers(1, 21, n).astype(float), rng.integers(1, 21, n).astype(float)
    measure(f"torus {n} x {n}", torus_grid(n, n, du, dv, name="torus"))
    measure(f"L polycube, {args.ep_divisions} x {args.ep_divisions} per cube face", ell(args.ep_divisions))


if __name__ == "__main__":
    main()
