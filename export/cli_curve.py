"""``nupatch curve POLY.obj -d D -o OUT [-n K]``: [KSD] subdivision curves (docs/cli.md).

``.step .iges .dxf``: the exact limit as B-spline curves of degree D; ``.obj .svg``: the
polygon after K steps (default 4).  Bad input: one line, exit 2, no file.
"""

from __future__ import annotations

import argparse

from patching.curves.curve import Curve
from patching.curves.polyline import read_polyline
from patching.curves.uniform import MAX_DEGREE, MIN_DEGREE
from patching.errors import UnsupportedError

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "curve",
        help=f"subdivision curve of degree {MIN_DEGREE}..{MAX_DEGREE} from an OBJ polyline (semi-sharp corners, "
        "control vectors) to STEP/IGES/DXF B-splines or a refined OBJ/SVG polygon",
    )
    p.add_argument("polyline", help="OBJ file with v, one l polyline, t corner / t controlvector tags")
    p.add_argument("-d", "--degree", type=int, default=3, help=f"degree {MIN_DEGREE}..{MAX_DEGREE} (default 3)")
    p.add_argument("-o", "--output", required=True, help="OUT.step|.iges|.dxf (exact) or OUT.obj|.svg (polygon)")
    p.add_argument("-n", "--steps", type=int, default=4, help="subdivision steps of the .obj/.svg polygon (default 4)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from export.curves import write_curve

    if args.steps < 0 or args.steps > 16:
        raise UnsupportedError(f"-n {args.steps}: the number of steps must be 0..16")
    poly = read_polyline(args.polyline)
    vectors = {v: (vec, s) for v, (vec, s) in poly.vectors.items()}
    curve = Curve(poly.points, args.degree, poly.closed, corners=poly.corners, vectors=vectors, name=poly.name)
    write_curve(curve, args.output, steps=args.steps)
    return 0
