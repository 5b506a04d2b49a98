"""Large builds, old code against new: ``nupatch build`` as a whole process on the 10k-face torus,
the 15k-face refined icosahedron (``benchmarks/build.py``'s meshes) and a 50k-face torus
(250 x 200, intervals drawn from 1 to 20 as for the 10k one), for this checkout and a second
one (``--before DIR``, e.g. ``git worktree add /tmp/before <commit>``) alternated in one run,
so both meet the same machine load; beside them OpenCASCADE's floor for the same faces
(``benchmarks/small_build.py``'s floor script: the Bézier nets into one
``BRepBuilderAPI_MakeFace`` each, a compound, STEP), also a whole process.

Every child runs in a temporary directory outside any checkout with ``PYTHONPATH`` set to its
checkout; its CPU (user + system) seconds and peak resident set come from ``os.wait4``'s
rusage of that one child.  Each side builds without the on-disk cache (``NUPATCH_NO_CACHE=1``)
and, for the cases in ``CACHED``, also with its own cache directory, filled by one build
before the timed rounds.  The STEP files of the two sides are compared: size, face count, and
bytes once the FILE_NAME header (time stamp) is removed.  Run by hand:
``.venv/bin/python benchmarks/large_build.py --before DIR [--runs 2] [CASE ...]``.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

CASES = ("torus", "refined", "torus50k")
CACHED = ("torus", "refined")  # the 50k torus has no EPs: nothing to cache, and it is the costly one


def mesh_of(kind: str):
    from build import ep_mesh
    from patching.mesh.primitives import torus_grid

    if kind == "refined":
        return ep_mesh("refined")
    m, n = (100, 100) if kind == "torus" else (250, 200)
    rng = np.random.default_rng(0)
    return torus_grid(m, n, rng.uniform(1, 20, m), rng.uniform(1, 20, n), name=f"bench_{kind}")


def run_child(cmd: list[str], env: dict[str, str], cwd: str) -> dict[str, float]:
    """Wall, CPU seconds and peak RSS (MB) of one child process, from its own rusage."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed with {proc.returncode}")
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime, "rss": usage.ru_maxrss / 1024}


def step_body(path: Path) -> bytes:
    """The STEP text without its FILE_NAME header entity (which carries the time stamp)."""
    return re.sub(rb"FILE_NAME\(.*?\);", b"", path.read_bytes(), count=1, flags=re.S)


def load() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("cases", nargs="*", metavar="CASE", help=f"any of {', '.join(CASES)} (default: all)")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--before", required=True, help="a second checkout timed in the same rotation")
    args = parser.parse_args()
    cases = args.cases or list(CASES)
    for kind in cases:
        if kind not in CASES:
            parser.error(f"unknown case {kind!r} (choose from {', '.join(CASES)})")

    import patching
    from export import write_obj
    from small_build import FLOOR

    trees = {"before": str(Path(args.before).resolve()), "after": str(ROOT)}
    print("start:", load(), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "floor.py").write_text(FLOOR)
        meshes = {}
        for kind in cases:
            mesh = mesh_of(kind)
            write_obj(mesh, tmp / f"{kind}.obj")
            surface = patching.build(mesh)
            nets = np.empty(surface.n_patches, dtype=object)
            for k, (_, _, _, net) in enumerate(surface.patches()):
                nets[k] = np.asarray(net, dtype=float)
            np.save(tmp / f"{kind}.npy", nets, allow_pickle=True)
            meshes[kind] = (mesh.n_faces, surface.n_patches)
            del surface, nets

        def build(kind: str, side: str, cached: bool) -> dict[str, float]:
            env = dict(os.environ)
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPATH"] = trees[side]
            env["NUPATCH_CACHE_DIR"] = str(tmp / f"cache-{side}")
            if not cached:
                env["NUPATCH_NO_CACHE"] = "1"
            out = tmp / f"{kind}-{side}{'-cached' if cached else ''}.step"
            cmd = [sys.executable, "-m", "export.cli", "build", str(tmp / f"{kind}.obj"), "-o", str(out), "-q"]
            return run_child(cmd, env, str(tmp))

        for kind in cases:  # fill each side's cache (and warm the .pyc and file caches)
            if kind in CACHED:
                for side in trees:
                    build(kind, side, True)
        times: dict[tuple[str, str], list[dict[str, float]]] = {}
        for run in range(args.runs):
            order = list(trees) if run % 2 == 0 else list(trees)[::-1]
            for kind in cases:
                for side in order:
                    times.setdefault((kind, side), []).append(build(kind, side, False))
                    if kind in CACHED:
                        times.setdefault((kind, side + " cached"), []).append(build(kind, side, True))
                cmd = [sys.executable, str(tmp / "floor.py"), str(tmp / f"{kind}.npy"), str(tmp / f"{kind}-floor.step")]
                times.setdefault((kind, "floor"), []).append(run_child(cmd, dict(os.environ), str(tmp)))
                print(f"  round {run + 1} {kind} done:", load(), flush=True)
        print("end:", load())
        print(f"\n{args.runs} runs alternated; each figure: the runs' values, then the median")
        for kind in cases:
            faces, patches = meshes[kind]
            print(f"{kind}: {faces} faces, {patches} patches")
            for (k, side), rows in times.items():
                if k != kind:
                    continue
                cells = []
                for key, unit in (("cpu", "s"), ("wall", "s"), ("rss", "MB")):
                    values = [r[key] for r in rows]
                    cells.append(f"{key} {' '.join(f'{v:.1f}' for v in values)} -> {np.median(values):.1f} {unit}")
                print(f"  {side:14s} " + "; ".join(cells))
            before, after = tmp / f"{kind}-before.step", tmp / f"{kind}-after.step"
            nb, na = (p.read_bytes().count(b"ADVANCED_FACE(") for p in (before, after))
            same = step_body(before) == step_body(after)
            print(f"  STEP before {before.stat().st_size / 1e6:.1f} MB, {nb} faces; after {after.stat().st_size / 1e6:.1f} MB, "
                  f"{na} faces; bytes equal apart from FILE_NAME: {same}; floor STEP "
                  f"{(tmp / f'{kind}-floor.step').stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
