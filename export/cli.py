"""The ``nupatch`` command line (docs/cli.md): a thin layer over the public functions.

Bad input: one line ``nupatch: error: <what> (<where>)`` on stderr, exit 2, no output file.
Any other exception is a bug: one line asking for a report, exit 1 (``--debug`` shows it).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import sys
import time
import warnings
from pathlib import Path

import patching
from export.atomic import check_output_path
from patching.errors import NupatchError
from patching.options import CHOICES, BuildOptions

from export.tolerances import G1_TOLERANCE_DEG, N_WORST, SHARP_ANGLE_DEG

__all__ = ["main"]

#: ``nupatch check``'s defaults, from ``export.tolerances`` (which imports no OpenCASCADE, so
#: parsing the command line stays fast).
CHECK_DEFAULTS = {"worst": N_WORST, "sharp_angle_deg": SHARP_ANGLE_DEG, "g1_tolerance_deg": G1_TOLERANCE_DEG}


def _progress(args: argparse.Namespace, message: str) -> None:
    if not getattr(args, "quiet", False):
        print(f"nupatch: {message}", file=sys.stderr)


class _Bar:
    """A tqdm bar on stderr for work that has taken more than a second (tqdm's ``delay``).

    Shown when stderr is a terminal, or when ``NUPATCH_PROGRESS=1`` (logs, tests); never with
    ``-q``.  A ticker thread refreshes it twice a second, so that one long stage (the B-rep of
    10,000 faces) shows up while it runs rather than when it ends.
    """

    DELAY = 1.0

    def __init__(self, args: argparse.Namespace, total: int, unit: str, description: str = "") -> None:
        import os
        import threading

        wanted = sys.stderr.isatty() or os.environ.get("NUPATCH_PROGRESS") == "1"
        if args.quiet or not wanted:
            self.bar = _NoBar()  # tqdm's import (its version from the package metadata) is ~5 ms
        else:
            from tqdm import tqdm

            self.bar = tqdm(
                total=total, unit=unit, desc=description, file=sys.stderr, delay=self.DELAY,
                leave=False, dynamic_ncols=True,
                bar_format="nupatch: {desc} {bar:20} {n_fmt}/{total_fmt} {unit} [{elapsed}]",
            )
        self.stop = threading.Event()
        self.ticker = threading.Thread(target=self._tick, daemon=True)
        if not self.bar.disable:
            self.ticker.start()

    def _tick(self) -> None:
        while not self.stop.wait(0.5):
            if self.bar.format_dict["elapsed"] >= self.DELAY:
                self.bar.refresh()
                # tqdm's close() clears the line only if it printed after its delay, and it
                # learns that from ``last_print_t``, which refresh() leaves alone: without this
                # a bar shown only by the ticker stayed on the line, before the summary.
                self.bar.last_print_t = time.time()

    def describe(self, text: str) -> None:
        self.bar.set_description_str(text, refresh=False)

    def update(self) -> None:
        self.bar.update()

    def write(self, line: str) -> None:
        self.bar.write(line, file=sys.stderr)

    def __enter__(self) -> "_Bar":
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        if self.ticker.is_alive():
            self.ticker.join()
        self.bar.close()


class _NoBar:
    """What ``_Bar`` uses of a disabled tqdm bar: nothing shown, lines still written."""

    disable = True

    def set_description_str(self, text: str, refresh: bool = False) -> None:
        pass

    def update(self) -> None:
        pass

    def write(self, line: str, file=None) -> None:
        print(line, file=file or sys.stderr)

    def close(self) -> None:
        pass


def _jobs(args: argparse.Namespace) -> list:
    """One job per mesh, every option and output path checked before any work."""
    from export.formats import format_of
    from export.pipeline import BuildJob
    from export.tolerances import check_tolerance

    if args.tolerance is not None:
        check_tolerance(args.tolerance)
    if args.jobs < 1:
        raise NupatchError(f"-j must be at least 1, not {args.jobs}", "command line")
    several = len(args.mesh) + len(args.example or []) > 1
    if not args.mesh and not args.example:
        raise NupatchError("give a MESH file or --example NAME (nupatch models lists them)", "command line")
    directory = Path(args.output) if several and args.output else None
    if directory is not None and not directory.is_dir():
        raise NupatchError("with several meshes, -o must name an existing directory", str(directory))
    jobs, seen = [], {}
    from export.cli_models import example_paths

    for name in args.mesh + example_paths(args.example):
        mesh_path = Path(name)
        suffix = "." + (args.format or "step")
        if directory is not None:
            out = directory / (mesh_path.stem + suffix)
        elif name == "-" and not args.output:
            out = Path("-")  # standard input to standard output
        else:
            out = Path(args.output) if args.output else mesh_path.with_suffix(suffix)
        if str(out) != "-" and out.resolve() == mesh_path.resolve():
            raise NupatchError("the output would overwrite the input mesh", str(out))
        if out.resolve() in seen:
            raise NupatchError(f"{name} and {seen[out.resolve()]} would both be written to {out}", "command line")
        seen[out.resolve()] = name
        fmt = format_of(out, args.format)
        check_output_path(out)
        jobs.append(BuildJob(str(mesh_path), str(out), fmt, args.tolerance, _options(args), args.pack, args.intervals, not args.no_cache))
    return jobs


def _options(args: argparse.Namespace) -> BuildOptions:
    """The BuildOptions of ``build`` / ``render``'s flags (validated once, there)."""
    return BuildOptions(angles=args.angles, anchors=args.anchors, g1_solve=args.g1_solve, method=args.method,
                        eigen_angles=args.eigen_angles)


def cmd_build(args: argparse.Namespace) -> int:
    from export.pipeline import STAGES, run_build

    jobs = _jobs(args)
    if any(_has_control_vectors(job.mesh) for job in jobs):
        return _build_grid_with_vectors(args, jobs)
    if len(jobs) == 1 and not args.dask:  # in this process: errors reach main()'s handler (and --debug)
        if getattr(args, "own_process", False):
            _import_frozen(*_BUILD_PATH)
        start = time.perf_counter()
        with _Bar(args, len(STAGES), "stages", f"{Path(jobs[0].mesh).name}: {STAGES[0]}") as bar:
            started = []

            def stage(name: str) -> None:
                bar.describe(f"{Path(jobs[0].mesh).name}: {name}")
                if started:
                    bar.update()
                started.append(name)

            faces, patches = run_build(jobs[0], stage)
        _progress(args, f"{patches} patches from {faces} faces, wrote {jobs[0].out} ({jobs[0].fmt}) in {time.perf_counter() - start:.2f} s")
        return 0
    return _build_many(args, jobs)


def _build_grid_with_vectors(args: argparse.Namespace, jobs: list) -> int:
    """A regular grid with ``t controlvector`` tags: the exact B-spline face of [KSD] eq. (15)
    (``export.curves.grid_surface_with_vectors``), periodic in closed directions."""
    import warnings

    from export.curves import grid_surface_with_vectors, write_surface_step
    from export.inputs import read_control_mesh

    job = jobs[0]
    if len(jobs) > 1 or args.dask:
        raise NupatchError("a mesh with control vectors is built on its own (one MESH, no -j / --dask)", job.mesh)
    if job.fmt != "step" or str(job.out) == "-":
        raise NupatchError(f"a grid with control vectors is written as one exact B-spline face: give -o OUT.step, "
                           f"not {job.fmt}" + (" to standard output" if str(job.out) == "-" else ""), job.mesh)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="control vector ignored")
        mesh = read_control_mesh(job.mesh, job.intervals)
    text = Path(job.mesh).read_text(encoding="utf-8-sig", errors="replace")
    surface, closed = grid_surface_with_vectors(mesh, text, Path(job.mesh).name)
    write_surface_step(surface, job.out, mesh.name or Path(job.mesh).stem, periodic=closed)
    nu, nv = surface.poles.shape[:2]
    _progress(args, f"one exact B-spline face ({nu} x {nv} poles, bicubic, control vectors) from {mesh.n_faces} faces, "
              f"wrote {job.out} in {time.perf_counter() - start:.2f} s")
    return 0


