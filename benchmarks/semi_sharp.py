"""Semi-sharp tags on small meshes: patches and time to STEP on the global path
(``refinement="global"``) and under the default rule (``"auto"``: adaptive beyond
``operator.MAX_AUTO_GLOBAL_FACES`` global faces), in the same run.

    .venv/bin/python benchmarks/semi_sharp.py [--max-global N]

Each build runs in its own process (imports excluded from the time); the global path is
skipped above N global faces (default 25,000: the 5 x 4 torus at s = 6 takes over 2 minutes).
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SHAPES = REPO.parent / "shared" / "opensubdiv-shapes"
TORUS_CREASES = {"one": [(0, 4)], "three": [(0, 4), (9, 13), (2, 18)]}


def meshes():
    """(name, mesh): the 5 x 4 torus with one and three semi-sharp edges, the 96-face cube with
    a semi-sharp loop (tests/test_adaptive.py), and OpenSubdiv shapes with semi-sharp tags."""
    sys.path.insert(0, str(REPO))
    import patching
    from patching.mesh.primitives import torus_grid
    from tests.helpers import cube_level2

    for kind, edges in TORUS_CREASES.items():
        for s in (2, 3, 5, 6, 9.99):
            yield f"torus 5x4, {kind} crease s={s:g}", dataclasses.replace(torus_grid(5, 4), creases={e: float(s) for e in edges})
    for s in (2, 3, 5):
        yield f"cube 96 faces, loop s={s}", cube_level2(float(s))
    for name in ("catmark_cube_creases1", "catmark_tent_creases1", "catmark_torus_creases0", "catmark_pawn"):
        if (SHAPES / f"{name}.obj").is_file():
            yield name, patching.read_mesh(SHAPES / f"{name}.obj")


def run_one(index: int, refinement: str) -> dict:
    import export
    import patching

    name, mesh = list(meshes())[index]
    start = time.perf_counter()
    surface = patching.build(mesh, refinement=refinement)
    built = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.step"
        export.to_step(surface, out)
        size = out.stat().st_size
    return {"patches": surface.n_patches, "build": built - start, "total": time.perf_counter() - start, "mb": size / 1e6}


def main(argv: list[str]) -> None:
    if argv and argv[0] == "--one":
        print(json.dumps(run_one(int(argv[1]), argv[2])))
        return
    limit = int(argv[argv.index("--max-global") + 1]) if "--max-global" in argv else 25_000
    from patching.operator.refinement import refinement_plan
    from patching.topology.tables import Topology

    print("| mesh | faces | global faces | global: patches, s, MB | auto: path, patches, s, MB |")
    print("| --- | --- | --- | --- | --- |")
    for i, (name, mesh) in enumerate(meshes()):
        steps, adaptive = refinement_plan(Topology(mesh))
        n_global = mesh.n_faces * 4**steps
        cells = []
        for refinement in ("global", "auto"):
            if refinement == "global" and (n_global > limit or refinement_plan(Topology(mesh), "global")[1]):
                cells.append("skipped")
                continue
            out = subprocess.run([sys.executable, __file__, "--one", str(i), refinement], capture_output=True, text=True)
            if out.returncode:
                cells.append("failed: " + (out.stderr.strip().splitlines() or ["?"])[-1])
                continue
            r = json.loads(out.stdout)
            path = ("adaptive, " if adaptive else "global, ") if refinement == "auto" else ""
            cells.append(f"{path}{r['patches']:,}, {r['total']:.1f} s, {r['mb']:.1f} MB")
        print(f"| {name} | {mesh.n_faces} | {n_global:,} | {cells[0]} | {cells[1]} |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
