"""Build benchmark (issue 3): a 100 x 100 torus grid (10k faces) with non-uniform intervals.

Prints the time to build M, to evaluate M @ P, to make the B-rep, to write the STEP, the
end-to-end ``nupatch build`` (a fresh process, as a user runs it), and the OpenCASCADE floor:
the same number of bicubic Bézier faces made directly with OCC (no shared topology) and
written to STEP, in the same run.  Run by hand: ``.venv/bin/python benchmarks/build.py [m n]``.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import patching  # noqa: E402
from export.brep import to_shape  # noqa: E402
from export.step import write_step  # noqa: E402
from patching.obj import write_obj  # noqa: E402
from patching.primitives import torus_grid  # noqa: E402


def timed(fn, *args):
    start = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - start


def occ_floor(nets: np.ndarray, path: Path) -> tuple[float, float]:
    """Faces straight from OCC: Geom_BezierSurface -> BRepBuilderAPI_MakeFace -> compound -> STEP."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.Geom import Geom_BezierSurface
    from OCP.gp import gp_Pnt
    from OCP.TColgp import TColgp_Array2OfPnt
    from OCP.TopoDS import TopoDS_Compound

    start = time.perf_counter()
    builder = BRep_Builder()
    compound = TopoDS_Compound()
    builder.MakeCompound(compound)
    for net in nets:
        poles = TColgp_Array2OfPnt(1, 4, 1, 4)
        for i in range(4):
            for j in range(4):
                poles.SetValue(i + 1, j + 1, gp_Pnt(*net[i, j]))
        face = BRepBuilderAPI_MakeFace(Geom_BezierSurface(poles), 1e-7).Face()
        builder.Add(compound, face)
    made = time.perf_counter() - start
    _, wrote = timed(write_step, compound, path, "floor")
    return made, wrote


def main() -> None:
    m, n = (int(a) for a in sys.argv[1:3]) if len(sys.argv) >= 3 else (100, 100)
    rng = np.random.default_rng(0)
    mesh = torus_grid(m, n, rng.uniform(1, 20, m), rng.uniform(1, 20, n), name="bench_torus")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        obj = tmp / "bench_torus.obj"
        write_obj(mesh, obj)
        op, t_m = timed(patching.build_operator, mesh)
        surface, t_eval = timed(op.evaluate, mesh.vertices)
        shape, t_brep = timed(to_shape, surface)
        _, t_step = timed(write_step, shape, tmp / "ours.step", mesh.name)
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "export.cli", "build", str(obj), "-o", str(tmp / "cli.step"), "-q"], check=True)
        t_cli = time.perf_counter() - start
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import export.brep, export.step, patching"], check=True)
        t_imports = time.perf_counter() - start
        made, wrote = occ_floor(surface.groups[0].coefficients, tmp / "floor.step")
        size_ours = (tmp / "ours.step").stat().st_size
        size_floor = (tmp / "floor.step").stat().st_size
    faces = mesh.n_faces
    floor = made + wrote
    rows = [
        ("build M", t_m, f"{faces / t_m:,.0f} faces/s"),
        ("M @ P (evaluate)", t_eval, f"{faces / t_eval:,.0f} faces/s"),
        ("B-rep (shared topology)", t_brep, ""),
        ("write STEP", t_step, f"{size_ours / 1e6:.1f} MB"),
        ("in-process total", t_m + t_eval + t_brep + t_step, ""),
        ("nupatch build (fresh process)", t_cli, f"of which imports {t_imports:.2f} s"),
        ("OCC floor: make faces", made, ""),
        ("OCC floor: write STEP", wrote, f"{size_floor / 1e6:.1f} MB"),
        ("OCC floor total", floor, ""),
    ]
    print(f"torus {m} x {n} = {faces} faces")
    for name, t, note in rows:
        print(f"  {name:32s} {t:8.3f} s  {note}")
    print(f"  ratio in-process / floor      {(t_m + t_eval + t_brep + t_step) / floor:8.2f}")
    print(f"  ratio end-to-end / floor      {t_cli / floor:8.2f}  (target <= 1.5)")
    print(f"  ratio end-to-end - imports / floor {(t_cli - t_imports) / floor:8.2f}")


if __name__ == "__main__":
    main()
