"""Reading triangle meshes (STL, OBJ, PLY, OFF, GLB) for ``nupatch fit``, through trimesh.

The edge of the fitting pipeline (docs/cli.md, ``fit``): ``patching.fitting`` takes arrays, this
module turns a file into them.  Vertices with identical coordinates are merged (STL stores
every triangle's corners separately; OBJ exporters split vertices at texture seams), so that
the triangles share edges.  OBJ and OFF faces of more than three vertices are refused (naming
the line) rather than triangulated: ``fit`` takes triangle meshes.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from patching.errors import NupatchError, InputFileError, MeshError

__all__ = ["TRIANGLE_FORMATS", "read_triangles"]

#: Suffixes ``read_triangles`` accepts, with trimesh's file type names.
TRIANGLE_FORMATS = {".stl": "stl", ".obj": "obj", ".ply": "ply", ".off": "off", ".glb": "glb"}


def _refuse_polygons(path: Path, kind: str, text: str) -> None:
    """MeshError at the first OBJ `f` line or OFF face line with more than three vertices."""
    lines = text.splitlines()
    if kind == "obj":
        for number, line in enumerate(lines, 1):
            parts = line.split()
            if parts and parts[0] == "f" and len(parts) - 1 != 3:
                raise MeshError(f"face with {len(parts) - 1} vertices: fit takes a triangle mesh", f"{path}:{number}")
        return
    # OFF: header "OFF", then "nv nf ne", nv vertex lines, nf face lines "k i j ..."
    body = [(n, l.split()) for n, l in enumerate(lines, 1) if l.strip() and not l.lstrip().startswith("#")]
    if not body:
        return
    start = 1 if body[0][1][0].upper().endswith("OFF") and len(body[0][1]) == 1 else 0
    if start >= len(body):
        return
    counts = body[start][1]
    if body[0][1][0].upper().endswith("OFF") and len(body[0][1]) > 1:
        counts, start = body[0][1][1:], 0
    try:
        nv, nf = int(counts[0]), int(counts[1])
    except (ValueError, IndexError):
        return  # trimesh reports the malformed header
    for number, parts in body[start + 1 + nv : start + 1 + nv + nf]:
        if parts and parts[0].isdigit() and int(parts[0]) != 3:
            raise MeshError(f"face with {parts[0]} vertices: fit takes a triangle mesh", f"{path}:{number}")


def read_triangles(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, str]:
    """(vertices (n, 3) float64, triangles (t, 3) int64, name: the file's stem) of a triangle
    mesh file; InputFileError when it cannot be read, MeshError when it holds no triangles or
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
    if kind in ("obj", "off"):
        _refuse_polygons(path, kind, data.decode("utf-8", errors="replace"))
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
    if finite.all():
        vertices, inverse = np.unique(vertices, axis=0, return_inverse=True)
        faces = inverse.reshape(-1)[faces]
    return vertices, faces, path.stem
