"""The ``toolpath --picture`` PNG: the surface coloured by piece, the path drawn on it
(headless matplotlib, written atomically)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from patching.surface import BezierSurface
from patching.toolpath import ToolPath

from .atomic import atomic_output

__all__ = ["draw_toolpath"]


def draw_toolpath(surface: BezierSurface, path: ToolPath, out: str | os.PathLike, samples: int = 7, size=(1200, 900)) -> Path:
    """Patches coloured by the piece that machines them (grey: not machined), the path of
    tool tips as a black line, in an oblique view from above."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from patching.evaluation import evaluate_nets

    colour_of = {}
    for k, piece in enumerate(path.pieces):
        for f in piece.faces.ravel():
            colour_of[int(f)] = k
    palette = [c for i, c in enumerate(plt.get_cmap("tab20").colors) if i not in (14, 15)]  # no greys
    u = np.linspace(0.0, 1.0, samples)
    s, t = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    quads, colours = [], []
    for g in surface.groups:
        pts = evaluate_nets(g.coefficients, s, t).reshape(len(g.faces), samples, samples, 3)
        q = np.stack([pts[:, :-1, :-1], pts[:, 1:, :-1], pts[:, 1:, 1:], pts[:, :-1, 1:]], axis=3)
        for f, cell in zip(g.faces, q):
            k = colour_of.get(int(f))
            c = (0.75, 0.75, 0.75, 1.0) if k is None else (*palette[k % len(palette)], 1.0)
            quads.append(cell.reshape(-1, 4, 3))
            colours.append(np.tile(c, (cell.shape[0] * cell.shape[1], 1)))
    quads = np.concatenate(quads)
    colours = np.concatenate(colours)
    fig = plt.figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    ax = fig.add_subplot(projection="3d")
    ax.add_collection3d(Poly3DCollection(quads, facecolors=colours, edgecolors="none", alpha=0.85))
    starts = np.flatnonzero(np.r_[True, np.diff(path.piece) != 0])
    for a, b in zip(starts, np.r_[starts[1:], len(path.piece)]):
        c = path.contacts[a:b] + 0.02 * path.radius * path.normals[a:b]
        ax.plot(c[:, 0], c[:, 1], c[:, 2], color="black", lw=0.6)
    lo, hi = quads.reshape(-1, 3).min(axis=0), quads.reshape(-1, 3).max(axis=0)
    mid, half = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.view_init(elev=55, azim=-60)
    ax.set_axis_off()
    ax.set_title(f"{surface.name}: {len(path.pieces)} pieces, ball R = {path.radius:g} mm, scallop {path.scallop:g} mm")
    out = Path(out)
    with atomic_output(out) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    plt.close(fig)
    return out
