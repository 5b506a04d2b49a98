"""Continuity of a B-rep across its shared edges, measured with OpenCASCADE alone (docs/verification.md).

For every edge that two faces share (``TopExp.MapShapesAndAncestors``), points are sampled
at ``samples_per_edge`` equally spaced parameters w of the edge, including its ends.  At each
w both faces are evaluated at the (u, v) their pcurves give (exact for SameParameter edges;
otherwise the edge's 3D point is projected onto the face), and we record

- the gap |S1(u1, v1) - S2(u2, v2)|;
- the normal jump atan2(|n1 x n2|, n1 . n2) in degrees, with n = S_u x S_v negated on a
  face whose orientation in the shape is REVERSED, so a smooth consistently oriented surface
  measures 0, not 180.

Every shared edge is then classified (the per-edge G0/G1 table, ``ContinuityReport.edges``):

- *sharp*: its normal jump is at least ``sharp_angle_deg`` (default 10 deg) at every sample,
  ends included.  A crease (an infinitely sharp edge, C0 by design, docs/surface.md) keeps its angle
  along its whole length; a continuity defect vanishes wherever the two nets still agree (at
  the ends of an edge whose interior row moved: a nudge of 20% of a torus' tube radius gives
  19 deg at the middle of an edge, 0 at its ends), so it is never taken for a crease however
  large.  10 deg is far above any defect nupatch's constructions leave (G1 residuals 1e-7 deg,
  round-off 1e-11 deg) and below the angle any designed crease has: CAD systems' own "smooth
  edge" defaults for tangent chains are 1-10 deg.  Sharp edges are reported apart and left out
  of the ``smooth`` maxima, so a creased model's test can assert those at round-off;
- *fading*: a crease that fades out into a dart (``t crease`` edges ending at a vertex with
  one sharp edge, docs/surface.md: by design the jump is the crease's at one end and 0 at the
  dart, where every patch shares one tangent plane).  Recognised from the measured profile and
  the edge's neighbours, not from tags (a STEP file carries none): the gap is within tolerance,
  the jump is at most ``g1_tolerance_deg`` at one end (the dart) and above it at every other
  sample, at least ``sharp_angle_deg`` at the other end, and that end's vertex is shared by a
  sharp edge or by another fading edge (the crease it continues; a crease of two edges between
  two darts is two fading edges).  A continuity defect is not taken for one: a moved interior
  row vanishes at both ends of its edge, and a broken tangent plane at the dart gives a jump
  there.  Not recognised: a crease of a single edge between two darts (0 at both ends, like a
  defect): it is reported G0.  Fading edges are counted apart (``n_fading_edges``) and, like
  sharp ones, left out of the ``smooth`` maxima and of ``g1``;
- otherwise *G1* when its largest normal jump is at most ``g1_tolerance_deg``, *G0* when only
  its gap is at most ``gap_tolerance`` (relative to the diagonal), else *open* (a gap).

Samples where a normal vanishes (a degenerate corner) give no angle.  An edge with one face
is a free edge; an edge used twice by one face (a seam) is compared with itself across the
seam.  Edge and face indices are 0-based positions in ``TopExp.MapShapes`` order; for a shape
from ``export.brep.to_shape`` the face index is the patch row when the surface is connected
(several components come one after the other: ``export.brep.shape_face_rows``).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass

import numpy as np
from export.tolerances import G1_TOLERANCE_DEG, GAP_TOLERANCE, N_WORST, SHARP_ANGLE_DEG
from .ocp_compat import TopoDS, TopTools_IndexedDataMapOfShapeListOfShape, TopTools_IndexedMapOfShape, box_bounds
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Curve2d, BRepAdaptor_Surface
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.gp import gp_Pnt, gp_Vec
from OCP.ShapeAnalysis import ShapeAnalysis_Surface
from OCP.TopAbs import (
    TopAbs_EDGE,
    TopAbs_FACE,
    TopAbs_FORWARD,
    TopAbs_REVERSED,
    TopAbs_SHELL,
    TopAbs_SOLID,
    TopAbs_VERTEX,
)
from OCP.TopExp import TopExp
from OCP.TopoDS import TopoDS_Shape

__all__ = ["EdgeDefect", "ContinuityReport", "check_continuity"]



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
    #: "G1", "G0", "open" (gap above tolerance), "sharp" (a crease) or "fading" (a crease
    #: fading into a dart; module docstring).
    kind: str = ""
    #: Smallest normal jump along the edge (degrees), what ``sharp`` is decided by.
    min_angle_deg: float = 0.0


@dataclass(frozen=True)
class ContinuityReport:
    """Validity, topology counts and the largest gap and normal jump over the shared edges.

    max_gap is absolute (model units); max_gap_relative divides it by ``diagonal``, the
    bounding-box diagonal of the shape.  worst_edges lists up to ``worst`` (5) non-sharp edges
    by normal jump, then up to as many more by gap; sharp_edges up to as many sharp edges by
    angle.  max_normal_jump_deg and max_gap are over all shared edges, the ``smooth`` maxima
    over the edges neither sharp nor fading (what a creased model's test asserts); n_g1 + n_g0
    + n_open + n_sharp + n_fading = the number of shared edge pairs; fading_edges lists up to
    ``worst`` fading edges by angle.  ``edges`` is the whole per-edge table
    (every shared edge) when asked for with ``all_edges=True``, else empty.  Face indices are
    positions in ``TopExp.MapShapes`` order (``export.brep.shape_face_rows``), or the ids given as
    ``face_ids`` (mesh faces when checking a ``BezierSurface``).
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
    max_smooth_gap: float = 0.0
    max_smooth_normal_jump_deg: float = 0.0
    n_g1_edges: int = 0
    n_g0_edges: int = 0
    n_open_edges: int = 0
    n_sharp_edges: int = 0
    sharp_edges: tuple[EdgeDefect, ...] = ()
    n_fading_edges: int = 0
    fading_edges: tuple[EdgeDefect, ...] = ()
    sharp_angle_deg: float = SHARP_ANGLE_DEG
    g1_tolerance_deg: float = G1_TOLERANCE_DEG
    gap_tolerance: float = GAP_TOLERANCE
    edges: tuple[EdgeDefect, ...] = ()

    def as_dict(self) -> dict:
        """Plain JSON-ready dict (tuples become lists)."""

        def plain(value):
            if isinstance(value, (list, tuple)):
                return [plain(v) for v in value]
            if isinstance(value, dict):
                return {k: plain(v) for k, v in value.items()}
            return value

        return plain(asdict(self))

    def to_json(self, indent: int | None = 2) -> str:
        """The report as JSON."""
        return json.dumps(self.as_dict(), indent=indent)

    @property
    def g1(self) -> bool:
        """Every shared edge neither sharp nor fading is G1 (and so G0) within the tolerances."""
        return self.n_g0_edges == 0 and self.n_open_edges == 0

    def summary(self, table: tuple[EdgeDefect, ...] | None = None) -> str:
        """A one-screen text report; ``table``: the edges to list (default: the worst ones,
        then the sharp ones)."""
        lines = [
            f"valid (BRepCheck_Analyzer): {'yes' if self.valid else 'NO'}",
            f"solids {self.n_solids}, shells {self.n_shells}, faces {self.n_faces}, "
            f"edges {self.n_edges} ({self.n_shared_edges} shared, {self.n_free_edges} free)",
            f"max gap: {self.max_gap:.3e} ({self.max_gap_relative:.3e} of the diagonal {self.diagonal:.6g})",
            f"max normal jump: {self.max_normal_jump_deg:.3e} deg "
            f"({self.samples_per_edge} samples per shared edge)",
            f"smooth edges: {self.n_g1_edges} G1 (jump <= {self.g1_tolerance_deg:g} deg), "
            f"{self.n_g0_edges} G0 only, {self.n_open_edges} open (gap > {self.gap_tolerance:g} of the diagonal); "
            f"max gap {self.max_smooth_gap:.3e}, max normal jump {self.max_smooth_normal_jump_deg:.3e} deg",
            f"sharp edges (jump >= {self.sharp_angle_deg:g} deg all along): {self.n_sharp_edges}",
            f"fading creases (sharp at one end, G1 at the other, continuing a crease): {self.n_fading_edges}",
        ]
        if table is None:
            sections = (
                ("worst edges", self.worst_edges),
                ("sharp edges", self.sharp_edges),
                ("fading creases", self.fading_edges),
            )
        else:
            sections = (("edges", table),)
        for title, rows in sections:
            if not rows:
                continue
            lines.append(f"{title}:{'edge':>6}  {'faces':<13} {'kind':<6} {'gap':>10}  {'jump(deg)':>10}  at")
            for d in rows:
                x, y, z = d.position
                lines.append(
                    f"  {d.edge:>10d}  {d.faces[0]:>5d},{d.faces[1]:<7d} {d.kind:<6} {d.gap:10.3e}  {d.angle_deg:10.3e}"
                    f"  ({x:.6g}, {y:.6g}, {z:.6g})"
                )
        return "\n".join(lines)


def _count(shape: TopoDS_Shape, kind) -> int:
    shapes = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, kind, shapes)
    return shapes.Extent()


