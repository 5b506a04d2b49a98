"""``nupatch toolpath MESH|STEP -o OUT.nc --tool ball:R --scallop H [--tolerance T] [--feed F]
[--picture P.png] [--json]``: 3-axis ball-end G-code over the up-facing surface
([FSLYJ] sec. 4.3; ``patching.toolpath``, ``export.gcode``; STEP input through
``export.toolpath_step``)."""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from patching.errors import NupatchError

__all__ = ["add_parser", "parse_tool", "run"]

DEFAULT_FEED = 1000.0


def parse_tool(text: str) -> float:
    """'ball:R' -> R (mm)."""
    kind, _, value = text.partition(":")
    if kind.strip().lower() != "ball" or not value:
        raise NupatchError(f"--tool must be ball:R (a ball-end mill of radius R mm), not '{text}'", "--tool")
    try:
        radius = float(value)
    except ValueError:
        raise NupatchError(f"--tool ball:R needs a number R, not '{value}'", "--tool") from None
    if not (math.isfinite(radius) and radius > 0):
        raise NupatchError(f"the tool radius R must be finite and > 0, not {value}", "--tool")
    return radius


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("toolpath", help="3-axis ball-end CNC tool path (G-code) over the up-facing surface")
    p.add_argument("mesh", metavar="MESH|STEP", help="control mesh (OBJ), or a STEP file of untrimmed polynomial B-spline faces")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="G-code file (.nc or .gcode)")
    p.add_argument("--tool", required=True, metavar="ball:R", help="ball-end mill of radius R (mm)")
    p.add_argument("--scallop", required=True, type=float, metavar="H", help="largest scallop height (mm), 0 < H < R")
    p.add_argument("--tolerance", type=float, metavar="T", help="chord error and gouge tolerance (mm), default H/4")
    p.add_argument("--feed", type=float, default=DEFAULT_FEED, metavar="F", help=f"feed rate mm/min (default {DEFAULT_FEED:g})")
    p.add_argument("--picture", metavar="P.png", help="also draw the surface coloured by piece with the path")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    import patching
    from export.atomic import check_output_path
    from patching.toolpath import check_parameters, tool_path

    from .gcode import SUFFIXES, machining_figures, safe_height, write_gcode
    from .toolpath_step import is_step, read_step_patches

    source, out = Path(args.mesh), Path(args.output)
    radius = parse_tool(args.tool)
    tolerance = check_parameters(radius, float(args.scallop), args.tolerance)
    if out.suffix.lower() not in SUFFIXES:
        raise NupatchError(f"toolpath writes G-code: OUT must end in {' or '.join(SUFFIXES)}", str(out))
    if not (math.isfinite(args.feed) and args.feed > 0):
        raise NupatchError(f"the feed must be finite and > 0 mm/min, not {args.feed:g}", "--feed")
    picture = Path(args.picture) if args.picture else None
    if picture is not None and picture.suffix.lower() != ".png":
        raise NupatchError("--picture writes PNG: P must end in .png", str(picture))
    for target in (out, picture):
        if target is not None and target.exists() and target.resolve() == source.resolve():
            raise NupatchError("the output would overwrite the input", str(target))
    check_output_path(out)
    if picture is not None:
        check_output_path(picture)
    start = time.perf_counter()
    if is_step(source):
        surface, mesh = read_step_patches(source)
    else:
        mesh = patching.read_mesh(source)
        surface = patching.build(mesh)
    path = tool_path(surface, mesh, radius, float(args.scallop), tolerance)
    top = float(max(np.max(g.coefficients[..., 2]) for g in surface.groups))
    write_gcode(path, out, args.feed, top, surface.name)
    if picture is not None:
        from .toolpath_picture import draw_toolpath

        draw_toolpath(surface, path, picture)
    report = {
        "input": str(source),
        "output": str(out),
        "tool": {"kind": "ball", "radius": radius},
        "scallop": float(args.scallop),
        "tolerance": tolerance,
        **path.report,
        **machining_figures(path, args.feed, safe_height(path, top)),
        "seconds": round(time.perf_counter() - start, 3),
    }
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(
            f"{out}: {report['pieces']} pieces, path {report['path_length']:.1f} mm, "
            f"~{report['time_min']:.1f} min at F{args.feed:g}; scallop <= {report['max_scallop']:.4g} mm, "
            f"chord error <= {report['max_chord_error']:.3g} mm, clearance >= {report['min_clearance']:.5g} mm "
            f"(R - T = {radius - tolerance:.5g})"
        )
    return 0
