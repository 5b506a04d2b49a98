"""Continuity of a B-rep across its shared edges, measured with OpenCASCADE alone (DESIGN 5).

For every edge that two faces share (``TopExp.MapShapesAndAncestors``), points are sampled
at ``samples_per_edge`` equally spaced parameters w of the edge, including its ends.  At each
w both faces are evaluated at the (u, v) their pcurves give (exact for SameParameter edges;
otherwise the edge's 3D point is projected onto the face), and we record

- the gap |S1(u1, v1) - S2(u2, v2)|;
- the normal jump atan2(|n1 x n2|, n1 . n2) in degrees, with n = S_u x S_v negated on a
  face whose orientation in the shape is REVERSED, so a smooth consistently oriented surface
  measures 0, not 180.

Samples where a normal vanishes (a degenerate corner) give no angle.  An edge with one face
is a free edge; an edge used twice by one face (a seam) is compared with itself across the
seam.  Edge and face indices are 0-based positions in ``TopExp.MapShapes`` order; for a shape
from ``export.brep.to_shape`` the face index is the patch row.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass

import numpy as np
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Curve2d, BRepAdaptor_Surface
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.gp import gp_Pnt, gp_Vec
from OCP.ShapeAnalysis import ShapeAnalysis_Surface
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_FORWARD, TopAbs_REVERSED, TopAbs_SHELL, TopAbs_SOLID
from OCP.TopExp import TopExp
from OCP.TopoDS import TopoDS, TopoDS_Shape
from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape, TopTools_IndexedMapOfShape

__all__ = ["EdgeDefect", "ContinuityReport", "check_continuity"]

#: Entries of ``ContinuityReport.worst_edges`` per criterion (normal jump, then gap).
N_WORST = 5


@dataclass(frozen=True)
class EdgeDefect:
    """One shared edge's worst sample: the largest gap and normal jump along it.

    edge: index of the edge; faces: the two face indices; position: (x, y, z) of the sample
    where the quantity the edge was ranked by (angle or gap) is largest.
    """

    edge: int
    faces: tuple[int, int]
    gap: float
    angle_deg: float
    position: tuple[float, float, float]


@dataclass(frozen=True)
class ContinuityReport:
    """Validity, topology counts and the largest gap and normal jump over the shared edges.

    max_gap is absolute (model units); max_gap_relative divides it by ``diagonal``, the
    bounding-box diagonal of the shape.  worst_edges lists up to 5 edges by normal jump,
    then up to 5 more by gap.
    """

    valid: bool
    n_solids: int
    n_shells: int
    n_faces: int
    n_edges: int
    n_shared_edges: int
    n_free_edges: int
    samples_per_edge: int
    diagonal: float
    max_gap: float
    max_gap_relative: float
    max_normal_jump_deg: float
    worst_edges: tuple[EdgeDefect, ...]

    def as_dict(self) -> dict:
        """Plain JSON-ready dict (tuples become lists)."""
        return asdict(self)

    def to_json(self, indent: int | None = 2) -> str:
        """The report as JSON."""
        return json.dumps(self.as_dict(), indent=indent)

    def summary(self) -> str:
        """A one-screen text report."""
        lines = [
            f"valid (BRepCheck_Analyzer): {'yes' if self.valid else 'NO'}",
            f"solids {self.n_solids}, shells {self.n_shells}, faces {self.n_faces}, "
            f"edges {self.n_edges} ({self.n_shared_edges} shared, {self.n_free_edges} free)",
            f"max gap: {self.max_gap:.3e} ({self.max_gap_relative:.3e} of the diagonal {self.diagonal:.6g})",
            f"max normal jump: {self.max_normal_jump_deg:.3e} deg "
            f"({self.samples_per_edge} samples per shared edge)",
        ]
        if self.worst_edges:
            lines.append("worst edges:  edge   faces          gap          angle(deg)  at")
            for d in self.worst_edges:
                x, y, z = d.position
                lines.append(
                    f"  {d.edge:>10d}   {d.faces[0]:>5d},{d.faces[1]:<6d} {d.gap:11.3e}  {d.angle_deg:11.3e}"
                    f"  ({x:.6g}, {y:.6g}, {z:.6g})"
                )
        return "\n".join(lines)


def _count(shape: TopoDS_Shape, kind) -> int:
    shapes = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, kind, shapes)
    return shapes.Extent()


def _diagonal(shape: TopoDS_Shape) -> float:
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)  # poles' box for Bézier/B-spline faces: cheap, and >= the surface's
    if box.IsVoid():
        return 0.0
    x0, y0, z0, x1, y1, z1 = box.Get()
    return math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2 + (z1 - z0) ** 2)


class _Surfaces:
    """Surface adaptors of the shape's faces, built once per face, and their D1 evaluation."""

    def __init__(self, faces: TopTools_IndexedMapOfShape, tol: float) -> None:
        self.faces = faces
        self.tol = tol
        self.adaptors: dict[int, BRepAdaptor_Surface] = {}
        self.projectors: dict[int, ShapeAnalysis_Surface] = {}
        self.p, self.du, self.dv = gp_Pnt(), gp_Vec(), gp_Vec()

    def index(self, face) -> int:
        return self.faces.FindIndex(face) - 1

    def adaptor(self, i: int) -> BRepAdaptor_Surface:
        if i not in self.adaptors:
            self.adaptors[i] = BRepAdaptor_Surface(TopoDS.Face_s(self.faces.FindKey(i + 1)), False)
        return self.adaptors[i]

    def project(self, i: int, point: gp_Pnt):
        if i not in self.projectors:
            face = TopoDS.Face_s(self.faces.FindKey(i + 1))
            self.projectors[i] = ShapeAnalysis_Surface(BRep_Tool.Surface_s(face))
        return self.projectors[i].ValueOfUV(point, self.tol)

    def sample(self, edge, face, orientation, ws: np.ndarray, curve) -> list[tuple[float, ...]]:
        """(x, y, z, nx, ny, nz) at each w: the face's point and its outward S_u x S_v."""
        i = self.index(face)
        surface = self.adaptor(i)
        sign = -1.0 if face.Orientation() == TopAbs_REVERSED else 1.0
        if orientation is not None:  # one side of a seam: its own pcurve
            edge = TopoDS.Edge_s(edge.Oriented(orientation))
        pcurve = BRepAdaptor_Curve2d(edge, face) if curve is None else None
        p, du, dv = self.p, self.du, self.dv
        out = []
        for w in ws:
            uv = pcurve.Value(w) if curve is None else self.project(i, curve.Value(w))
            surface.D1(uv.X(), uv.Y(), p, du, dv)
            n = du.Crossed(dv)
            out.append((p.X(), p.Y(), p.Z(), sign * n.X(), sign * n.Y(), sign * n.Z()))
        return out


