"""Pictures of a surface a CAD user can read, headless: shaded, zebra stripes, curvature maps
with a legend beside the model, and blending functions.

What is drawn.  A mesh's surface is sampled on the exact patches (``export.render_geometry``:
one m x m grid a patch, m from the picture's pixel size, curvatures from the patches' second
derivatives); a STEP file is sampled with OpenCASCADE (``sample_shape``: ``BRepMesh`` nodes,
deflection one pixel, and ``GeomLProp_SLProps`` at each node's (u, v)).

- Zebra (reflection lines): a point p with unit normal n is seen along the ray
  v = (p - e) / |p - e| from an eye e one model diagonal in front of the model (a finite eye:
  a flat face shows straight stripes instead of one flat colour), reflected to
  r = v - 2 (v . n) n; the stripe parameter phi = asin(r . w) in [-pi/2, pi/2] is the
  reflected ray's angle out of the plane of the light lines, w the screen axis across them
  (``--stripe-direction``), and ``stripes`` dark and as many light bands cut [-pi/2, pi/2]:
  light lines at infinity, as in CAD systems' zebra analysis.  phi is continuous where n is:
  a stripe breaks across a normal jump (G0 only) and kinks across a curvature jump (G1, not
  G2).  asin rather than an angle around an axis: no wrap-around seam.  The bands are shaded
  (diffuse light from the eye) so the shape reads under them; edges are anti-aliased by
  supersampling (the image drawn ``supersample`` times larger and averaged down; above 4
  megapixels only VTK's multisampling, which smooths triangle edges, not stripe edges).
- Curvature: mean H, Gaussian K, principal k1 >= k2 (``render_geometry``'s signs: convex > 0)
  or max(|k1|, |k2|); the colour range is the 2nd to 98th percentile of the values weighted
  by area (or ``--range``), symmetric about 0 in a diverging map for the signed ones; values
  beyond it take the end colours (the legend's arrows).  The legend is a strip of its own
  beside the model (``export.render_legend``), units 1/mm and 1/mm^2 (model units as mm).
- Blending functions: ``export.render_blending``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from patching.errors import NupatchError

from .render_camera import SHEET, VIEWS, Camera, fit, sheet_viewports
from .render_scene import (
    ZEBRA_DARK,
    ZEBRA_LIGHT,
    Field,
    Sampled,
    Style,
    ViewLayer,
    write_png,
)

__all__ = [
    "CURVATURES",
    "MODES",
    "Field",
    "Picture",
    "Sampled",
    "Style",
    "ViewLayer",
    "cameras",
    "legend_width",
    "mode_values",
    "picture_pixel",
    "render",
    "robust_range",
    "sample_shape",
    "sample_surface",
    "style",
    "supersample_factor",
    "write_png",
    "zebra_parameter",
    "zebra_values",
]

MODES = ("shaded", "zebra", "mean", "gaussian", "k1", "k2", "max-abs", "blending")
#: Curvature modes: (legend title, unit, diverging about 0).
CURVATURES = {
    "mean": ("mean curvature H", "1/mm", True),
    "gaussian": ("Gaussian curvature K", "1/mm²", True),
    "k1": ("largest principal curvature k1", "1/mm", True),
    "k2": ("smallest principal curvature k2", "1/mm", True),
    "max-abs": ("max(|k1|, |k2|)", "1/mm", False),
}


@dataclass(frozen=True)
class Picture:
    """How a picture looks: view (a name of ``render_camera.VIEWS``), azimuth / elevation
    (degrees, override the view's), views (1, or 4 for the sheet), stripes (dark bands of the
    zebra), stripe_direction (degrees from vertical light lines), edges (draw the patch edges),
    value_range (colour range, else robust), supersample (None: automatic)."""

    view: str = "iso"
    azimuth: float | None = None
    elevation: float | None = None
    views: int = 1
    stripes: int = 32
    stripe_direction: float = 0.0
    edges: bool = False
    value_range: tuple[float, float] | None = None
    supersample: int | None = None

    def __post_init__(self) -> None:
        if self.view not in VIEWS:
            raise NupatchError(f"--view {self.view}: not one of {', '.join(VIEWS)}", "command line")
        if self.views not in (1, 4):
            raise NupatchError(f"--views {self.views}: 1 or 4", "command line")
        if not 1 <= self.stripes <= 500:
            raise NupatchError(f"--stripes {self.stripes}: 1 to 500", "command line")
        for name, x in (("--azimuth", self.azimuth), ("--elevation", self.elevation), ("--stripe-direction", self.stripe_direction)):
            if x is not None and not math.isfinite(x):
                raise NupatchError(f"{name} must be a finite number of degrees, not {x}", "command line")
        if self.elevation is not None and abs(self.elevation) > 90:
            raise NupatchError(f"--elevation {self.elevation:g}: -90 to 90 degrees", "command line")
        if self.value_range is not None:
            lo, hi = self.value_range
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise NupatchError(f"--range {lo:g} {hi:g}: need finite LO < HI", "command line")
        if self.supersample is not None and not 1 <= self.supersample <= 4:
            raise NupatchError(f"supersample {self.supersample}: 1 to 4", "command line")

    def directions(self) -> list[tuple[float, float, str]]:
        """(azimuth, elevation, label) of every view drawn."""
        if self.views == 4:
            return [(*VIEWS[name], name) for name in SHEET]
        az, el = VIEWS[self.view]
        az = az if self.azimuth is None else self.azimuth
        el = el if self.elevation is None else self.elevation
        return [(az, el, "")]


# -- sampling -------------------------------------------------------------------------------


def sample_surface(surface, pixel: float, lines: np.ndarray | None = None, m: int | None = None) -> Sampled:
    """The patches of a BezierSurface sampled for a picture whose pixel is ``pixel`` model
    units (``render_geometry``); lines: overlay segments (the control mesh), default none.
    m: samples per patch side (default from the pixel)."""
    from .render_geometry import grid_size, grid_triangles, sample_patches

    m = grid_size(surface, pixel) if m is None else int(m)
    s = sample_patches(surface, m)
    p = len(s.faces)

    def flat(a: np.ndarray) -> np.ndarray:
        return a.reshape(p * m * m, *a.shape[3:])

    return Sampled(
        flat(s.points), flat(s.normals), flat(s.mean), flat(s.gaussian), grid_triangles(p, m),
        np.zeros((0, 2, 3)) if lines is None else np.asarray(lines, dtype=float).reshape(-1, 2, 3),
        k1=flat(s.k1), k2=flat(s.k2), weights=flat(s.area), edges=s.edge_lines(), edge_normals=s.edge_normals(),
    )


def sample_shape(shape, tolerance: float, lines: np.ndarray | None = None) -> Sampled:
    """Tessellate ``shape`` (linear deflection ``tolerance``) and evaluate each face's surface
    at its nodes (module docstring).  ``lines``: (l, 2, 3) segments to overlay; default the
    faces' boundary edges (also the ``edges``)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.GeomLProp import GeomLProp_SLProps
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp
    from OCP.TopLoc import TopLoc_Location

    from .ocp_compat import TopoDS, TopTools_IndexedMapOfShape

    BRepMesh_IncrementalMesh(shape, float(tolerance), False, 0.1, False)
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    rows, tris = [], []
    base = 0
    for i in range(1, faces.Extent() + 1):
        face = TopoDS.Face_s(faces.FindKey(i))
        location = TopLoc_Location()
        poly = BRep_Tool.Triangulation_s(face, location)
        if poly is None:
            continue
        surface = BRep_Tool.Surface_s(face)
        sign = -1.0 if face.Orientation() == TopAbs_REVERSED else 1.0
        props = GeomLProp_SLProps(surface, 2, 1e-12)
        for k in range(1, poly.NbNodes() + 1):
            u, v = poly.UVNode(k).Coord()
            props.SetParameters(u, v)
            row = list(props.Value().Coord())
            row += [sign * c for c in props.Normal().Coord()] if props.IsNormalDefined() else [0.0, 0.0, 0.0]
            if props.IsCurvatureDefined():
                # OpenCASCADE's curvatures follow the surface's own normal, positive where the
                # surface bends towards it: flip to "convex > 0" about the outward normal.
                big, small = props.MaxCurvature(), props.MinCurvature()
                k1, k2 = sorted((-sign * big, -sign * small), reverse=True)
                row += [-sign * props.MeanCurvature(), props.GaussianCurvature(), k1, k2]
            else:
                row += [np.nan] * 4
            rows.append(row)
        t = np.array([poly.Triangle(k).Get() for k in range(1, poly.NbTriangles() + 1)], dtype=np.int64) - 1
        if sign < 0:
            t = t[:, ::-1]
        tris.append(t + base)
        base += poly.NbNodes()
    if not tris:
        raise NupatchError("nothing to draw: the shape has no faces", "render")
    from OCP.BRepAdaptor import BRepAdaptor_Curve

    edges = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_EDGE, edges)
    segments = []
    for i in range(1, edges.Extent() + 1):
        edge = TopoDS.Edge_s(edges.FindKey(i))
        if BRep_Tool.Degenerated_s(edge):
            continue
        curve = BRepAdaptor_Curve(edge)
        w = np.linspace(curve.FirstParameter(), curve.LastParameter(), 17)
        p = np.array([curve.Value(float(x)).Coord() for x in w])
        segments.append(np.stack([p[:-1], p[1:]], axis=1))
    face_edges = np.concatenate(segments) if segments else np.zeros((0, 2, 3))
    data = np.array(rows, dtype=float)
    triangles = np.concatenate(tris)
    return Sampled(
        data[:, :3], data[:, 3:6], data[:, 6], data[:, 7], triangles,
        face_edges if lines is None else np.asarray(lines, dtype=float).reshape(-1, 2, 3),
        k1=data[:, 8], k2=data[:, 9], weights=_vertex_areas(data[:, :3], triangles), edges=face_edges,
    )


