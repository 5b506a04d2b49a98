"""Speed and figures of ``nupatch toolpath`` ([FSLYJ] sec. 4.3) on the shipped models that face
up: pieces, points, path length, estimated machining time at the feed, and the check's
largest scallop, chord error and smallest clearance, with CPU and wall seconds of
``patching.toolpath.tool_path`` (the surface build excluded, G-code writing included).

    .venv/bin/python benchmarks/toolpath.py [--feed 1000] [--models l_bracket,...]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np

import patching
from export.gcode import machining_figures, safe_height, write_gcode
from patching.toolpath import tool_path

#: (model, ball radius R, scallop H) in mm; T = H / 4.
CASES = [
    ("clamped_grid", 0.5, 0.02),
    ("l_bracket", 0.5, 0.02),
    ("l_bracket", 0.25, 0.005),
    ("machined_bracket", 0.5, 0.02),
    ("square_frame", 0.5, 0.02),
    ("torus_nonuniform", 0.5, 0.02),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--feed", type=float, default=1000.0)
    parser.add_argument("--models", default="", help="comma-separated subset of the models")
    args = parser.parse_args()
    wanted = set(filter(None, args.models.split(",")))
    head = f"{'model':18} {'R':>5} {'H':>6} {'pieces':>6} {'points':>6} {'path mm':>8} {'min':>6} {'scallop':>8} {'chord':>8} {'R-clear':>8} {'cpu s':>6} {'wall s':>6}"
    print(head)
    for name, r, h in CASES:
        if wanted and name not in wanted:
            continue
        mesh = patching.read_mesh(ROOT / "models" / f"{name}.obj")
        surface = patching.build(mesh)
        wall, cpu = time.perf_counter(), time.process_time()
        path = tool_path(surface, mesh, r, h)
        top = float(max(np.max(g.coefficients[..., 2]) for g in surface.groups))
        with tempfile.TemporaryDirectory() as tmp:
            write_gcode(path, Path(tmp) / "out.nc", args.feed, top, name)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        rep = path.report
        fig = machining_figures(path, args.feed, safe_height(path, top))
        print(
            f"{name:18} {r:5g} {h:6g} {rep['pieces']:6d} {rep['points']:6d} {rep['path_length']:8.1f} "
            f"{fig['time_min']:6.2f} {rep['max_scallop']:8.5f} {rep['max_chord_error']:8.5f} "
            f"{r - rep['min_clearance']:8.5f} {cpu:6.1f} {wall:6.1f}"
        )


if __name__ == "__main__":
    main()
