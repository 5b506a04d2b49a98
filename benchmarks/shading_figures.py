"""Pictures of [ZBK]'s comparisons, as PNGs under docs/figures/ (run by hand):

    PYTHONPATH=. python benchmarks/shading_figures.py [NAME.png ...]   (default: all)

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
* shading_semi_sharp_decay.png ([ZBK] Fig. 4): blend weights (variant B, blending from level
  2, as the figure) after 4 and 5 steps of the tetrahedron with three edges of sharpness 4
  (Loop) and of a cube with a loop of four such edges around its top face (Catmull-Clark):
  after 4 steps the edges' vertices have b = 0, after 5 (the edges ran out at level 4) the
  extraordinary ones and their 1-rings are blended (close-ups of one crease corner at both
  levels, face edges drawn); and the zebra of N_B after 5 steps.
* shading_darts.png ([ZBK] Figs. 5, 12, 13): the tetrahedron with two sharp edges (Loop) and
  the cube with three (a path: its two ends are darts; Catmull-Clark), 4 steps, blend weights
  and zebra of N_B with darts treated as smooth vertices (the default, [ZBK] sec. 5) and as
  sharp vertices (``darts="sharp"``).
* shading_semi_sharp_models.png ([ZBK] Figs. 8, 9): [OSD]'s semi-sharp icosahedron (Loop) and
  creased torus (Catmull-Clark), 4 steps: limit normals (no subdivision shading) vs variant B.
* shading_helmet.png ([ZBK] Figs. 8, 9 on a creased model): [OSD]'s catmark_helmet with its
  creases set to sharpness 2 (the paper's value), 4 Catmull-Clark steps, blending from level
  1: zebra of the limit normals and of N_B (variant B), the blend weights, N_B shaded.
"""

from __future__ import annotations

import dataclasses
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
from export.render import Picture
from export.render_camera import VIEWS
from export.render_subdivided import render_subdivided
from patching.shading import shading_operator

OUT = Path(__file__).resolve().parent.parent / "docs" / "figures"
ONLY: set[str] = set()  # figure names to write (command line); empty: all
SHAPES = Path("/work/shared/opensubdiv-shapes")
PANEL = (420, 420)
AZIMUTH, ELEVATION = VIEWS["iso"]  # the view render_subdivided draws (export.render.Picture)


def _shape(name: str) -> patching.ControlMesh:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return patching.read_mesh(SHAPES / f"{name}.obj")


def tetrahedron(sharp_edges) -> patching.ControlMesh:
    v = np.array([[1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1]], float)
    return patching.from_arrays(v, [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]], creases={e: 4.0 for e in sharp_edges})


def sharp_cube(edges=((4, 5), (5, 7), (6, 7), (4, 6), (1, 5), (3, 7), (1, 3))) -> patching.ControlMesh:
    """A cube with sharpness-4 edges (default: the top face's four and three more)."""
    v = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
    f = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return patching.from_arrays(v, f, creases={e: 4.0 for e in edges})


def _png(mesh, scheme, levels, normals, variant="b", mode="zebra", darts="smooth", view=None) -> np.ndarray:
    """view: (azimuth, elevation) in degrees, default the iso view."""
    picture = None if view is None else Picture(azimuth=view[0], elevation=view[1])
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "panel.png"
        render_subdivided(mesh, path, levels, scheme, normals, variant, mode, PANEL, darts=darts, picture=picture)
        return plt.imread(path)


def _blend_panel(ax, mesh, scheme, levels, variant, blend_level=1, darts="smooth", view=(AZIMUTH, ELEVATION),
                 zoom=None):
    """Faces coloured by their corners' mean b, seen from the renderer's camera (parallel
    projection, azimuth and elevation of ``export.render``), drawn back to front.  zoom:
    (control vertex, half-width as a share of the mesh's size): a close-up around the refined
    vertex nearest to that control vertex, face edges drawn."""
    op = shading_operator(mesh, levels, scheme, "shading", variant, blend_level=blend_level, darts=darts)
    out = op.evaluate(mesh.vertices)
    az, el = np.radians(view[0]), np.radians(view[1])
    to_eye = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    up = np.array([0.0, 0.0, 1.0]) - np.sin(el) * to_eye
    up /= np.linalg.norm(up)
    right = np.cross(-to_eye, up)
    p = out.points[out.faces]
    order = np.argsort((p @ to_eye).mean(axis=1))
    xy = np.stack([p @ right, p @ up], axis=-1)[order]
    colours = plt.cm.coolwarm(op.blend[out.faces].mean(axis=1))[order]
    ax.add_collection(PolyCollection(xy, facecolors=colours, edgecolors="none" if zoom is None else "k",
                                     linewidths=0.2))
    ax.autoscale()
    if zoom is not None:
        target = mesh.vertices[zoom[0]]
        c = out.points[np.argmin(np.linalg.norm(out.points - target, axis=1))]
        half = zoom[1] * float(np.ptp(out.points, axis=0).max())
        ax.set_xlim(c @ right - half, c @ right + half)
        ax.set_ylim(c @ up - half, c @ up + half)
    ax.set_aspect("equal")
    ax.set_axis_off()