def _build_many(args: argparse.Namespace, jobs: list) -> int:
    """Build every job in up to ``-j`` processes; each result on its own line, exit 2 if any failed.

    As its own process with a pool, the build path (OCP) is imported frozen before the workers
    are forked (``_import_frozen``): they inherit its objects in the collector's permanent
    generation, so no worker's collection walks them (nor copies their pages on write)."""
    from export.pipeline import build_files

    if getattr(args, "own_process", False) and not args.dask and args.jobs > 1 and len(jobs) > 1:
        _import_frozen(*_BUILD_PATH)

    with _Bar(args, len(jobs), "meshes") as bar:
        bar.describe(f"building on the Dask cluster {args.dask}" if args.dask else f"building in {min(args.jobs, len(jobs))} processes")

        def report(result) -> None:
            for note in result.notes:
                bar.write(f"nupatch: warning: {note}")
            if result.status != "ok":
                bar.write(f"nupatch: {' '.join(result.message.split())}")
            elif not args.quiet:
                bar.write(f"nupatch: {result.message}")
            bar.update()

        if args.dask:
            from export.dask_batch import build_on_dask

            results = build_on_dask(jobs, args.dask, report)
        else:
            results = build_files(jobs, args.jobs, report)
    failed = sum(r.status != "ok" for r in results)
    if failed:
        _progress(args, f"{failed} of {len(jobs)} meshes failed")
    return 2 if failed else 0


