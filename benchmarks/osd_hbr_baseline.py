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
step).  Hbr's Chaikin code (``hbr/subdivision.h``) is not Sdc's (``sdc/crease.cpp``), which
nupatch follows and which tests/reference_loop.py re-implements; replacing nupatch's child
sharpness by Hbr's rule does not remove the difference, so it lies in how Hbr blends such a
vertex, not investigated further.
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
from patching.mesh.obj import parse_obj


def _shape_text(shapes: Path, name: str) -> str | None:
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


def _canonical(face) -> tuple:
    i = int(np.argmin(face))
    return tuple(face[i:]) + tuple(face[:i])


def compare(name: str, text: str, files: list[Path]) -> list[tuple]:
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
        _, cur = loop_operator(cur, method)
        bv, bf = _read_level(path)
        ours = cur.vertices
        if bv.shape != ours.shape:
            rows.append((level, ours.shape[0], float("nan"), float("nan"), f"{bv.shape[0]} baseline vertices"))
            continue
        _, idx = cKDTree(bv).query(ours)
        one_to_one = np.unique(idx).size == idx.size
        mine = sorted(_canonical([int(idx[x]) for x in cur.face(i)]) for i in range(cur.n_faces))
        theirs = sorted(_canonical(face) for face in bf)
        faces_ok = one_to_one and mine == theirs
        d = float(np.abs(ours - bv[idx]).max())
        rows.append((level, ours.shape[0], d, d / size, "yes" if faces_ok else "NO"))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("baseline", type=Path, help="the directory of the loop_*_levelK.obj files")
    ap.add_argument("--shapes", type=Path, help="the directory of the shapes (.h or .obj)")
    args = ap.parse_args(argv)
    shapes = args.shapes or args.baseline.resolve().parent.parent / "shapes"
    names = sorted({p.name.rsplit("_level", 1)[0] for p in args.baseline.glob("loop_*_level0.obj")})
    if not names:
        print(f"no loop_*_level0.obj in {args.baseline}", file=sys.stderr)
        return 2
    worst = 0.0
    print(f"{'shape':28s} {'level':>5s} {'vertices':>8s} {'max |diff|':>11s} {'relative':>10s}  faces match")
    for name in names:
        text = _shape_text(shapes, name)
        if text is None:
            print(f"{name:28s} no shape source in {shapes}")
            continue
        files = sorted(args.baseline.glob(f"{name}_level*.obj"), key=lambda p: int(p.stem.rsplit("level", 1)[1]))
        for level, n, d, rel, ok in compare(name, text, files):
            worst = worst if np.isnan(rel) else max(worst, rel)
            print(f"{name:28s} {level:5d} {n:8d} {d:11.3e} {rel:10.3e}  {ok}")
    print(f"largest relative difference: {worst:.3e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
