"""USD control meshes (``.usd .usda .usdc``) through usd-core (docs/input.md).

Every ``UsdGeom.Mesh`` prim of the stage (instance proxies included) becomes part of one
``ControlMesh``: its ``points`` in the prim's world transform (``ComputeLocalToWorldTransform``
at the default time, row vectors: p_world = p M), ``faceVertexCounts``/``Indices``,
``creaseIndices``/``Lengths``/``Sharpnesses`` (one sharpness per crease, or one per crease edge),
``cornerIndices``/``Sharpnesses``, ``holeIndices``, ``interpolateBoundary``
(``none`` 0, ``edgeAndCorner`` 1, ``edgeOnly`` 2) and ``triangleSubdivisionRule``
(``catmullClark``, ``smooth``: ``ControlMesh.triangle_subdivision`` "catmark", "smooth", as the
OBJ tag ``t smoothtriangles``); prims that differ in either of the last two are refused.  Sharpness values are OpenSubdiv's, as in
the OBJ tags (>= 10 infinitely sharp).  A ``leftHanded`` prim, or a world transform that
mirrors, has its faces reversed so that normals point the way the prim's do.

Knot intervals: the primvar ``nupatch:intervals``, one float per face-vertex (``faceVarying``:
the edge from that face-vertex to the next one of its face), constant on strips; without it the
``--intervals`` rule applies.  ``subdivisionScheme`` must be ``catmullClark``; ``none`` (a
polygonal mesh: Blender writes it when it applies the subdivision modifier to the geometry, or
exports a mesh with no modifier) is read as a Catmull-Clark control mesh too, with a warning
naming the prim, because building smooths what the file calls flat; ``loop`` and ``bilinear``
are refused (``nupatch subdivide --scheme loop`` reads OBJ triangle meshes).

Coordinates are taken as they are, in the stage's units (``metersPerUnit`` is not applied):
the output files say millimetres, as for OBJ.  Errors name the file and the prim.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from patching.errors import InputFileError, KnotError, MeshError, NupatchError, UnsupportedError
from patching.mesh import ControlMesh, NupatchWarning, from_arrays

__all__ = ["USD_SUFFIXES", "INTERVALS_PRIMVAR", "read_usd", "parse_usda", "write_usd"]

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
INTERVALS_PRIMVAR = "nupatch:intervals"
_BOUNDARY = {"none": 0, "edgeAndCorner": 1, "edgeOnly": 2}
_SCHEMES = ("catmullClark", "none")
_TRIANGLES = {"catmullClark": "catmark", "smooth": "smooth"}


def _pxr():
    try:
        from pxr import Sdf, Usd, UsdGeom, Vt  # noqa: F401
    except ModuleNotFoundError:
        raise NupatchError("reading USD needs usd-core: pip install 'nupatch[usd]'", "usd") from None
    return Sdf, Usd, UsdGeom, Vt


def read_usd(path: str | os.PathLike) -> ControlMesh:
    """The control mesh of every UsdGeom.Mesh prim of the USD file ``path`` (module docstring);
    the product name is the file's stem."""
    Sdf, Usd, UsdGeom, Vt = _pxr()
    path = Path(path)
    if not path.is_file():
        raise InputFileError("no such file" if not path.exists() else "not a file", str(path))
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as exc:  # pxr raises Tf.ErrorException with a multi-line text
        raise InputFileError(f"not a USD stage ({_first_line(exc)})", str(path)) from None
    if stage is None:
        raise InputFileError("not a USD stage", str(path))
    return stage_mesh(stage, path.name, path.stem)


def parse_usda(text: str, source: str = "<stdin>", name: str = "mesh") -> ControlMesh:
    """The control mesh of a stage given as ``.usda`` text (``-`` on the command line)."""
    Sdf, Usd, UsdGeom, Vt = _pxr()
    layer = Sdf.Layer.CreateAnonymous(".usda")
    try:
        ok = layer.ImportFromString(text)
    except Exception as exc:
        raise InputFileError(f"not a USD stage ({_first_line(exc)})", source) from None
    if not ok:
        raise InputFileError("not a USD stage", source)
    return stage_mesh(Usd.Stage.Open(layer), source, name)


