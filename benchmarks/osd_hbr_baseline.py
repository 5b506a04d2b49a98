"""Loop positions against [OSD]'s ``regression/hbr_regression/baseline/loop_*_level{0..4}.obj``
(written by its old Hbr library, 9 significant digits, float32 arithmetic).  Run by hand; the
data is not part of nupatch:

    git -C OpenSubdiv archive HEAD regression | tar -x -C /tmp/osd
    PYTHONPATH=. python benchmarks/osd_hbr_baseline.py /tmp/osd/regression/hbr_regression/baseline \\
        [--shapes /tmp/osd/regression/shapes]

The input meshes and their tags are read from ``SHAPES/NAME.h`` ([OSD]'s C string of an OBJ
text) or ``SHAPES/NAME.obj`` (default: the ``shapes`` folder beside the baseline's parent);
without an ``interpolateboundary`` tag Hbr's default (edge only, 2) applies, and ``t
creasemethod ... chaikin`` selects Chaikin creasing, as ``regression/common/hbr_utils.h``
reads them.  File ``levelK`` holds the vertices and faces of refinement level K + 1 (the
baseline writes the vertices each refinement adds).  Hbr numbers vertices in its own order, so
each of our vertices is matched to the nearest baseline vertex; the match must be one to one
and carry our faces onto the baseline's (same orientation) before positions are compared.
Prints, per shape and level, the largest coordinate difference, absolute and relative to the
shape's size; 9 printed digits are a relative 5e-9, Hbr's float32 arithmetic a few 1e-8 a
level.

Measured (2026-12-01, OpenSubdiv 3.6.0's baseline): every loop_* shape and level agrees within
1.1e-7 of its size (float32), faces matching, except ``loop_chaikin1`` (Chaikin creasing) from
level 2 on (4e-3 to 8e-3 of its size at 4 vertices a level, the vertex points of vertices
where two semi-sharp halves of different sharpness, 1 and 0.25, both turn smooth in the same
step).

The cause (2026-12-04): Hbr's vertex rule is not Far's.  Hbr (``hbr/vertex.h`` ``GetMask``,
``GetFractionalMask``, ``hbr/loop.h`` ``Subdivide(vertex)``) blends the mask of the edges with
``s >= 1`` (weight ``1 - f``) with the mask of the edges with ``s > 0`` (weight ``f``), ``f`` the
mean of the sharpness values in (0, 1): a uniform-decay reading that ignores the child
sharpness Chaikin gives.  Far (``Sdc::Scheme::ComputeVertexVertexMask``,
``Crease::ComputeFractionalWeightAtVertex``) takes the parent rule (edges ``s > 0``), the child
rule from the Chaikin child halves, and the mean parent sharpness of the halves that turn
smooth.  At halves of 1 and 0.25 that both turn smooth: Far 0.625 of the crease mask, Hbr 0.25.
``--rules hbr`` re-runs the comparison with Hbr's vertex rule, edge rule (crease above
sharpness 1, else the s-blend) and Chaikin child sharpness (3/4 s plus 1/4 of the mean of all
other sharp edges, infinite ones included, minus 1) emulated here (``hbr_step``): loop_chaikin1
then agrees to 1.4e-7 (float32) at every level.  nupatch follows Far, which it equals
(``benchmarks/osd_far_reference.py``): Far is the library the issue names and OpenSubdiv's
current one, and OpenSubdiv's own Far-vs-Hbr test skips these shapes: ``regression/
far_regression/far_regression.cpp`` ``areVerticesCompatibleWithHbr`` lists "Chaikin creasing --
Hbr known to be incorrect" among the known incompatibilities (others within 1e-6).
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from patching.loop import loop_operator
from patching.loop.refine import LoopLevel
from patching.loop.rules import INFINITE, loop_beta
from patching.mesh import ControlMesh
from patching.mesh.obj import parse_obj


def hbr_step(mesh: ControlMesh, method: str) -> ControlMesh:
    """One Loop step with Hbr's rules (module docstring), plain loops (small shapes only); the
    child topology is nupatch's (``loop_operator``), its positions and crease tags Hbr's."""
    L = LoopLevel.of(mesh, method)
    t = L.topo
    nv, ne = t.n_vertices, t.n_edges
    es = np.where(np.isinf(L.es), INFINITE, L.es)
    vs = np.where(np.isinf(L.vs), INFINITE, L.vs)
    a, b = t.edges[:, 0], t.edges[:, 1]
    c, d = L.opposite
    P = mesh.vertices
    inc: list[list[int]] = [[] for _ in range(nv)]
    for e in range(ne):
        inc[a[e]].append(e)
        inc[b[e]].append(e)
    new = np.zeros((nv + ne, 3))
    for e in range(ne):  # hbr/loop.h Subdivide(edge): crease unless interior with s <= 1
        s = es[e]
        if t.edge_is_boundary[e] or s > 1.0:
            new[nv + e] = 0.5 * (P[a[e]] + P[b[e]])
        else:
            new[nv + e] = (0.375 + 0.125 * s) * (P[a[e]] + P[b[e]])
            new[nv + e] += 0.125 * (1.0 - s) * sum(P[x] for x in (c[e], d[e]) if x >= 0)
    for v in range(nv):  # hbr/loop.h Subdivide(vertex) with vertex.h GetMask / GetFractionalMask
        ss = es[inc[v]]
        others = [b[e] if a[e] == v else a[e] for e in inc[v]]
        masks = [3 if vs[v] >= 1 else min(3, int((ss >= 1).sum())), 3 if vs[v] > 0 else min(3, int((ss > 0).sum()))]
        if masks[0] != masks[1]:
            frac = ([vs[v]] if 0 < vs[v] < 1 else []) + [x for x in ss if 0 < x < 1]
            weights = [1.0 - float(np.mean(frac)), float(np.mean(frac))]
        else:
            masks, weights = masks[:1], [1.0]
        for i, (m, w) in enumerate(zip(masks, weights)):
            if m <= 1:
                beta = float(loop_beta(len(others)))
                new[v] += w * ((1 - len(others) * beta) * P[v] + beta * P[others].sum(axis=0))
            elif m == 2:
                sharp = (ss > 0) if i == 1 else (ss >= 1)  # AddCreaseEdgesWithWeight(next = i == 1)
                new[v] += w * (0.75 * P[v] + 0.125 * P[np.asarray(others)[sharp]].sum(axis=0))
            else:
                new[v] += w * P[v]
    _, child = loop_operator(mesh, method)
    creases = {}
    for e in range(ne):  # hbr/subdivision.h SubdivideCreaseWeight
        if es[e] <= 0 or (t.edge_is_boundary[e] and mesh.interpolate_boundary != 0):
            continue
        for v in (a[e], b[e]):
            if es[e] >= INFINITE:
                cs = INFINITE
            elif method == "chaikin":
                o = [es[x] for x in inc[v] if x != e and es[x] > 0]
                cs = (0.25 * float(np.mean(o)) if o else 0.0) + 0.75 * es[e] - 1.0
            else:
                cs = es[e] - 1.0
            if cs > 0:
                creases[(int(min(v, nv + e)), int(max(v, nv + e)))] = float(cs)
    return dataclasses.replace(child, vertices=new, creases=creases)


def shape_text(shapes: Path, name: str) -> str | None:
    obj = shapes / f"{name}.obj"
    if obj.is_file():
        return obj.read_text()
    h = shapes / f"{name}.h"
    if not h.is_file():
        return None
    lines = re.findall(r'^"(.*)"\s*;?\s*$', h.read_text(), flags=re.MULTILINE)
    return "".join(line.encode().decode("unicode_escape") for line in lines)


def _read_level(path: Path):
    v, f = [], []
    for line in path.read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            v.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            f.append([int(x.split("/")[0]) - 1 for x in parts[1:]])
    return np.array(v), f


def canonical_face(face) -> tuple:
    i = int(np.argmin(face))
    return tuple(face[i:]) + tuple(face[:i])


def compare(name: str, text: str, files: list[Path], rules: str = "nupatch") -> list[tuple]:
    """(level, n vertices, max abs diff, relative, faces match) per baseline file."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mesh = parse_obj(text, source=f"{name}.h", name=name)
    if not re.search(r"^t\s+interpolateboundary", text, flags=re.MULTILINE):
        mesh = dataclasses.replace(mesh, interpolate_boundary=2)
    method = "chaikin" if re.search(r"^t\s+creasemethod\s+\S+\s+chaikin", text, flags=re.MULTILINE) else "uniform"
    size = float(np.ptp(mesh.vertices, axis=0).max())
    rows = []
    cur = mesh
    for level, path in enumerate(files, start=1):
        cur = hbr_step(cur, method) if rules == "hbr" else loop_operator(cur, method)[1]
        bv, bf = _read_level(path)
        ours = cur.vertices
        if bv.shape != ours.shape:
            rows.append((level, ours.shape[0], float("nan"), float("nan"), f"{bv.shape[0]} baseline vertices"))
            continue
        _, idx = cKDTree(bv).query(ours)
        one_to_one = np.unique(idx).size == idx.size
        mine = sorted(canonical_face([int(idx[x]) for x in cur.face(i)]) for i in range(cur.n_faces))
        theirs = sorted(canonical_face(face) for face in bf)
        faces_ok = one_to_one and mine == theirs
        d = float(np.abs(ours - bv[idx]).max())
        rows.append((level, ours.shape[0], d, d / size, "yes" if faces_ok else "NO"))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("baseline", type=Path, help="the directory of the loop_*_levelK.obj files")
    ap.add_argument("--shapes", type=Path, help="the directory of the shapes (.h or .obj)")
    ap.add_argument("--rules", choices=("nupatch", "hbr"), default="nupatch", help="hbr: Hbr's rules emulated (hbr_step)")
    args = ap.parse_args(argv)
    shapes = args.shapes or args.baseline.resolve().parent.parent / "shapes"
    names = sorted({p.name.rsplit("_level", 1)[0] for p in args.baseline.glob("loop_*_level0.obj")})
    if not names:
        print(f"no loop_*_level0.obj in {args.baseline}", file=sys.stderr)
        return 2
    worst = 0.0
    print(f"{'shape':28s} {'level':>5s} {'vertices':>8s} {'max |diff|':>11s} {'relative':>10s}  faces match")
    for name in names:
        text = shape_text(shapes, name)
        if text is None:
            print(f"{name:28s} no shape source in {shapes}")
            continue
        files = sorted(args.baseline.glob(f"{name}_level*.obj"), key=lambda p: int(p.stem.rsplit("level", 1)[1]))
        for level, n, d, rel, ok in compare(name, text, files, args.rules):
            worst = worst if np.isnan(rel) else max(worst, rel)
            print(f"{name:28s} {level:5d} {n:8d} {d:11.3e} {rel:10.3e}  {ok}")
    print(f"largest relative difference: {worst:.3e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