def shape_diagonal(shape: TopoDS_Shape) -> float:
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)  # poles' box for Bézier/B-spline faces: cheap, and >= the surface's
    if box.IsVoid():
        return 0.0
    x0, y0, z0, x1, y1, z1 = box_bounds(box)
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


def _edge_ends(edge, vertices: TopTools_IndexedMapOfShape, first: np.ndarray, last: np.ndarray) -> tuple[int, int]:
    """Indices (in ``vertices``) of the edge's vertices at its first and last sample (-1 where
    it has none); the order is taken from the sample points, whatever the edge's orientation."""
    a, b = TopExp.FirstVertex_s(edge), TopExp.LastVertex_s(edge)
    if a.IsNull() or b.IsNull():
        return -1, -1
    pa, pb = BRep_Tool.Pnt_s(a), BRep_Tool.Pnt_s(b)
    da = np.linalg.norm(np.array([pa.X(), pa.Y(), pa.Z()]) - first)
    db = np.linalg.norm(np.array([pb.X(), pb.Y(), pb.Z()]) - first)
    ia, ib = vertices.FindIndex(a) - 1, vertices.FindIndex(b) - 1
    return (ia, ib) if da <= db else (ib, ia)


def _fading(
    angle: np.ndarray, sharp: np.ndarray, closed: np.ndarray, ends: np.ndarray, g1_deg: float, sharp_deg: float
) -> np.ndarray:
    """(e,) bool: the edges that are creases fading into a dart (module docstring).

    angle (e, samples) degrees; sharp, closed (e,) bool; ends (e, 2) vertex ids at the first
    and last sample."""
    inner = (angle[:, 1:-1] > g1_deg).all(axis=1)
    dart_first = (angle[:, 0] <= g1_deg) & (angle[:, -1] >= sharp_deg)
    dart_last = (angle[:, -1] <= g1_deg) & (angle[:, 0] >= sharp_deg)
    cand = (dart_first | dart_last) & inner & closed & ~sharp & (ends >= 0).all(axis=1)
    if not cand.any():
        return cand
    crease_end = np.where(dart_first, ends[:, 1], ends[:, 0])
    n = int(ends.max()) + 1
    sharp_ends = ends[sharp].ravel()
    support = np.bincount(sharp_ends[sharp_ends >= 0], minlength=n) + np.bincount(crease_end[cand], minlength=n)
    # another sharp or fading edge at the crease end (the candidate counts itself once)
    return cand & (support[np.maximum(crease_end, 0)] >= 2)


