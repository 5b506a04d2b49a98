"""Output formats: one writer function per format in one registry, one atomic wrapper.

``WRITERS`` maps a format name to ``writer(job, tmp_path)``; ``write`` picks the format (from
the argument, else the file's suffix), builds what the writer needs once and calls it inside
``export.atomic.atomic_output``, so every format appears complete or not at all.

- ``step``, ``iges``, ``brep``: the exact B-rep through OpenCASCADE (STEPControl, IGESControl
  in B-rep mode, BRepTools' text format).
- ``stl``, ``glb``, ``obj``: triangles of OpenCASCADE's tessellation (``BRepMesh_IncrementalMesh``
  with linear deflection ``tolerance``, default 1e-3 of the control points' diagonal, at least
  1e-7 (OpenCASCADE's precision), and angular deflection 0.5 rad).  Their points and *vertex normals come from the patches*: each
  tessellation node's (u, v) on its face is the patch parameter (s, t), where the Bézier net
  and its derivatives are evaluated (unit S_s x S_t), not from the facets.  Vertices are per
  face (a node on a shared edge appears once for each face), so a normal never averages two
  faces.  glTF and OBJ also carry (s, t) as texture coordinates; glTF carries the patch row as
  the float attribute ``_PATCH`` (exact up to 2^24 patches).  STL has no vertex normals: its
  facet normals are the triangles' own.
- Units: millimetres everywhere (STEP and IGES say so); the glTF positions are millimetres
  too, under a root node scaled by 0.001, since glTF's unit is the metre.
"""

from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Callable

import numpy as np

from patching.bernstein import evaluate_pairs
from patching.errors import OutputError
from patching.surface import BezierSurface

from export.atomic import atomic_output
from export.tolerances import ANGULAR_DEFLECTION, MIN_TESSELLATION, TESSELLATION_RELATIVE, check_tolerance

__all__ = ["FORMATS", "SUFFIXES", "WRITERS", "Tessellation", "check_tolerance", "format_of", "tessellate", "write"]

@dataclass(frozen=True)
class Tessellation:
    """Triangles on the patches, vertices per face.

    points: (v, 3) float64 surface points; normals: (v, 3) float64 unit outward normals of
    the patches; uv: (v, 2) float64 patch parameters (s, t); patch: (v,) int64 patch row;
    triangles: (t, 3) int64 vertex indices, counter-clockwise seen from outside.
    """

    points: np.ndarray
    normals: np.ndarray
    uv: np.ndarray
    patch: np.ndarray
    triangles: np.ndarray
    tolerance: float


def _evaluate(surface: BezierSurface, patch: np.ndarray, uv: np.ndarray, chunk: int = 65536):
    """Points and unit normals S_s x S_t / |.| of patch rows ``patch`` (m,) at ``uv`` (m, 2)."""
    points = np.empty((len(patch), 3))
    normals = np.empty((len(patch), 3))
    offset = 0
    for g in surface.groups:
        rows = np.flatnonzero((patch >= offset) & (patch < offset + len(g.faces)))
        for lo in range(0, len(rows), chunk):
            r = rows[lo : lo + chunk]
            nets = g.coefficients[patch[r] - offset]  # (c, d+1, d+1, 3)
            points[r], ds, dt = evaluate_pairs(nets, uv[r, 0], uv[r, 1], derivatives=True)
            n = np.cross(ds, dt)
            normals[r] = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        offset += len(g.faces)
    return points, normals


