"""Speed of ``patching.fitting.fit`` ([FSLYJ] sec. 4.1): a ~100k-triangle torus (trimesh's
generator) fitted with a ~2k-face control mesh; target under 60 s on the 2-core shared box.

Prints one row per run: triangles, control faces, alternations, seconds per stage and in all
(wall), the run's CPU seconds (its process, from ``getrusage(RUSAGE_CHILDREN)``), the load
average at its end, CG iterations, and the distances both ways relative to the diagonal.  ``--against REV`` also runs the same
fit with the code of git revision REV (extracted to a temporary directory, each run in its own
process), alternating with the working tree's, so that a shared, noisy machine compares both
under the same load.  Run by hand:
    PYTHONPATH=. python benchmarks/fit.py [--triangles 100000] [--faces 2000] [--against main] [--distance sdm,tdm] [--iterations K] [--repeat 1]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def torus(triangles: int):
    """A torus (R = 1, r = 0.35) of about ``triangles`` triangles, sections in ratio 2:1."""
    import numpy as np
    import trimesh

    minor = max(8, int(round(np.sqrt(triangles / 4))))
    return trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=2 * minor, minor_sections=minor)


def worker(triangles: int, faces: int, distance: str | None, iterations: int | None = None) -> dict:
    """One fit, in this process, with whatever ``patching`` is first on sys.path."""
    from patching.fitting import fit

    mesh = torus(triangles)
    t0 = time.perf_counter()
    kwargs = {} if distance is None else {"distance": distance}
    if iterations is not None:
        kwargs["max_iterations"] = iterations
    from patching.fitting import solve

    solvers = []
    init = solve.LeastSquares.__init__

    def keep(self, *a, **kw):  # to read the CG iteration count afterwards
        init(self, *a, **kw)
        solvers.append(self)

    solve.LeastSquares.__init__ = keep
    result = fit(mesh.vertices, mesh.faces, faces=faces, name="torus", **kwargs)
    total = time.perf_counter() - t0
    r = result.report
    return dict(
        triangles=r.input_triangles, faces=r.control_faces, points=r.data_points, iterations=r.iterations,
        total=total, timings=r.timings, steps=r.steps, cg=sum(getattr(x, "cg_iterations", 0) for x in solvers),
        distances=[r.max_input_to_surface, r.rms_input_to_surface, r.max_surface_to_input, r.rms_surface_to_input],
    )


def spawn(src: Path, args, distance: str | None) -> dict:
    command = [sys.executable, str(Path(__file__).resolve()), "--worker", "--src", str(src),
               "--triangles", str(args.triangles), "--faces", str(args.faces)]
    if args.iterations is not None:
        command += ["--iterations", str(args.iterations)]
    if distance is not None:
        command += ["--distance", distance]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(command, check=True, capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(src)))
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    result["cpu"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    result["load"] = os.getloadavg()[0]
    return result


def row(label: str, r: dict) -> str:
    stages = " ".join(f"{k} {v:.1f}" for k, v in r["timings"].items())
    d = r["distances"]
    return (f"{label:<22} {r['triangles']:>9} {r['faces']:>6} {r['points']:>7} {r['iterations']:>5} {r['total']:>8.1f}"
            f" {r['cpu']:>7.1f} {r['load']:>5.1f} {r['cg']:>5}  {stages}"
            f"  | in->s max {d[0]:.1e} rms {d[1]:.1e}; s->in max {d[2]:.1e} rms {d[3]:.1e}")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--triangles", type=int, default=100_000)
    parser.add_argument("--faces", type=int, default=2000)
    parser.add_argument("--against", metavar="REV", help="also run git revision REV's code, alternating")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--iterations", type=int, help="most alternations of every run (default: fit's), to compare at equal work")
    parser.add_argument("--distance", help="the distance model(s) of this tree's runs: sdm, tdm or sdm,tdm (default: fit's)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--src", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        sys.path.insert(0, args.src)
        print(json.dumps(worker(args.triangles, args.faces, args.distance, args.iterations)))  # one model in a worker
        return
    print(f"{'code':<22} {'triangles':>9} {'faces':>6} {'points':>7} {'iters':>5} {'total s':>8} {'cpu s':>7} {'load':>5} {'cg':>5}  stages (s)")
    with tempfile.TemporaryDirectory() as tmp:
        old = None
        if args.against:
            old = Path(tmp) / "old"
            old.mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.against, "patching"], check=True, capture_output=True).stdout
            subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
        for _ in range(args.repeat):
            if old is not None:
                print(row(f"{args.against}", spawn(old, args, None)), flush=True)
            for model in (args.distance.split(",") if args.distance else [None]):
                r = spawn(ROOT, args, model)
                print(row(f"this tree ({model or 'default'})", r), flush=True)
                print(f"{'':<22} steps: {' '.join(r['steps'])}; target under 60 s -> {'met' if r['total'] < 60 else 'NOT met'}", flush=True)


if __name__ == "__main__":
    main()
