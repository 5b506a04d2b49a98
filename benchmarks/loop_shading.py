"""Loop subdivision and subdivision shading on a 100k-triangle output: operator build rate and
product rate (operator reused).  Prints figures; run by hand:

    PYTHONPATH=. python benchmarks/loop_shading.py

Control mesh: a triangulated torus of 20 x 10 quads (400 triangles) with every fifth diagonal
flipped (valence-5 and -7 vertices) and a ring of infinitely sharp and semi-sharp (s = 1.5)
edges; 4 Loop steps give 102,400 triangles.  Also the share of vertices whose normal needs
N_S (b > 0) at level 4, [ZBK] sec. 5, with blending seeded at level 1 and at level 4.
"""

from __future__ import annotations

import time

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
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    mesh = torus()
    levels = 4
    faces_out = mesh.n_faces * 4**levels
    print(f"control mesh: {mesh.n_faces} triangles; {levels} Loop steps: {faces_out:,} triangles")

    def geometry_only():
        m, S_total = mesh, None
        for _ in range(levels):
            S, m = loop_operator(m)
            S_total = S if S_total is None else (S @ S_total).tocsr()
        return S_total

    t_geo, S_total = best(geometry_only)
    t_prod, _ = best(lambda: S_total @ mesh.vertices, 10)
    print(f"Loop operator ({levels} steps, composed): built in {t_geo:.3f} s = {faces_out / t_geo:,.0f} output faces/s")
    print(f"Loop product S @ P: {t_prod * 1e3:.2f} ms = {faces_out / t_prod:,.0f} output faces/s")
    for mode in ("limit", "shading"):
        t_op, op = best(lambda: shading_operator(mesh, levels, "loop", normals=mode), 2)
        t_ev, out = best(lambda: op.evaluate(mesh.vertices), 5)
        print(f"{mode:8s}: operator built in {t_op:.3f} s = {faces_out / t_op:,.0f} output faces/s; "
              f"evaluate (points + normals) {t_ev * 1e3:.1f} ms = {faces_out / t_ev:,.0f} output faces/s; "
              f"{out.normals.shape[0]:,} normals for {out.points.shape[0]:,} vertices")
    op1 = shading_operator(mesh, levels, "loop")
    op4 = shading_operator(mesh, levels, "loop", blend_level=4)
    n = op1.mesh.n_vertices
    print(f"vertices needing N_S at level 4 (b > 0): seeded at level 1 {np.count_nonzero(op1.blend > 0):,} "
          f"({np.mean(op1.blend > 0):.1%}), seeded at level 4 {np.count_nonzero(op4.blend > 0):,} "
          f"({np.mean(op4.blend > 0):.1%}) of {n:,}")


if __name__ == "__main__":
    main()