def _first_line(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return text[:200]


def _get(attr, Usd):
    """An attribute's value at the default time, else at its earliest time sample."""
    if not attr or not attr.HasValue():
        return None
    value = attr.Get(Usd.TimeCode.Default())
    if value is None:
        value = attr.Get(Usd.TimeCode.EarliestTime())
    return value


def stage_mesh(stage, source: str, name: str) -> ControlMesh:
    """One ControlMesh from all UsdGeom.Mesh prims of an open ``Usd.Stage``."""
    Sdf, Usd, UsdGeom, Vt = _pxr()
    prims = [p for p in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()) if p.IsA(UsdGeom.Mesh)]
    if not prims:
        raise InputFileError("no UsdGeom.Mesh prim in the stage", source)
    vertices, faces_flat, counts = [], [], []
    intervals: dict[tuple[int, int], float] = {}
    creases: dict[tuple[int, int], float] = {}
    corners: dict[int, float] = {}
    holes: list[int] = []
    locations: dict[tuple, str] = {}
    boundary_of: dict[int, str] = {}
    triangles_of: dict[str, str] = {}
    n_v = n_f = 0
    for prim in prims:
        where = f"{source}: prim {prim.GetPath()}"
        mesh = UsdGeom.Mesh(prim)
        scheme = _get(mesh.GetSubdivisionSchemeAttr(), Usd) or "catmullClark"
        if scheme not in _SCHEMES:
            raise UnsupportedError(
                f"subdivisionScheme '{scheme}' is not supported (nupatch reads catmullClark control meshes)", where
            )
        if scheme == "none":
            warnings.warn(NupatchWarning(
                f"subdivisionScheme 'none' (a polygonal mesh) read as a Catmull-Clark control mesh ({where})"
            ), stacklevel=2)
        points = _get(mesh.GetPointsAttr(), Usd)
        fvc = _get(mesh.GetFaceVertexCountsAttr(), Usd)
        fvi = _get(mesh.GetFaceVertexIndicesAttr(), Usd)
        if points is None or fvc is None or fvi is None or len(fvc) == 0:
            raise MeshError("mesh prim without points or faces", where)
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        fvc = np.asarray(fvc, dtype=np.int64)
        fvi = np.asarray(fvi, dtype=np.int64)
        if fvc.sum() != fvi.size or (fvc < 3).any():
            raise MeshError(
                f"faceVertexCounts (sum {int(fvc.sum())}, smallest {int(fvc.min())}) do not fit "
                f"{fvi.size} faceVertexIndices (faces need at least 3 vertices)", where,
            )
        if ((fvi < 0) | (fvi >= len(p))).any():
            bad = int(fvi[(fvi < 0) | (fvi >= len(p))][0])
            raise MeshError(f"faceVertexIndices use vertex {bad}, but the prim has {len(p)} points", where)
        bad = np.flatnonzero(~np.isfinite(p).all(axis=1))
        if bad.size:
            raise MeshError(f"point {int(bad[0])} is not finite ({p[bad[0]].tolist()})", where)
        matrix = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()), dtype=np.float64)
        world = p @ matrix[:3, :3] + matrix[3, :3]
        offsets = np.concatenate([[0], np.cumsum(fvc)])
        face_start = np.repeat(offsets[:-1], fvc)
        local = np.arange(fvi.size) - face_start
        nxt = face_start + (local + 1) % np.repeat(fvc, fvc)
        # knot intervals: faceVarying primvar, one value per face-vertex's edge (to the next one)
        primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(INTERVALS_PRIMVAR)
        if primvar and primvar.HasValue():
            values = np.asarray(primvar.ComputeFlattened(), dtype=np.float64).ravel()
            if values.size != fvi.size:
                raise KnotError(
                    f"primvar {INTERVALS_PRIMVAR} has {values.size} values for {fvi.size} face-vertices "
                    "(one per edge in faceVertexIndices order)", where,
                )
            a, b = np.minimum(fvi, fvi[nxt]), np.maximum(fvi, fvi[nxt])
            bad = np.flatnonzero(~(np.isfinite(values) & (values >= 0)))
            if bad.size:
                i = int(bad[0])
                raise KnotError(f"knot interval {values[i]:g} of edge {a[i]}-{b[i]} must be finite and >= 0", where)
            # the two face-vertices of an interior edge must agree
            order = np.lexsort((values, b, a))
            sa, sb, sv = a[order], b[order], values[order]
            clash = np.flatnonzero((sa[1:] == sa[:-1]) & (sb[1:] == sb[:-1]) & (sv[1:] != sv[:-1]))
            if clash.size:
                i = int(clash[0])
                raise KnotError(f"edge {sa[i]}-{sb[i]} has two knot intervals, {sv[i]:g} and {sv[i + 1]:g}", where)
            keys = zip((a + n_v).tolist(), (b + n_v).tolist())
            intervals.update(zip(keys, values.tolist()))
            locations.update(dict.fromkeys((("interval", k) for k in zip((a + n_v).tolist(), (b + n_v).tolist())), where))
        flip = (_get(mesh.GetOrientationAttr(), Usd) == "leftHanded") != bool(np.linalg.det(matrix[:3, :3]) < 0)
        if flip:  # reverse each face, keeping its first vertex (the edges stay the same)
            fvi = fvi[face_start + np.where(local == 0, 0, np.repeat(fvc, fvc) - local)]
        # creases: runs of creaseLengths vertices, one sharpness per run or per run edge
        ci = _get(mesh.GetCreaseIndicesAttr(), Usd)
        if ci is not None and len(ci):
            ci = np.asarray(ci, dtype=np.int64)
            cl = np.asarray(_get(mesh.GetCreaseLengthsAttr(), Usd) or [], dtype=np.int64)
            cs = np.asarray(_get(mesh.GetCreaseSharpnessesAttr(), Usd) or [], dtype=np.float64)
            n_edges = int(np.maximum(cl - 1, 0).sum())
            if cl.sum() != ci.size or (cl < 2).any() or cs.size not in (cl.size, n_edges):
                raise MeshError(
                    f"creaseLengths (sum {int(cl.sum())}) and creaseSharpnesses ({cs.size}) do not fit "
                    f"{ci.size} creaseIndices", where,
                )
            start = 0
            k = 0
            for run, length in enumerate(cl):
                chain = ci[start : start + length]
                for j in range(length - 1):
                    s = float(cs[run] if cs.size == cl.size else cs[k])
                    a, b = int(chain[j]) + n_v, int(chain[j + 1]) + n_v
                    key = (min(a, b), max(a, b))
                    creases[key] = s
                    locations[("crease", key)] = where
                    k += 1
                start += length
        cvi = _get(mesh.GetCornerIndicesAttr(), Usd)
        if cvi is not None and len(cvi):
            cvs = np.asarray(_get(mesh.GetCornerSharpnessesAttr(), Usd) or [], dtype=np.float64)
            if cvs.size != len(cvi):
                raise MeshError(f"{len(cvi)} cornerIndices but {cvs.size} cornerSharpnesses", where)
            for v, s in zip(np.asarray(cvi, dtype=np.int64), cvs):
                corners[int(v) + n_v] = float(s)
                locations[("corner", int(v) + n_v)] = where
        hi = _get(mesh.GetHoleIndicesAttr(), Usd)
        if hi is not None and len(hi):
            hi = np.asarray(hi, dtype=np.int64)
            if ((hi < 0) | (hi >= fvc.size)).any():
                raise MeshError(f"holeIndices name face {int(hi[(hi < 0) | (hi >= fvc.size)][0])} of {fvc.size}", where)
            holes.extend(int(f) + n_f for f in hi)
        boundary = _get(mesh.GetInterpolateBoundaryAttr(), Usd) or "edgeAndCorner"
        if boundary not in _BOUNDARY:
            raise MeshError(f"interpolateBoundary '{boundary}' is not one of {', '.join(_BOUNDARY)}", where)
        boundary_of[_BOUNDARY[boundary]] = where
        rule = _get(mesh.GetTriangleSubdivisionRuleAttr(), Usd) or "catmullClark"
        if rule not in _TRIANGLES:
            raise MeshError(f"triangleSubdivisionRule '{rule}' is not one of {', '.join(_TRIANGLES)}", where)
        triangles_of[_TRIANGLES[rule]] = where
        if rule == "smooth":
            locations[("tag", "smoothtriangles")] = where
        for f in range(fvc.size):
            locations[("face", n_f + f)] = f"{where} face {f}"
        vertices.append(world)
        faces_flat.append(fvi + n_v)
        counts.append(fvc)
        n_v += len(p)
        n_f += fvc.size
    for attr, values in (("interpolateBoundary", boundary_of), ("triangleSubdivisionRule", triangles_of)):
        if len(values) > 1:
            (k1, w1), (k2, w2) = list(values.items())[:2]
            raise UnsupportedError(
                f"mesh prims with different {attr} ({k1} at {w1}, {k2}) cannot build as one surface", w2
            )
    counts_all = np.concatenate(counts)
    flat = np.concatenate(faces_flat)
    offsets_all = np.concatenate([[0], np.cumsum(counts_all)])
    faces = [flat[offsets_all[f] : offsets_all[f + 1]] for f in range(counts_all.size)]
    if counts_all.size and (counts_all == counts_all[0]).all():
        faces = flat.reshape(-1, int(counts_all[0]))
    return from_arrays(
        np.concatenate(vertices),
        faces,
        intervals=intervals,
        creases=creases,
        corners=corners,
        holes=holes,
        interpolate_boundary=next(iter(boundary_of)),
        name=name,
        locations=locations,
        triangle_subdivision=next(iter(triangles_of)),
    )


