"""Loop positions against OpenSubdiv's Far itself ([OSD] ``sdc/``, ``vtr/``, ``far/``, the
library nupatch follows, not the legacy Hbr of ``osd_hbr_baseline.py``), compiled here from an
OpenSubdiv source tree with the C++ driver ``benchmarks/osd_far_dump.cpp``.  Run by hand (needs
g++; the OpenSubdiv sources are not part of nupatch):

    git -C OpenSubdiv archive HEAD opensubdiv regression | tar -x -C /tmp/osd
    PYTHONPATH=. nice python benchmarks/osd_far_reference.py /tmp/osd [--levels 4] [--float32-weights]

The driver parses each ``regression/shapes/loop_*.h`` with OpenSubdiv's own regression parser
(``regression/common/shape_utils.cpp``; its tags, ``creasemethod`` and ``interpolateboundary``
as ``far_utils.h`` maps them) and refines the positions with ``Far::PrimvarRefinerReal<double>``.
That parser stores positions and sharpness as float32, so nupatch is given the same
float32-rounded positions and tags; Far's sharpness arithmetic stays float32 (``Sdc::Crease``
works in ``float``), which leaves differences of ~1e-9 where a fractional weight is not a
float32 number (a corner whose three halves of 0.9921875, 0.9921875 and 0.015625 turn smooth:
2/3).  ``--float32-weights`` rounds nupatch's fractional vertex weights to float32 as Far does,
to show that nothing else differs.  Our vertices are matched to Far's by nearest neighbour (Far
numbers them its own way); the match must be one to one and carry our faces onto Far's.

Measured 2026-12-04 (OpenSubdiv 3.6.0, commit 7d0ab55, levels 1-4; load average 6 on 2
cores): 27 loop_* shapes (4 non-manifold ones nupatch refuses), 108 shape-levels, faces
matching everywhere; all agree to <= 2.2e-14 (loop_pole360's 360-term masks) except
loop_chaikin1 at level 4, 6.5e-10 at 4 vertices (the 2/3 weight above); with
``--float32-weights`` that is 5.6e-17, so nupatch's Chaikin creasing -- including the vertices
where halves of sharpness 1 and 0.25 turn smooth in the same step, where the Hbr baseline
differs by 8e-3 (``osd_hbr_baseline.py`` says why) -- is Far's.  Without the float32 rounding of
the input, loop_cube_creases0/1 and loop_fvar_bound2 (sharpness 0.1, 0.2) differ by up to 7e-9.

``--scheme catmark --levels 3`` compares the catmark_* shapes with nupatch's Catmull-Clark
(``patching.subdivision``, ``--rules opensubdiv``, uniform or Chaikin creasing; the file's
``t smoothtriangles 0/0/1 smooth`` tag, Far's ``TRI_SUB_SMOOTH``, is read by nupatch's OBJ
reader as ``ControlMesh.triangle_subdivision``).  Measured 2026-12-04: 78 shapes (9
non-manifold ones refused), 234 shape-levels, all <= 2.4e-14 of their size (catmark_pole360's
360-term masks; all others <= 5.4e-15, catmark_chaikin0/1/2 exactly), catmark_smoothtris1
(``TRI_SUB_SMOOTH``) included: 2.2e-16 (7e-2 before nupatch had the rule);
catmark_val2_back2back and catmark_val2_foldover agree in positions (2e-16) but their
coincident vertices defeat the nearest-neighbour face check ("NO").
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

import patching.loop.refine as loop_refine
from patching.errors import NupatchError
from patching.loop import loop_operator
from patching.mesh.obj import parse_obj
from patching.subdivision import subdivision_operator

sys.path.insert(0, str(Path(__file__).resolve().parent))
from osd_hbr_baseline import canonical_face, shape_text

HERE = Path(__file__).resolve().parent


def build_driver(osd: Path, out: Path) -> Path:
    """Compile osd_far_dump.cpp with Sdc, Vtr, the Far refiner and the regression parser."""
    lib = osd / "opensubdiv"
    common = osd / "regression" / "common"
    sources = sorted((lib / "sdc").glob("*.cpp")) + sorted((lib / "vtr").glob("*.cpp"))
    sources += [lib / "far" / f"{n}.cpp" for n in ("topologyRefiner", "topologyRefinerFactory", "topologyDescriptor", "error")]
    sources += [common / "shape_utils.cpp", common / "far_utils.cpp", HERE / "osd_far_dump.cpp"]
    include = out / "include"
    include.mkdir(parents=True, exist_ok=True)
    link = include / "opensubdiv"
    if not link.exists():
        link.symlink_to(lib.resolve())
    exe = out / "osd_far_dump"
    cmd = ["g++", "-O1", "-std=c++14", f"-I{include}", f"-I{common}", "-o", str(exe), *map(str, sources)]
    subprocess.run(cmd, check=True)
    return exe


def far_levels(exe: Path, obj: Path, levels: int, scheme: str = "loop") -> list[tuple[np.ndarray, list]]:
    out = subprocess.run([str(exe), str(obj), str(levels), scheme], capture_output=True, text=True, check=True).stdout
    result: list[tuple[list, list]] = []
    for line in out.splitlines():
        p = line.split()
        if p[0] == "level":
            result.append(([], []))
        elif p[0] == "v":
            result[-1][0].append([float(x) for x in p[1:]])
        elif p[0] == "f":
            result[-1][1].append([int(x) for x in p[1:]])
    return [(np.array(v), f) for v, f in result]


def float32_fractional_weight(parent_vs, child_vs, transition_sum, transition_count):
    """rules.fractional_weight with Far's float32 mean (``transitionSum / (float)count``)."""
    turn = (np.asarray(parent_vs) > 0) & (np.asarray(child_vs) <= 0)
    s = (np.asarray(transition_sum) + np.where(turn, parent_vs, 0.0)).astype(np.float32)
    c = (np.asarray(transition_count) + turn).astype(np.float32)
    w = np.where(c > 0, s / np.maximum(c, np.float32(1)), np.float32(0)).astype(np.float32)
    return np.minimum(w.astype(np.float64), 1.0)


