"""``nupatch render MESH|STEP [--zebra | --curvature [KIND] | --blending V [--graph]] -o OUT.png``:
the picture options and the run (``export.render``, docs/pictures.md).

``export.cli`` makes the sub-parser, adds the build options, ``-q`` and ``--intervals``, and
calls ``add_arguments`` and ``run``.  The look of a picture is one flag of a mutually
exclusive group, listed in ``LOOKS``: a new mode is one entry there (its flag, argparse
keywords, and the mode its parsed value selects) plus its case in ``export.render``.  Another
surface to draw (instead of the patches) is one entry of ``SOURCES`` plus its options."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from patching.errors import NupatchError

from .render import CURVATURES, Picture
from .render_camera import VIEWS

__all__ = ["LOOKS", "SOURCES", "add_arguments", "look_of", "picture_of", "run"]

#: (flag, argparse keywords, mode of the parsed value or None when the flag is absent).
LOOKS: list[tuple[str, dict, object]] = [
    ("--zebra", {"action": "store_true", "help": "zebra stripes (reflection lines), shaded and anti-aliased"},
     lambda v: "zebra" if v else None),
    ("--curvature", {"nargs": "?", "const": "mean", "choices": tuple(CURVATURES),
                         "help": "curvature colour map with a legend beside the model: mean (default), gaussian, "
                              "k1, k2 (principal) or max-abs"},
     lambda v: v),
    ("--blending", {"metavar": "V", "help": "blending function of control point V (an index), or 'ep' for every "
                                          "extraordinary point's: colours, iso-lines, local maxima (MESH only)"},
     lambda v: None if v is None else "blending"),
]


#: Other surfaces than the patches, for other modules' pictures (a subdivided mesh with shading
#: normals, say): (wants(args) -> bool, sample(args, mesh, pixel, lines) -> render.Sampled).
#: The first whose ``wants`` accepts the parsed arguments samples the mesh instead of the patches
#: (pixel: model units per pixel of the picture; lines: the control mesh's edges or None); every
#: look that needs only points, normals and triangles (shaded, zebra) then works on it.
SOURCES: list[tuple[object, object]] = []


def _stripe_direction(text: str) -> float:
    named = {"vertical": 0.0, "horizontal": 90.0}
    if text.lower() in named:
        return named[text.lower()]
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"vertical, horizontal or an angle in degrees, not '{text}'") from None


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The render sub-command's own arguments (``export.cli`` adds the build options)."""
    p.add_argument("source", metavar="MESH|STEP", help="control mesh (OBJ) or STEP file")
    p.add_argument("-o", "--output", metavar="OUT.png", help="image (default: the source with .png)")
    look = p.add_mutually_exclusive_group()
    for flag, keywords, _ in LOOKS:
        look.add_argument(flag, **keywords)
    p.add_argument("--graph", action="store_true", help="with --blending: the function as a height field over a planar layout of the control mesh")
    p.add_argument("--mesh", action="store_true", help="overlay the control mesh (MESH) or the faces' edges (STEP)")
    p.add_argument("--edges", action="store_true", help="draw the patch edges (a STEP file's face edges)")
    p.add_argument("--view", choices=tuple(VIEWS), default="iso", help="camera direction (default iso)")
    p.add_argument("--azimuth", type=float, metavar="DEG", help="camera azimuth, degrees about z (-90: front, 0: right)")
    p.add_argument("--elevation", type=float, metavar="DEG", help="camera elevation, degrees above the xy plane")
    p.add_argument("--views", type=int, choices=(1, 4), default=1, help="4: a sheet of front, top, right and iso views")
    p.add_argument("--stripes", type=int, default=Picture.stripes, metavar="N",
                   help=f"zebra: N dark and N light stripes over the reflected rays' half circle (default {Picture.stripes})")
    p.add_argument("--stripe-direction", type=_stripe_direction, default=0.0, metavar="DIR",
                   help="zebra: light lines vertical (default), horizontal, or turned by DIR degrees")
    p.add_argument("--range", type=float, nargs=2, metavar=("LO", "HI"), help="colour range (default: 2nd to 98th percentile)")
    p.add_argument("--size", default="800x600", metavar="WxH", help="image size in pixels (default 800x600)")
    p.add_argument("--tolerance", type=float, metavar="T", help="tessellation chord error (default: a third of a pixel)")
    p.add_argument("--renderer", choices=("auto", "vtk", "matplotlib"), default="auto",
                   help="VTK off-screen, or matplotlib Agg (auto: VTK, matplotlib if VTK has no context)")


def look_of(args: argparse.Namespace) -> str:
    """The mode the flags select ('shaded' without any)."""
    for flag, _, mode_of in LOOKS:
        mode = mode_of(getattr(args, flag.lstrip("-").replace("-", "_")))
        if mode is not None:
            return mode
    return "shaded"


