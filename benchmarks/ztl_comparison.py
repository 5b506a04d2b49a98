"""[ZTL]'s comparison reproduced: [LFS16]'s standard eigen-polyhedron angles, [ZTL]'s modified
angles and NURSS ([SZSS98], ``subdivide(rules="nurss")``) on [ZTL]'s figure configurations, its
random test, and the eigen-structure at the EP.

    .venv/bin/python benchmarks/ztl_comparison.py [--samples 30] [--figures-only]

The measure is [ZTL]'s (Discussion): after five refinement steps the EP's blending function
(z = 1 at the EP, 0 elsewhere) has one interior control point higher than all its
neighbours.  ``modified_angles.maxima`` counts with the edge neighbours (the reading used so
far); the column "1-ring" counts with every vertex sharing a face (the other reading of
"neighbors").  "2nd" is the second-highest maximum over the highest (a genuine second hill
has a value that stays put under more steps; a ripple of the count does not).  Disk:
``subdivide._blending_disk`` (three rings of quads per sector, every strip parallel to spoke i
carries d_i, unit-spaced planar layout).  Eigenvalues: of the EP's (2n+1) x (2n+1) local
matrix (stationary from the first step), largest moduli after 1.

Figures: docs/figures/ztl_fig<k>.png, the refined control mesh after five steps as a shaded
height field, standard | modified | NURSS, for [ZTL] Figs. 1, 6-10.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from patching.errors import UnsupportedError  # noqa: E402
from patching.mesh.control_mesh import from_arrays  # noqa: E402
from patching.rules import eigen_polyhedron as eig  # noqa: E402
from patching.rules.nurss import nurss_local_matrix  # noqa: E402
from patching.subdivision.catmark import subdivision_operator  # noqa: E402
from patching.topology.tables import Topology  # noqa: E402
from subdivide import _blending_disk  # noqa: E402

FIGURES = ROOT / "docs" / "figures"
#: Pictures show the quads whose centre is within this distance of the EP (rings of unit
#: spacing): the 1-ring and the inner half of the 2-ring, where every extra maximum lies.
RADIUS = 1.6
LEVELS = 5
REL_TOL = 1e-12
CONFIGS = {
    "Fig 1": [1, 15, 1, 1, 15],
    "Fig 6": [1, 10, 10],
    "Fig 7": [1, 1, 1e4, 1e4, 1e4],
    "Fig 8": [100, 100, 1, 1, 100, 100, 100],
    "Fig 9": [100, 100, 1, 1, 100, 100, 1, 1],
    "Fig 10": [1, 1, 1, 5, 5],
}
SCHEMES = {"standard": ("seed", "standard"), "modified": ("seed", "modified"), "NURSS": ("nurss", "standard")}


def refined(d, scheme: str, levels: int = LEVELS, disk=None, with_ep: bool = False):
    """The disk after ``levels`` steps (and with ``with_ep`` the EP's vertex id in it: a
    step numbers face points, edge points, then vertex points)."""
    rules, angles = SCHEMES[scheme]
    mesh = disk if disk is not None else _blending_disk(d, from_arrays)
    ep = 0
    for _ in range(levels):
        ep += mesh.n_faces + Topology(mesh).n_edges
        _, mesh = subdivision_operator(mesh, rules=rules, angles=angles)
    return (mesh, ep) if with_ep else mesh


def counts(mesh) -> tuple[int, int, float]:
    """(maxima over edge neighbours, maxima over the face 1-ring, 2nd highest / highest)."""
    t = Topology(mesh)
    z = mesh.vertices[:, 2]
    inside = ~t.vertex_is_boundary & t.vertex_is_used
    tol = REL_TOL * np.abs(z).max()
    best = np.full(mesh.n_vertices, -np.inf)
    np.maximum.at(best, t.edges[:, 0], z[t.edges[:, 1]])
    np.maximum.at(best, t.edges[:, 1], z[t.edges[:, 0]])
    edge = np.flatnonzero(inside & (z > best + tol))
    f_of = np.repeat(np.arange(mesh.n_faces), np.diff(mesh.face_offsets))
    a = sp.csr_matrix((np.ones(f_of.size), (mesh.face_vertices, f_of)), shape=(mesh.n_vertices, mesh.n_faces))
    pairs = (a @ a.T).tocoo()
    off = pairs.row != pairs.col
    ring = best.copy()
    np.maximum.at(ring, pairs.row[off], z[pairs.col[off]])
    face = np.flatnonzero(inside & (z > ring + tol))
    heights = np.sort(z[edge])[::-1]
    return edge.size, face.size, float(heights[1] / heights[0]) if heights.size > 1 else 0.0


def eigenvalues(d, scheme: str) -> np.ndarray:
    rules, angles = SCHEMES[scheme]
    m = nurss_local_matrix(d) if rules == "nurss" else eig.local_subdivision_matrix(d, angles=angles)
    return np.sort(np.abs(np.linalg.eigvals(m)))[::-1]


def figures_table() -> dict:
    print(f"1. [ZTL]'s figures: maxima of the EP's blending function after {LEVELS} steps (edge neighbours / "
          f"face 1-ring, 2nd highest maximum / highest) and the EP matrix's eigenvalues lambda_2, lambda_3, |lambda_4|")
    head = f"  {'config':8} {'intervals':34} {'scheme':>9} {'maxima':>7} {'1-ring':>7} {'2nd':>6} {'lambda_2':>9} {'lambda_3':>9} {'|l_4|':>7}"
    print(head)
    meshes = {}
    for name, d in CONFIGS.items():
        for scheme in SCHEMES:
            try:
                mesh = refined(d, scheme)
            except UnsupportedError:
                print(f"  {name:8} {str(d):34} {scheme:>9}   rule undefined")
                continue
            meshes[(name, scheme)] = mesh
            e, f, second = counts(mesh)
            ev = eigenvalues(d, scheme)
            print(f"  {name:8} {str([float(x) for x in d]):34} {scheme:>9} {e:>7} {f:>7} {second:>6.3f} {ev[1]:>9.5f} {ev[2]:>9.5f} {ev[3]:>7.4f}",
                  flush=True)
    return meshes


def _disk(d, outer):
    """_blending_disk with the strips beyond the 1-ring (a_i, [FSLYJ] Fig. 11) set to ``outer``."""
    mesh = _blending_disk(d, from_arrays)
    t = Topology(mesh)
    iv = t.halfedge_interval
    spokes = t.one_ring(0)
    inner = set(np.asarray(t.edge_strip)[t.edge_of[spokes]].tolist())
    tags = {}
    for e, (a, b) in enumerate(t.edges.tolist()):
        strip = int(t.edge_strip[e])
        if strip in inner:
            continue
        tags[(a, b)] = float(outer)
    for h in spokes.tolist():
        a, b = int(t.origin[h]), int(t.dest[h])
        tags[(a, b)] = float(iv[h])
    return from_arrays(mesh.vertices, [list(mesh.face_vertices[mesh.face_offsets[f]:mesh.face_offsets[f + 1]]) for f in range(mesh.n_faces)],
                       intervals=tags)


def fig7_readings() -> None:
    d = CONFIGS["Fig 7"]
    print("\n2. [ZTL] Fig. 7 (valence 5, intervals 1, 1, 1e4, 1e4, 1e4), the readings the text leaves open:")
    print(f"  {'reading':52} {'scheme':>9} {'maxima':>7} {'1-ring':>7} {'2nd':>6} {'EP/peak':>8}")
    for label, outer in (("strips beyond the 1-ring = their spoke's d_i", None), ("strips beyond the 1-ring = 1", 1.0),
                         ("strips beyond the 1-ring = 100", 100.0)):
        for scheme in SCHEMES:
            disk = _blending_disk(d, from_arrays) if outer is None else _disk(d, outer)
            mesh, ep = refined(d, scheme, disk=disk, with_ep=True)
            e, f, second = counts(mesh)
            z = mesh.vertices[:, 2]
            print(f"  {label:52} {scheme:>9} {e:>7} {f:>7} {second:>6.3f} {z[ep] / z.max():>8.4f}", flush=True)
    for scheme in ("standard", "modified"):
        row = []
        mesh = _blending_disk(d, from_arrays)
        for level in range(1, 8):
            _, mesh = subdivision_operator(mesh, rules=SCHEMES[scheme][0], angles=SCHEMES[scheme][1])
            if level >= 3:
                e, f, second = counts(mesh)
                row.append(f"{level}: {e}/{f} ({second:.3f})")
        print(f"  levels 3-7, {scheme:>9}: " + ", ".join(row), flush=True)


def random_table(samples: int) -> None:
    print(f"\n3. [ZTL]'s random test (intervals uniform in [1e-6, 1], the paper: 1e6 EPs, one maximum in all), "
          f"{samples} EPs per valence: share with one maximum after {LEVELS} steps, over the edge neighbours / the 1-ring; "
          f"median lambda_2 - lambda_3 of NURSS (0 for the others by construction)")
    print(f"  {'n':>3} " + " ".join(f"{s:>13}" for s in SCHEMES) + f" {'split NURSS':>12} {'s/EP':>6}")
    for n in (3, 5, 6, 7, 8):
        rng = np.random.default_rng(1000 * n + 17)
        single = {s: 0 for s in SCHEMES}
        single_ring = {s: 0 for s in SCHEMES}
        undefined = {s: 0 for s in SCHEMES}
        split = []
        t0 = time.perf_counter()
        for _ in range(samples):
            d = rng.uniform(1e-6, 1.0, n)
            for scheme in SCHEMES:
                try:
                    e, f, _ = counts(refined(d, scheme))
                    single[scheme] += e == 1
                    single_ring[scheme] += f == 1
                except UnsupportedError:
                    undefined[scheme] += 1
            ev = eigenvalues(d, "NURSS")
            split.append(ev[1] - ev[2])
        cells = " ".join(f"{single[s] / samples:>6.0%} /{single_ring[s] / samples:>5.0%}" + ("" if not undefined[s] else f"({undefined[s]}u)")
                         for s in SCHEMES)
        print(f"  {n:>3} {cells} {np.median(split):>12.2e} {(time.perf_counter() - t0) / (3 * samples):>6.2f}", flush=True)


def pictures(meshes: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    FIGURES.mkdir(parents=True, exist_ok=True)
    light = np.array([-0.4, -0.5, 0.77])
    for name, d in CONFIGS.items():
        fig = plt.figure(figsize=(13, 4.6), constrained_layout=True)
        for k, scheme in enumerate(SCHEMES):
            ax = fig.add_subplot(1, 3, k + 1, projection="3d")
            mesh = meshes.get((name, scheme))
            if mesh is None:
                ax.set_title(f"{scheme}: undefined")
                continue
            p = mesh.vertices.copy()
            quads = p[mesh.face_vertices.reshape(-1, 4)]
            quads = quads[np.linalg.norm(quads[:, :, :2].mean(axis=1), axis=1) < RADIUS]  # the EP's 2-ring
            width = 2.0 * RADIUS
            quads[:, :, 2] *= 0.5 * width / p[:, 2].max()
            p = quads.reshape(-1, 3)
            nrm = np.cross(quads[:, 2] - quads[:, 0], quads[:, 3] - quads[:, 1])
            nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
            colours = plt.cm.Greys_r(0.15 + 0.8 * np.abs(nrm @ light))
            ax.add_collection3d(Poly3DCollection(quads, facecolors=colours, edgecolors=colours, linewidths=0.1))
            lo, hi = p.min(0), p.max(0)
            ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(0, hi[2])
            ax.set_box_aspect((1, 1, 0.5), zoom=1.25)
            ax.view_init(elev=32, azim=-60)
            ax.set_axis_off()
            e, f, _ = counts(mesh)
            ax.set_title(f"{scheme}: {e} maxima ({f} over the 1-ring)", fontsize=9)
        fig.suptitle(f"[ZTL] {name}: valence {len(d)}, spoke intervals {', '.join(f'{x:g}' for x in d)} "
                     f"(EP's blending function after {LEVELS} steps)")
        path = FIGURES / f"ztl_{name.replace(' ', '').lower()}.png"
        fig.savefig(path, dpi=70)
        plt.close(fig)
        print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size / 1024:.0f} KB)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=30)
    ap.add_argument("--figures-only", action="store_true")
    args = ap.parse_args()
    meshes = figures_table()
    pictures(meshes)
    if args.figures_only:
        return
    fig7_readings()
    random_table(args.samples)


if __name__ == "__main__":
    main()
