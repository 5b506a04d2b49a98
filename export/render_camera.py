"""Cameras of the pictures: named views, azimuth and elevation, parallel projection fitted to
the model, the four-view sheet's layout, and the size of a pixel in model units (which the
tessellation follows, ``render_geometry.grid_size``).

Angles as in CAD systems with z up: the eye sits in the direction
(cos el cos az, cos el sin az, sin el) from the model; azimuth -90 looks from the front (-y),
0 from the right (+x), elevation 90 from the top (with +y up in the picture).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["SHEET", "VIEWS", "Camera", "fit", "frame", "sheet_viewports"]

#: Named views: (azimuth, elevation) in degrees.  iso: the isometric view from front-right-top
#: (elevation atan(1 / sqrt 2) = 35.26 deg, all three axes equally foreshortened).
VIEWS = {
    "iso": (-55.0, math.degrees(math.atan(1 / math.sqrt(2)))),
    "front": (-90.0, 0.0),
    "back": (90.0, 0.0),
    "right": (0.0, 0.0),
    "left": (180.0, 0.0),
    "top": (-90.0, 90.0),
    "bottom": (-90.0, -90.0),
}
#: The four-view sheet (--views 4), row by row from the top left: as on a drawing.
SHEET = ("front", "top", "right", "iso")
#: Share of the viewport's shorter fitted side the model fills.
FILL = 0.92
#: The zebra's eye: this many model diagonals in front of the model's centre.
EYE_DISTANCE = 1.0


@dataclass(frozen=True)
class Camera:
    """Parallel projection: screen x = (p - centre) . right / pixel, y likewise with up.

    view: unit direction the eye looks in; up, right: unit screen axes; centre: the model
    point at the viewport's centre; pixel: model units per pixel; eye: a point on the eye's
    side, EYE_DISTANCE model diagonals away (the zebra's rays start there: ``render.zebra_values``);
    viewport: (x0, y0, x1, y1) pixels of the image, y from the top; label: view name."""

    view: np.ndarray
    up: np.ndarray
    right: np.ndarray
    centre: np.ndarray
    pixel: float
    eye: np.ndarray
    viewport: tuple[int, int, int, int]
    label: str = ""

    @property
    def half_height(self) -> float:
        """VTK's parallel scale: half the viewport's height in model units."""
        return 0.5 * self.pixel * (self.viewport[3] - self.viewport[1])

    def project(self, points: np.ndarray) -> np.ndarray:
        """(n, 3) -> (n, 3): pixel x, pixel y (down, image rows) in the image, and depth
        (larger is farther from the eye)."""
        x0, y0, x1, y1 = self.viewport
        d = np.asarray(points, dtype=float) - self.centre
        x = 0.5 * (x0 + x1) + d @ self.right / self.pixel
        y = 0.5 * (y0 + y1) - d @ self.up / self.pixel
        return np.stack([x, y, d @ self.view], axis=-1)


def frame(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(view, up, right) unit vectors for an eye at azimuth/elevation degrees (module docstring)."""
    az, el = math.radians(azimuth), math.radians(elevation)
    to_eye = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    view = -to_eye
    if abs(math.sin(el)) > 1 - 1e-9:  # straight down or up: the picture's up is away from the azimuth
        up = np.array([-math.cos(az), -math.sin(az), 0.0])
    else:
        up = np.array([0.0, 0.0, 1.0]) - math.sin(el) * to_eye
    up /= np.linalg.norm(up)
    right = np.cross(view, up)
    return view, up, right / np.linalg.norm(right)


def fit(points: np.ndarray, azimuth: float, elevation: float, viewport: tuple[int, int, int, int],
        label: str = "", fill: float = FILL) -> Camera:
    """The camera of that direction whose picture of ``points`` fills ``fill`` of the viewport."""
    view, up, right = frame(azimuth, elevation)
    points = np.asarray(points, dtype=float)
    lo, hi = points.min(axis=0), points.max(axis=0)
    diagonal = float(np.linalg.norm(hi - lo)) or 1.0
    x, y = points @ right, points @ up
    width, height = viewport[2] - viewport[0], viewport[3] - viewport[1]
    span_x, span_y = float(np.ptp(x)), float(np.ptp(y))
    pixel = max(span_x / (fill * width), span_y / (fill * height), 1e-12 * diagonal)
    centre_depth = 0.5 * (lo + hi) @ view
    centre = 0.5 * (x.min() + x.max()) * right + 0.5 * (y.min() + y.max()) * up + centre_depth * view
    eye = centre - EYE_DISTANCE * diagonal * view
    return Camera(view, up, right, centre, pixel, eye, viewport, label)


def sheet_viewports(size: tuple[int, int], views: int) -> list[tuple[int, int, int, int]]:
    """Viewports (x0, y0, x1, y1) of one view or a 2 x 2 sheet in an image of ``size``."""
    w, h = size
    if views == 1:
        return [(0, 0, w, h)]
    hw, hh = w // 2, h // 2
    return [(0, 0, hw, hh), (hw, 0, w, hh), (0, hh, hw, h), (hw, hh, w, h)]
