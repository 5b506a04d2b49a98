"""Pictures of a surface, headless: shaded, zebra stripes, curvature with a legend.

Renderer: VTK (9.x, installed with cadquery-ocp), off-screen.  On a machine without a display
VTK's render-window factory falls back from X to EGL; we silence its warning about X.  VTK is
the well-kept choice here: it is already in the environment (no new dependency), renders
smooth-shaded triangles with per-pixel interpolated scalars (crisp zebra stripes from a banded
lookup table) and has a scalar bar for the legend.  If VTK cannot open any off-screen context
(``RuntimeError``), matplotlib's Agg backend draws the same triangles and colours (flat-shaded,
slower, and with its painter's-algorithm depth sorting): ``renderer="matplotlib"`` forces it.

What is drawn is sampled with OpenCASCADE on the B-rep, whatever the source (a STEP file, or a
mesh built by nupatch): ``BRepMesh_IncrementalMesh`` nodes, and at each node's (u, v) the face
surface's point, unit normal, mean and Gaussian curvature (``GeomLProp_SLProps``), with
normals flipped on REVERSED faces.

- Zebra: the view direction v (parallel projection) reflected in the normal,
  r = v - 2 (v . n) n; the stripe parameter is phi = asin(r . right), the reflected ray's
  elevation out of the plane (v, up), drawn as ``ZEBRA_STRIPES`` black and white bands over
  [-pi/2, pi/2]: the reflection of a field of light lines at infinity parallel to the camera's
  up axis, as in CAD systems' zebra analysis.  A stripe breaks across a normal jump (a G1
  defect) and kinks across a curvature jump (G1 but not G2).  asin rather than an angle around
  the up axis: no wrap-around seam, so no aliasing where r points away from the light lines.
- Curvature: mean H = (k1 + k2) / 2 or Gaussian K = k1 k2, a diverging map centred on 0 and
  clipped at the 2nd and 98th percentiles of |value|, with a legend.
- Mesh: the control mesh's edges (mesh input) or the faces' boundary edges (STEP input) on top.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from patching.errors import NupatchError

__all__ = ["MODES", "Sampled", "sample_shape", "render"]

MODES = ("shaded", "zebra", "mean", "gaussian")
ZEBRA_STRIPES = 16
#: Camera: looking down at the model from azimuth 35 deg, elevation 30 deg.
AZIMUTH, ELEVATION = 35.0, 30.0


@dataclass(frozen=True)
class Sampled:
    """Triangles with per-vertex geometry: points (v, 3), normals (v, 3) unit outward,
    mean and gaussian (v,) curvatures, triangles (t, 3) int64, lines (l, 2, 3) overlay segments."""

    points: np.ndarray
    normals: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    triangles: np.ndarray
    lines: np.ndarray


def sample_shape(shape, tolerance: float, lines: np.ndarray | None = None) -> Sampled:
    """Tessellate ``shape`` (linear deflection ``tolerance``) and evaluate each face's surface
    at its nodes (module docstring).  ``lines``: (l, 2, 3) segments to overlay; default the
    faces' boundary edges."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.GeomLProp import GeomLProp_SLProps
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp
    from OCP.TopLoc import TopLoc_Location
    from .ocp_compat import TopoDS
    from .ocp_compat import TopTools_IndexedMapOfShape

    BRepMesh_IncrementalMesh(shape, float(tolerance), False, 0.3, False)
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    points, normals, mean, gauss, tris = [], [], [], [], []
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
            points.append(props.Value().Coord())
            if props.IsNormalDefined():
                normals.append(tuple(sign * c for c in props.Normal().Coord()))
            else:
                normals.append((0.0, 0.0, 0.0))
            if props.IsCurvatureDefined():
                # Curvatures follow the surface's own normal: flip H with the face.
                mean.append(sign * props.MeanCurvature())
                gauss.append(props.GaussianCurvature())
            else:
                mean.append(0.0)
                gauss.append(0.0)
        t = np.array([poly.Triangle(k).Get() for k in range(1, poly.NbTriangles() + 1)], dtype=np.int64) - 1
        if sign < 0:
            t = t[:, ::-1]
        tris.append(t + base)
        base += poly.NbNodes()
    if not tris:
        raise NupatchError("nothing to draw: the shape has no faces", "render")
    if lines is None:
        from OCP.BRepAdaptor import BRepAdaptor_Curve

        edges = TopTools_IndexedMapOfShape()
        TopExp.MapShapes_s(shape, TopAbs_EDGE, edges)
        segments = []
        for i in range(1, edges.Extent() + 1):
            edge = TopoDS.Edge_s(edges.FindKey(i))
            if BRep_Tool.Degenerated_s(edge):
                continue
            curve = BRepAdaptor_Curve(edge)
            w = np.linspace(curve.FirstParameter(), curve.LastParameter(), 9)
            p = np.array([curve.Value(float(x)).Coord() for x in w])
            segments.append(np.stack([p[:-1], p[1:]], axis=1))
        lines = np.concatenate(segments) if segments else np.zeros((0, 2, 3))
    return Sampled(
        np.array(points, dtype=float),
        np.array(normals, dtype=float),
        np.array(mean, dtype=float),
        np.array(gauss, dtype=float),
        np.concatenate(tris),
        np.asarray(lines, dtype=float).reshape(-1, 2, 3),
    )


