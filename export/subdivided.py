"""Subdivided meshes with normals: OBJ (``vn`` and ``f v//n``) and binary glTF (``.glb`` with
NORMAL), and the ``subdivide --scheme/--normals`` branch of the command line.

OBJ: one ``v`` per refined vertex, one ``vn`` per normal region (a sharp vertex has one per
region between its sharp edges, [ZBK] sec. 3.4), faces ``f a//na b//nb ...``; without
normals the refined control mesh with its tags (``export.write_obj``) so that it reads
back.  With normals the crease and corner tags follow too (hole faces are left out).
glb: vertices split where a vertex has more than one normal, quads cut into two triangles
along their 0-2 diagonal, written by trimesh (``include_normals``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import patching
from patching.errors import NupatchError
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # patching.shading (and patching.loop) only when a subdivide needs them: every CLI start imports this module
    from patching.shading import SubdividedMesh

from .atomic import atomic_output

__all__ = ["OUTPUT_SUFFIXES", "run_subdivide", "split_by_normal", "with_mesh_options", "write_subdivided_glb", "write_subdivided_obj"]

OUTPUT_SUFFIXES = (".obj", ".glb")


def _obj_text(result: SubdividedMesh, refined: patching.ControlMesh, comment: str) -> str:
    lines = [f"# {line}" for line in comment.splitlines()]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in result.points.tolist()]
    if result.normals is not None:
        lines += [f"vn {x:.17g} {y:.17g} {z:.17g}" for x, y, z in result.normals.tolist()]
        f1 = result.faces + 1
        n1 = result.corner_normal + 1
        k = f1.shape[1]
        lines += ["f " + " ".join(f"{f1[i, j]}//{n1[i, j]}" for j in range(k)) for i in range(f1.shape[0])]
    else:
        lines += ["f " + " ".join(str(v) for v in row) for row in (result.faces + 1).tolist()]
    for (a, b), s in sorted(refined.creases.items()):
        lines.append(f"t crease 2/1/0 {a} {b} {s!r}")
    for v, s in sorted(refined.corners.items()):
        lines.append(f"t corner 1/1/0 {v} {s!r}")
    lines.append(f"t interpolateboundary 1/0/0 {refined.interpolate_boundary}")
    return "\n".join(lines) + "\n"


def write_subdivided_obj(result: SubdividedMesh, refined: patching.ControlMesh, path, comment: str = "") -> None:
    """Write ``result`` (arrays of ``patching.shading``) as OBJ, atomically."""
    with atomic_output(path) as tmp:
        Path(tmp).write_text(_obj_text(result, refined, comment), encoding="utf-8")


def split_by_normal(result: SubdividedMesh):
    """(vertices, normals, triangles): one vertex per (vertex, normal) pair (glTF, pictures);
    quads cut along their 0-2 diagonal."""
    faces, cn = result.faces, result.corner_normal
    if cn is None:
        verts, tri_src, normals = result.points, faces, None
    else:
        key = faces.astype(np.int64) * (result.normals.shape[0] + 1) + cn
        uniq, inv = np.unique(key.ravel(), return_inverse=True)
        vid = uniq // (result.normals.shape[0] + 1)
        nid = uniq % (result.normals.shape[0] + 1)
        verts, normals = result.points[vid], result.normals[nid]
        tri_src = inv.reshape(faces.shape)
    if tri_src.shape[1] == 4:
        tri_src = np.concatenate([tri_src[:, [0, 1, 2]], tri_src[:, [0, 2, 3]]])
    return verts, normals, tri_src


def write_subdivided_glb(result: SubdividedMesh, path) -> None:
    """Write ``result`` as binary glTF with a NORMAL attribute, atomically (trimesh)."""
    try:
        import trimesh
    except ImportError:
        raise NupatchError("writing .glb needs trimesh: pip install 'nupatch[mesh]'", str(path)) from None
    verts, normals, tris = split_by_normal(result)
    mesh = trimesh.Trimesh(vertices=verts, faces=tris, vertex_normals=normals, process=False)
    data = mesh.export(file_type="glb", include_normals=normals is not None)
    with atomic_output(path) as tmp:
        Path(tmp).write_bytes(data)


def with_mesh_options(mesh: patching.ControlMesh, args: argparse.Namespace) -> patching.ControlMesh:
    """The mesh with ``--triangles`` and ``--crease-method`` as its triangle rule and crease
    method where given, else with its own tags (``t smoothtriangles``, ``t creasemethod``).  A
    flag that overrides a tag drops the tag's line from the mesh's locations, so that errors
    about the option do not name a line that did not choose it."""
    import dataclasses

    changes = {}
    if getattr(args, "triangles", None) is not None:
        changes["triangle_subdivision"] = args.triangles
    if getattr(args, "crease_method", None) is not None:
        changes["crease_method"] = args.crease_method
    if not changes:
        return mesh
    dropped = {("tag", "smoothtriangles") if k == "triangle_subdivision" else ("tag", "creasemethod") for k in changes}
    locations = {k: v for k, v in mesh.locations.items() if k not in dropped}
    return dataclasses.replace(mesh, locations=locations, **changes)


def run_subdivide(args: argparse.Namespace, progress=None) -> int:
    """``nupatch subdivide`` with ``--scheme``/``--normals``/``.glb``."""
    from export.atomic import check_output_path
    from patching.shading import shading_operator

    mesh_path, out = Path(args.mesh), Path(args.output)
    suffix = out.suffix.lower()
    if out.resolve() == mesh_path.resolve():
        raise NupatchError("the output would overwrite the input mesh", str(out))
    if suffix not in OUTPUT_SUFFIXES:
        raise NupatchError("subdivide writes .obj or .glb: give OUT one of these suffixes", str(out))
    if args.steps < 0:
        raise NupatchError(f"-n must be a number of steps >= 0, got {args.steps}", "-n")
    if args.normals != "none" and args.steps < 1:
        raise NupatchError("--normals needs at least one subdivision step (-n 1 or more)", "-n")
    check_output_path(out)
    start = time.perf_counter()
    mesh = with_mesh_options(patching.read_mesh(mesh_path), args)
    op = shading_operator(mesh, args.steps, args.scheme, args.normals, args.shading_variant, rules=args.rules)
    result = op.evaluate(mesh.vertices)
    comment = (
        f"nupatch {patching.__version__}: {args.steps} {args.scheme} step(s) of {mesh_path.name}, normals {args.normals}"
        + (f" (variant {args.shading_variant})" if args.normals == "shading" else "")
    )
    if suffix == ".glb":
        write_subdivided_glb(result, out)
    elif args.normals == "none":
        from export.atomic import atomic_write_text
        from patching.mesh import format_obj

        atomic_write_text(out, format_obj(op.mesh, comment))
    else:
        write_subdivided_obj(result, op.mesh, out, comment)
    if progress:
        progress(args, f"{result.faces.shape[0]} faces from {mesh.n_faces} in {args.steps} step(s), wrote {out} in {time.perf_counter() - start:.2f} s")
    return 0


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The flags this module adds to ``nupatch subdivide``."""
    p.add_argument("--scheme", choices=("catmark", "loop"), default="catmark",
                   help="catmark: Catmull-Clark (default); loop: OpenSubdiv's Loop scheme, triangles and uniform knots only")
    p.add_argument("--normals", choices=("none", "limit", "shading"), default="none",
                   help="write normals: limit normals, or subdivision shading (blended; ZBK)")
    p.add_argument("--shading-variant", choices=("a", "b"), default="b",
                   help="blend weights at sharp vertices: b (0, default) or a (as smooth vertices)")


def wants_this(args: argparse.Namespace) -> bool:
    """Whether ``subdivide`` goes through this module (Loop, normals or a .glb output)."""
    return (getattr(args, "scheme", "catmark") != "catmark" or getattr(args, "normals", "none") != "none"
            or Path(args.output).suffix.lower() == ".glb")