def write_usd(mesh: ControlMesh, path: str | os.PathLike, prim_path: str = "/mesh") -> Path:
    """Write ``mesh`` as one UsdGeom.Mesh prim with its creases, corners, holes,
    interpolateBoundary, triangleSubdivisionRule (when smooth) and the ``nupatch:intervals``
    primvar (every face-vertex's edge)."""
    from export.atomic import atomic_output

    Sdf, Usd, UsdGeom, Vt = _pxr()
    from patching.topology import Topology

    path = Path(path)
    topo = Topology(mesh)
    with atomic_output(path) as tmp:
        target = tmp.with_suffix(path.suffix)  # usd-core picks the format from the suffix
        stage = Usd.Stage.CreateNew(str(target))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        m = UsdGeom.Mesh.Define(stage, prim_path)
        m.CreatePointsAttr([tuple(v) for v in mesh.vertices.tolist()])
        m.CreateFaceVertexCountsAttr(mesh.face_sizes.tolist())
        m.CreateFaceVertexIndicesAttr(mesh.face_vertices.tolist())
        m.CreateSubdivisionSchemeAttr("catmullClark")
        m.CreateInterpolateBoundaryAttr({v: k for k, v in _BOUNDARY.items()}[mesh.interpolate_boundary])
        if mesh.triangle_subdivision != "catmark":
            m.CreateTriangleSubdivisionRuleAttr({v: k for k, v in _TRIANGLES.items()}[mesh.triangle_subdivision])
        if mesh.creases:
            keys = list(mesh.creases)
            m.CreateCreaseIndicesAttr([v for k in keys for v in k])
            m.CreateCreaseLengthsAttr([2] * len(keys))
            m.CreateCreaseSharpnessesAttr([float(mesh.creases[k]) for k in keys])
        if mesh.corners:
            m.CreateCornerIndicesAttr(list(mesh.corners))
            m.CreateCornerSharpnessesAttr([float(s) for s in mesh.corners.values()])
        if mesh.holes:
            m.CreateHoleIndicesAttr(sorted(mesh.holes))
        pv = UsdGeom.PrimvarsAPI(m.GetPrim()).CreatePrimvar(
            INTERVALS_PRIMVAR, Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.faceVarying
        )
        pv.Set(topo.halfedge_interval.astype(np.float64).tolist())
        stage.GetRootLayer().Save()
        os.replace(target, tmp)
    return path