def compare(exe: Path, name: str, text: str, levels: int, work: Path, scheme: str = "loop") -> list[tuple]:
    obj = work / f"{name}.obj"
    obj.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mesh = parse_obj(text, source=obj.name, name=name)
    if not re.search(r"^t\s+interpolateboundary", text, flags=re.MULTILINE):
        mesh = dataclasses.replace(mesh, interpolate_boundary=2)  # far_utils.h's default: edge only
    method = "chaikin" if re.search(r"^t\s+creasemethod\s+\S+\s+chaikin", text, flags=re.MULTILINE) else "uniform"

    def f32(tags: dict) -> dict:
        return {k: float(np.float32(v)) for k, v in tags.items()}

    mesh = dataclasses.replace(
        mesh, vertices=mesh.vertices.astype(np.float32).astype(np.float64), creases=f32(mesh.creases), corners=f32(mesh.corners)
    )
    size = float(np.ptp(mesh.vertices, axis=0).max())
    far = far_levels(exe, obj, levels, scheme)
    rows, cur = [], mesh
    for level in range(1, levels + 1):
        if scheme == "loop":
            _, cur = loop_operator(cur, method)
        else:
            _, cur = subdivision_operator(cur, rules="opensubdiv", crease_method=method)
        fv, ff = far[level]
        ours = cur.vertices
        if fv.shape != ours.shape:
            rows.append((method, level, ours.shape[0], float("nan"), float("nan"), 0, f"{fv.shape[0]} Far vertices"))
            continue
        _, idx = cKDTree(fv).query(ours)
        one_to_one = np.unique(idx).size == idx.size
        mine = sorted(canonical_face([int(idx[x]) for x in cur.face(i)]) for i in range(cur.n_faces))
        faces_ok = one_to_one and mine == sorted(canonical_face(f) for f in ff)
        d = np.abs(ours - fv[idx]).max(axis=1)
        rows.append((method, level, ours.shape[0], float(d.max()), float(d.max()) / size, int((d > 1e-12).sum()), "yes" if faces_ok else "NO"))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("osd", type=Path, help="an OpenSubdiv source tree (opensubdiv/ and regression/)")
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--scheme", choices=("loop", "catmark"), default="loop",
                    help="catmark: the catmark_* shapes against nupatch's Catmull-Clark (--rules opensubdiv)")
    ap.add_argument("--float32-weights", action="store_true", help="round nupatch's fractional weights to float32 as Far does")
    ap.add_argument("--build", type=Path, help="where to compile the driver (default: a temporary folder)")
    args = ap.parse_args(argv)
    if args.float32_weights:
        loop_refine.fractional_weight = float32_fractional_weight
    shapes = sorted((args.osd / "regression" / "shapes").glob(f"{args.scheme}_*.h"))
    if not shapes:
        print(f"no regression/shapes/{args.scheme}_*.h under {args.osd}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        work = args.build or Path(tmp)
        exe = build_driver(args.osd, work)
        print(f"{'shape':26s} {'method':8s} {'level':>5s} {'vertices':>8s} {'max |diff|':>11s} {'relative':>10s} {'> 1e-12':>7s}  faces")
        relative = []
        for h in shapes:
            try:
                rows = compare(exe, h.stem, shape_text(h.parent, h.stem), args.levels, work, args.scheme)
            except NupatchError as exc:
                print(f"{h.stem:26s} refused by nupatch: {str(exc).splitlines()[0][:70]}")
                continue
            relative += [r[4] for r in rows if not np.isnan(r[4])]
            print("\n".join(f"{h.stem:26s} {m:8s} {lv:5d} {n:8d} {d:11.3e} {rel:10.3e} {bad:7d}  {ok}" for m, lv, n, d, rel, bad, ok in rows))
        print(f"largest relative difference: {max(relative, default=0.0):.3e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
