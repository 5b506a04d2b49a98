"""Speed of ``patching.fitting.fit`` ([FSLYJ] sec. 4.1): a ~100k-triangle torus (trimesh's
generator) fitted with a ~2k-face control mesh; target under 60 s on the 2-core shared box.

Prints one row per run: triangles, control faces, alternations, seconds per stage and in all,
and the distances both ways relative to the diagonal.  Run by hand:
    PYTHONPATH=. python benchmarks/fit.py [--triangles 100000] [--faces 2000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from patching.fitting import fit  # noqa: E402


def torus(triangles: int) -> trimesh.Trimesh:
    """A torus (R = 1, r = 0.35) of about ``triangles`` triangles, sections in ratio 2:1."""
    minor = max(8, int(round(np.sqrt(triangles / 4))))
    return trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=2 * minor, minor_sections=minor)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--triangles", type=int, default=100_000)
    parser.add_argument("--faces", type=int, default=2000)
    args = parser.parse_args()
    mesh = torus(args.triangles)
    t0 = time.perf_counter()
    result = fit(mesh.vertices, mesh.faces, faces=args.faces, name="torus")
    total = time.perf_counter() - t0
    r = result.report
    stages = " ".join(f"{k} {v:.1f}" for k, v in r.timings.items())
    print(f"{'triangles':>9} {'ctrl faces':>10} {'points':>7} {'iters':>5} {'total s':>8}  stages (s)")
    print(f"{r.input_triangles:>9} {r.control_faces:>10} {r.data_points:>7} {r.iterations:>5} {total:>8.1f}  {stages}")
    print(
        f"input->surface max {r.max_input_to_surface:.2e} rms {r.rms_input_to_surface:.2e}; "
        f"surface->input max {r.max_surface_to_input:.2e} rms {r.rms_surface_to_input:.2e} (of the diagonal)"
    )
    print(f"steps: {' '.join(r.steps)}; target: under 60 s -> {'met' if total < 60 else 'NOT met'}")


if __name__ == "__main__":
    main()
