"""STEP input for ``nupatch toolpath``: the faces of a B-rep as Bezier patches on a quad mesh.

Every face's surface, restricted to the face's (u, v) bounds (``BRepTools.UVBounds``,
``Geom_RectangularTrimmedSurface``), is converted to a B-spline
(``GeomConvert.SurfaceToBSplineSurface``) and split at its knots into Bezier patches
(``GeomConvert_BSplineSurfaceToBezierSurface``), each raised to one degree in u and v
(``Geom_BezierSurface.Increase``).  The patches of a face become a grid of quads of their own
(corners: the patches' corner poles).  Corners of different faces that coincide (within
1e-7 of the size) are welded when the result is a manifold, consistently oriented quad mesh
and every side shared by two patches is the same curve on both (sampled, within 1e-6 of the
size); then the segmentation may join patches of neighbouring faces into one piece.  Otherwise
no vertex is shared between faces and each face is cut on its own (a face that faces up
everywhere is then one piece).  A
REVERSED face has its (u, v) swapped so that S_u x S_v is the face's outward normal.

Refused, one line naming the face: a trimmed face (its area differs from its (u, v)
rectangle's by more than 1e-6 relative: holes or a boundary that is not the four iso-lines),
a rational face (weights not all equal: cylinders, spheres, rational NURBS), a degree above
``MAX_DEGREE``, and a file without faces.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from patching.errors import InputFileError, UnsupportedError
from patching.mesh import ControlMesh, from_arrays
from patching.surface import BezierSurface, PatchGroup
from patching.topology import Topology
from patching.topology.patch_topology import patch_topology

__all__ = ["MAX_DEGREE", "STEP_SUFFIXES", "is_step", "read_step_patches"]

STEP_SUFFIXES = (".step", ".stp")
MAX_DEGREE = 9
#: relative area difference above which a face counts as trimmed.
TRIMMED = 1e-6
#: normal turn across a welded side above which the side is a crease.
CREASE_DEGREES = 10.0


def is_step(source: str | os.PathLike) -> bool:
    return Path(source).suffix.lower() in STEP_SUFFIXES


def _face_nets(face, where: str) -> tuple[list[list[np.ndarray]], int]:
    """The Bezier nets of one face, rows over u: nets[i][j] (d+1, d+1, 3), and d."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.BRepGProp import BRepGProp
    from OCP.BRepTools import BRepTools
    from OCP.Geom import Geom_RectangularTrimmedSurface
    from OCP.GeomConvert import GeomConvert, GeomConvert_BSplineSurfaceToBezierSurface
    from OCP.GProp import GProp_GProps

    u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
    surf = BRep_Tool.Surface_s(face)
    trimmed = Geom_RectangularTrimmedSurface(surf, u0, u1, v0, v1)
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    area = props.Mass()
    whole = GProp_GProps()
    BRepGProp.SurfaceProperties_s(BRepBuilderAPI_MakeFace(trimmed, 1e-9).Face(), whole)
    if abs(area - whole.Mass()) > TRIMMED * max(abs(whole.Mass()), 1e-300):
        raise UnsupportedError(
            f"trimmed face (area {area:.6g} of its (u, v) rectangle's {whole.Mass():.6g}): toolpath machines untrimmed faces only",
            where,
        )
    bs = GeomConvert.SurfaceToBSplineSurface_s(trimmed)
    if bs.IsURational() or bs.IsVRational():
        raise UnsupportedError("rational face (weights not all equal): toolpath machines polynomial B-spline faces only", where)
    conv = GeomConvert_BSplineSurfaceToBezierSurface(bs)
    nu, nv = conv.NbUPatches(), conv.NbVPatches()
    patches = [[conv.Patch(i + 1, j + 1) for j in range(nv)] for i in range(nu)]
    d = max(max(p.UDegree(), p.VDegree()) for row in patches for p in row)
    if d > MAX_DEGREE:
        raise UnsupportedError(f"degree {d} above {MAX_DEGREE}", where)
    nets = []
    for row in patches:
        out = []
        for p in row:
            p.Increase(d, d)
            net = np.array(
                [[[c.X(), c.Y(), c.Z()] for c in (p.Pole(a + 1, b + 1) for b in range(d + 1))] for a in range(d + 1)]
            )
            out.append(net)
        nets.append(out)
    return nets, d


