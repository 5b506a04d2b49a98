"""Pictures of [ZBK]'s comparisons, as PNGs under docs/figures/ (run by hand):

    PYTHONPATH=. python benchmarks/shading_figures.py

Every shaded or zebra panel is drawn by ``export.render_subdivided.render_subdivided`` (what
``nupatch render MESH --scheme S -n K --normals flat|limit|shading [--shading-variant a|b]
[--zebra]`` draws); blend-weight panels colour each face by the mean blend weight b of its
corners (blue 0, red 1, as [ZBK]'s figures), with matplotlib, from the renderer's camera.  Shapes: [OSD]'s loop_cube and
loop_icos_semisharp and catmark_torus_creases1 (from /work/shared/opensubdiv-shapes) and
meshes made here: a tetrahedron with three edges of sharpness 4 around one face, a cube with
seven such edges (all edges at three of its faces but one), and a tetrahedron with two.

* shading_flat_limit_blended.png: flat, limit and blended normals (zebra), Loop's cube.
* shading_variants_loop.png / shading_variants_catmark.png ([ZBK] Figs. 3, 10, 11): variants
  A and B on the sharp tetrahedron (Loop) and cube (Catmull-Clark), 4 steps: zebra of the
  blended normals and the blend weights.
* shading_semi_sharp_decay.png ([ZBK] Fig. 4): blend weights (variant B) of the tetrahedron
  after 4 Loop steps, seeded at level 1 (the sharpness-4 edges still sharp: their vertices get
  0) and at level 4 (the edges have decayed: their extraordinary vertices seed 1).
* shading_darts.png ([ZBK] Figs. 5, 12): the tetrahedron with two sharp edges (its two far
  ends are darts), limit vs blended normals and the blend weights, darts as smooth vertices
  (the only treatment implemented: [ZBK] sec. 5 recommends it).
* shading_semi_sharp_models.png ([ZBK] Figs. 8, 9): [OSD]'s semi-sharp icosahedron (Loop) and
  creased torus (Catmull-Clark), 4 steps: limit normals (no subdivision shading) vs variant B.
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import PolyCollection

import patching
from export.atomic import atomic_output
from export.render import AZIMUTH, ELEVATION
from export.render_subdivided import render_subdivided
from patching.shading import shading_operator

OUT = Path(__file__).resolve().parent.parent / "docs" / "figures"
SHAPES = Path("/work/shared/opensubdiv-shapes")
PANEL = (420, 420)


def _shape(name: str) -> patching.ControlMesh:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return patching.read_mesh(SHAPES / f"{name}.obj")


def tetrahedron(sharp_edges) -> patching.ControlMesh:
    v = np.array([[1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1]], float)
    return patching.from_arrays(v, [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]], creases={e: 4.0 for e in sharp_edges})


def sharp_cube() -> patching.ControlMesh:
    v = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
    f = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    edges = [(4, 5), (5, 7), (6, 7), (4, 6), (1, 5), (3, 7), (1, 3)]  # the top face's four, three more
    return patching.from_arrays(v, f, creases={e: 4.0 for e in edges})


def _png(mesh, scheme, levels, normals, variant="b", mode="zebra") -> np.ndarray:
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "panel.png"
        render_subdivided(mesh, path, levels, scheme, normals, variant, mode, PANEL)
        return plt.imread(path)


def _blend_panel(ax, mesh, scheme, levels, variant, blend_level=1):
    """Faces coloured by their corners' mean b, seen from the renderer's camera (parallel
    projection, azimuth and elevation of ``export.render``), drawn back to front."""
    op = shading_operator(mesh, levels, scheme, "shading", variant, blend_level=blend_level)
    out = op.evaluate(mesh.vertices)
    az, el = np.radians(AZIMUTH), np.radians(ELEVATION)
    to_eye = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    up = np.array([0.0, 0.0, 1.0]) - np.sin(el) * to_eye
    up /= np.linalg.norm(up)
    right = np.cross(-to_eye, up)
    p = out.points[out.faces]
    order = np.argsort((p @ to_eye).mean(axis=1))
    xy = np.stack([p @ right, p @ up], axis=-1)[order]
    colours = plt.cm.coolwarm(op.blend[out.faces].mean(axis=1))[order]
    ax.add_collection(PolyCollection(xy, facecolors=colours, edgecolors="none"))
    ax.autoscale()
    ax.set_aspect("equal")
    ax.set_axis_off()


def _figure(name: str, rows: list[list[tuple]], titles: list[list[str]]) -> None:
    """rows of panels: ("png", image) or ("blend", mesh, scheme, levels, variant)."""
    nr, nc = len(rows), max(len(r) for r in rows)
    fig = plt.figure(figsize=(3.3 * nc, 3.5 * nr))
    for i, row in enumerate(rows):
        for j, panel in enumerate(row):
            ax = fig.add_subplot(nr, nc, i * nc + j + 1)
            if panel[0] == "png":
                ax.imshow(panel[1])
                ax.set_axis_off()
            else:
                _blend_panel(ax, *panel[1:])
            ax.set_title(titles[i][j], fontsize=9)
    fig.tight_layout()
    OUT.mkdir(parents=True, exist_ok=True)
    with atomic_output(OUT / name) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
    print("wrote", OUT / name)


def main() -> None:
    cube = _shape("loop_cube")
    _figure("shading_flat_limit_blended.png",
            [[("png", _png(cube, "loop", 3, n)) for n in ("flat", "limit", "shading")],
             [("png", _png(cube, "loop", 3, n, mode="shaded")) for n in ("flat", "limit", "shading")]],
            [["flat (face normals), zebra", "limit normals N_L, zebra", "blended N_B (variant B), zebra"],
             ["flat, shaded", "limit, shaded", "blended, shaded"]])
    for scheme, mesh, name in (("loop", tetrahedron([(0, 1), (1, 2), (0, 2)]), "shading_variants_loop.png"),
                               ("catmark", sharp_cube(), "shading_variants_catmark.png")):
        rows, titles = [], []
        for variant in ("a", "b"):
            rows.append([("png", _png(mesh, scheme, 4, "limit")), ("png", _png(mesh, scheme, 4, "shading", variant)),
                         ("png", _png(mesh, scheme, 4, "shading", variant, "shaded")),
                         ("blend", mesh, scheme, 4, variant)])
            v = variant.upper()
            titles.append(["limit normals, zebra", f"variant {v}, zebra", f"variant {v}, shaded",
                           f"variant {v}, blend weights b"])
        _figure(name, rows, titles)
    tet = tetrahedron([(0, 1), (1, 2), (0, 2)])
    _figure("shading_semi_sharp_decay.png",
            [[("blend", tet, "loop", 4, "b", 1), ("blend", tet, "loop", 4, "b", 4),
              ("png", _png(tet, "loop", 4, "shading"))]],
            [["b seeded at level 1 (edges sharp)", "b seeded at level 4 (edges smooth)", "N_B (seeded at 1), zebra"]])
    darts = tetrahedron([(0, 1), (0, 2)])
    _figure("shading_darts.png",
            [[("png", _png(darts, "loop", 4, "limit")), ("png", _png(darts, "loop", 4, "shading")),
              ("blend", darts, "loop", 4, "b")]],
            [["limit normals, zebra", "blended, darts smooth, zebra", "blend weights b"]])
    models = [("loop", _shape("loop_icos_semisharp")), ("catmark", _shape("catmark_torus_creases1"))]
    _figure("shading_semi_sharp_models.png",
            [[("png", _png(m, s, 4, "limit")), ("png", _png(m, s, 4, "shading"))] for s, m in models],
            [[f"{m.name}: limit normals", f"{m.name}: variant B"] for _, m in models])


if __name__ == "__main__":
    main()
