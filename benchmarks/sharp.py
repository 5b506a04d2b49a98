"""Speed of sharp features through EPs (issue 4): the machined bracket (models/) refined by
the seed's sharp subdivision rules, so that it keeps its creases, corners and darts at every
scale, with the sector EPs of seed 002 section 4.2 at its concave corners.

    .venv/bin/python benchmarks/sharp.py [--steps 3]

Prints the same rows as ``benchmarks/build.py`` (whose timing helpers it uses): building M
(cold and warm), M @ P, the B-rep, `nupatch build` in a fresh process, and the OpenCASCADE
floor for the same patches.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import patching  # noqa: E402
from benchmarks.build import occ_floor, timed  # noqa: E402
from export import to_shape, write_step  # noqa: E402
from patching.features import features  # noqa: E402
from patching.obj import write_obj  # noqa: E402
from patching.subdivision import subdivide  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3)
    args = parser.parse_args()
    mesh = subdivide(patching.read_mesh(ROOT / "models" / "machined_bracket.obj"), args.steps, rules="seed")
    topo = patching.Topology(mesh)
    feats = features(topo)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        obj = tmp / "sharp.obj"
        write_obj(mesh, obj)
        _, t_cold = timed(patching.build_operator, mesh)
        op, t_m = timed(patching.build_operator, mesh)
        surface = op.evaluate(mesh.vertices)
        reps = 10
        start = time.perf_counter()
        for _ in range(reps):
            op.coefficients(mesh.vertices)
        t_prod = (time.perf_counter() - start) / reps
        shape, t_brep = timed(to_shape, surface)
        _, t_step = timed(write_step, shape, tmp / "ours.step", "sharp")
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "export.cli", "build", str(obj), "-o", str(tmp / "cli.step"), "-q"], check=True, cwd=ROOT)
        t_cli = time.perf_counter() - start
        made, wrote = occ_floor([net for _, _, _, net in surface.patches()], tmp / "floor.step")
    faces = mesh.n_faces
    print(
        f"machined bracket, {args.steps} steps: {faces} faces ({', '.join(f'{len(g.faces)} of degree {g.degree}' for g in surface.groups)}), "
        f"{int(feats.sharp.sum())} sharp edges, {int(feats.corner.sum())} corners, {int(feats.dart.sum())} darts, "
        f"{int(feats.sector_vertex.sum())} sector EPs"
    )
    for name, t, note in (
        ("build M, first (cold caches)", t_cold, f"{faces / t_cold:,.0f} faces/s"),
        ("build M, again", t_m, f"{faces / t_m:,.0f} faces/s"),
        ("M @ P", t_prod, f"{faces / t_prod:,.0f} faces/s, nnz/face {op.matrix.nnz / faces:.0f}"),
        ("B-rep (shared topology)", t_brep, ""),
        ("write STEP", t_step, ""),
        ("nupatch build (fresh process)", t_cli, ""),
        ("OCC floor total", made + wrote, ""),
    ):
        print(f"  {name:32s} {t:8.3f} s  {note}")
    print(f"  ratio end-to-end / floor         {t_cli / (made + wrote):8.2f}  (target <= 1.5)")
    # Semi-sharp: the bracket's creases at sharpness 3 cost ceil(3) steps before patching;
    # the issue asks for no more than building the pre-subdivided mesh.
    base = patching.read_mesh(ROOT / "models" / "machined_bracket.obj")
    semi = patching.from_arrays(
        base.vertices, [list(base.face(f)) for f in range(base.n_faces)], intervals=dict(base.intervals),
        creases={e: 3.0 for e in base.creases}, name="semi",
    )
    patching.build_operator(semi)  # warm the caches of both
    _, t_semi = timed(patching.build_operator, semi)
    pre, t_sub = timed(subdivide, semi, 3, "seed")
    patching.build_operator(pre)
    _, t_pre = timed(patching.build_operator, pre)
    print(f"semi-sharp 3 on the bracket's creases: build M {t_semi:.3f} s; pre-subdivided 3 times "
          f"({pre.n_faces} faces): subdivide {t_sub:.3f} s + build M {t_pre:.3f} s; ratio {t_semi / (t_sub + t_pre):.2f}")


if __name__ == "__main__":
    main()
