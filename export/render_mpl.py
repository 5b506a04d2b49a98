"""The matplotlib (Agg) fallback of ``export.render_vtk``, for machines where VTK opens no
OpenGL context: the same cameras (``render_camera``: parallel projection, the triangles
projected to pixels here), triangles sorted back to front (painter's algorithm) and filled with
the colour of their mean scalar, shaded by their normal; lines drawn on top where their
surface normal faces the eye (back edges are dropped, an edge hidden behind a nearer part of
the surface is not); supersampled by ``factor`` like the VTK drawing.  Slower, and flat-shaded
per triangle."""

from __future__ import annotations

import numpy as np

from .render_scene import SHADED_COLOUR, Sampled, Style, ViewLayer, downsample

__all__ = ["draw"]


def draw(sampled: Sampled, layers: list[ViewLayer], look: Style, size: tuple[int, int], factor: int) -> np.ndarray:
    """(h, w, 3) uint8 image of ``size`` with one viewport per layer."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    w, h = size
    W, H = w * factor, h * factor
    dpi = 100.0
    fig = Figure(figsize=(W / dpi, H / dpi), dpi=dpi, facecolor="white")
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(0, W)
    ax.set_ylim(H, 0)
    ax.set_axis_off()
    tri = sampled.triangles
    ambient, diffuse, _ = look.lighting
    for layer in layers:
        cam = layer.camera
        x0, y0, _x1, _y1 = cam.viewport
        xy = cam.project(sampled.points)
        screen = xy[:, :2] * factor
        normal = sampled.normals[tri].mean(axis=1)
        facing = -(normal @ cam.view)
        keep = facing > -1e-9  # back faces of a closed part are hidden anyway
        depth = xy[tri, 2].mean(axis=1)
        order = np.flatnonzero(keep)[np.argsort(-depth[keep])]
        shade = ambient + diffuse * np.clip(facing[order], 0.0, 1.0) / max(np.linalg.norm(normal[order], axis=1).max(), 1e-300)
        if layer.scalars is None or look.table is None:
            base = np.tile(SHADED_COLOUR, (order.size, 1))
        else:
            lo, hi = look.range
            value = layer.scalars[tri[order]].mean(axis=1)
            k = np.clip(((value - lo) / (hi - lo) * len(look.table)).astype(int), 0, len(look.table) - 1)
            base = look.table[k]
        colours = np.clip(base * shade[:, None], 0.0, 1.0)
        polys = PolyCollection(screen[tri[order]], facecolors=colours, edgecolors=colours, linewidths=0.3, antialiased=True)
        polys.set_clip_box(None)
        ax.add_collection(polys)
        if len(layer.lines):
            seen = np.ones(len(layer.lines), dtype=bool)
            if sampled.edge_normals is not None and len(sampled.edge_normals) == len(layer.lines):
                seen = sampled.edge_normals @ cam.view < 1e-9
            ends = cam.project(layer.lines.reshape(-1, 3))[:, :2].reshape(-1, 2, 2) * factor
            ax.add_collection(LineCollection(ends[seen], colors=layer.line_colours[seen], linewidths=layer.line_widths[seen] * factor * 0.72))
        if len(layer.markers):
            p = cam.project(layer.markers)[:, :2] * factor
            ax.scatter(p[:, 0], p[:, 1], s=(7.0 * factor) ** 2, c=[(0.85, 0.05, 0.05)], edgecolors="white", linewidths=1.5 * factor, zorder=5)
        if cam.label:
            ax.text((x0 + 8) * factor, (y0 + 8) * factor, cam.label, fontsize=10 * factor, color="0.2", va="top")
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())[:H, :W, :3]
    return downsample(np.ascontiguousarray(rgba), factor)