def picture_of(args: argparse.Namespace) -> Picture:
    return Picture(
        view=args.view, azimuth=args.azimuth, elevation=args.elevation, views=args.views, stripes=args.stripes,
        stripe_direction=args.stripe_direction, edges=args.edges,
        value_range=tuple(args.range) if args.range is not None else None,
    )


def run(args: argparse.Namespace, options, size: tuple[int, int], progress) -> int:
    """Draw the picture (``export.cli`` has parsed ``size`` and made the BuildOptions)."""
    import patching
    from export.atomic import check_output_path

    from .render import picture_pixel, sample_shape, sample_surface

    source = Path(args.source)
    out = Path(args.output) if args.output else source.with_suffix(".png")
    if out.resolve() == source.resolve():
        raise NupatchError("the output would overwrite the input", str(out))
    if out.suffix.lower() != ".png" and str(out) != "-":
        raise NupatchError("render writes PNG images: OUT must end in .png", str(out))
    if args.tolerance is not None:
        from export.tolerances import check_tolerance

        check_tolerance(args.tolerance)
    mode = look_of(args)
    if args.graph and mode != "blending":
        raise NupatchError("--graph draws a blending function: give --blending V too", "command line")
    picture = picture_of(args)
    check_output_path(out)
    start = time.perf_counter()
    legend = mode not in ("shaded", "zebra")
    if source.suffix.lower() in (".step", ".stp"):
        if mode == "blending":
            raise NupatchError("--blending needs a control mesh (OBJ): a STEP file has no control points", str(source))
        from export.budget import check_shape_budget
        from export.step import read_step
        from export.step_check import require_step_header

        require_step_header(source)
        shape = read_step(source)
        tolerance = args.tolerance or picture_pixel(_box_corners(shape), size, picture, legend)
        check_shape_budget(shape, tolerance)  # before BRepMesh, as for a mesh
        sampled = sample_shape(shape, tolerance)
    else:
        from export.inputs import read_control_mesh

        from .render_geometry import grid_size

        mesh = read_control_mesh(source, args.intervals)
        lines = mesh.vertices[np.asarray(patching.Topology(mesh).edges)] if args.mesh else None
        other = next((sample for wants, sample in SOURCES if wants(args)), None)
        if other is not None:
            sampled = other(args, mesh, picture_pixel(mesh.vertices, size, picture, legend), lines)
            return _draw(sampled, out, mode, size, args, picture, progress, start)
        operator = patching.build_operator(mesh, options)
        surface = operator.evaluate(mesh.vertices)
        if surface.n_patches == 0:
            patching.build(mesh, options)  # raises build's own message for an empty surface
        if args.tolerance is not None:
            from export.budget import check_tessellation_budget

            check_tessellation_budget(surface, args.tolerance)
            pixel = 3.0 * args.tolerance  # grid_size keeps the chord error below a third of a pixel
        else:
            coefficients = np.concatenate([g.coefficients.reshape(-1, 3) for g in surface.groups])
            pixel = picture_pixel(coefficients, size, picture, legend)
        m = grid_size(surface, pixel)
        if mode == "blending":
            from .render_blending import control_points, graph_sampled, surface_field

            columns = control_points(args.blending, mesh, operator)
            label = f"blending function of control point {int(columns[0])}" if len(columns) == 1 else \
                f"blending functions of the {len(columns)} extraordinary points (largest)"
            if args.graph:
                sampled = graph_sampled(operator, mesh, columns, min(m, 33), label)
            else:
                sampled = surface_field(operator, surface, sample_surface(surface, pixel, lines, m), columns, m, label)
        else:
            sampled = sample_surface(surface, pixel, lines, m)
    return _draw(sampled, out, mode, size, args, picture, progress, start)


def _draw(sampled, out: Path, mode: str, size, args, picture, progress, start: float) -> int:
    from export.atomic import atomic_output

    from .render import render

    with atomic_output(out) as tmp:
        used = render(sampled, tmp, mode, size, overlay=args.mesh, renderer=args.renderer, picture=picture)
    progress(f"drew {out} ({mode}, {size[0]}x{size[1]}, {used}) in {time.perf_counter() - start:.2f} s")
    return 0


def _box_corners(shape) -> np.ndarray:
    """(8, 3) corners of the shape's bounding box (fits the camera before tessellating)."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    from .ocp_compat import box_bounds

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)  # the poles' box: cheap, and contains the faces
    x0, y0, z0, x1, y1, z1 = box_bounds(box)
    corners = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], dtype=float)
    if not np.isfinite(corners).all():
        raise NupatchError("the shape has no finite bounding box", "render")
    return corners
