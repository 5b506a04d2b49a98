"""VTK off-screen drawing of ``export.render``'s layers: one renderer a viewport, smooth-shaded
triangles coloured per pixel from interpolated scalars (``InterpolateScalarsBeforeMapping``:
crisp zebra bands and colour ranges), lines lifted a pixel and a half towards the eye (so the
surface under them does not hide them), markers as spheres, and supersampling by ``factor``
(drawn larger, averaged down: anti-aliased stripe edges, which multisampling does not smooth
inside triangles); without supersampling (factor 1) 8x multisampling smooths the triangles'
edges at least.  Multisampling on top of supersampling made VTK's software rasteriser several
times slower (9.5 s against 2.5 s for an 800 x 600 zebra, both under load) for no visible gain,
so it is off then.

On a machine without a display VTK's render-window factory falls back from X to EGL; its
warning about X is silenced.  ``RuntimeError`` when no OpenGL context opens (the caller falls
back to matplotlib)."""

from __future__ import annotations

import numpy as np

from .render_scene import SHADED_COLOUR, Sampled, Style, ViewLayer, downsample

__all__ = ["draw"]

#: Lines are lifted this many pixels towards the eye, markers their radius plus this.
LIFT_PIXELS = 1.5
MARKER_PIXELS = 5.0
#: Multisampling (samples a pixel) when there is no supersampling.
MULTI = 8


def _vtk():
    """The VTK classes used here, from their own modules: ``import vtk`` loads all of VTK
    (seconds); the OpenGL2 module registers the render window (``draw`` adds FreeType, the
    text back end, only for a picture with view labels)."""
    from types import SimpleNamespace

    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401
    # the names below are returned through locals(), so read by no line here: noqa F401
    from vtkmodules.vtkCommonCore import vtkLogger, vtkLookupTable, vtkObject, vtkPoints  # noqa: F401
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData  # noqa: F401
    from vtkmodules.vtkFiltersCore import vtkGlyph3D  # noqa: F401
    from vtkmodules.vtkFiltersSources import vtkSphereSource  # noqa: F401
    from vtkmodules.vtkRenderingCore import (  # noqa: F401
        vtkActor,
        vtkPolyDataMapper,
        vtkRenderer,
        vtkRenderWindow,
        vtkTextActor,
        vtkWindowToImageFilter,
    )

    return SimpleNamespace(**{k: v for k, v in locals().items() if k.startswith("vtk") and k != "vtkmodules"})