def tessellate(surface: BezierSurface, shape=None, tolerance: float | None = None) -> Tessellation:
    """OpenCASCADE's tessellation of the B-rep of ``surface`` with points and normals of the
    patches at its nodes.  ``shape`` is ``export.brep.to_shape(surface)`` if already built
    (its faces, in ``TopExp.MapShapes`` order, are the patch rows)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp
    from OCP.TopLoc import TopLoc_Location
    from .ocp_compat import TopoDS
    from .ocp_compat import TopTools_IndexedMapOfShape

    from export.brep import shape_face_rows, to_shape

    if shape is None:
        shape = to_shape(surface)
    if tolerance is None:
        tolerance = max(TESSELLATION_RELATIVE * surface.size, MIN_TESSELLATION)
    check_tolerance(tolerance)
    from .budget import check_tessellation_budget

    check_tessellation_budget(surface, tolerance)  # refused before BRepMesh if it would not fit
    mesher = BRepMesh_IncrementalMesh(shape, float(tolerance), False, ANGULAR_DEFLECTION, False)
    if not mesher.IsDone():
        raise RuntimeError("BRepMesh_IncrementalMesh failed")
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    if faces.Extent() != surface.n_patches:
        raise RuntimeError(f"the shape has {faces.Extent()} faces for {surface.n_patches} patches")
    uv_parts, patch_parts, tri_parts, occ_first = [], [], [], []
    base = 0
    location = TopLoc_Location()
    rows = shape_face_rows(surface.topology).tolist()  # the patch row of each face
    reversed_row = np.zeros(surface.n_patches, dtype=bool)
    for k, row in enumerate(rows):
        face = TopoDS.Face_s(faces.FindKey(k + 1))
        poly = BRep_Tool.Triangulation_s(face, location)
        if poly is None:
            raise RuntimeError(f"no triangulation for patch {row}")
        n_nodes, n_tris = poly.NbNodes(), poly.NbTriangles()
        uv = np.array([poly.UVNode(i).Coord() for i in range(1, n_nodes + 1)])
        tris = np.array([poly.Triangle(i).Get() for i in range(1, n_tris + 1)], dtype=np.int64) - 1
        # Outward normals: the solid's faces may be REVERSED as a whole (to_shape's orientation fix).
        reversed_row[row] = face.Orientation() == TopAbs_REVERSED
        if reversed_row[row]:
            tris = tris[:, ::-1]
        occ_first.append(poly.Node(1).Coord())
        uv_parts.append(uv)
        patch_parts.append(np.full(n_nodes, row, dtype=np.int64))
        tri_parts.append(tris + base)
        base += n_nodes
    uv = np.concatenate(uv_parts)
    patch = np.concatenate(patch_parts)
    points, normals = _evaluate(surface, patch, uv)
    # The face taken for row k must be patch k: its first node is where the patch puts it.
    firsts = np.cumsum([0] + [len(p) for p in patch_parts[:-1]])
    gap = np.linalg.norm(points[firsts] - np.array(occ_first), axis=1).max()
    if gap > 1e-9 * max(surface.size, 1.0):
        raise RuntimeError(f"tessellation nodes are {gap:.3g} off the patches: faces and patches disagree")
    normals[reversed_row[patch]] *= -1.0
    return Tessellation(points, normals, uv, patch, np.concatenate(tri_parts), float(tolerance))


@dataclass
class ExportJob:
    """What writers take: the surface, its B-rep (built once), the product name, the final file
    name (for headers) and the tessellation tolerance; the tessellation is made on first use."""

    surface: BezierSurface
    shape: object
    file_name: str
    tolerance: float | None = None

    @cached_property
    def tessellation(self) -> Tessellation:
        return tessellate(self.surface, self.shape, self.tolerance)

    @property
    def name(self) -> str:
        return self.surface.name


def _write_step(job: ExportJob, tmp: Path) -> None:
    from export.step import write_step_file

    write_step_file(job.shape, tmp, job.name, job.file_name)


def _write_iges(job: ExportJob, tmp: Path) -> None:
    from OCP.IGESControl import IGESControl_Controller, IGESControl_Writer

    from export.step import quiet_occ

    IGESControl_Controller.Init_s()
    writer = IGESControl_Writer("MM", 1)  # mode 1: B-rep (MSBO solids, faces), not trimmed surfaces
    with quiet_occ():
        if not writer.AddShape(job.shape):
            raise RuntimeError(f"IGESControl_Writer.AddShape failed for {job.file_name}")
        writer.ComputeModel()
        from .reproducible import apply_to_iges

        apply_to_iges(writer)  # no login name; SOURCE_DATE_EPOCH's date
        if not writer.Write(str(tmp)):
            raise RuntimeError(f"IGESControl_Writer.Write failed for {job.file_name}")


def _write_brep(job: ExportJob, tmp: Path) -> None:
    from OCP.BRepTools import BRepTools
    from OCP.TopTools import TopTools_FormatVersion

    # The exact B-rep only: no triangulation that an earlier tessellation left on the shape.
    if not BRepTools.Write_s(job.shape, str(tmp), False, False, TopTools_FormatVersion.TopTools_FormatVersion_CURRENT):
        raise RuntimeError(f"BRepTools.Write failed for {job.file_name}")


def _write_stl(job: ExportJob, tmp: Path) -> None:
    """Binary STL: facet normals are the triangles' own (STL has no vertex normals)."""
    t = job.tessellation
    corners = t.points[t.triangles]  # (n, 3, 3)
    facet = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    facet /= np.maximum(np.linalg.norm(facet, axis=1, keepdims=True), 1e-300)
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
    data = np.zeros(len(t.triangles), dtype=record)
    data["normal"] = facet
    data["corners"] = corners
    header = f"nupatch {job.name} (millimetres)".encode()[:80].ljust(80, b" ")
    with open(tmp, "wb") as fh:
        fh.write(header)
        fh.write(struct.pack("<I", len(data)))
        fh.write(data.tobytes())


