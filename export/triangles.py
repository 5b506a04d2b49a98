"""Reading triangle meshes (STL, OBJ, PLY, OFF, GLB) for ``nupatch fit``.

The edge of the fitting pipeline (docs/cli.md, ``fit``): ``patching.fitting`` takes arrays, this
module turns a file into them.  Vertices with identical coordinates are merged (STL stores
every triangle's corners separately; OBJ exporters split vertices at texture seams), so that
the triangles share edges; the merge map is kept as ``InputLabels``, so that fit's errors
name the file's own vertex indices and lines, not the merged ones.  OBJ and OFF are parsed
here (faces of more than three vertices refused, naming the line, rather than triangulated:
``fit`` takes triangle meshes), PLY, STL and GLB through trimesh.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from patching.errors import NupatchError, InputFileError, MeshError
from patching.fitting import InputLabels

__all__ = ["TRIANGLE_FORMATS", "TriangleInput", "read_triangle_file", "read_triangles"]

#: Suffixes ``read_triangle_file`` accepts, with trimesh's file type names.
TRIANGLE_FORMATS = {".stl": "stl", ".obj": "obj", ".ply": "ply", ".off": "off", ".glb": "glb"}


def _obj_triangles(path: Path, text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(vertices, triangles, vertex lines, triangle lines) of an OBJ's `v` and `f` statements,
    in the file's order (1-based, negative relative indices, `a/t/n` forms; other statements
    ignored; DESIGN's OBJ conventions); MeshError at the first face of more than three
    vertices, InputFileError at a malformed number or an index that names no vertex."""
    vertices, vlines, faces, flines = [], [], [], []
    lines = text.splitlines()
    number = 0
    while number < len(lines):
        line, first = lines[number], number + 1
        number += 1
        while line.endswith("\\") and number < len(lines):  # continuation
            line = line[:-1] + " " + lines[number]
            number += 1
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        if parts[0] == "v":
            try:
                vertices.append([float(x) for x in parts[1:4]])
            except ValueError:
                raise InputFileError(f"malformed vertex '{' '.join(parts)}'", f"{path}:{first}") from None
            if len(vertices[-1]) != 3:
                raise InputFileError("a vertex needs three coordinates", f"{path}:{first}")
            vlines.append(first)
        elif parts[0] == "f":
            if len(parts) - 1 != 3:
                raise MeshError(f"face with {len(parts) - 1} vertices: fit takes a triangle mesh", f"{path}:{first}")
            face = []
            for token in parts[1:]:
                try:
                    i = int(token.split("/")[0])
                except ValueError:
                    raise InputFileError(f"malformed face index '{token}'", f"{path}:{first}") from None
                if i == 0 or (i < 0 and -i > len(vertices)):
                    raise InputFileError(f"face index {token} names no vertex", f"{path}:{first}")
                face.append(i - 1 if i > 0 else len(vertices) + i)  # relative: to the vertices so far
            faces.append(face)
            flines.append(first)
    for face, line in zip(faces, flines):  # absolute indices may name vertices defined later
        if max(face) >= len(vertices):
            raise InputFileError(f"face index {max(face) + 1} names no vertex (there are {len(vertices)})", f"{path}:{line}")
    return (np.array(vertices, dtype=np.float64).reshape(-1, 3), np.array(faces, dtype=np.int64).reshape(-1, 3),
            np.array(vlines, dtype=np.int64), np.array(flines, dtype=np.int64))