def read_step_patches(path: str | os.PathLike) -> tuple[BezierSurface, ControlMesh]:
    """The faces of a STEP file as a BezierSurface on a quad mesh of its patches (module
    docstring): face k of the file becomes a (rows x columns) grid of mesh quads."""
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp

    from .ocp_compat import TopoDS, TopTools_IndexedMapOfShape
    from .shapes_in import read_shape

    path = Path(path)
    shape = read_shape(path)
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    if faces.Extent() == 0:
        raise InputFileError("the STEP file holds no faces", str(path))
    points, quads, nets_by_degree = [], [], {}
    base = 0
    for k in range(1, faces.Extent() + 1):
        face = TopoDS.Face_s(faces.FindKey(k))
        nets, d = _face_nets(face, f"{path}: face {k}")
        grid = np.array([[n for n in row] for row in nets])  # (nu, nv, d+1, d+1, 3)
        if face.Orientation() == TopAbs_REVERSED:
            grid = grid.transpose(1, 0, 3, 2, 4)
        nu, nv = grid.shape[:2]
        corners = np.zeros((nu + 1, nv + 1, 3))
        corners[:-1, :-1] = grid[:, :, 0, 0]
        corners[-1, :-1] = grid[-1, :, d, 0]
        corners[:-1, -1] = grid[:, -1, 0, d]
        corners[-1, -1] = grid[-1, -1, d, d]
        ids = base + np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
        i, j = (a.ravel() for a in np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij"))
        quads.append(np.stack([ids[i, j], ids[i + 1, j], ids[i + 1, j + 1], ids[i, j + 1]], axis=1))
        points.append(corners.reshape(-1, 3))
        nets_by_degree.setdefault(d, []).append((len(np.concatenate(quads)) - i.size, grid[i, j]))
        base += corners.shape[0] * corners.shape[1]
    vertices = np.concatenate(points)
    if not np.all(np.isfinite(vertices)):
        raise InputFileError("non-finite pole coordinates", str(path))
    quads = np.concatenate(quads)
    groups = []
    for d in sorted(nets_by_degree):
        rows = nets_by_degree[d]
        groups.append(
            PatchGroup(
                degree=d,
                faces=np.concatenate([first + np.arange(len(n)) for first, n in rows]).astype(np.int64),
                coefficients=np.concatenate([n for _, n in rows]),
            )
        )
    all_poles = np.concatenate([g.coefficients.reshape(-1, 3) for g in groups])
    size = float(np.linalg.norm(all_poles.max(axis=0) - all_poles.min(axis=0)))
    mesh = _welded(vertices, quads, groups, size, path.stem)
    if mesh is None:
        mesh = from_arrays(vertices, quads, name=path.stem)
    n_faces = mesh.n_faces
    topology = patch_topology(Topology(mesh), np.arange(n_faces), np.ones((n_faces, 2)))
    return BezierSurface(groups=tuple(groups), topology=topology, name=path.stem, size=size), mesh


def _welded(vertices: np.ndarray, quads: np.ndarray, groups: list[PatchGroup], size: float, name: str) -> ControlMesh | None:
    """The quad mesh with coincident corners welded, or None where that is not sound (module
    docstring)."""
    from patching.errors import NupatchError
    from patching.surface import CORNER_PARAMETERS
    from patching.bernstein import group_nets
    from patching.toolpath.geometry import evaluate_points, unit_normals

    key = np.round(vertices / max(1e-7 * size, 1e-300)).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    if len(first) == len(vertices):
        return None
    welded = inverse[quads]
    if any(len(set(q)) < 4 for q in welded.tolist()):
        return None
    try:
        mesh = from_arrays(vertices[first], welded, name=name)
        topo = Topology(mesh)
    except NupatchError:
        return None
    # Every shared side the same curve on both patches.
    rows, all_nets, _ = group_nets(groups)
    nets = np.zeros((mesh.n_faces, *all_nets.shape[1:]))
    nets[rows] = all_nets
    h = np.flatnonzero(topo.twin >= 0)
    f, k = topo.face[h], h - mesh.face_offsets[topo.face[h]]
    g_, kg = topo.face[topo.twin[h]], topo.twin[h] - mesh.face_offsets[topo.face[topo.twin[h]]]
    tau = np.linspace(0.0, 1.0, 7)

    def side_points(face, side, t):
        a, b = CORNER_PARAMETERS[side], CORNER_PARAMETERS[(side + 1) % 4]
        st = (a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]).reshape(-1, 2)
        p, su, sv = evaluate_points(np.repeat(nets[face], len(t), axis=0), st[:, 0], st[:, 1])
        return p.reshape(len(face), len(t), 3), unit_normals(su, sv).reshape(len(face), len(t), 3)

    pa, na = side_points(f, k, tau)
    pb, nb = side_points(g_, kg, tau[::-1])
    if np.abs(pa - pb).max(initial=0.0) > 1e-6 * size:
        return None
    # A side where the normals turn by more than CREASE_DEGREES somewhere is a crease (sharp):
    # the segmentation never joins across it, as across a mesh's sharp edges.
    cos = np.einsum("nkc,nkc->nk", na, nb).min(axis=1, initial=1.0)
    crease = cos < np.cos(np.radians(CREASE_DEGREES))
    if not crease.any():
        return mesh
    ends = topo.edges[topo.edge_of[h[crease]]]
    return from_arrays(vertices[first], welded, creases={(int(a), int(b)): np.inf for a, b in ends}, name=name)
