"""Latency of a small build: ``nupatch build MESH`` as a whole process against OpenCASCADE's floor
for the same faces, also a whole process (Python, ``import numpy`` and OCP, the Bézier nets read
from an .npy file, one ``BRepBuilderAPI_MakeFace`` a patch into a compound, STEP written), the
two alternated in one run, nupatch with its on-disk cache of solved configurations (filled by a
warm-up round: an edit-build cycle's second build) and with ``--no-cache`` (a first build).  Optionally a second checkout (``--before DIR``, e.g. a worktree of
main) is timed in the same rotation, so that old and new meet the same machine load.

Each process's wall time and CPU time (user + system, from ``resource``'s children counters) are
printed; the CPU time is the steadier figure on a shared machine.  The children may write .pyc
files (the first round warms them), as an installed package has them.  Run by hand:
``.venv/bin/python benchmarks/small_build.py [--mesh models/l_bracket.obj] [--runs 5] [--before DIR]``.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

FLOOR = r"""
import sys
import numpy as np
from OCP.BRep import BRep_Builder
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
from OCP.Geom import Geom_BezierSurface
from OCP.gp import gp_Pnt
from OCP.TColgp import TColgp_Array2OfPnt
from OCP.TopoDS import TopoDS_Compound
from OCP.STEPControl import STEPControl_Writer, STEPControl_AsIs
from OCP.IFSelect import IFSelect_RetDone

nets = np.load(sys.argv[1], allow_pickle=True)
builder = BRep_Builder()
compound = TopoDS_Compound()
builder.MakeCompound(compound)
for net in nets:
    d = net.shape[0]
    poles = TColgp_Array2OfPnt(1, d, 1, d)
    for i in range(d):
        for j in range(d):
            poles.SetValue(i + 1, j + 1, gp_Pnt(*net[i, j]))
    builder.Add(compound, BRepBuilderAPI_MakeFace(Geom_BezierSurface(poles), 1e-7).Face())
writer = STEPControl_Writer()
writer.Transfer(compound, STEPControl_AsIs)
assert writer.Write(sys.argv[2]) == IFSelect_RetDone
"""


#: The floor with the same care about Python's cycle collector that ``nupatch build`` takes
#: (``export.cli._import_frozen``): collector off while OCP imports, the heap frozen after, so
#: neither OCP's import nor the interpreter's exit walks OCP's ~150,000 objects.  Printed beside
#: the plain floor (the acceptance's reference) to show what of nupatch's lead is that alone.
FLOOR_FROZEN = FLOOR.replace("import sys\n", "import gc, sys\ngc.disable()\n", 1).replace(
    "\nnets = np.load", "\ngc.freeze()\ngc.enable()\nnets = np.load", 1)


def timed_process(cmd: list[str], env: dict[str, str], cwd: str) -> tuple[float, float]:
    """(wall, user + system CPU) seconds of one child process, run in ``cwd`` (not a checkout:
    ``python -m`` puts the working directory first on sys.path, before PYTHONPATH)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL, cwd=cwd)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mesh", default=str(ROOT / "models" / "l_bracket.obj"))
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--before", help="a second checkout (e.g. main's worktree) timed in the same rotation")
    parser.add_argument("--extra", nargs="*", default=[], help="extra arguments of `nupatch build`")
    args = parser.parse_args()

    import patching

    surface = patching.build(patching.read_mesh(args.mesh))
    nets = np.empty(surface.n_patches, dtype=object)
    for k, (_, _, _, net) in enumerate(surface.patches()):
        nets[k] = np.asarray(net, dtype=float)
    # nupatch with its on-disk cache of solved configurations (filled by the warm-up round), and
    # without it (--no-cache: every local configuration solved, as in a first build)
    sides = {"floor": None, "floor-gc": None, "nupatch": str(ROOT), "no-cache": str(ROOT)}
    if args.before:
        sides["before"] = str(Path(args.before).resolve())
        sides["before no-cache"] = str(Path(args.before).resolve())  # its first build
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in sides}
    start_load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        np.save(tmp / "nets.npy", nets, allow_pickle=True)
        scripts = {"floor": tmp / "floor.py", "floor-gc": tmp / "floor_gc.py"}
        scripts["floor"].write_text(FLOOR)
        scripts["floor-gc"].write_text(FLOOR_FROZEN)
        for run in range(args.runs + 1):  # the first round warms the file cache and .pyc files
            for name, tree in sides.items():
                env = dict(os.environ)
                env.pop("PYTHONDONTWRITEBYTECODE", None)  # an installed package has its .pyc files
                if tree is None:
                    cmd = [sys.executable, str(scripts[name]), str(tmp / "nets.npy"), str(tmp / f"{name}.step")]
                else:
                    env["PYTHONPATH"] = tree
                    env["NUPATCH_CACHE_DIR"] = str(tmp / "cache")
                    flags = ["--no-cache"] if name.endswith("no-cache") else []
                    cmd = [sys.executable, "-m", "export.cli", "build", args.mesh, "-o", str(tmp / f"{name}.step"), "-q", *flags, *args.extra]
                t = timed_process(cmd, env, str(tmp))
                if run:
                    times[name].append(t)
    print(f"{Path(args.mesh).name}: {surface.n_patches} faces, {args.runs} runs alternated, median (min),"
          f" load {start_load:.1f} -> {os.getloadavg()[0]:.1f}")
    floor_wall = np.median([w for w, _ in times["floor"]])
    floor_cpu = np.median([c for _, c in times["floor"]])
    for name, rows in times.items():
        wall = np.array([w for w, _ in rows])
        cpu = np.array([c for _, c in rows])
        print(f"  {name:15s} wall {np.median(wall):6.2f} s ({wall.min():5.2f})  cpu {np.median(cpu):6.2f} s ({cpu.min():5.2f})"
              f"  ratio to floor: wall {np.median(wall) / floor_wall:4.2f}, cpu {np.median(cpu) / floor_cpu:4.2f}")


if __name__ == "__main__":
    main()