def _vertex_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """A third of the area of the triangles at each vertex (weights of statistics)."""
    a = 0.5 * np.linalg.norm(np.cross(points[triangles[:, 1]] - points[triangles[:, 0]], points[triangles[:, 2]] - points[triangles[:, 0]]), axis=1)
    return np.bincount(triangles.ravel(), np.repeat(a / 3.0, 3), minlength=len(points))


# -- cameras, zebra, colour ranges ---------------------------------------------------------


def legend_width(size: tuple[int, int]) -> int:
    """Pixels of the legend strip at the right of an image of ``size``."""
    return int(np.clip(0.17 * size[0], 110, 300))


def cameras(points: np.ndarray, size: tuple[int, int], picture: Picture, legend: bool) -> list[Camera]:
    """The cameras of the picture's views, fitted to ``points`` in the model area (the image
    less the legend strip)."""
    width = size[0] - (legend_width(size) if legend else 0)
    ports = sheet_viewports((width, size[1]), picture.views)
    return [fit(points, az, el, port, label) for (az, el, label), port in zip(picture.directions(), ports)]


def picture_pixel(points: np.ndarray, size: tuple[int, int], picture: Picture, legend: bool) -> float:
    """Model units per pixel of the picture's finest view (the tessellation follows it)."""
    return min(c.pixel for c in cameras(points, size, picture, legend))