def _off_triangles(path: Path, text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The same for OFF: a header `OFF` (or `COFF`, `NOFF`...; the counts on the same line or
    the next), `nv nf ne`, nv vertex lines `x y z ...`, nf face lines `k i j l ...` (0-based)."""
    body = [(n, l.split("#", 1)[0].split()) for n, l in enumerate(text.splitlines(), 1)]
    body = [(n, parts) for n, parts in body if parts]
    if not body or not body[0][1][0].upper().endswith("OFF"):
        raise InputFileError("no OFF header", str(path))
    head = body[0][1][1:] if len(body[0][1]) > 1 else (body[1][1] if len(body) > 1 else [])
    rest = body[1:] if len(body[0][1]) > 1 else body[2:]
    try:
        nv, nf = int(head[0]), int(head[1])
    except (ValueError, IndexError):
        raise InputFileError("malformed OFF counts (expected 'vertices faces edges')", f"{path}:{body[0][0]}") from None
    if len(rest) < nv + nf:
        raise InputFileError(f"the file ends before its {nv} vertices and {nf} faces", str(path))
    vertices, faces = np.empty((nv, 3)), np.empty((nf, 3), dtype=np.int64)
    for k, (number, parts) in enumerate(rest[:nv]):
        try:
            vertices[k] = [float(x) for x in parts[:3]]
        except ValueError:
            raise InputFileError(f"malformed vertex '{' '.join(parts)}'", f"{path}:{number}") from None
    for k, (number, parts) in enumerate(rest[nv : nv + nf]):
        try:
            ids = [int(x) for x in parts[1 : 1 + int(parts[0])]]
        except ValueError:
            raise InputFileError(f"malformed face '{' '.join(parts)}'", f"{path}:{number}") from None
        if len(ids) != 3:
            raise MeshError(f"face with {len(ids)} vertices: fit takes a triangle mesh", f"{path}:{number}")
        if min(ids) < 0 or max(ids) >= nv:
            raise InputFileError(f"face index out of range (there are {nv} vertices)", f"{path}:{number}")
        faces[k] = ids
    lines = np.array([n for n, _ in rest[: nv + nf]], dtype=np.int64)
    return vertices, faces, lines[:nv], lines[nv:]


@dataclass(frozen=True)
class TriangleInput:
    """A triangle mesh read from a file: coincident vertices merged, and the labels that let
    ``fit``'s errors name the file's own vertices and triangles (``InputLabels``)."""

    vertices: np.ndarray
    triangles: np.ndarray
    name: str
    labels: InputLabels


def read_triangle_file(path: str | os.PathLike) -> TriangleInput:
    """The triangle mesh of a file (``TRIANGLE_FORMATS``), coincident vertices merged (STL
    stores every triangle's corners separately; OBJ exporters split vertices at texture seams),
    so that the triangles share edges; triangles keep the file's order.  OBJ and OFF are read
    here, in the file's order, so errors name the file's vertex indices and lines; PLY, STL and
    GLB through trimesh (STL's vertices, which it does not index, are named by position).
    InputFileError when the file cannot be read, MeshError when it holds no triangles or
    polygons of more sides."""
    path = Path(path)
    kind = TRIANGLE_FORMATS.get(path.suffix.lower())
    if kind is None:
        raise InputFileError(f"unknown triangle mesh format '{path.suffix}' (expected {', '.join(TRIANGLE_FORMATS)})", str(path))
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputFileError("no such file", str(path)) from None
    except OSError as exc:
        raise InputFileError(f"cannot read file: {exc.strerror}", str(path)) from None
    vlines = flines = None
    if kind in ("obj", "off"):
        parse = _obj_triangles if kind == "obj" else _off_triangles
        vertices, faces, vlines, flines = parse(path, data.decode("utf-8", errors="replace"))
    else:
        try:
            import trimesh
        except ImportError:
            raise NupatchError("reading triangle meshes needs trimesh: pip install 'nupatch[fit]'", str(path)) from None
        try:
            loaded = trimesh.load(path, file_type=kind, force="mesh", process=False)
        except Exception as exc:  # trimesh raises many types on malformed files
            raise InputFileError(f"cannot read {kind.upper()} file: {type(exc).__name__}: {exc}", str(path)) from None
        vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
        faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    if faces.size == 0:
        raise MeshError("no triangles in the file", str(path))
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise MeshError(f"faces with {faces.shape[-1]} vertices: fit takes a triangle mesh", str(path))
    finite = np.isfinite(vertices).all(axis=1)
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        where = f"{path}:{int(vlines[k])}" if vlines is not None else str(path)
        raise MeshError(f"vertex {k} is not finite ({vertices[k].tolist()})", where)
    merged, first, inverse, counts = np.unique(vertices, axis=0, return_index=True, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    # number the merged vertices in the order of their first appearance in the file
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    merged, first, counts = merged[order], first[order], counts[order]
    faces = rank[inverse][faces]
    if kind == "stl":
        labels = InputLabels(positions=merged, source=str(path))
    else:
        labels = InputLabels(
            vertex_ids=first, coincident=counts, source=str(path),
            vertex_lines=None if vlines is None else vlines[first], triangle_lines=flines)
    return TriangleInput(merged, faces, path.stem, labels)


def read_triangles(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, str]:
    """(vertices (n, 3) float64, triangles (t, 3) int64, name: the file's stem) of a triangle
    mesh file (``read_triangle_file``)."""
    got = read_triangle_file(path)
    return got.vertices, got.triangles, got.name
