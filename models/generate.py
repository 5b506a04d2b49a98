"""Regenerate the parametric sample meshes in models/ (run from the repo root):

    .venv/bin/python models/generate.py
"""

from pathlib import Path

from patching.obj import write_obj
from patching.primitives import open_grid, torus_grid

HERE = Path(__file__).parent

# A 12 x 8 torus whose strips carry intervals from 0.5 to 6 (max/min 12), one of them a
# double knot (0: C1 ring) so that the demo exercises multiple knots too.
write_obj(
    torus_grid(12, 8, [1, 2, 4, 6, 3, 1, 0.5, 1, 2, 0, 1.5, 1], [1, 3, 1, 0.5, 2, 1, 4, 1], name="torus_nonuniform"),
    HERE / "torus_nonuniform.obj",
    comment="nupatch sample: closed 12 x 8 torus grid with non-uniform knot intervals (one zero strip)",
)
# An open 9 x 7 grid whose outermost strips carry 0: a clamped bicubic NURBS patch.
write_obj(
    open_grid(9, 7, [0, 1, 2, 1, 1, 3, 1, 0], [0, 1, 1, 2, 1, 0], name="clamped_grid"),
    HERE / "clamped_grid.obj",
    comment="nupatch sample: open 9 x 7 grid, zero outer strips (clamped NURBS), non-uniform inside",
)