def zebra_parameter(normals: np.ndarray, view: np.ndarray, up: np.ndarray, angle: float = 0.0) -> np.ndarray:
    """phi = asin(r . w) in [-pi/2, pi/2] of the view rays ``view`` ((3,) or (n, 3), unit)
    reflected in the normals, w = cos(angle) right + sin(angle) up, right = view x up (module
    docstring)."""
    view = np.broadcast_to(np.asarray(view, dtype=float), normals.shape)
    r = view - 2.0 * np.einsum("ij,ij->i", view, normals)[:, None] * normals
    right = np.cross(view, up)
    right /= np.linalg.norm(right, axis=-1, keepdims=True)
    a = math.radians(angle)
    w = math.cos(a) * right + math.sin(a) * np.asarray(up, dtype=float)
    return np.arcsin(np.clip(np.einsum("ij,ij->i", r, w), -1.0, 1.0))


def zebra_values(sampled: Sampled, camera: Camera, picture: Picture) -> np.ndarray:
    """The zebra parameter of every vertex seen by ``camera`` (rays from its eye)."""
    rays = sampled.points - camera.eye
    rays /= np.maximum(np.linalg.norm(rays, axis=1, keepdims=True), 1e-300)
    return zebra_parameter(sampled.normals, rays, camera.up, picture.stripe_direction)


