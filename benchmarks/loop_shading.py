"""Loop subdivision and subdivision shading on a 100k-triangle output: operator build rate and
product rate (operator reused).  Prints figures; run by hand:

    PYTHONPATH=. python benchmarks/loop_shading.py
    PYTHONPATH=. python benchmarks/loop_shading.py --baseline /path/to/other/checkout [--rounds 3]

With ``--baseline`` the same measurements run alternately in fresh processes on this checkout
and on the other one (its ``patching`` package: e.g. ``git archive main | tar -x -C DIR``), so
that both see the same load on a shared machine; each figure is the best of the rounds, wall
clock and process CPU time.

Control mesh: a triangulated torus of 20 x 10 quads (400 triangles) with every fifth diagonal
flipped (valence-5 and -7 vertices) and a ring of infinitely sharp and semi-sharp (s = 1.5)
edges; 4 Loop steps give 102,400 triangles.  "shading 1st build" is the first build in the process
(the configurations' eigen-analyses not yet cached in memory), the other builds the best of 2-3.  Also the share of vertices whose normal needs
N_S (b > 0) at level 4, [ZBK] sec. 5, with blending seeded at level 1 and at level 4;
``--shares`` prints that share for a few of [OSD]'s shapes and an icosphere (variant B, 4 steps).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import patching
from patching.loop import loop_operator
from patching.shading import shading_operator


def torus(n=20, m=10):
    u, w = np.meshgrid(2 * np.pi * np.arange(n) / n, 2 * np.pi * np.arange(m) / m, indexing="ij")
    P = np.stack([(2 + np.cos(w)) * np.cos(u), (2 + np.cos(w)) * np.sin(u), np.sin(w)], -1).reshape(-1, 3)
    idx = lambda i, j: (i % n) * m + (j % m)
    faces = []
    for i in range(n):
        for j in range(m):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            faces += [[a, b, d], [b, c, d]] if (3 * i + 7 * j) % 11 == 0 else [[a, b, c], [a, c, d]]
    creases = {tuple(sorted((idx(3, j), idx(3, j + 1)))): (10.0 if j < 5 else 1.5) for j in range(m)}
    return patching.from_arrays(P, faces, creases=creases)


def best(f, repeat=3):
    """(best wall time, best CPU time, result) of ``repeat`` calls."""
    wall, cpu = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = f()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu), out


def measure() -> dict:
    """Seconds (wall, cpu) of each build and product, and the counts printed with them."""
    mesh = torus()
    levels = 4
    res = {"faces": mesh.n_faces * 4**levels, "control": mesh.n_faces}
    # the first build of the process: its eigen-analyses of ring configurations not cached yet
    *res["shading 1st build"], _ = best(lambda: shading_operator(torus(), levels, "loop"), 1)

    def geometry_only():
        m, S_total = mesh, None
        for _ in range(levels):
            S, m = loop_operator(m)
            S_total = S if S_total is None else (S @ S_total).tocsr()
        return S_total

    *res["loop build"], S_total = best(geometry_only)
    *res["loop product"], _ = best(lambda: S_total @ mesh.vertices, 10)
    for mode in ("limit", "shading"):
        *res[f"{mode} build"], op = best(lambda: shading_operator(mesh, levels, "loop", normals=mode), 2)
        *res[f"{mode} evaluate"], out = best(lambda: op.evaluate(mesh.vertices), 5)
        res["normals"], res["vertices"] = int(out.normals.shape[0]), int(out.points.shape[0])
    op1 = shading_operator(mesh, levels, "loop")
    op4 = shading_operator(mesh, levels, "loop", blend_level=4)
    res["n"] = int(op1.mesh.n_vertices)
    res["b1"], res["b4"] = int(np.count_nonzero(op1.blend > 0)), int(np.count_nonzero(op4.blend > 0))
    return res


KEYS = ("loop build", "loop product", "limit build", "limit evaluate", "shading 1st build", "shading build", "shading evaluate")


def report(res: dict, label: str = "") -> None:
    f = res["faces"]
    print(f"{label}control mesh: {res['control']} triangles; 4 Loop steps: {f:,} triangles")
    for key in KEYS:
        wall, cpu = res[key]
        print(f"{label}{key:17s} {wall * 1e3:9.1f} ms wall = {f / wall:12,.0f} output faces/s;"
              f" {cpu * 1e3:9.1f} ms CPU = {f / max(cpu, 1e-9):12,.0f} faces/s")
    print(f"{label}{res['normals']:,} normals for {res['vertices']:,} vertices; vertices needing N_S at level 4"
          f" (b > 0): seeded at level 1 {res['b1']:,} ({res['b1'] / res['n']:.1%}), seeded at level 4"
          f" {res['b4']:,} ({res['b4'] / res['n']:.1%}) of {res['n']:,}")


def shares() -> None:
    """[ZBK] sec. 5's count (Spot: 1.8 % to 5 % of the vertices at level 4 need N_S): the share
    of level-4 vertices with b > 0, blending seeded at level 4 and at level 1."""
    import warnings

    from patching.loop import loop_subdivide

    t = (1 + 5**0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
         [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
         [8, 6, 7], [9, 8, 1]]
    meshes = [("icosphere (ico, 2 Loop steps)", "loop", loop_subdivide(patching.from_arrays(v, f), 2)),
              ("benchmark torus", "loop", torus())]
    shapes = Path(__file__).resolve().parent.parent.parent / "shared" / "opensubdiv-shapes"
    for name in ("loop_icos_semisharp", "catmark_pawn", "catmark_helmet", "catmark_torus_creases1"):
        if (shapes / f"{name}.obj").is_file():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                meshes.append((name, name.split("_")[0], patching.read_mesh(shapes / f"{name}.obj")))
    for name, scheme, mesh in meshes:
        row = []
        for bl in (4, 1):
            op = shading_operator(mesh, 4, scheme, blend_level=bl)
            k = int(np.count_nonzero(op.blend > 0))
            row.append(f"seeded at level {bl}: {k:,} of {op.mesh.n_vertices:,} ({k / op.mesh.n_vertices:.2%})")
        print(f"{name:30s} {mesh.n_faces:5d} faces; " + "; ".join(row))


def _run(path: str) -> dict:
    env = dict(os.environ, PYTHONPATH=path)
    out = subprocess.run([sys.executable, __file__, "--json"], env=env, check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="another checkout to measure alternately with this one")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--shares", action="store_true", help="the share of vertices needing N_S on a few meshes")
    args = ap.parse_args()
    if args.shares:
        shares()
        return
    if args.json:
        print(json.dumps(measure()))
        return
    if not args.baseline:
        report(measure())
        return
    here = str(Path(__file__).resolve().parent.parent)
    runs = {"before": [], "after": []}
    for _ in range(args.rounds):
        runs["before"].append(_run(str(Path(args.baseline).resolve())))
        runs["after"].append(_run(here))
    for label, rs in runs.items():
        merged = dict(rs[0])
        for key in KEYS:
            merged[key] = [min(r[key][0] for r in rs), min(r[key][1] for r in rs)]
        report(merged, f"{label:6s} | ")


if __name__ == "__main__":
    main()