def _figure(name: str, rows: list[list[tuple]], titles: list[list[str]]) -> None:
    """rows of panels: ("png", image) or ("blend", mesh, scheme, levels, variant[, blend level, darts])."""
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


def _want(name: str) -> bool:
    return not ONLY or name in ONLY


def main() -> None:
    cube = _shape("loop_cube")
    if _want("shading_flat_limit_blended.png"):
        _figure("shading_flat_limit_blended.png",
                [[("png", _png(cube, "loop", 3, n)) for n in ("flat", "limit", "shading")],
                 [("png", _png(cube, "loop", 3, n, mode="shaded")) for n in ("flat", "limit", "shading")]],
                [["flat (face normals), zebra", "limit normals N_L, zebra", "blended N_B (variant B), zebra"],
                 ["flat, shaded", "limit, shaded", "blended, shaded"]])
    for scheme, mesh, name in (("loop", tetrahedron([(0, 1), (1, 2), (0, 2)]), "shading_variants_loop.png"),
                               ("catmark", sharp_cube(), "shading_variants_catmark.png")):
        if not _want(name):
            continue
        rows, titles = [], []
        for variant in ("a", "b"):
            rows.append([("png", _png(mesh, scheme, 4, "limit")), ("png", _png(mesh, scheme, 4, "shading", variant)),
                         ("png", _png(mesh, scheme, 4, "shading", variant, "shaded")),
                         ("blend", mesh, scheme, 4, variant)])
            v = variant.upper()
            titles.append(["limit normals, zebra", f"variant {v}, zebra", f"variant {v}, shaded",
                           f"variant {v}, blend weights b"])
        _figure(name, rows, titles)
    cross_loop = sharp_cube(((4, 5), (5, 7), (7, 6), (6, 4)))
    tet = tetrahedron([(0, 1), (1, 2), (0, 2)])
    rows, titles = [], []
    for scheme, m in (("loop", tet), ("catmark", cross_loop)) if _want("shading_semi_sharp_decay.png") else ():
        corner = 0 if scheme == "loop" else 5  # a crease corner in view
        rows.append([("blend", m, scheme, 4, "b", 2), ("blend", m, scheme, 5, "b", 2),
                     ("blend", m, scheme, 4, "b", 2, "smooth", (AZIMUTH, ELEVATION), (corner, 0.06)),
                     ("blend", m, scheme, 5, "b", 2, "smooth", (AZIMUTH, ELEVATION), (corner, 0.06)),
                     ("png", _png(m, scheme, 5, "shading"))])
        titles.append([f"{scheme}: b after 4 steps (edges sharp)", f"{scheme}: b after 5 steps (edges smooth)",
                       f"close-up of corner {corner}, 4 steps", f"close-up of corner {corner}, 5 steps",
                       f"{scheme}: N_B after 5 steps, zebra"])
    if rows:
        _figure("shading_semi_sharp_decay.png", rows, titles)
    rows, titles = [], []
    dart_models = (("loop", tetrahedron([(0, 1), (0, 2)])), ("catmark", sharp_cube(((4, 5), (5, 7), (7, 6)))))
    for scheme, m in dart_models if _want("shading_darts.png") else ():
        rows.append([("blend", m, scheme, 4, "b", 1, d) for d in ("smooth", "sharp")]
                    + [("png", _png(m, scheme, 4, "shading", darts=d)) for d in ("smooth", "sharp")])
        titles.append([f"{scheme}: b, darts smooth", f"{scheme}: b, darts sharp",
                       f"{scheme}: N_B, darts smooth, zebra", f"{scheme}: N_B, darts sharp, zebra"])
    if rows:
        _figure("shading_darts.png", rows, titles)
    models = [("loop", _shape("loop_icos_semisharp")), ("catmark", _shape("catmark_torus_creases1"))]
    if _want("shading_semi_sharp_models.png"):
        _figure("shading_semi_sharp_models.png",
                [[("png", _png(m, s, 4, "limit")), ("png", _png(m, s, 4, "shading"))] for s, m in models],
                [[f"{m.name}: limit normals", f"{m.name}: variant B"] for _, m in models])
    helmet = _shape("catmark_helmet")
    helmet = dataclasses.replace(helmet, creases={k: 2.0 for k in helmet.creases})
    TOP = (90.0, 60.0)  # from above the crown: two of its four extraordinary vertices in view
    if _want("shading_helmet.png"):
        _figure("shading_helmet.png",
                [[("png", _png(helmet, "catmark", 4, "limit", view=TOP)), ("png", _png(helmet, "catmark", 4, "shading", view=TOP)),
                  ("blend", helmet, "catmark", 4, "b", 1, "smooth", TOP),
                  ("png", _png(helmet, "catmark", 4, "shading", mode="shaded", view=TOP))]],
                [["helmet, creases s = 2: N_L, zebra", "N_B (variant B), zebra", "blend weights b", "N_B, shaded"]])


if __name__ == "__main__":
    import sys

    ONLY = set(sys.argv[1:])
    main()