def check_continuity(
    shape_or_path,
    samples_per_edge: int = 9,
    *,
    worst: int = N_WORST,
    sharp_angle_deg: float = SHARP_ANGLE_DEG,
    g1_tolerance_deg: float = G1_TOLERANCE_DEG,
    gap_tolerance: float = GAP_TOLERANCE,
    all_edges: bool = False,
    face_ids=None,
) -> ContinuityReport:
    """Measure validity, free edges, gaps and normal jumps of a shape, a STEP file or a
    ``BezierSurface`` (docs/verification.md), and classify every shared edge (module docstring).

    For a ``BezierSurface`` the B-rep is built (unchecked, so that a broken surface is
    measured rather than refused) and faces are reported by their mesh face ids; ``face_ids``
    (sequence, face index -> id) renames faces likewise for a shape.
    """
    import numbers

    from patching.errors import NupatchError

    if isinstance(samples_per_edge, bool) or not isinstance(samples_per_edge, numbers.Integral) or samples_per_edge < 2:
        raise NupatchError(f"samples_per_edge must be an integer of at least 2 (the edge's two ends), not {samples_per_edge!r}", "samples_per_edge")
    if not isinstance(shape_or_path, (str, os.PathLike, TopoDS_Shape)) and type(shape_or_path).__name__ != "BezierSurface":
        raise NupatchError(
            f"check_continuity takes a BezierSurface, a TopoDS_Shape or a STEP file path, not {type(shape_or_path).__name__}",
            "shape_or_path",
        )
    from patching.surface import BezierSurface

    if isinstance(shape_or_path, BezierSurface):
        from export.brep import shape_face_rows, to_shape

        if face_ids is None:
            row_face = [face for _, _, face, _ in shape_or_path.patches()]
            face_ids = [row_face[r] for r in shape_face_rows(shape_or_path.topology).tolist()]
        shape = to_shape(shape_or_path, check=False)
    elif isinstance(shape_or_path, (str, os.PathLike)):
        from export.step import read_step

        shape = read_step(shape_or_path)
    else:
        shape = shape_or_path
    rename = (lambda i: i) if face_ids is None else (lambda i: int(face_ids[i]))

    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    edge_faces = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, edge_faces)
    diagonal = shape_diagonal(shape)
    tol = 1e-9 * diagonal if diagonal > 0 else 1e-9

    vertices = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_VERTEX, vertices)
    surfaces = _Surfaces(faces, tol)
    fractions = np.linspace(0.0, 1.0, samples_per_edge)
    pairs: list[tuple[int, tuple[int, int], np.ndarray]] = []
    pair_ends: list[tuple[int, int]] = []  # vertex indices at the first and last sample
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
            pair_faces = (rename(surfaces.index(sides[0][0])), rename(surfaces.index(other[0])))
            pairs.append((i - 1, pair_faces, samples))
            pair_ends.append(_edge_ends(edge, vertices, samples[0, 0, 0], samples[-1, 0, 0]))

    worst_list: list[EdgeDefect] = []
    sharp_list: list[EdgeDefect] = []
    table: list[EdgeDefect] = []
    max_gap = max_angle = smooth_gap = smooth_angle = 0.0
    fading_list: list[EdgeDefect] = []
    counts = {"G1": 0, "G0": 0, "open": 0, "sharp": 0, "fading": 0}
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
        edge_min = angle.min(axis=1)
        sharp = edge_min >= sharp_angle_deg
        closed = edge_gap <= gap_tolerance * diagonal
        fading = _fading(angle, sharp, closed, np.array(pair_ends), g1_tolerance_deg, sharp_angle_deg)
        kind = np.where(
            sharp,
            "sharp",
            np.where(fading, "fading", np.where(~closed, "open", np.where(edge_angle > g1_tolerance_deg, "G0", "G1"))),
        )
        sharp = sharp | fading  # left out of the smooth maxima and of the worst edges
        for k in counts:
            counts[k] = int(np.count_nonzero(kind == k))
        if (~sharp).any():
            smooth_gap = float(edge_gap[~sharp].max())
            smooth_angle = float(edge_angle[~sharp].max())
        mid = 0.5 * (p1 + p2)

        def defect(e: int, by: np.ndarray) -> EdgeDefect:
            s = int(np.argmax(by[e]))
            edge, pair_faces, _ = pairs[e]
            return EdgeDefect(
                edge,
                pair_faces,
                float(edge_gap[e]),
                float(edge_angle[e]),
                tuple(float(c) for c in mid[e, s]),
                str(kind[e]),
                float(edge_min[e]),
            )

        chosen: list[int] = []
        for key, by in ((edge_angle, angle), (edge_gap, gap)):
            order = [int(e) for e in np.argsort(-key, kind="stable") if key[e] > 0 and not sharp[e] and e not in chosen]
            for e in order[:worst]:
                chosen.append(e)
                worst_list.append(defect(e, by))
        for e in [int(e) for e in np.argsort(-edge_angle, kind="stable") if kind[e] == "sharp"][:worst]:
            sharp_list.append(defect(e, angle))
        for e in [int(e) for e in np.argsort(-edge_angle, kind="stable") if fading[e]][:worst]:
            fading_list.append(defect(e, angle))
        if all_edges:
            table = [defect(e, angle if edge_angle[e] > 0 else gap) for e in range(len(pairs))]

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
        worst_edges=tuple(worst_list),
        max_smooth_gap=smooth_gap,
        max_smooth_normal_jump_deg=smooth_angle,
        n_g1_edges=counts["G1"],
        n_g0_edges=counts["G0"],
        n_open_edges=counts["open"],
        n_sharp_edges=counts["sharp"],
        sharp_edges=tuple(sharp_list),
        n_fading_edges=counts["fading"],
        fading_edges=tuple(fading_list),
        sharp_angle_deg=sharp_angle_deg,
        g1_tolerance_deg=g1_tolerance_deg,
        gap_tolerance=gap_tolerance,
        edges=tuple(table),
    )
