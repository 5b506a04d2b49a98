"""Every ``catmark_*`` shape of the OpenSubdiv shapes folder built to STEP by ``nupatch build``
as a whole process: control-mesh faces, patches, B-rep faces (one a patch, or fewer where packed), seconds (wall and CPU) and megabytes, one row a shape,
against the targets (<= 30 s each; no STEP of a mesh under 1,000 faces above 5 MB).  With
``--before DIR`` a second checkout builds each shape right after, in the same run.  A shape that
takes longer than ``--timeout`` seconds is stopped and reported as such.  Run by hand:
``.venv/bin/python benchmarks/catmark_shapes.py [--timeout 120] [--before DIR] [--read] [NAME ...]``.
With ``--read`` each STEP file is read back by OpenCASCADE's ``STEPControl_Reader`` (through
``export.step.read_step``, in a process of its own): the seconds of the read alone.
With ``--moved`` each side also builds, right after, a copy of the shape whose control points
moved (by up to 1% of its size, tags and intervals kept): the next build of an edit cycle,
which takes the operator from ``export.operator_cache`` (rows "now moved", "before moved").
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SHAPES = ROOT.parent / "shared" / "opensubdiv-shapes"


def build(tree: str, mesh: Path, out: Path, timeout: float) -> tuple[str, float, float, int]:
    """(status, wall, cpu, patches) of ``nupatch build mesh -o out`` run from ``tree``."""
    env = dict(os.environ, PYTHONPATH=tree)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "export.cli", "build", str(mesh), "-o", str(out)],
                              env=env, capture_output=True, text=True, timeout=timeout, cwd=out.parent)  # not a checkout: -m puts cwd first on sys.path
        status = "ok" if proc.returncode == 0 else (proc.stderr.strip().splitlines() or ["failed"])[-1][:60]
        found = re.search(r"nupatch: (\d+) patches from", proc.stderr)
        patches = int(found.group(1)) if found else 0
    except subprocess.TimeoutExpired:
        status, patches = f"> {timeout:g} s", 0
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return status, wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), patches


READ = """
import sys, time
from export.step import read_step
start, cpu = time.perf_counter(), time.process_time()
read_step(sys.argv[1])
print(f"{time.perf_counter() - start:.2f} {time.process_time() - cpu:.2f}")
"""


def read_back(tree: str, path: Path, timeout: float) -> str:
    """'wall cpu' seconds of reading ``path`` back with ``export.step.read_step`` from ``tree``."""
    env = dict(os.environ, PYTHONPATH=tree)
    try:
        proc = subprocess.run([sys.executable, "-c", READ, str(path)], env=env, capture_output=True, text=True,
                              timeout=timeout, cwd=path.parent)
    except subprocess.TimeoutExpired:
        return f"> {timeout:g} s"
    return proc.stdout.strip() if proc.returncode == 0 else (proc.stderr.strip().splitlines() or ["failed"])[-1][:40]


def _moved(mesh):
    """The mesh with its control points moved by up to 1% of its bounding box's diagonal."""
    import dataclasses

    import numpy as np

    rng = np.random.default_rng(0)
    size = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    return dataclasses.replace(mesh, vertices=mesh.vertices + rng.uniform(-0.01, 0.01, mesh.vertices.shape) * size / np.sqrt(3))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("names", nargs="*", help="shape names (default: every catmark_*)")
    parser.add_argument("--timeout", type=float, default=120.0)
    parser.add_argument("--before", help="a second checkout (e.g. main's worktree)")
    parser.add_argument("--read", action="store_true", help="time reading each STEP file back")
    parser.add_argument("--moved", action="store_true", help="also build each shape again with moved control points")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    import patching
    from export import write_obj

    paths = [SHAPES / f"{n}.obj" for n in args.names] if args.names else sorted(SHAPES.glob("catmark_*.obj"))
    sides = {"now": str(ROOT)}
    if args.before:
        sides["before"] = str(Path(args.before).resolve())
    print(f"load {os.getloadavg()[0]:.1f} at the start (2 cores)")
    read_head = f" {'read wall, cpu s':>16s}" if args.read else ""
    print(f"{'shape':28s} {'faces':>6s} {'side':>12s} {'patches':>8s} {'B-rep faces':>11s} {'wall s':>7s} {'cpu s':>7s} {'MB':>7s}{read_head}  status")
    with tempfile.TemporaryDirectory() as tmp:
        for path in paths:
            moved = None
            try:
                mesh = patching.read_mesh(path)
                faces = mesh.n_faces
                if args.moved:
                    moved = Path(tmp) / f"{path.stem}_moved.obj"
                    write_obj(_moved(mesh), moved)
            except patching.NupatchError:  # refused input: count the OBJ's faces
                faces = sum(line.startswith("f ") for line in path.read_text().splitlines())
            runs = [(side, tree, path) for side, tree in sides.items()]
            if moved is not None:
                runs = [r for side, tree in sides.items() for r in ((side, tree, path), (f"{side} moved", tree, moved))]
            for side, tree, mesh_path in runs:
                out = Path(tmp) / f"{side}.step"
                out.unlink(missing_ok=True)
                status, wall, cpu, n_patches = build(tree, mesh_path, out, args.timeout)
                size = out.stat().st_size / 1e6 if out.exists() else float("nan")
                patches = out.read_text(errors="replace").count("ADVANCED_FACE(") if out.exists() else 0
                flag = " (over 5 MB)" if faces < 1000 and size > 5 else ""
                read = f" {read_back(tree, out, args.timeout) if out.exists() else '-':>16s}" if args.read else ""
                print(f"{path.stem:28s} {faces:6d} {side:>12s} {n_patches:8d} {patches:11d} {wall:7.1f} {cpu:7.1f} {size:7.2f}{read}  {status}{flag}",
                      flush=True)
    print(f"load {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
