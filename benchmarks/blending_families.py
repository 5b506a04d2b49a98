"""The EP's own blending function over four mesh families: the share with a single local
maximum, by interval ratio, for each anchor rule and for the red G1 solve's variants: shipped
(monotone spoke curves, ``patching.extraordinary.g1_patches.MONOTONE_SPOKES``), ``plain`` (the
least change alone, as before 4 December 2026) and ``weighted`` (``Q_WEIGHT = 10``, not shipped).

    .venv/bin/python benchmarks/blending_families.py [--draws 8] [--samples 65] [--seed 0]
                                                     [--ratios 2,5,10,20] [--modes shipped,plain]

Families (every strip of the mesh gets an interval drawn uniformly from [1, R], no jitter;
``tests.helpers.with_random_intervals``):

- ``prism``: the n-gonal prism (n = 5, 6) refined by one Catmull-Clark step: the two cap
  centres are EPs of valence n, two faces from the valence-3 cap corners (the family of the
  reported defect; ``benchmarks/blending_prisms.py``).
- ``polycube``: the L-shaped tricube and the cube, each cube face divided 2 x 2
  (``patching.mesh.primitives.polycube``): EPs of valence 3 and 5 two faces apart.
- ``disc``: ``tests.helpers.ep_disc``, one EP of valence n = 3, 5, 6, 7 with three rings,
  every strip random (the family of ``benchmarks/blending.py``).
- ``offcentre``: discs whose EP sits off-centre: per spoke 2 or 3 rings (at least one of each),
  so the clamped boundary is two faces from the EP on some sides and three on others.

A configuration is one EP of one interval draw: its blending function is sampled on
``samples`` x ``samples`` grids per patch over its whole support (65: 8 samples between the
EP and the spot one eighth of a face out where the reported second hill stood), the grids
joined through the patch topology (``patching.evaluation.sampling.sample_graph``).  A discrete
maximum other than the highest counts if Newton's method on a patch polynomial confirms it
(``_confirmed_maxima_nodes``) or, for one on a seam (a spoke or a patch corner, where no single
patch polynomial has a critical point), if it is strictly higher than every sample within three
grid steps through the joined graph (a ridge crossing the grid obliquely fails this).
Columns: configurations, share with one maximum, share whose other maxima all stand below 1%
of the peak ("<1%": ripples in a tail, invisible in a picture), the worst second maximum over
the peak, seconds per draw.
"""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import scipy.sparse as sp

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import patching  # noqa: E402
from patching.evaluation.sampling import (  # noqa: E402
    _confirmed_maxima_nodes,
    _maxima_nodes,
    _touched_rows,
    column_values,
    node_values,
    sample_graph,
)
from patching.extraordinary import g1_patches  # noqa: E402
from patching.mesh.primitives import polycube  # noqa: E402
from patching.subdivision import subdivide  # noqa: E402
from patching.topology.tables import Topology  # noqa: E402
from tests.helpers import ep_disc, prism, with_random_intervals  # noqa: E402


#: Other maxima below this fraction of the peak are counted apart (column "<1%").
VISIBLE = 0.01
#: name -> (BuildOptions fields, overrides of ``g1_patches`` module settings: the red solve's
#: stage-2 weight of q, the monotone spoke curves)
MODES = {
    "shipped": ({}, {}),
    "plain": ({}, {"MONOTONE_SPOKES": False}),
    "weighted": ({}, {"Q_WEIGHT": 10.0, "MONOTONE_SPOKES": False}),
    "extraction": ({"anchors": "extraction"}, {}),
    "faired": ({"anchors": "faired"}, {}),
    "modified": ({"eigen_angles": "modified"}, {}),
    "limit-fit": ({"anchors": "limit-fit"}, {}),
}


@contextmanager
def stage_settings(overrides: dict):
    """Build with other ``g1_patches`` settings ({}: the shipped ones)."""
    old = {name: getattr(g1_patches, name) for name in overrides}
    for name, value in overrides.items():
        setattr(g1_patches, name, value)
    try:
        yield
    finally:
        for name, value in old.items():
            setattr(g1_patches, name, value)


def off_centre_disc(n: int, rings: np.ndarray, intervals: np.ndarray) -> patching.ControlMesh:
    """ep_disc with 3 rings, the strips beyond ``rings[i]`` on spoke i set to interval 0 (the
    clamped boundary moved in): the EP is off-centre in the part of nonzero area."""
    d = intervals.copy()
    for i, r in enumerate(rings.tolist()):
        d[i, r:] = 0.0
    return ep_disc(n, d)


def draws(family: str, ratio: float, count: int, seed: int):
    """(mesh, EP vertices) per draw of a family."""
    rng = np.random.default_rng([seed, int(ratio * 10), sum(map(ord, family))])
    for c in range(count):
        s = int(rng.integers(1 << 31))
        if family == "prism":
            n = (5, 6)[c % 2]
            yield with_random_intervals(subdivide(prism(n), 1), ratio, seed=s), np.array([0, 1])
        elif family == "polycube":
            voxels = [(0, 0, 0), (1, 0, 0), (0, 1, 0)] if c % 2 else [(0, 0, 0)]
            mesh = with_random_intervals(polycube(voxels, 2), ratio, seed=s)
            yield mesh, Topology(mesh).extraordinary
        elif family == "disc":
            n = (3, 5, 6, 7)[c % 4]
            yield ep_disc(n, np.random.default_rng(s).uniform(1.0, ratio, (n, 3))), np.array([0])
        elif family == "offcentre":
            n = (3, 5, 6, 7)[c % 4]
            r = np.random.default_rng(s)
            rings = r.integers(2, 4, n)
            rings[r.integers(n)] = 2
            rings[(int(np.flatnonzero(rings == 2)[0]) + 1 + r.integers(n - 1)) % n] = 3
            yield off_centre_disc(n, rings, r.uniform(1.0, ratio, (n, 3))), np.array([0])
        else:
            raise ValueError(family)


