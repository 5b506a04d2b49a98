"""The data a picture is made of, shared by ``export.render`` and its drawing back ends
(``render_vtk``, ``render_mpl``): sampled triangles, a scalar field, a colouring, one
viewport's layer, and the image helpers (supersampling's average, the PNG writer)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .render_camera import Camera

__all__ = ["SHADED_COLOUR", "ZEBRA_DARK", "ZEBRA_LIGHT", "Field", "Sampled", "Style", "ViewLayer", "downsample", "write_png"]

#: Dark and light band grey levels of the zebra; the colour of a shaded picture.
ZEBRA_DARK, ZEBRA_LIGHT = 0.06, 0.97
SHADED_COLOUR = (0.62, 0.72, 0.86)


@dataclass(frozen=True)
class Field:
    """A scalar function drawn as colours with iso-lines and marked points (blending functions).

    values: (v,) per vertex; title, unit: the legend's; markers: (k, 3) points (local maxima);
    levels: iso-values; lines: (l, 2, 3) extra segments (the control mesh in a graph); range:
    the colour range (default: the values'); marker_normals: (k, 3) surface normals at the
    markers (a view hides those facing away)."""

    values: np.ndarray
    title: str
    unit: str = ""
    markers: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    levels: tuple[float, ...] = ()
    lines: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    range: tuple[float, float] | None = None
    marker_normals: np.ndarray | None = None


@dataclass(frozen=True)
class Sampled:
    """Triangles with per-vertex geometry: points (v, 3), normals (v, 3) unit outward, mean and
    gaussian (v,) curvatures, triangles (t, 3) int64, lines (l, 2, 3) the overlay (control
    mesh or a STEP file's face edges).  Optional: k1, k2 (v,) principal curvatures, weights
    (v,) area weights for statistics, edges (e, 2, 3) patch edges with edge_normals (e, 3),
    field (a blending function)."""

    points: np.ndarray
    normals: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    triangles: np.ndarray
    lines: np.ndarray
    k1: np.ndarray | None = None
    k2: np.ndarray | None = None
    weights: np.ndarray | None = None
    edges: np.ndarray | None = None
    edge_normals: np.ndarray | None = None
    field: Field | None = None


@dataclass(frozen=True)
class Style:
    """How a mode colours the surface: table (k, 3) RGB colours over range (lo, hi) of the
    scalars (None: one colour), the legend (title, unit, note) or None, extend (which ends are
    clipped: 'neither', 'min', 'max', 'both'), lighting (ambient, diffuse, specular) and the
    colour map's name (for the legend)."""

    table: np.ndarray | None
    range: tuple[float, float]
    legend: tuple[str, str, str] | None
    extend: str
    lighting: tuple[float, float, float]
    cmap: str = ""


@dataclass(frozen=True)
class ViewLayer:
    """One viewport's content: camera, per-vertex scalars (or None), line segments (l, 2, 3)
    with their colours (l, 3) and widths in pixels (l,), markers (k, 3)."""

    camera: Camera
    scalars: np.ndarray | None
    lines: np.ndarray
    line_colours: np.ndarray
    line_widths: np.ndarray
    markers: np.ndarray


def write_png(image: np.ndarray, path: Path) -> None:
    """(h, w, 3) uint8 -> PNG at ``path`` (the caller's temporary file)."""
    from matplotlib import image as mpimg

    mpimg.imsave(path, np.ascontiguousarray(image), format="png")


def downsample(image: np.ndarray, factor: int) -> np.ndarray:
    """Average ``factor`` x ``factor`` blocks of an (h f, w f, 3) image (anti-aliasing)."""
    if factor == 1:
        return image
    h, w = image.shape[0] // factor, image.shape[1] // factor
    blocks = image[: h * factor, : w * factor].astype(np.float32).reshape(h, factor, w, factor, -1)
    return np.clip(np.rint(blocks.mean(axis=(1, 3))), 0, 255).astype(np.uint8)