def robust_range(values: np.ndarray, weights: np.ndarray | None = None, percentiles=(2.0, 98.0),
                 diverging: bool = True) -> tuple[float, float]:
    """The colour range: the weighted ``percentiles`` of the finite values; for a diverging map
    symmetric about 0 (+-the larger of the two magnitudes), else from 0 up (non-negative
    values) or between the two percentiles."""
    values = np.asarray(values, dtype=float)
    ok = np.isfinite(values)
    if weights is not None:
        ok &= np.isfinite(weights) & (weights > 0)
    v = values[ok]
    if v.size == 0:
        return (-1.0, 1.0) if diverging else (0.0, 1.0)
    w = np.ones_like(v) if weights is None else np.asarray(weights, dtype=float)[ok]
    order = np.argsort(v)
    cumulative = np.cumsum(w[order])
    cumulative /= cumulative[-1]
    lo, hi = (float(v[order][min(np.searchsorted(cumulative, q / 100.0), v.size - 1)]) for q in percentiles)
    scale = max(abs(lo), abs(hi), float(np.abs(v).max()) * 1e-12, 1e-300)
    if diverging:
        top = max(abs(lo), abs(hi))
        top = top if top > 1e-9 * scale and top > 0 else (float(np.abs(v).max()) or 1.0)
        return -top, top
    if lo >= 0:
        lo = 0.0
    if hi <= lo:
        hi = lo + (scale if scale > 1e-300 else 1.0)
    return lo, hi


def _colour_table(name: str, n: int = 256) -> np.ndarray:
    import matplotlib

    return np.asarray(matplotlib.colormaps[name](np.linspace(0.0, 1.0, n)))[:, :3]


def _extend(values: np.ndarray, lo: float, hi: float) -> str:
    v = values[np.isfinite(values)]
    below, above = bool((v < lo).any()), bool((v > hi).any())
    return {(False, False): "neither", (True, False): "min", (False, True): "max", (True, True): "both"}[(below, above)]


def mode_values(sampled: Sampled, mode: str) -> np.ndarray:
    """Per-vertex scalar of a curvature or blending mode."""
    if mode == "blending":
        if sampled.field is None:
            raise ValueError("mode 'blending' needs sampled.field")
        return sampled.field.values
    if mode in ("k1", "k2", "max-abs") and sampled.k1 is None:
        raise NupatchError(f"--curvature {mode} needs principal curvatures, which this sampling lacks", "render")
    if mode == "max-abs":
        return np.maximum(np.abs(sampled.k1), np.abs(sampled.k2))
    return {"mean": sampled.mean, "gaussian": sampled.gaussian, "k1": sampled.k1, "k2": sampled.k2}[mode]


def style(sampled: Sampled, mode: str, picture: Picture) -> Style:
    """The colouring of a mode (module docstring)."""
    if mode == "shaded":
        return Style(None, (0.0, 1.0), None, "neither", (0.25, 0.75, 0.35))
    if mode == "zebra":
        n = 2 * picture.stripes
        table = np.where((np.arange(n) % 2 == 0)[:, None], ZEBRA_LIGHT, ZEBRA_DARK) * np.ones((1, 3))
        return Style(table, (-math.pi / 2, math.pi / 2), None, "neither", (0.5, 0.5, 0.0))
    values = mode_values(sampled, mode)
    if mode == "blending":
        f = sampled.field
        lo, hi = picture.value_range or f.range or robust_range(values, None, (0.0, 100.0), diverging=False)
        note = "iso-lines: " + ", ".join(f"{x:g}" for x in f.levels) if f.levels else ""
        return Style(_colour_table("viridis"), (lo, hi), (f.title, f.unit, note), _extend(values, lo, hi), (0.45, 0.55, 0.15), "viridis")
    title, unit, diverging = CURVATURES[mode]
    if picture.value_range is not None:
        (lo, hi), note = picture.value_range, "range as given"
    else:
        (lo, hi), note = robust_range(values, sampled.weights, diverging=diverging), "range: 2nd-98th percentile"
    name = "RdBu_r" if diverging else "viridis"
    return Style(_colour_table(name), (lo, hi), (title, unit, note), _extend(values, lo, hi), (0.45, 0.55, 0.15), name)


