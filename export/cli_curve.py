"""``nupatch curve POLY.obj -d D -o OUT [-n K]``: [KSD] subdivision curves (docs/cli.md).

``.step .iges .dxf``: the exact limit as B-spline curves of degree D; ``.obj .svg``: the
polygon after K steps (default 4).  ``--modified [--tolerance T]`` (-d 5): the modified quintic
T~5, whose limit is no B-spline: STEP/IGES/DXF get one within T of it.  Bad input: one line, exit 2, no file.
"""

from __future__ import annotations

import argparse
import math

from patching.curves.curve import Curve, ModifiedQuinticCurve
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
    p.add_argument(
        "--modified", action="store_true",
        help="the modified quintic T~5 of [KSD] eq. (7) (needs -d 5): STEP/IGES/DXF get a quintic B-spline within "
        "--tolerance of it (T~5 has no exact B-spline form), OBJ/SVG its refined polygon",
    )
    p.add_argument(
        "--tolerance", type=float, default=None,
        help="with --modified: largest distance of the exported B-spline from the T~5 curve, in the polygon's "
        "units (default 1e-6 of its bounding-box diagonal)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from export.curves import write_curve

    if args.steps < 0 or args.steps > 16:
        raise UnsupportedError(f"-n {args.steps}: the number of steps must be 0..16")
    poly = read_polyline(args.polyline)
    vectors = {v: (vec, s) for v, (vec, s) in poly.vectors.items()}
    if args.tolerance is not None and not args.modified:
        raise UnsupportedError("--tolerance goes with --modified (the other schemes are exported exactly)")
    if args.modified:
        if args.degree != 5:
            raise UnsupportedError(f"--modified is the quintic T~5: give -d 5, not -d {args.degree}")
        if vectors:
            raise UnsupportedError("--modified takes corner tags, not control vectors")
        if args.tolerance is not None and not (math.isfinite(args.tolerance) and args.tolerance > 0):
            raise UnsupportedError(f"--tolerance must be a positive number, not {args.tolerance}")
        curve = ModifiedQuinticCurve(poly.points, poly.closed, poly.corners, args.tolerance, poly.name)
        write_curve(curve, args.output, steps=args.steps)
        return 0
    curve = Curve(poly.points, args.degree, poly.closed, corners=poly.corners, vectors=vectors, name=poly.name)
    write_curve(curve, args.output, steps=args.steps)
    return 0