def _shapes(listed) -> list:
    """The shapes of a TopTools_ListOfShape; Python iteration over one costs ~100 us, so the
    usual one or two are taken with First() and Last()."""
    n = listed.Size()
    if n <= 2:
        return [listed.First(), listed.Last()][2 - n :] if n else []
    return list(listed)


def _sample_edge(surfaces: _Surfaces, edge, side1, side2, fractions: np.ndarray) -> np.ndarray:
    """(samples, 2, 2, 3): at each w, (point, normal) on the face of side1 and of side2.

    A side is (face, orientation): orientation None for an ordinary edge, FORWARD or
    REVERSED to pick one pcurve of a seam.  SameParameter edges are evaluated through their
    pcurves at the edge parameter; others by projecting the edge's 3D point.
    """
    curve = BRepAdaptor_Curve(edge)
    first, last = curve.FirstParameter(), curve.LastParameter()
    ws = [float(w) for w in first + (last - first) * fractions]
    projected = None if BRep_Tool.SameParameter_s(edge) else curve
    a = surfaces.sample(edge, side1[0], side1[1], ws, projected)
    b = surfaces.sample(edge, side2[0], side2[1], ws, projected)
    return np.array([a, b]).reshape(2, len(ws), 2, 3).transpose(1, 0, 2, 3)