def draw(sampled: Sampled, layers: list[ViewLayer], look: Style, size: tuple[int, int], factor: int) -> np.ndarray:
    """(h, w, 3) uint8 image of ``size`` (the model area) with one viewport per layer."""
    vtk = _vtk()
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray, vtk_to_numpy

    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)  # "bad X server connection"
    vtk.vtkObject.GlobalWarningDisplayOff()

    def polydata(points: np.ndarray, cells: np.ndarray, kind: str):
        data = vtk.vtkPolyData()
        pts = vtk.vtkPoints()
        pts.SetData(numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
        data.SetPoints(pts)
        n = cells.shape[1]
        flat = np.hstack([np.full((len(cells), 1), n, dtype=np.int64), cells]).ravel()
        array = vtk.vtkCellArray()
        array.SetCells(len(cells), numpy_to_vtkIdTypeArray(flat, deep=True))
        {"polys": data.SetPolys, "lines": data.SetLines, "verts": data.SetVerts}[kind](array)
        return data

    if any(layer.camera.label for layer in layers):
        import vtkmodules.vtkRenderingFreeType  # noqa: F401
    w, h = size
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(w * factor, h * factor)
    window.SetMultiSamples(MULTI if factor == 1 else 0)
    if not window.SupportsOpenGL():
        raise RuntimeError("VTK could not open an off-screen OpenGL context")
    lut = None
    if look.table is not None:
        lut = vtk.vtkLookupTable()
        lut.SetNumberOfTableValues(len(look.table))
        for k, (r, g, b) in enumerate(look.table):
            lut.SetTableValue(k, float(r), float(g), float(b), 1.0)
        lut.SetRange(*look.range)
        lut.Build()
    ambient, diffuse, specular = look.lighting
    for layer in layers:
        cam = layer.camera
        x0, y0, x1, y1 = cam.viewport
        ren = vtk.vtkRenderer()
        ren.SetViewport(x0 / w, 1 - y1 / h, x1 / w, 1 - y0 / h)
        ren.SetBackground(1.0, 1.0, 1.0)
        surface = polydata(sampled.points, sampled.triangles, "polys")
        surface.GetPointData().SetNormals(numpy_to_vtk(np.ascontiguousarray(sampled.normals), deep=True))
        mapper = vtk.vtkPolyDataMapper()
        mapper.SetInputData(surface)
        actor = vtk.vtkActor()
        actor.SetMapper(mapper)
        prop = actor.GetProperty()
        prop.SetAmbient(ambient)
        prop.SetDiffuse(diffuse)
        prop.SetSpecular(specular)
        prop.SetSpecularPower(40)
        if layer.scalars is None or lut is None:
            mapper.ScalarVisibilityOff()
            prop.SetColor(*SHADED_COLOUR)
        else:
            surface.GetPointData().SetScalars(numpy_to_vtk(np.ascontiguousarray(layer.scalars, dtype=np.float64), deep=True))
            mapper.SetLookupTable(lut)
            mapper.SetScalarRange(*look.range)
            mapper.InterpolateScalarsBeforeMappingOn()  # colours per pixel, not per vertex
            prop.SetAmbientColor(1.0, 1.0, 1.0)
        ren.AddActor(actor)
        lift = -cam.view * cam.pixel
        if len(layer.lines):
            for width in np.unique(layer.line_widths):
                mine = layer.line_widths == width
                segs = layer.lines[mine] + LIFT_PIXELS * lift
                ends = segs.reshape(-1, 3)
                data = polydata(ends, np.arange(len(ends)).reshape(-1, 2), "lines")
                colours = np.repeat(np.clip(layer.line_colours[mine] * 255, 0, 255).astype(np.uint8), 2, axis=0)
                data.GetPointData().SetScalars(numpy_to_vtk(colours, deep=True))
                line_mapper = vtk.vtkPolyDataMapper()
                line_mapper.SetInputData(data)
                line_mapper.SetColorModeToDirectScalars()
                line_actor = vtk.vtkActor()
                line_actor.SetMapper(line_mapper)
                line_actor.GetProperty().SetLineWidth(float(width) * factor)
                line_actor.GetProperty().SetLighting(False)
                ren.AddActor(line_actor)
        if len(layer.markers):
            # a white disc, then the red one nearer the eye than the white one's front
            for radius, colour, height in ((MARKER_PIXELS + 2.0, (1.0, 1.0, 1.0), MARKER_PIXELS + 3.0),
                                           (MARKER_PIXELS, (0.85, 0.05, 0.05), 2 * MARKER_PIXELS + 6.0)):
                sphere = vtk.vtkSphereSource()
                sphere.SetRadius(radius * cam.pixel)
                sphere.SetThetaResolution(24)
                sphere.SetPhiResolution(12)
                centres = polydata(layer.markers + height * lift, np.arange(len(layer.markers)).reshape(-1, 1), "verts")
                glyph = vtk.vtkGlyph3D()
                glyph.SetInputData(centres)
                glyph.SetSourceConnection(sphere.GetOutputPort())
                glyph_mapper = vtk.vtkPolyDataMapper()
                glyph_mapper.SetInputConnection(glyph.GetOutputPort())
                glyph_mapper.ScalarVisibilityOff()
                glyph_actor = vtk.vtkActor()
                glyph_actor.SetMapper(glyph_mapper)
                glyph_actor.GetProperty().SetColor(*colour)
                glyph_actor.GetProperty().SetLighting(False)
                ren.AddActor(glyph_actor)
        if cam.label:
            text = vtk.vtkTextActor()
            text.SetInput(cam.label)
            text.GetTextProperty().SetFontSize(int(14 * factor))
            text.GetTextProperty().SetColor(0.2, 0.2, 0.2)
            text.SetPosition(8 * factor, (y1 - y0 - 22) * factor)
            ren.AddViewProp(text)
        camera = ren.GetActiveCamera()
        camera.ParallelProjectionOn()  # one view direction everywhere: the pixel size is exact
        camera.SetFocalPoint(*cam.centre)
        camera.SetPosition(*(cam.centre - cam.view * float(np.linalg.norm(cam.centre - cam.eye))))
        camera.SetViewUp(*cam.up)
        camera.SetParallelScale(cam.half_height)
        ren.ResetCameraClippingRange()
        window.AddRenderer(ren)
    window.Render()
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.ReadFrontBufferOff()
    grab.ShouldRerenderOff()
    grab.SetInputBufferTypeToRGB()
    grab.Update()
    out = grab.GetOutput()
    width, height, _ = out.GetDimensions()
    pixels = vtk_to_numpy(out.GetPointData().GetScalars()).reshape(height, width, -1)[::-1, :, :3]
    window.Finalize()
    if pixels.shape[:2] != (h * factor, w * factor):
        raise RuntimeError(f"VTK drew {pixels.shape[1]}x{pixels.shape[0]}, not {w * factor}x{h * factor}")
    return downsample(np.ascontiguousarray(pixels), factor)