def _has_control_vectors(source) -> bool:
    """Whether an OBJ file carries ``t controlvector`` tags (read by ``subdivide``)."""
    path = Path(str(source))
    if str(source) == "-" or path.suffix.lower() != ".obj" or not path.is_file():
        return False
    import re

    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except OSError:
        return False
    return re.search(r"^\s*t\s+controlvector\s", text, re.MULTILINE) is not None


def cmd_subdivide(args: argparse.Namespace) -> int:
    """nupatch subdivide MESH -n K -o OUT.obj: the refined control mesh with its tags (docs/cli.md)."""
    from export import subdivided  # --scheme / --normals / .glb (export/subdivided.py)

    if subdivided.wants_this(args):
        if _has_control_vectors(args.mesh):
            raise NupatchError("control vectors ([KSD] sec. 5) need --scheme catmark, no --normals and an .obj output", args.mesh)
        return subdivided.run_subdivide(args, _progress)
    from export.atomic import atomic_write_text
    from patching.mesh import format_obj
    from patching.subdivision.catmark import rules_tag, subdivide

    from export.inputs import read_control_mesh

    mesh_path = Path(args.mesh)
    out = Path(args.output)
    if str(out) != "-" and out.resolve() == mesh_path.resolve():
        raise NupatchError("the output would overwrite the input mesh", str(out))
    if out.suffix.lower() != ".obj" and str(out) != "-":
        raise NupatchError("subdivide writes OBJ: give OUT a .obj suffix", str(out))
    if args.steps < 0:
        raise NupatchError(f"-n must be a number of steps >= 0, got {args.steps}", "-n")
    check_output_path(out)
    start = time.perf_counter()
    comment = (
        f"nupatch {patching.__version__}: {args.steps} subdivision step(s) of {mesh_path.name}, rules {args.rules}, "
        f"angles {args.eigen_angles}, crease method "
    )
    if _has_control_vectors(args.mesh):  # [KSD] sec. 5: docs/curves.md, surfaces
        import warnings

        from export.curves import subdivide_with_vectors

        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="control vector ignored")
            mesh = read_control_mesh(mesh_path, args.intervals)
        options = subdivided.with_mesh_options(mesh, args)  # the tags, or the flags over them
        if options.crease_method != "uniform" or args.eigen_angles != "standard" or options.triangle_subdivision == "smooth":
            raise NupatchError("control vectors take the default --crease-method, --eigen-angles and --triangles "
                               "(and no creasemethod or smoothtriangles tag)", args.mesh)
        text = subdivide_with_vectors(mesh, mesh_path, args.steps, args.rules, comment + "uniform")
        atomic_write_text(out, text)
        _progress(args, f"{args.steps} step(s) with control vectors, wrote {out}")
        return 0
    mesh = subdivided.with_mesh_options(read_control_mesh(mesh_path, args.intervals), args)
    comment += mesh.crease_method
    if mesh.triangle_subdivision != "catmark":
        comment += f", triangles {mesh.triangle_subdivision}"
    refined = subdivide(mesh, args.steps, rules=args.rules, angles=args.eigen_angles)
    atomic_write_text(out, format_obj(refined, comment) + rules_tag(args.rules) + "\n")
    _progress(args, f"{refined.n_faces} faces from {mesh.n_faces} in {args.steps} step(s), wrote {out} in {time.perf_counter() - start:.2f} s")
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    from patching.topology.summary import mesh_summary

    from export.inputs import read_control_mesh

    mesh = read_control_mesh(args.mesh, args.intervals)
    info = mesh_summary(mesh)
    valences, intervals = info["extraordinary_points"]["by_valence"], info["intervals"]
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{mesh.name}: {info['vertices']} vertices, {info['faces']} faces, {info['edges']} edges")
    print(f"  face sizes: {info['face_sizes']}")
    print(f"  extraordinary points: {info['extraordinary_points']['count']}" + (f" (valence: count {valences})" if valences else ""))
    print(f"  strips: {info['strips']}, intervals from {intervals['min']:g} to {intervals['max']:g}")
    print(f"  sharp edges: {info['sharp_edges']}, semi-sharp: {info['semi_sharp_edges']}")
    if "sharp_features" in info:
        f = info["sharp_features"]
        print(f"  corners: {f['corners']}, darts: {f['darts']}, vertices whose sectors take the EP path: {f['sector_vertices']}")
    print(f"  boundary edges: {info['boundary_edges']} ({'closed' if info['closed'] else 'open'})")
    print(f"  holes: {info['holes']}, corner tags: {info['corner_tags']}")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from export.continuity import check_continuity

    from export.shapes_in import read_shape

    path = Path(args.file)
    shape = read_shape(path)
    if not args.sharp_angle > 0 or not args.g1_tolerance >= 0 or args.worst < 0 or args.samples < 2:
        raise NupatchError("--sharp-angle must be > 0, --g1-tolerance >= 0, --worst >= 0 and --samples >= 2", "command line")
    report = check_continuity(
        shape,
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


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise NupatchError(f"--size must be WIDTHxHEIGHT in pixels, not '{text}'", "command line") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise NupatchError(f"--size {text}: width and height must be 16 to 8192 pixels", "command line")
    return w, h


def cmd_render(args: argparse.Namespace) -> int:
    from export.cli_render import run

    if args.normals:  # a subdivided mesh drawn with its normals
        from export.render_subdivided import run_render_subdivided

        return run_render_subdivided(args, _size(args.size), _progress)
    return run(args, _options(args), _size(args.size), lambda message: _progress(args, message))


class _Parser(argparse.ArgumentParser):
    """argparse with docs/cli.md's one-line errors (argparse prints the usage, then the error)."""

    def error(self, message: str):
        print(f"nupatch: error: {' '.join(message.split())} (command line)", file=sys.stderr)
        sys.exit(2)


def _add_build_options(p: argparse.ArgumentParser) -> None:
    """The BuildOptions flags, their choices and defaults from ``patching.options``."""
    defaults = BuildOptions()
    p.add_argument(
        "--angles", choices=CHOICES["angles"], default=defaults.angles,
        help=f"angle configuration at extraordinary points (default: {defaults.angles})",
    )
    p.add_argument(
        "--anchors", choices=CHOICES["anchors"], default=defaults.anchors,
        help=f"rule for the auxiliary anchors at extraordinary points (default: {defaults.anchors})",
    )
    p.add_argument(
        "--eigen-angles", choices=CHOICES["eigen_angles"], default=defaults.eigen_angles,
        help="angles of the eigen-polyhedron that gives the anchors' limit point and tangent plane: "
        "standard (2 pi / n, default) or modified ([ZTL])",
    )
    p.add_argument(
        "--g1-solve", choices=CHOICES["g1_solve"], default=defaults.g1_solve,
        help="joint: one fairing solve per cluster of adjacent extraordinary points (default); seed: [FSLYJ]'s per-point steps",
    )
    p.add_argument(
        "--method", choices=CHOICES["method"], default=defaults.method,
        help="fslyj: [FSLYJ]'s construction at extraordinary points (default); t-spline: the T-spline "
        "baseline of [SSEL13] (uniform angles, no auxiliary anchors; fixes --angles, --anchors, --g1-solve)",
    )


#: The subcommands, in the order ``nupatch --help`` lists them.
COMMANDS = ("build", "info", "subdivide", "check", "toolpath", "render", "curve", "fit", "models")


def _command_of(argv: list[str]) -> str | None:
    """The subcommand that ``argv`` runs, when it is plain to see (only ``--debug`` before
    it), else None (help, --version, a typo: the whole parser answers those)."""
    for token in argv:
        if token == "--debug":
            continue
        return token if token in COMMANDS else None
    return None


def _parser(only: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser; ``only``: just that subcommand's (``main`` passes the one
    being run, so that ``nupatch build`` neither builds nor imports the other commands'
    parsers: the render, curve, fit and toolpath modules are a tenth of a small build)."""
    want = lambda name: only is None or only == name  # noqa: E731
    parser = _Parser(
        prog="nupatch",
        description="Quad control meshes with knot intervals to smooth Bezier/NURBS B-reps (STEP).",
    )
    parser.add_argument("--version", action="version", version=f"nupatch {patching.__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    from export.formats import FORMATS
    from patching.subdivision.catmark import ANGLE_CHOICES, CREASE_METHODS, RULE_SETS
    from patching.mesh.control_mesh import TRIANGLE_SUBDIVISIONS
    from export.inputs import add_intervals_argument

    if want("build"):
        p = sub.add_parser("build", help="build a control mesh (OBJ) into a STEP solid or shell (or IGES, BREP, STL, glTF, OBJ)")
        p.add_argument("mesh", metavar="MESH", nargs="*", help="control mesh(es): OBJ with OpenSubdiv tags, USD, or - (standard input)")
        p.add_argument("--example", action="append", metavar="NAME", help="a sample model shipped with nupatch (nupatch models lists them)")
        p.add_argument(
            "-o", "--output", metavar="OUT",
            help="output file (default: MESH with .step, or the --format's suffix); with several meshes, a directory",
        )
        p.add_argument("-j", "--jobs", type=int, default=1, metavar="N", help="build several meshes in N processes (default 1)")
        p.add_argument(
            "--dask", metavar="ADDRESS",
            help="build on a Dask cluster instead: tcp://host:port of a running scheduler, or 'local' for a LocalCluster here "
            "(extra [dask]); the files are written here",
        )
        p.add_argument("--format", choices=FORMATS, help="output format (default: from OUT's suffix)")
        p.add_argument(
            "--tolerance", type=float, metavar="T",
            help="linear deflection of the stl/glb/obj tessellation, model units (default: 1e-3 of the control mesh's diagonal)",
        )
        _add_build_options(p)
        p.add_argument(
            "--pack", action="store_true", default=None,
            help="merge rectangular regions of bicubic patches into multi-span B-spline faces (step/iges/brep; the same surface), "
            "after global refinement of semi-sharp tags (default: only what the adaptive refinement of semi-sharp tags builds is packed)",
        )
        p.add_argument(
            "--no-pack", dest="pack", action="store_false",
            help="one Bezier face per patch, also where semi-sharp tags are refined adaptively",
        )
        p.add_argument(
            "--no-cache", action="store_true",
            help="solve every local configuration and assemble the operator afresh, without the on-disk "
            "caches of solved ones ($XDG_CACHE_HOME/nupatch; also NUPATCH_NO_CACHE=1)",
        )
        p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr (errors and warnings still)")
        add_intervals_argument(p)
        p.set_defaults(func=cmd_build)

    if want("info"):
        p = sub.add_parser("info", help="report vertices, faces, extraordinary points, strips, creases")
        p.add_argument("mesh", metavar="MESH")
        p.add_argument("--json", action="store_true", help="machine-readable output")
        add_intervals_argument(p)
        p.set_defaults(func=cmd_info)

    if want("subdivide"):
        p = sub.add_parser("subdivide", help="refine a control mesh by non-uniform Catmull-Clark subdivision, keeping its tags")
        p.add_argument("mesh", metavar="MESH", help="control mesh, OBJ with OpenSubdiv tags")
        p.add_argument("-n", dest="steps", type=int, default=1, metavar="K", help="number of steps (default 1)")
        p.add_argument("-o", "--output", metavar="OUT.obj", required=True, help="refined mesh, with interval and crease tags")
        p.add_argument("--rules", choices=RULE_SETS, default="seed", help="seed: [TLC]'s non-uniform rules (default); opensubdiv: OpenSubdiv's, uniform intervals only; nurss: Sederberg et al.'s NURSS at extraordinary points (a baseline)")
        p.add_argument(
            "--eigen-angles", "--angles", dest="eigen_angles", choices=ANGLE_CHOICES, default="standard",
            help="eigen-polyhedron angles at non-uniform EPs: standard, or modified ([ZTL]); --angles is its former name",
        )
        p.add_argument(
            "--crease-method", choices=CREASE_METHODS, default=None,
            help="how semi-sharp sharpness decays per step (chaikin: OpenSubdiv's CREASE_CHAIKIN, --rules opensubdiv "
            "only); default: the mesh's 't creasemethod 0/0/1 chaikin' tag, else uniform",
        )
        p.add_argument(
            "--triangles", choices=TRIANGLE_SUBDIVISIONS, default=None,
            help="Catmull-Clark's rule beside triangles: catmark, or smooth (OpenSubdiv's TRI_SUB_SMOOTH, --rules opensubdiv "
            "only); default: the mesh's 't smoothtriangles 0/0/1 smooth' tag, else catmark",
        )
        p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
        from export.subdivided import add_arguments as _subdivided_arguments  # --scheme, --normals

        _subdivided_arguments(p)
        add_intervals_argument(p)
        p.set_defaults(func=cmd_subdivide)

    if want("check"):
        p = sub.add_parser("check", help="validity and continuity of a STEP, IGES or BREP file: per-edge G0/G1 table, sharp edges")
        p.add_argument("file", metavar="FILE", help="STEP, IGES or BREP file (told by its header)")
        p.add_argument("--json", action="store_true", help="machine-readable output")
        p.add_argument("--worst", type=int, default=CHECK_DEFAULTS["worst"], metavar="N", help=f"list the N worst edges by normal jump and by gap (default {CHECK_DEFAULTS['worst']})")
        p.add_argument("--all", action="store_true", help="list every shared edge")
        p.add_argument("--samples", type=int, default=9, metavar="K", help="samples per shared edge, ends included (default 9)")
        p.add_argument(
            "--sharp-angle", type=float, default=CHECK_DEFAULTS["sharp_angle_deg"], metavar="DEG",
            help=f"an edge whose normal jump is at least DEG all along is sharp, a crease (default {CHECK_DEFAULTS['sharp_angle_deg']:g})",
        )
        p.add_argument(
            "--g1-tolerance", type=float, default=CHECK_DEFAULTS["g1_tolerance_deg"], metavar="DEG",
            help=f"largest normal jump of a G1 edge (default {CHECK_DEFAULTS['g1_tolerance_deg']:g})",
        )
        p.add_argument("--require-g1", action="store_true", help="exit 1 unless every non-sharp edge is G1")
        p.set_defaults(func=cmd_check)

    if want("toolpath"):
        from export.cli_toolpath import add_parser as _add_toolpath

        _add_toolpath(sub)

    if want("render"):
        p = sub.add_parser("render", help="draw a mesh's surface or a STEP file to PNG, headless: shaded, zebra, curvature, blending functions")
        from export.cli_render import add_arguments as _render_arguments

        _render_arguments(p)
        _add_build_options(p)
        p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
        add_intervals_argument(p)
        from export.render_subdivided import add_arguments as _add_subdivided_render

        _add_subdivided_render(p)
        p.set_defaults(func=cmd_render)

    if want("curve"):
        from export import cli_curve

        cli_curve.add_parser(sub)

    if want("fit"):
        from export import cli_fit

        cli_fit.add_parser(sub)

    if want("models"):
        from export import cli_models

        cli_models.add_parser(sub)

    return parser


#: The modules a build imports (OpenCASCADE's OCP among them): what ``_import_frozen`` loads.
_BUILD_PATH = ("export.inputs", "export.brep", "export.step", "export.formats", "export.budget")


def _import_frozen(*modules: str) -> None:
    """Import ``modules`` (OpenCASCADE's OCP among them) with the cycle collector off, then
    move every object alive to the collector's permanent generation (``gc.freeze``).

    Only for a process that is ``nupatch`` itself (``main(None)``).  OCP is one extension
    module of thousands of classes: importing it makes ~200,000 objects that live as long as
    the process, and every full collection walks all of them (0.08 s of CPU each on the
    2-core machine): two that its import's allocations trigger, one the build's, and the
    interpreter's at exit.
    Frozen, a small build's whole process takes ~0.6 s less CPU (docs/speed.md).  A frozen
    object is still freed when its last reference goes; the collector just never looks at it
    again, and garbage cycles that the build itself makes are still collected."""
    import importlib

    enabled = gc.isenabled()
    gc.disable()
    try:
        for name in modules:
            importlib.import_module(name)
    finally:
        gc.freeze()
        if enabled:
            gc.enable()


def main(argv: list[str] | None = None) -> int:
    """Run ``nupatch`` on ``argv`` (None: this process's own command line, ``sys.argv``).

    With ``argv`` None the call is the process (the console script, ``python -m export``):
    the build then imports OpenCASCADE frozen (``_import_frozen``) and the heap is frozen
    before returning, so that the interpreter's exit does not walk it.  Called with a list
    (tests, scripts running several commands in one interpreter) it leaves the collector as
    it is."""
    from export.signals import Terminated, install

    install()  # SIGTERM and SIGHUP unwind like Ctrl-C (export.signals)
    args = _parser(_command_of(sys.argv[1:] if argv is None else list(argv))).parse_args(argv)
    args.own_process = argv is None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", patching.NupatchWarning)
        try:
            code = args.func(args)
        except NupatchError as exc:
            code = _fail(f"error: {exc}", 2)
        except Terminated as exc:
            code = _fail(exc.message, exc.exit_code)
        except KeyboardInterrupt:
            code = _fail("interrupted", 130)
        except BrokenPipeError:  # the reader went away (`nupatch check x.step | head`): stop quietly
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
            code = 141
        except Exception as exc:  # a bug: say so in one line unless --debug
            if args.debug:
                raise
            code = _fail(f"internal error: {type(exc).__name__}: {exc} (please report; --debug shows the traceback)", 1)
        finally:
            for w in caught:
                if issubclass(w.category, patching.NupatchWarning):
                    print(f"nupatch: warning: {w.message}", file=sys.stderr)
    if argv is None:
        gc.freeze()  # the process ends: its last collections need not walk what is left
    return code


def _fail(message: str, code: int) -> int:
    print(f"nupatch: {' '.join(message.split())}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