def _camera(points: np.ndarray):
    """(view direction v (from the eye), up, right) of the fixed camera."""
    az, el = math.radians(AZIMUTH), math.radians(ELEVATION)
    to_eye = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    view = -to_eye
    up = np.array([0.0, 0.0, 1.0]) - math.sin(el) * to_eye
    up /= np.linalg.norm(up)
    right = np.cross(view, up)
    return view, up, right


def zebra_parameter(normals: np.ndarray, view: np.ndarray, up: np.ndarray) -> np.ndarray:
    """asin(r . right) in [-pi/2, pi/2] of the reflected view ray r (module docstring)."""
    r = view - 2.0 * (normals @ view)[:, None] * normals
    right = np.cross(view, up)
    return np.arcsin(np.clip(r @ right, -1.0, 1.0))


def _scalars(sampled: Sampled, mode: str):
    """(values or None, (lo, hi), title) for a mode."""
    if mode == "shaded":
        return None, (0.0, 1.0), ""
    if mode == "zebra":
        view, up, _ = _camera(sampled.points)
        return zebra_parameter(sampled.normals, view, up), (-math.pi / 2, math.pi / 2), ""
    values = sampled.mean if mode == "mean" else sampled.gaussian
    finite = np.abs(values[np.isfinite(values)])
    top = float(np.percentile(finite, 98)) if finite.size else 1.0
    top = top if top > 0 else 1.0
    title = "mean curvature H" if mode == "mean" else "Gaussian curvature K"
    return np.clip(np.nan_to_num(values), -top, top), (-top, top), title


def render(sampled: Sampled, path: str | os.PathLike, mode: str = "shaded", size: tuple[int, int] = (800, 600),
           overlay: bool = False, renderer: str = "auto") -> str:
    """Draw ``sampled`` to the PNG ``path`` (written by the caller's atomic wrapper: pass the
    temporary path); returns the renderer used, "vtk" or "matplotlib"."""
    if mode not in MODES:
        raise ValueError(f"mode {mode!r} not in {MODES}")
    if renderer in ("auto", "vtk"):
        try:
            _render_vtk(sampled, Path(path), mode, size, overlay)
            return "vtk"
        except RuntimeError:
            if renderer == "vtk":
                raise
    _render_matplotlib(sampled, Path(path), mode, size, overlay)
    return "matplotlib"


