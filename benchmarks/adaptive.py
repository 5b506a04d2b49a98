"""Feature-adaptive refinement (patching.operator.adaptive) on the OpenSubdiv shapes that global
refinement refuses: levels, patches, windows, build time and peak memory, against the number
of faces global refinement would need (588 x 4^6 for the pawn).

    .venv/bin/python benchmarks/adaptive.py [SHAPE ...]

Each shape runs in its own process, so that its peak resident memory (ru_maxrss) is its own.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SHAPES = REPO.parent / "shared" / "opensubdiv-shapes"
DEFAULT = ["catmark_hole_test2", "catmark_gregory_test7", "catmark_helmet", "catmark_pawn"]


def run_one(name: str) -> dict:
    sys.path.insert(0, str(REPO))
    import numpy as np

    import patching
    from patching.operator.adaptive import adaptive_operator, junction_residuals

    mesh = patching.read_mesh(SHAPES / f"{name}.obj")
    start = time.perf_counter()
    ap = adaptive_operator(mesh)
    seconds = time.perf_counter() - start
    coeffs = ap.nets(mesh.vertices)
    finite = all(np.isfinite(arr).all() for _, arr in coeffs.values())
    levels = ap.level
    transitions = int((levels[ap.junctions[:, 0].astype(int)] != levels[ap.junctions[:, 2].astype(int)]).sum())
    gap, angle = junction_residuals(ap, mesh.vertices)
    size = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    return {
        "gap": gap / size,
        "angle_deg": float(np.degrees(angle)),
        "shape": name,
        "faces": mesh.n_faces,
        "steps": ap.steps,
        "global_faces": mesh.n_faces * 4**ap.steps,
        "patches": ap.n_patches,
        "per_level": np.bincount(levels, minlength=ap.steps + 1).tolist(),
        "largest_window": max(s[3] for s in ap.stats),
        "transitions": transitions,
        "nnz": int(ap.matrix.nnz),
        "seconds": round(seconds, 2),
        "peak_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "finite": finite,
    }


def main(argv: list[str]) -> None:
    if argv and argv[0] == "--one":
        print(json.dumps(run_one(argv[1])))
        return
    names = argv or DEFAULT
    print(f"{'shape':24} {'N':>2} {'faces':>6} {'global':>9} {'patches':>8} {'window':>7} {'T-junc':>7} {'s':>7} {'MB':>7} {'gap/size':>9} {'deg':>9}  per level")
    for name in names:
        out = subprocess.run([sys.executable, __file__, "--one", name], capture_output=True, text=True)
        if out.returncode:
            print(f"{name:24} failed: {out.stderr.strip().splitlines()[-1] if out.stderr else out.returncode}")
            continue
        r = json.loads(out.stdout)
        print(
            f"{r['shape']:24} {r['steps']:>2} {r['faces']:>6} {r['global_faces']:>9} {r['patches']:>8} "
            f"{r['largest_window']:>7} {r['transitions']:>7} {r['seconds']:>7} {r['peak_mb']:>7} {r['gap']:>9.1e} {r['angle_deg']:>9.1e}  {r['per_level']}"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
