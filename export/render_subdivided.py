"""Pictures of a subdivided mesh drawn with its normals: flat (face normals), limit normals or
subdivision-shading normals ([ZBK]), through ``nupatch render MESH --scheme loop|catmark -n K
--normals flat|limit|shading [--shading-variant a|b] [--zebra]``.

The mesh is refined K steps (``patching.shading``); each triangle corner gets its normal (flat:
the face's; limit and shading: its region's, so a vertex on a sharp crease carries one per
side, [ZBK] sec. 3.4), the vertices are split where they carry more than one, and the
triangles are drawn by ``export.render.render`` (VTK, or matplotlib) without any geometry of
their own: the normals alone shade them.  ``--zebra`` draws reflection lines of those normals,
the view [ZBK] compares normal fields with (its Figs. 3-5, 8-13): they wiggle where the normal
field has the artefacts of the limit normals near extraordinary vertices and run smoothly
where it is a smooth field.  Quads (Catmull-Clark) are cut along their 0-2 diagonal.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

import patching
from patching.errors import NupatchError

from .atomic import atomic_output, check_output_path
from .render import Sampled, render
from .subdivided import split_by_normal

if TYPE_CHECKING:
    from patching.shading import SubdividedMesh

__all__ = ["NORMALS", "render_subdivided", "run_render_subdivided", "subdivided_sampled"]

#: ``--normals`` of ``render``: face normals, limit normals, subdivision shading.
NORMALS = ("flat", "limit", "shading")


def _flat(result: SubdividedMesh) -> SubdividedMesh:
    """The same faces with one normal per face (Newell's: the sum of corner cross products)."""
    f = result.faces
    p = result.points[f]
    n = np.cross(p, np.roll(p, -1, axis=1)).sum(axis=1)
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    from patching.shading import SubdividedMesh

    return SubdividedMesh(result.points, f, np.repeat(np.arange(f.shape[0])[:, None], f.shape[1], axis=1), n)


def subdivided_sampled(mesh: patching.ControlMesh, levels: int, scheme: str = "loop", normals: str = "shading",
                       variant: str = "b", rules: str = "opensubdiv", crease_method: str | None = None,
                       darts: str = "smooth") -> Sampled:
    """The refined mesh as ``export.render.Sampled`` triangles with the chosen normals (module
    docstring); curvatures are zero (not drawn), the overlay lines are the control mesh's edges."""
    if normals not in NORMALS:
        raise NupatchError(f"--normals must be one of {', '.join(NORMALS)} to render, got '{normals}'", "--normals")
    from patching.shading import shading_operator  # not at import: the render parser is built on every start

    op = shading_operator(mesh, levels, scheme, "limit" if normals == "flat" else normals, variant,
                          rules=rules, crease_method=crease_method, darts=darts)
    result = op.evaluate(mesh.vertices)
    if normals == "flat":
        result = _flat(result)
    points, nrm, tris = split_by_normal(result)
    zero = np.zeros(points.shape[0])
    edges = patching.Topology(mesh).edges
    return Sampled(points, nrm, zero, zero, tris.astype(np.int64), mesh.vertices[np.asarray(edges)])


def render_subdivided(mesh: patching.ControlMesh, path: str | os.PathLike, levels: int, scheme: str = "loop",
                      normals: str = "shading", variant: str = "b", mode: str = "shaded",
                      size: tuple[int, int] = (800, 600), overlay: bool = False, renderer: str = "auto",
                      rules: str = "opensubdiv", crease_method: str | None = None, darts: str = "smooth",
                      picture=None) -> str:
    """Draw ``mesh`` refined ``levels`` steps with ``normals`` to the PNG ``path`` (atomically);
    mode "shaded" or "zebra"; darts as ``patching.shading.shading_operator``; picture an
    ``export.render.Picture`` (view, azimuth, elevation; default the iso view).  Returns the
    renderer used ("vtk" or "matplotlib")."""
    if mode not in ("shaded", "zebra"):
        raise NupatchError(f"a subdivided mesh is drawn shaded or with --zebra, not '{mode}'", "render")
    sampled = subdivided_sampled(mesh, levels, scheme, normals, variant, rules, crease_method, darts)
    with atomic_output(path) as tmp:
        return render(sampled, tmp, mode, size, overlay=overlay, renderer=renderer, picture=picture)


def run_render_subdivided(args: argparse.Namespace, size: tuple[int, int], progress=None) -> int:
    """``nupatch render MESH --normals ...`` (the flags of ``add_arguments``)."""
    source = Path(args.source)
    out = Path(args.output) if args.output else source.with_suffix(".png")
    if source.suffix.lower() in (".step", ".stp"):
        raise NupatchError("--normals draws a subdivided control mesh: give an OBJ mesh, not a STEP file", str(source))
    if out.resolve() == source.resolve():
        raise NupatchError("the output would overwrite the input", str(out))
    if out.suffix.lower() != ".png":
        raise NupatchError("render writes PNG images: OUT must end in .png", str(out))
    if args.curvature:
        raise NupatchError("--curvature is not drawn for a subdivided mesh: use --zebra or shading", "--curvature")
    if args.levels < 1:
        raise NupatchError(f"-n must be a number of steps >= 1 to draw normals, got {args.levels}", "-n")
    check_output_path(out)
    start = time.perf_counter()
    from .subdivided import with_mesh_options

    mesh = with_mesh_options(patching.read_mesh(source), args)  # --crease-method over the mesh's tag
    mode = "zebra" if args.zebra else "shaded"
    used = render_subdivided(mesh, out, args.levels, args.scheme, args.normals, args.shading_variant, mode, size,
                             overlay=args.mesh, renderer=args.renderer, rules=args.rules)
    if progress:
        progress(args, f"drew {out} ({args.scheme} x{args.levels}, {args.normals} normals, {mode}, {used}) "
                       f"in {time.perf_counter() - start:.2f} s")
    return 0


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The flags this module adds to ``nupatch render``."""
    p.add_argument("--normals", choices=NORMALS,
                   help="draw the mesh subdivided -n times with these normals instead of its surface: flat (face "
                        "normals), limit, or shading (subdivision shading, ZBK)")
    p.add_argument("-n", dest="levels", type=int, default=3, metavar="K",
                   help="subdivision steps with --normals (default 3)")
    p.add_argument("--scheme", choices=("catmark", "loop"), default="catmark",
                   help="with --normals: catmark (Catmull-Clark, default) or loop (triangles)")
    p.add_argument("--shading-variant", choices=("a", "b"), default="b",
                   help="with --normals shading: blend weights at sharp vertices, b (0, default) or a (as smooth)")
    p.add_argument("--rules", choices=("opensubdiv", "seed"), default="opensubdiv",
                   help="with --normals --scheme catmark: the rule set (default opensubdiv)")
    p.add_argument("--crease-method", choices=("uniform", "chaikin"), default=None,
                   help="with --normals: how semi-sharp sharpness decays (default: the mesh's "
                        "'t creasemethod' tag, else uniform)")