def _seam_maximum(graph, adjacency, values: np.ndarray, node: int, steps: int = 3) -> bool:
    """Is ``node`` strictly higher than every node within ``steps`` graph steps?"""
    seen = {node}
    front = [node]
    for _ in range(steps):
        front = [int(j) for i in front for j in adjacency[i].indices if j not in seen]
        seen.update(front)
    others = np.array(sorted(seen - {node}))
    return bool(others.size and values[node] > values[others].max())


def ep_maxima(op, v: int, samples: int) -> np.ndarray:
    """Heights of the local maxima of control point v's blending function, highest first."""
    rows = _touched_rows(op, np.array([v]))
    graph = sample_graph(op, rows, samples)
    values = node_values(graph, column_values(op, [v], rows, samples))[0][:, 0]
    nodes, heights = _maxima_nodes(values, graph.pairs, 1e-10, graph.neighbour_table)
    if nodes.size <= 1:
        return heights
    confirmed = set(_confirmed_maxima_nodes(op, graph, v, values)[0].tolist())
    shared = np.bincount(graph.node.ravel(), minlength=graph.n_nodes) > 1
    adjacency = sp.coo_matrix((np.ones(len(graph.pairs)), graph.pairs.T), shape=(graph.n_nodes,) * 2).tocsr()
    adjacency = (adjacency + adjacency.T).tocsr()
    keep = [0] + [
        k for k in range(1, nodes.size)
        if int(nodes[k]) in confirmed or (shared[nodes[k]] and _seam_maximum(graph, adjacency, values, int(nodes[k])))
    ]
    return heights[keep]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=8, help="interval draws per family and ratio")
    ap.add_argument("--samples", type=int, default=65)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--ratios", default="2,5,10,20")
    ap.add_argument("--families", default="prism,polycube,disc,offcentre")
    ap.add_argument("--modes", default="shipped,plain")
    args = ap.parse_args()
    ratios = [float(r) for r in args.ratios.split(",")]
    families = args.families.split(",")
    modes = args.modes.split(",")
    print(f"{args.draws} draws per family and ratio, {args.samples} x {args.samples} samples per patch, seed {args.seed}")
    head = f"{'family':>9} {'ratio':>5} {'mode':>10} {'configs':>7} {'one max':>7} {'<1%':>6} {'worst 2nd':>9} {'s/draw':>6}"
    print(head)
    print("-" * len(head))
    total = {m: [0, 0] for m in modes}
    by_ratio = {(m, r): [0, 0] for m in modes for r in ratios}
    bad = []
    for family in families:
        for ratio in ratios:
            stats = {m: [0, 0, 0.0, 0.0, 0] for m in modes}
            for c, (mesh, eps) in enumerate(draws(family, ratio, args.draws, args.seed)):
                topo = Topology(mesh)
                for mode in modes:
                    fields, overrides = MODES[mode]
                    t0 = time.perf_counter()
                    with stage_settings(overrides):
                        op = patching.build_operator(mesh, topology=topo, **fields)
                    for v in eps.tolist():
                        h = ep_maxima(op, int(v), args.samples)
                        s = stats[mode]
                        s[0] += 1
                        s[1] += h.size == 1
                        s[4] += h.size == 1 or h[1] < VISIBLE * h[0]
                        if h.size > 1:
                            s[2] = max(s[2], float(h[1] / h[0]))
                            bad.append((family, ratio, c, mode, int(v), int(topo.valence[v]), h.size, round(float(h[1] / h[0]), 4)))
                    stats[mode][3] += time.perf_counter() - t0
            for mode in modes:
                n_, one, worst, t, visible = stats[mode]
                total[mode][0] += n_
                total[mode][1] += one
                for r in ratios:
                    if r >= ratio:
                        by_ratio[(mode, r)][0] += n_
                        by_ratio[(mode, r)][1] += one
                print(f"{family:>9} {ratio:>5.0f} {mode:>10} {n_:>7} {one / n_:>7.1%} {visible / n_:>6.1%} {worst:>9.4f} {t / args.draws:>6.2f}", flush=True)
    print("\nall families, ratio <= R:")
    for r in ratios:
        print("  R = %4.0f  " % r + "  ".join(f"{m}: {by_ratio[(m, r)][1]}/{by_ratio[(m, r)][0]} = {by_ratio[(m, r)][1] / max(by_ratio[(m, r)][0], 1):.1%}" for m in modes))
    if bad:
        print("\nfunctions with more than one maximum (family, ratio, draw, mode, EP, valence, maxima, 2nd/peak):")
        for item in bad:
            print("  ", item)


if __name__ == "__main__":
    main()