def check_continuity(shape_or_path: TopoDS_Shape | str | os.PathLike, samples_per_edge: int = 9) -> ContinuityReport:
    """Measure validity, free edges, gaps and normal jumps of a shape or a STEP file (DESIGN 5)."""
    if samples_per_edge < 2:
        raise ValueError("samples_per_edge must be at least 2 (the edge's two ends)")
    if isinstance(shape_or_path, (str, os.PathLike)):
        from export.step import read_step

        shape = read_step(shape_or_path)
    else:
        shape = shape_or_path

    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    edge_faces = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, edge_faces)
    diagonal = _diagonal(shape)
    tol = 1e-9 * diagonal if diagonal > 0 else 1e-9

    surfaces = _Surfaces(faces, tol)
    fractions = np.linspace(0.0, 1.0, samples_per_edge)
    pairs: list[tuple[int, tuple[int, int], np.ndarray]] = []
    n_free = 0
    for i in range(1, edge_faces.Extent() + 1):
        edge = TopoDS.Edge_s(edge_faces.FindKey(i))
        if BRep_Tool.Degenerated_s(edge) or not BRep_Tool.IsGeometric_s(edge):
            continue
        ancestors = _shapes(edge_faces.FindFromIndex(i))
        distinct = []
        for f in ancestors:
            if not any(f.IsSame(g) for g in distinct):
                distinct.append(f)
        if len(distinct) == 1 and len(ancestors) >= 2:  # seam: the face on both sides
            f = TopoDS.Face_s(distinct[0])
            sides = [(f, TopAbs_FORWARD), (f, TopAbs_REVERSED)]
        elif len(distinct) == 1:
            n_free += 1
            continue
        else:  # two faces (or, non-manifold, more: each against the first)
            sides = [(TopoDS.Face_s(f), None) for f in distinct]
        for other in sides[1:]:
            samples = _sample_edge(surfaces, edge, sides[0], other, fractions)
            face_ids = (surfaces.index(sides[0][0]), surfaces.index(other[0]))
            pairs.append((i - 1, face_ids, samples))

    worst: list[EdgeDefect] = []
    max_gap = 0.0
    max_angle = 0.0
    if pairs:
        data = np.stack([s for _, _, s in pairs])  # (e, samples, 2 faces, point|normal, 3)
        p1, p2 = data[:, :, 0, 0], data[:, :, 1, 0]
        n1, n2 = data[:, :, 0, 1], data[:, :, 1, 1]
        gap = np.linalg.norm(p1 - p2, axis=-1)
        cross = np.linalg.norm(np.cross(n1, n2), axis=-1)
        dot = np.einsum("esk,esk->es", n1, n2)
        scale = np.linalg.norm(n1, axis=-1) * np.linalg.norm(n2, axis=-1)
        # A normal shorter than ~1e-12 of the typical one (a degenerate point) gives no angle.
        typical = np.median(scale) if np.any(scale > 0) else 1.0
        angle = np.where(scale > 1e-24 * typical, np.degrees(np.arctan2(cross, dot)), 0.0)
        max_gap = float(gap.max())
        max_angle = float(angle.max())
        edge_gap, edge_angle = gap.max(axis=1), angle.max(axis=1)
        mid = 0.5 * (p1 + p2)

        def defect(e: int, by: np.ndarray) -> EdgeDefect:
            s = int(np.argmax(by[e]))
            edge, face_ids, _ = pairs[e]
            return EdgeDefect(
                edge,
                face_ids,
                float(edge_gap[e]),
                float(edge_angle[e]),
                tuple(float(c) for c in mid[e, s]),
            )

        chosen: list[int] = []
        for key, by in ((edge_angle, angle), (edge_gap, gap)):
            order = [int(e) for e in np.argsort(-key, kind="stable") if key[e] > 0 and e not in chosen]
            for e in order[:N_WORST]:
                chosen.append(e)
                worst.append(defect(e, by))

    return ContinuityReport(
        valid=bool(BRepCheck_Analyzer(shape).IsValid()),
        n_solids=_count(shape, TopAbs_SOLID),
        n_shells=_count(shape, TopAbs_SHELL),
        n_faces=faces.Extent(),
        n_edges=edge_faces.Extent(),
        n_shared_edges=len({e for e, _, _ in pairs}),
        n_free_edges=n_free,
        samples_per_edge=samples_per_edge,
        diagonal=diagonal,
        max_gap=max_gap,
        max_gap_relative=max_gap / diagonal if diagonal > 0 else 0.0,
        max_normal_jump_deg=max_angle,
        worst_edges=tuple(worst),
    )
