"""Pictures of [ZBK]'s comparisons: flat vs limit vs blended (subdivision-shading) normals, and
variants A/B at a sharp crease, as highlight-line renderings (PNG under docs/figures/).

    PYTHONPATH=. python benchmarks/shading_figures.py

Each face is coloured by the mean over its corners of a stripe function of the corner normal,
``0.5 + 0.5 cos(40 n . d)`` (highlight lines: they wiggle where the normal field is not
smooth), on Loop's ``loop_cube`` (many valence-3/4/5 vertices) and a tetrahedron with three
infinitely sharp edges, each after 4 steps.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

import patching  # noqa: E402
from patching.shading import shading_operator  # noqa: E402

OUT = Path(__file__).resolve().parent.parent / "docs" / "figures"
SHAPE = Path("/work/shared/opensubdiv-shapes/loop_cube.obj")
D = np.array([0.3, 0.5, 0.81])
D = D / np.linalg.norm(D)


def _colours(corner_normals: np.ndarray) -> np.ndarray:
    s = 0.5 + 0.5 * np.cos(40.0 * corner_normals @ D)
    return plt.cm.viridis(s.mean(axis=1))


def _panel(ax, points, faces, corner_normals, title):
    poly = Poly3DCollection(points[faces], facecolors=_colours(corner_normals), edgecolors="none")
    ax.add_collection3d(poly)
    lo, hi = points.min(0), points.max(0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.view_init(25, 35)
    ax.set_axis_off()
    ax.set_title(title, fontsize=9)


def _figure(mesh, levels, rows, name):
    fig = plt.figure(figsize=(4 * len(rows), 4.2))
    for i, (title, normals, variant) in enumerate(rows):
        op = shading_operator(mesh, levels, "loop", normals="limit" if normals == "flat" else normals, variant=variant)
        out = op.evaluate(mesh.vertices)
        if normals == "flat":
            tri = out.points[out.faces]
            fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            fn /= np.linalg.norm(fn, axis=1)[:, None]
            cn = np.repeat(fn[:, None], 3, axis=1)
        else:
            cn = out.normals[out.corner_normal]
        _panel(fig.add_subplot(1, len(rows), i + 1, projection="3d"), out.points, out.faces, cn, title)
    OUT.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(OUT / name, dpi=110)
    plt.close(fig)
    print("wrote", OUT / name)


def main() -> None:
    cube = patching.read_mesh(SHAPE)
    _figure(cube, 4, [("flat (face normals)", "flat", "b"), ("limit normals N_L", "limit", "b"),
                      ("blended N_B (subdivision shading)", "shading", "b")], "loop_shading_cube.png")
    tet = patching.from_arrays(
        np.array([[1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1]], float),
        [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
        creases={(0, 1): 10.0, (1, 2): 10.0, (0, 2): 10.0},
    )
    _figure(tet, 4, [("limit normals N_L", "limit", "b"), ("shading, variant A", "shading", "a"),
                     ("shading, variant B", "shading", "b")], "loop_shading_variants.png")


if __name__ == "__main__":
    main()