# -- drawing --------------------------------------------------------------------------------


def _layers(sampled: Sampled, mode: str, picture: Picture, overlay: bool, legend: bool, size) -> list[ViewLayer]:
    out = []
    for cam in cameras(sampled.points, size, picture, legend):
        if mode == "zebra":
            scalars = zebra_values(sampled, cam, picture)
        elif mode == "shaded":
            scalars = None
        else:
            scalars = np.nan_to_num(mode_values(sampled, mode))
        groups = []  # (segments, colour, width)
        if mode == "blending" and sampled.field is not None:
            from .render_blending import iso_segments

            levels = sampled.field.levels
            if levels:
                groups.append((iso_segments(sampled.points, sampled.triangles, sampled.field.values, levels), (0.05, 0.05, 0.05), 1.0))
            if len(sampled.field.lines):
                groups.append((sampled.field.lines, (0.35, 0.35, 0.35), 1.0))
        if picture.edges and sampled.edges is not None and len(sampled.edges):
            groups.append((sampled.edges, (0.85, 0.2, 0.1) if mode == "zebra" else (0.15, 0.15, 0.15), 1.0))
        if overlay and len(sampled.lines):
            groups.append((sampled.lines, (0.1, 0.1, 0.1), 1.5))
        if groups:
            lines = np.concatenate([g[0] for g in groups])
            colours = np.concatenate([np.tile(g[1], (len(g[0]), 1)) for g in groups])
            widths = np.concatenate([np.full(len(g[0]), g[2]) for g in groups])
        else:
            lines, colours, widths = np.zeros((0, 2, 3)), np.zeros((0, 3)), np.zeros(0)
        markers = np.zeros((0, 3))
        if mode == "blending" and sampled.field is not None:
            markers = sampled.field.markers
            if sampled.field.marker_normals is not None:  # hidden behind the part: not drawn
                markers = markers[sampled.field.marker_normals @ cam.view < -0.05]
        out.append(ViewLayer(cam, scalars, lines, colours, widths, markers))
    return out


def supersample_factor(size: tuple[int, int], picture: Picture) -> int:
    """Automatic supersampling: 3 up to 1 megapixel, 2 up to 4, then 1 (VTK multisamples then)."""
    if picture.supersample is not None:
        return picture.supersample
    pixels = size[0] * size[1]
    return 3 if pixels <= 1_000_000 else 2 if pixels <= 4_000_000 else 1


def render(sampled: Sampled, path: str | os.PathLike, mode: str = "shaded", size: tuple[int, int] = (800, 600),
           overlay: bool = False, renderer: str = "auto", picture: Picture | None = None) -> str:
    """Draw ``sampled`` to the PNG ``path`` (written by the caller's atomic wrapper: pass the
    temporary path); returns the renderer used, "vtk" or "matplotlib".  overlay: draw
    ``sampled.lines`` (the control mesh)."""
    if mode not in MODES:
        raise ValueError(f"mode {mode!r} not in {MODES}")
    picture = picture or Picture()
    try:
        import matplotlib  # noqa: F401  (colour tables, legend, fallback)
    except ImportError:
        raise NupatchError("pictures need matplotlib: pip install 'nupatch[render]'", "render") from None
    look = style(sampled, mode, picture)
    legend = look.legend is not None
    layers = _layers(sampled, mode, picture, overlay, legend, size)
    width = size[0] - (legend_width(size) if legend else 0)
    factor = supersample_factor(size, picture)
    image, used = None, "matplotlib"
    if renderer in ("auto", "vtk"):
        from .render_vtk import draw as draw_vtk

        try:
            image, used = draw_vtk(sampled, layers, look, (width, size[1]), factor), "vtk"
        except RuntimeError:
            if renderer == "vtk":
                raise
    if image is None:
        from .render_mpl import draw as draw_mpl

        image = draw_mpl(sampled, layers, look, (width, size[1]), factor)
    if legend:
        from .render_legend import legend_image

        title, unit, note = look.legend
        strip = legend_image((size[0] - width, size[1]), look.cmap, look.range, title, unit, note, look.extend)
        image = np.concatenate([image, strip], axis=1)
    write_png(image, Path(path))
    return used
