"""The ``nupatch`` command line (DESIGN 4): a thin layer over the public functions.

Bad input: one line ``nupatch: error: <what> (<where>)`` on stderr, exit 2, no output file.
Any other exception is a bug: one line asking for a report, exit 1 (``--debug`` shows it).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import patching
from patching.atomic import check_output_path
from patching.errors import InputFileError, NupatchError

__all__ = ["main"]

ANGLES = ("optimized", "default", "uniform")
ANCHORS = ("eigen-polyhedron", "extraction")


def _progress(args: argparse.Namespace, message: str) -> None:
    if not getattr(args, "quiet", False):
        print(f"nupatch: {message}", file=sys.stderr)


def cmd_build(args: argparse.Namespace) -> int:
    from export.formats import format_of, write

    mesh_path = Path(args.mesh)
    fmt = args.format
    out = Path(args.output) if args.output else mesh_path.with_suffix("." + (fmt or "step"))
    if out.resolve() == mesh_path.resolve():
        raise NupatchError("the output would overwrite the input mesh", str(out))
    fmt = format_of(out, fmt)
    if args.tolerance is not None and not (args.tolerance > 0 and args.tolerance < float("inf")):
        raise NupatchError(f"the tessellation tolerance must be finite and > 0, not {args.tolerance:g}", "--tolerance")
    check_output_path(out)
    start = time.perf_counter()
    mesh = patching.read_mesh(mesh_path)
    surface = patching.build(mesh, angles=args.angles, anchors=args.anchors)
    _progress(args, f"{surface.n_patches} patches from {mesh.n_faces} faces in {time.perf_counter() - start:.2f} s")
    start = time.perf_counter()
    write(surface, out, fmt, tolerance=args.tolerance)
    _progress(args, f"wrote {out} ({fmt}) in {time.perf_counter() - start:.2f} s")
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    import numpy as np

    mesh = patching.read_mesh(args.mesh)
    topo = patching.Topology(mesh)
    ep = topo.extraordinary
    valences = {int(v): int(c) for v, c in zip(*np.unique(topo.valence[ep], return_counts=True))}
    strips = topo.strips_summary()
    intervals = sorted({d for _, _, d in strips})
    info = {
        "name": mesh.name,
        "vertices": mesh.n_vertices,
        "faces": mesh.n_faces,
        "face_sizes": {int(k): int(c) for k, c in zip(*np.unique(mesh.face_sizes, return_counts=True))},
        "edges": topo.n_edges,
        "extraordinary_points": {"count": int(ep.size), "by_valence": valences},
        "strips": len(strips),
        "intervals": {"distinct": intervals[:20], "min": min(intervals), "max": max(intervals)},
        "sharp_edges": int(np.count_nonzero(topo.edge_sharpness >= patching.mesh.INFINITELY_SHARP)),
        "semi_sharp_edges": int(np.count_nonzero((topo.edge_sharpness > 0) & (topo.edge_sharpness < 10))),
        "boundary_edges": int(np.count_nonzero(topo.edge_is_boundary)),
        "closed": bool(not topo.edge_is_boundary.any()),
        "interpolate_boundary": mesh.interpolate_boundary,
    }
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{mesh.name}: {info['vertices']} vertices, {info['faces']} faces, {info['edges']} edges")
    print(f"  face sizes: {info['face_sizes']}")
    print(f"  extraordinary points: {ep.size}" + (f" (valence: count {valences})" if valences else ""))
    print(f"  strips: {len(strips)}, intervals from {min(intervals):g} to {max(intervals):g}")
    print(f"  sharp edges: {info['sharp_edges']}, semi-sharp: {info['semi_sharp_edges']}")
    print(f"  boundary edges: {info['boundary_edges']} ({'closed' if info['closed'] else 'open'})")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from export.continuity import check_continuity

    path = Path(args.file)
    _require_step(path)
    if not args.sharp_angle > 0 or not args.g1_tolerance >= 0 or args.worst < 0 or args.samples < 2:
        raise NupatchError("--sharp-angle must be > 0, --g1-tolerance >= 0, --worst >= 0 and --samples >= 2", "command line")
    report = check_continuity(
        path,
        samples_per_edge=args.samples,
        worst=args.worst,
        sharp_angle_deg=args.sharp_angle,
        g1_tolerance_deg=args.g1_tolerance,
        all_edges=args.all,
    )
    if args.json:
        print(report.to_json())
    else:
        print(report.summary(report.edges if args.all else None))
    if not report.valid:
        return 1
    return 1 if args.require_g1 and not report.g1 else 0


def _require_step(path: Path) -> None:
    try:
        with open(path, "rb") as fh:
            head = fh.read(64)
    except FileNotFoundError:
        raise InputFileError("no such file", str(path)) from None
    except OSError as exc:
        raise InputFileError(f"cannot read file: {exc.strerror}", str(path)) from None
    if not head.lstrip().startswith(b"ISO-10303-21"):
        raise InputFileError("not a STEP file (no ISO-10303-21 header)", str(path))


class _Parser(argparse.ArgumentParser):
    """argparse with DESIGN 4's one-line errors (argparse prints the usage, then the error)."""

    def error(self, message: str):
        print(f"nupatch: error: {' '.join(message.split())} (command line)", file=sys.stderr)
        sys.exit(2)


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="nupatch",
        description="Quad control meshes with knot intervals to smooth Bezier/NURBS B-reps (STEP).",
    )
    parser.add_argument("--version", action="version", version=f"nupatch {patching.__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    from export.formats import FORMATS

    p = sub.add_parser("build", help="build a control mesh (OBJ) into a STEP solid or shell (or IGES, BREP, STL, glTF, OBJ)")
    p.add_argument("mesh", metavar="MESH", help="control mesh, OBJ with OpenSubdiv tags")
    p.add_argument("-o", "--output", metavar="OUT", help="output file (default: MESH with .step, or the --format's suffix)")
    p.add_argument("--format", choices=FORMATS, help="output format (default: from OUT's suffix)")
    p.add_argument(
        "--tolerance", type=float, metavar="T",
        help="linear deflection of the stl/glb/obj tessellation, model units (default: 1e-3 of the control mesh's diagonal)",
    )
    p.add_argument("--angles", choices=ANGLES, default="optimized", help="angle configuration at extraordinary points (default: optimized)")
    p.add_argument("--anchors", choices=ANCHORS, default="eigen-polyhedron", help="rule for the auxiliary anchors at extraordinary points (default: eigen-polyhedron)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=cmd_build)

    p = sub.add_parser("info", help="report vertices, faces, extraordinary points, strips, creases")
    p.add_argument("mesh", metavar="MESH")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_info)

    from export.continuity import G1_TOLERANCE_DEG, N_WORST, SHARP_ANGLE_DEG

    p = sub.add_parser("check", help="validity and continuity of a STEP file: per-edge G0/G1 table, sharp edges")
    p.add_argument("file", metavar="FILE.step")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--worst", type=int, default=N_WORST, metavar="N", help=f"list the N worst edges by normal jump and by gap (default {N_WORST})")
    p.add_argument("--all", action="store_true", help="list every shared edge")
    p.add_argument("--samples", type=int, default=9, metavar="K", help="samples per shared edge, ends included (default 9)")
    p.add_argument(
        "--sharp-angle", type=float, default=SHARP_ANGLE_DEG, metavar="DEG",
        help=f"an edge whose normal jump is at least DEG all along is sharp, a crease (default {SHARP_ANGLE_DEG:g})",
    )
    p.add_argument(
        "--g1-tolerance", type=float, default=G1_TOLERANCE_DEG, metavar="DEG",
        help=f"largest normal jump of a G1 edge (default {G1_TOLERANCE_DEG:g})",
    )
    p.add_argument("--require-g1", action="store_true", help="exit 1 unless every non-sharp edge is G1")
    p.set_defaults(func=cmd_check)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", patching.NupatchWarning)
        try:
            code = args.func(args)
        except NupatchError as exc:
            code = _fail(f"error: {exc}", 2)
        except KeyboardInterrupt:
            code = _fail("interrupted", 130)
        except Exception as exc:  # a bug: say so in one line unless --debug
            if args.debug:
                raise
            code = _fail(f"internal error: {type(exc).__name__}: {exc} (please report; --debug shows the traceback)", 1)
        finally:
            for w in caught:
                if issubclass(w.category, patching.NupatchWarning):
                    print(f"nupatch: warning: {w.message}", file=sys.stderr)
    return code


def _fail(message: str, code: int) -> int:
    print(f"nupatch: {' '.join(message.split())}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
