"""Cold builds of an EP-dense mesh: ``build_operator`` in a fresh process (no in-process cache
warm), without the on-disk cache of solved local configurations and with it (filled by a
warm-up round), alternated in one run; optionally a second checkout (``--before DIR``) in the
same rotation, also without and with the cache.  The mesh is ``benchmarks/build.py``'s "coarse" one: an icosphere's triangles
split into quads once, 15k faces, half of the vertices EPs of valence 3, 5 and 6, intervals
drawn from {1, 2, 5} per strip.  ``--plain`` adds this tree without the monotone spoke step
(``g1_patches.MONOTONE_SPOKES = False``, the red solve before issue 19).  Each child prints the wall and CPU seconds of the build alone
(the mesh read and the imports excluded; ``--operators``: also the whole operator read back from
``export.operator_cache``, filled by the warm-up round, as ``nupatch build`` takes it), split into user and system
time (``getrusage``: on a VM most of the system time is first touches of fresh pages), and the
process's peak resident memory (which includes the imports and the mesh).  Run by hand:
``.venv/bin/python benchmarks/cold_build.py [--runs 3] [--before DIR] [--plain]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

CHILD = r"""
import json, sys, time
import patching
mesh = patching.read_mesh(sys.argv[1])
if len(sys.argv) > 3 and sys.argv[3] == "plain":  # the red solve without the monotone spoke step
    from patching.extraordinary import g1_patches
    g1_patches.MONOTONE_SPOKES = False
import contextlib
from export.solve_cache import using_disk_cache
if sys.argv[2] == "cache":
    context = using_disk_cache()
elif sys.argv[2] == "operator":  # both caches, as nupatch build uses them
    from export.operator_cache import operator_for, using_operator_cache
    context = contextlib.ExitStack()
    context.enter_context(using_disk_cache())
    operators = context.enter_context(using_operator_cache())
else:
    context = contextlib.nullcontext()
import resource
with context:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    wall, cpu = time.perf_counter(), time.process_time()
    if sys.argv[2] == "operator":
        op = operator_for(mesh, patching.BuildOptions(), operators)
    else:
        op = patching.build_operator(mesh)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    after = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"wall": wall, "cpu": cpu, "nnz": int(op.matrix.nnz), "user": after.ru_utime - usage.ru_utime,
                  "sys": after.ru_stime - usage.ru_stime, "rss": after.ru_maxrss / 1024,
                  "faults": after.ru_minflt - usage.ru_minflt, "hit": sys.argv[2] == "operator" and operators.hits == 1}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--before", help="a second checkout (e.g. main's worktree), timed without and with the cache")
    parser.add_argument("--plain", action="store_true",
                        help="also this tree without the monotone spoke step (g1_patches.MONOTONE_SPOKES = False), without and with the cache")
    parser.add_argument("--operators", action="store_true",
                        help="also this tree with the whole-operator cache (export.operator_cache) filled, as nupatch build reads it")
    args = parser.parse_args()

    from build import ep_mesh
    from export import write_obj

    mesh = ep_mesh("coarse")
    sides = {"no cache": (str(ROOT), "none"), "cache": (str(ROOT), "cache")}
    if args.operators:
        sides["operator"] = (str(ROOT), "operator")
    if args.plain:
        sides["plain"] = (str(ROOT), "none", "plain")
        sides["plain cache"] = (str(ROOT), "cache", "plain")
    if args.before:
        sides["before"] = (str(Path(args.before).resolve()), "none")
        sides["before cache"] = (str(Path(args.before).resolve()), "cache")  # its own entries (another source digest)
    times: dict[str, list[dict]] = {name: [] for name in sides}
    start_load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        obj = Path(tmp) / "coarse.obj"
        write_obj(mesh, obj)
        for run in range(args.runs + 1):  # the first round fills the cache and the .pyc files
            for name, (tree, mode, *plain) in sides.items():
                env = dict(os.environ, PYTHONPATH=tree, NUPATCH_CACHE_DIR=str(Path(tmp) / "cache"))
                env.pop("PYTHONDONTWRITEBYTECODE", None)
                out = subprocess.run([sys.executable, "-c", CHILD, str(obj), mode, *plain], env=env, check=True,  # cwd: not a checkout
                                     capture_output=True, text=True, cwd=tmp).stdout  # ("-c" puts it first on sys.path)
                if run:
                    row = json.loads(out.strip().splitlines()[-1])
                    if mode == "operator" and not row["hit"]:
                        raise SystemExit("the operator cache was filled by the warm-up round but missed")
                    times[name].append(row)
    load = os.getloadavg()[0]
    print(f"coarse: {mesh.n_faces} faces, build_operator in a fresh process, {args.runs} runs alternated, median (min),"
          f" load {start_load:.1f} -> {load:.1f}")
    for name, rows in times.items():
        wall = np.array([r["wall"] for r in rows])
        cpu = np.array([r["cpu"] for r in rows])
        user = np.array([r["user"] for r in rows])
        system = np.array([r["sys"] for r in rows])
        rss = np.array([r["rss"] for r in rows])
        touched = np.array([r["faults"] for r in rows]) * 4096 / 2**20
        print(f"  {name:12s} wall {np.median(wall):6.2f} s ({wall.min():5.2f})  cpu {np.median(cpu):6.2f} s ({cpu.min():5.2f})"
              f"  = user {np.median(user):5.2f} ({user.min():5.2f}) + sys {np.median(system):5.2f} ({system.min():5.2f})"
              f"  peak rss {np.median(rss):4.0f} MB  faulted {np.median(touched):5.0f} MB  nnz {rows[0]['nnz']}")


if __name__ == "__main__":
    main()