def _render_vtk(sampled: Sampled, path: Path, mode: str, size: tuple[int, int], overlay: bool) -> None:
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray

    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)  # "bad X server connection"
    vtk.vtkObject.GlobalWarningDisplayOff()

    def polydata(points: np.ndarray, cells: np.ndarray, kind: str):
        data = vtk.vtkPolyData()
        pts = vtk.vtkPoints()
        pts.SetData(numpy_to_vtk(np.ascontiguousarray(points), deep=True))
        data.SetPoints(pts)
        n = cells.shape[1]
        flat = np.hstack([np.full((len(cells), 1), n, dtype=np.int64), cells]).ravel()
        array = vtk.vtkCellArray()
        array.SetCells(len(cells), numpy_to_vtkIdTypeArray(flat, deep=True))
        data.SetPolys(array) if kind == "polys" else data.SetLines(array)
        return data

    surface = polydata(sampled.points, sampled.triangles, "polys")
    surface.GetPointData().SetNormals(numpy_to_vtk(np.ascontiguousarray(sampled.normals), deep=True))
    values, (lo, hi), title = _scalars(sampled, mode)
    mapper = vtk.vtkPolyDataMapper()
    mapper.SetInputData(surface)
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    ren = vtk.vtkRenderer()
    ren.SetBackground(1.0, 1.0, 1.0)
    if values is None:
        mapper.ScalarVisibilityOff()
        actor.GetProperty().SetColor(0.62, 0.72, 0.86)
        actor.GetProperty().SetSpecular(0.3)
        actor.GetProperty().SetSpecularPower(30)
    else:
        surface.GetPointData().SetScalars(numpy_to_vtk(np.ascontiguousarray(values), deep=True))
        lut = vtk.vtkLookupTable()
        if mode == "zebra":
            lut.SetNumberOfTableValues(ZEBRA_STRIPES)
            for k in range(ZEBRA_STRIPES):
                c = 0.05 if k % 2 else 0.97
                lut.SetTableValue(k, c, c, c, 1.0)
            actor.GetProperty().SetAmbient(1.0)  # the stripes are the light: no shading on top
            actor.GetProperty().SetDiffuse(0.0)
        else:
            lut.SetNumberOfTableValues(256)
            for k in range(256):  # blue - white - red
                x = k / 255.0 * 2 - 1
                r, g, b = (1.0, 1 - x, 1 - x) if x > 0 else (1 + x, 1 + x, 1.0)
                lut.SetTableValue(k, 0.15 + 0.85 * r, 0.15 + 0.85 * g, 0.15 + 0.85 * b, 1.0)
        lut.SetRange(lo, hi)
        lut.Build()
        mapper.SetLookupTable(lut)
        mapper.SetScalarRange(lo, hi)
        mapper.InterpolateScalarsBeforeMappingOn()  # crisp bands, interpolated per pixel
        if title:
            bar = vtk.vtkScalarBarActor()
            bar.SetLookupTable(lut)
            bar.SetTitle(title)
            bar.SetNumberOfLabels(5)
            bar.SetLabelFormat("%-#8.3g")
            bar.SetWidth(0.12)
            bar.SetHeight(0.8)
            bar.SetPosition(0.86, 0.1)
            bar.UnconstrainedFontSizeOn()
            for prop, font in ((bar.GetTitleTextProperty(), 16), (bar.GetLabelTextProperty(), 14)):
                prop.SetFontSize(font)
                prop.SetColor(0.1, 0.1, 0.1)
                prop.ShadowOff()
                prop.ItalicOff()
            ren.AddActor2D(bar)
    ren.AddActor(actor)
    if overlay and len(sampled.lines):
        ends = sampled.lines.reshape(-1, 3)
        edges = polydata(ends, np.arange(len(ends)).reshape(-1, 2), "lines")
        line_mapper = vtk.vtkPolyDataMapper()
        line_mapper.SetInputData(edges)
        line_mapper.SetResolveCoincidentTopologyToPolygonOffset()
        line_actor = vtk.vtkActor()
        line_actor.SetMapper(line_mapper)
        line_actor.GetProperty().SetColor(0.1, 0.1, 0.1)
        line_actor.GetProperty().SetLineWidth(1.5)
        line_actor.GetProperty().SetLighting(False)
        ren.AddActor(line_actor)
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(*size)
    window.SetMultiSamples(8)
    window.AddRenderer(ren)
    camera = ren.GetActiveCamera()
    view, up, _ = _camera(sampled.points)
    centre = 0.5 * (sampled.points.min(axis=0) + sampled.points.max(axis=0))
    camera.SetFocalPoint(*centre)
    camera.SetPosition(*(centre - view))
    camera.SetViewUp(*up)
    camera.ParallelProjectionOn()  # one view direction everywhere, as the zebra assumes
    ren.ResetCamera()
    camera.Zoom(1.25 if not title else 1.05)  # ResetCamera leaves a wide margin; less with a legend
    if not window.SupportsOpenGL():
        raise RuntimeError("VTK could not open an off-screen OpenGL context")
    window.Render()
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.ReadFrontBufferOff()
    grab.Update()
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(str(path))
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()
    window.Finalize()
    if not path.exists() or path.stat().st_size == 0:
        raise RuntimeError("VTK wrote no image")


def _render_matplotlib(sampled: Sampled, path: Path, mode: str, size: tuple[int, int], overlay: bool) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import cm, colors
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    values, (lo, hi), title = _scalars(sampled, mode)
    dpi = 100
    fig = plt.figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    ax.set_axis_off()
    tri = sampled.triangles
    view, _, _ = _camera(sampled.points)
    if values is None:
        shade = np.clip(-(sampled.normals[tri].mean(axis=1) @ view), 0.0, 1.0)
        face_colors = np.outer(0.35 + 0.65 * shade, [0.62, 0.72, 0.86])
        cmap = norm = None
    elif mode == "zebra":
        band = np.floor((values[tri].mean(axis=1) - lo) / (hi - lo) * ZEBRA_STRIPES).astype(int) % 2
        face_colors = np.where(band[:, None] == 1, 0.05, 0.97) * np.ones((1, 3))
        cmap = norm = None
    else:
        cmap, norm = matplotlib.colormaps["coolwarm"], colors.Normalize(lo, hi)
        face_colors = cmap(norm(values[tri].mean(axis=1)))
    ax.add_collection3d(Poly3DCollection(sampled.points[tri], facecolors=face_colors, edgecolors="none"))
    if overlay and len(sampled.lines):
        ax.add_collection3d(Line3DCollection(sampled.lines, colors="k", linewidths=0.8))
    lo_xyz, hi_xyz = sampled.points.min(axis=0), sampled.points.max(axis=0)
    half = 0.5 * float((hi_xyz - lo_xyz).max())
    centre = 0.5 * (lo_xyz + hi_xyz)
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        setter(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=ELEVATION, azim=AZIMUTH)
    if cmap is not None:
        fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.7, label=title)
    fig.savefig(path, dpi=dpi, format="png")
    plt.close(fig)
