"""``nupatch fit TRIS -o OUT.step [--faces N] [--control-mesh C.obj] [--sharp-angle DEG] [--json]`` (docs/cli.md):
[FSLYJ] sec. 4.1's fitting of the G1 spline to a triangle mesh (``patching.fitting``), written
as a STEP solid (closed input) or shell (open input)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from patching.errors import NupatchError

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> None:
    from patching.topology.intervals import INTERVAL_RULES

    p = subparsers.add_parser(
        "fit", help="fit the G1 spline to a triangle mesh (STL, OBJ, PLY, OFF, GLB) and write it as STEP"
    )
    p.add_argument("input", metavar="TRIS", help="triangle mesh: .stl .obj .ply .off .glb")
    p.add_argument("-o", "--output", metavar="OUT.step", required=True, help="the fitted surface, STEP")
    p.add_argument("--faces", type=int, metavar="N", help="control mesh faces asked of the remesher (default: triangles / 8, 96 to 2000)")
    p.add_argument(
        "--control-mesh", metavar="C.obj",
        help="start from this control mesh (topology, tags and positions) instead of remeshing",
    )
    p.add_argument("--save-control-mesh", metavar="FIT.obj", help="also write the fitted control mesh (OBJ, reads back with build)")
    p.add_argument("--iterations", type=int, default=30, metavar="K", help="most alternations (default 30)")
    p.add_argument(
        "--sharp-angle", type=float, metavar="DEG",
        help="input edges whose triangles' normals differ by more than DEG degrees become creases of the control mesh (default: off)",
    )
    p.add_argument(
        "--distance", choices=("sdm", "tdm"), default="sdm",
        help="squared-distance model after the point-distance steps: sdm (with curvature, default) or tdm (tangent distance)",
    )
    p.add_argument(
        "--intervals", choices=INTERVAL_RULES, default="tags",
        help="knot intervals of the control mesh: tags (a --control-mesh's own; the remeshed one's are all 1, "
        "the paper's choice), uniform, chord or centripetal (each strip from its edge lengths before the fit)",
    )
    p.add_argument("--json", action="store_true", help="the report as JSON on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import patching
    from export import to_step, write_obj
    from export.triangles import read_triangle_file
    from patching.fitting import fit

    out = Path(args.output)
    if out.suffix.lower() not in (".step", ".stp"):
        raise NupatchError(f"the output must be a .step file, not '{out.suffix}'", str(out))
    if args.faces is not None and args.faces < 1:
        raise NupatchError(f"--faces must be at least 1, not {args.faces}", "command line")
    if args.iterations < 0:
        raise NupatchError(f"--iterations must be >= 0, not {args.iterations}", "command line")
    if args.sharp_angle is not None and not 0.0 < args.sharp_angle < 180.0:
        raise NupatchError(f"--sharp-angle must be between 0 and 180 degrees, not {args.sharp_angle:g}", "command line")
    if not out.resolve().parent.is_dir():
        raise NupatchError("the output's directory does not exist", str(out))
    got = read_triangle_file(args.input)
    vertices, triangles, name = got.vertices, got.triangles, got.name
    control = patching.read_mesh(args.control_mesh) if args.control_mesh else None
    if not args.quiet:
        print(f"nupatch: fitting {triangles.shape[0]} triangles ...", file=sys.stderr)
    result = fit(
        vertices, triangles, faces=args.faces, control_mesh=control, max_iterations=args.iterations,
        distance=args.distance, sharp_angle=args.sharp_angle, intervals=args.intervals, name=name, labels=got.labels,
    )
    to_step(result.surface, out)
    if args.save_control_mesh:
        write_obj(result.control_mesh, args.save_control_mesh, comment=f"nupatch fit of {Path(args.input).name}")
    report = result.report
    if args.json:
        print(json.dumps(dict(report.as_dict(), output=str(out), closed=bool(result.surface.topology.is_closed)), indent=2))
    else:
        print(report.summary())
        print(f"wrote {out} ({'solid' if result.surface.topology.is_closed else 'shell'}, {report.patches} faces)")
    return 0