def _write_obj(job: ExportJob, tmp: Path) -> None:
    """Wavefront OBJ: v (millimetres), vt = patch (s, t), vn = patch normals, f v/vt/vn."""
    t = job.tessellation
    with open(tmp, "w", encoding="utf-8") as fh:  # a mesh name need not be ASCII (Würfel)
        fh.write(f"# nupatch {job.name}: {len(t.points)} vertices, {len(t.triangles)} triangles, millimetres\n")
        fh.write(f"# tessellation tolerance {t.tolerance:g}; vt = patch parameters (s, t), vn = patch normals\n")
        fh.write(f"o {job.name}\n")
        np.savetxt(fh, t.points, fmt="v %.10g %.10g %.10g")
        np.savetxt(fh, t.uv, fmt="vt %.10g %.10g")
        np.savetxt(fh, t.normals, fmt="vn %.9f %.9f %.9f")
        i = np.repeat(t.triangles + 1, 3, axis=1)
        np.savetxt(fh, i, fmt="f %d/%d/%d %d/%d/%d %d/%d/%d")


def _write_glb(job: ExportJob, tmp: Path) -> None:
    """Binary glTF 2.0: one mesh, indexed triangles, POSITION/NORMAL/TEXCOORD_0/_PATCH."""
    t = job.tessellation
    arrays = [
        ("POSITION", t.points.astype("<f4"), "VEC3"),
        ("NORMAL", t.normals.astype("<f4"), "VEC3"),
        ("TEXCOORD_0", t.uv.astype("<f4"), "VEC2"),
        ("_PATCH", t.patch.astype("<f4"), "SCALAR"),
    ]
    blob = bytearray()
    views, accessors, attributes = [], [], {}
    for name, data, kind in arrays:
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": data.nbytes, "target": 34962})
        accessor = {"bufferView": len(views) - 1, "componentType": 5126, "count": len(data), "type": kind}
        if name == "POSITION":
            accessor["min"] = data.min(axis=0).tolist()
            accessor["max"] = data.max(axis=0).tolist()
        accessors.append(accessor)
        attributes[name] = len(accessors) - 1
        blob += data.tobytes()
    indices = t.triangles.astype("<u4")
    views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": indices.nbytes, "target": 34963})
    accessors.append({"bufferView": len(views) - 1, "componentType": 5125, "count": indices.size, "type": "SCALAR"})
    blob += indices.tobytes()
    gltf = {
        "asset": {"version": "2.0", "generator": "nupatch"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": job.name, "mesh": 0, "scale": [0.001, 0.001, 0.001]}],  # mm -> m
        "meshes": [{"name": job.name, "primitives": [{"attributes": attributes, "indices": len(accessors) - 1, "mode": 4}]}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    with open(tmp, "wb") as fh:
        fh.write(struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + 8 + len(blob)))
        fh.write(struct.pack("<II", len(text), 0x4E4F534A) + text)
        fh.write(struct.pack("<II", len(blob), 0x004E4942) + bytes(blob))


def _write_3dm(job: ExportJob, tmp: Path) -> None:
    from .rhino import write_3dm

    write_3dm(job.surface, tmp)


#: Format name -> writer(job, tmp_path).  Adding a format is one function and one entry.
WRITERS: dict[str, Callable[[ExportJob, Path], None]] = {
    "step": _write_step,
    "iges": _write_iges,
    "brep": _write_brep,
    "stl": _write_stl,
    "glb": _write_glb,
    "obj": _write_obj,
    "3dm": _write_3dm,
}
FORMATS = tuple(WRITERS)
#: File suffix -> format, for ``format_of``.
SUFFIXES = {".step": "step", ".stp": "step", ".iges": "iges", ".igs": "iges", ".brep": "brep",
            ".stl": "stl", ".glb": "glb", ".obj": "obj", ".3dm": "3dm"}


def format_of(path: str | os.PathLike, fmt: str | None = None) -> str:
    """The format named by ``fmt``, else by the suffix of ``path`` (OutputError if neither)."""
    if fmt is not None:
        if fmt not in WRITERS:
            raise OutputError(f"output format '{fmt}' is not supported (supported: {', '.join(FORMATS)})", str(path))
        return fmt
    if str(path) == "-":  # standard output (export.atomic.STDOUT): STEP unless --format says
        return "step"
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIXES:
        raise OutputError(
            f"cannot tell the output format from the suffix '{suffix}' (use --format or one of {', '.join(SUFFIXES)})",
            str(path),
        )
    return SUFFIXES[suffix]


def write(surface: BezierSurface, path: str | os.PathLike, fmt: str | None = None, *,
          tolerance: float | None = None, shape=None) -> Path:
    """Write ``surface`` to ``path`` in format ``fmt`` (default: from the suffix), atomically.

    ``shape``: its B-rep if already built (``export.brep.to_shape``); ``tolerance``: linear
    deflection of the tessellated formats (model units; default 1e-3 of ``surface.size``).
    """
    path = Path(path)
    fmt = format_of(path, fmt)
    if tolerance is not None:
        check_tolerance(tolerance)
    if shape is None:
        from export.brep import to_shape

        shape = to_shape(surface)
    job = ExportJob(surface, shape, path.name, tolerance)
    with atomic_output(path) as tmp:
        WRITERS[fmt](job, tmp)
    return path
