"""The control mesh as arrays plus tags (docs/input.md), and the checks that need no topology.

Faces are stored flat, as OpenSubdiv and USD do: ``face_vertices`` (sum of face sizes,) int64
and ``face_offsets`` (f + 1,) int64, so face k is ``face_vertices[face_offsets[k]:face_offsets[k+1]]``.
Edges in tags are unordered vertex pairs, normalised to ``(min, max)``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from patching.errors import KnotError, MeshError, TagError

__all__ = ["ControlMesh", "from_arrays", "NupatchWarning", "INFINITELY_SHARP", "MAX_COORDINATE", "TRIANGLE_SUBDIVISIONS", "CREASE_METHODS"]

#: Crease sharpness at or above which an edge is infinitely sharp (docs/input.md, OpenSubdiv's 10).
INFINITELY_SHARP = 10.0
#: Triangle rules of Catmull-Clark ([OSD] ``Sdc::Options::TRI_SUB_CATMARK``, ``TRI_SUB_SMOOTH``).
TRIANGLE_SUBDIVISIONS = ("catmark", "smooth")
#: How semi-sharp sharpness decays a step ([OSD] ``Sdc::Options::CreasingMethod``).
CREASE_METHODS = ("uniform", "chaikin")
#: Largest coordinate magnitude taken: beyond it STL and glTF (32-bit floats, up to 3.4e38)
#: would hold infinities, OpenCASCADE's meshing hangs (from 1e77) and volumes overflow.
MAX_COORDINATE = 1e30


class NupatchWarning(UserWarning):
    """Something odd but harmless in the input (isolated vertices, unknown tags)."""


@dataclass(frozen=True)
class ControlMesh:
    """A polygonal control mesh with knot-interval and sharpness tags.

    vertices: (n, 3) float64.  face_vertices, face_offsets: flat faces, see module docstring.
    intervals: {(a, b): d}, knot interval d >= 0 of edge a-b (a < b); the whole strip gets it.
    creases: {(a, b): s}, sharpness s >= 0 (s >= 10 infinitely sharp).
    corners: {v: s}.  holes: face ids.  interpolate_boundary: 0, 1 or 2 (docs/input.md; default 1).
    triangle_subdivision: "catmark" (default) or "smooth", [OSD]'s ``Sdc::Options::
    TriangleSubdivision`` (the OBJ tag ``t smoothtriangles 0/0/1 smooth``): "smooth" changes the
    smooth edge points beside triangles under ``subdivide(rules="opensubdiv")`` only.
    crease_method: "uniform" (default) or "chaikin", [OSD]'s ``Sdc::Options::CreasingMethod``
    (the OBJ tag ``t creasemethod 0/0/1 chaikin``): how semi-sharp sharpness decays per
    subdivision step (``patching.rules.crease``); the default of every subdivision function.
    name: product name for export.  locations: where each item came from, for error messages,
    keyed ("vertex", v), ("face", f), ("interval", (a, b)), ("crease", (a, b)), ("corner", v),
    ("hole", f); values such as "part.obj:12".
    """

    vertices: np.ndarray
    face_vertices: np.ndarray
    face_offsets: np.ndarray
    intervals: Mapping[tuple[int, int], float] = field(default_factory=dict)
    creases: Mapping[tuple[int, int], float] = field(default_factory=dict)
    corners: Mapping[int, float] = field(default_factory=dict)
    holes: frozenset[int] = frozenset()
    interpolate_boundary: int = 1
    name: str = "mesh"
    locations: Mapping[tuple, str] = field(default_factory=dict)
    triangle_subdivision: str = "catmark"
    crease_method: str = "uniform"

    def __repr__(self) -> str:
        """Counts, not arrays: ``ControlMesh('cube', 8 vertices, 6 faces, 0 intervals, ...)``."""
        return (
            f"ControlMesh({self.name!r}, {self.n_vertices} vertices, {self.n_faces} faces, "
            f"{len(self.intervals)} interval tags, {len(self.creases)} creases, {len(self.corners)} corners, "
            f"{len(self.holes)} holes, interpolate_boundary={self.interpolate_boundary})"
        )

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.face_offsets.shape[0] - 1)

    @property
    def face_sizes(self) -> np.ndarray:
        """(f,) int64, number of vertices of each face."""
        return np.diff(self.face_offsets)

    @property
    def is_quad_mesh(self) -> bool:
        return bool(np.all(self.face_sizes == 4))

    def quads(self) -> np.ndarray:
        """(f, 4) int64 face-vertex table; only for an all-quad mesh."""
        if not self.is_quad_mesh:
            raise ValueError("not an all-quad mesh")
        return self.face_vertices.reshape(-1, 4)

    def face(self, f: int) -> np.ndarray:
        return self.face_vertices[self.face_offsets[f] : self.face_offsets[f + 1]]

    def where(self, kind: str, key) -> str:
        """The place an item came from: its file and line, or its id."""
        loc = self.locations.get((kind, key))
        if loc:
            return loc
        if isinstance(key, tuple):
            return f"{kind} {key[0]}-{key[1]}"
        return f"{kind} {key}"

    def with_positions(self, vertices: np.ndarray) -> "ControlMesh":
        """The same mesh and tags with other control-point positions (same shape)."""
        from dataclasses import replace

        vertices = np.asarray(vertices, dtype=np.float64)
        if vertices.shape != self.vertices.shape:
            raise MeshError(f"expected {self.vertices.shape} positions, got {vertices.shape}", self.name)
        return replace(self, vertices=vertices)


def _edge_key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


def _finite_nonnegative(value: float) -> bool:
    return math.isfinite(value) and value >= 0.0


def from_arrays(
    vertices,
    faces,
    intervals: Mapping[tuple[int, int], float] | None = None,
    creases: Mapping[tuple[int, int], float] | None = None,
    corners: Mapping[int, float] | None = None,
    holes: Sequence[int] = (),
    interpolate_boundary: int = 1,
    name: str = "mesh",
    locations: Mapping[tuple, str] | None = None,
    triangle_subdivision: str = "catmark",
    crease_method: str = "uniform",
) -> ControlMesh:
    """Build and check a ControlMesh from arrays (docs/input.md, the Python API).

    vertices: (n, 3) floats.  faces: an (f, k) int array or a list of index lists (0-based).
    Raises MeshError, KnotError or TagError naming the offending item; warns (NupatchWarning)
    about isolated vertices.  Topological checks (manifold, orientation, strips) are made when
    the topology is built.
    """
    from patching.validation import as_edge_tag, as_faces, as_holes, as_name, as_vertex_tag

    name = as_name(name)
    if isinstance(vertices, (str, bytes)) or vertices is None:
        raise MeshError(f"vertices must be an (n, 3) array of numbers, not {type(vertices).__name__}", "vertices")
    faces = as_faces(faces)
    intervals = as_edge_tag(intervals, "intervals", KnotError)
    creases = as_edge_tag(creases, "creases", TagError)
    corners = as_vertex_tag(corners, "corners")
    holes = as_holes(holes, "holes")
    if isinstance(interpolate_boundary, bool) or not isinstance(interpolate_boundary, (int, np.integer)):
        raise TagError(f"interpolate_boundary must be the integer 0, 1 or 2, not {interpolate_boundary!r}", "interpolate_boundary")
    locations = dict(locations or {})

    def where(kind, key):
        loc = locations.get((kind, key))
        if loc:
            return loc
        return f"{kind} {key[0]}-{key[1]}" if isinstance(key, tuple) else f"{kind} {key}"

    try:
        verts = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise MeshError(f"vertices are not numbers: {exc}", name) from None
    if verts.ndim != 2 or verts.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3), got {verts.shape}", f"vertices of {name}")
    bad = np.flatnonzero(~np.isfinite(verts).all(axis=1))
    if bad.size:
        raise MeshError("non-finite vertex coordinate", where("vertex", int(bad[0])))
    huge = np.flatnonzero(np.abs(verts).max(axis=1, initial=0.0) > MAX_COORDINATE)
    if huge.size:
        v = int(huge[0])
        raise MeshError(
            f"coordinate {float(np.abs(verts[v]).max()):.3g} of vertex {v} is beyond {MAX_COORDINATE:g}, "
            "too large to export (STL and glTF hold 32-bit floats)",
            where("vertex", v),
        )

    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        sizes = np.full(faces.shape[0], faces.shape[1], dtype=np.int64)
        flat = faces.astype(np.int64, copy=False).ravel()
    else:
        face_list = [list(map(int, f)) for f in faces]
        sizes = np.array([len(f) for f in face_list], dtype=np.int64)
        flat = np.array([i for f in face_list for i in f], dtype=np.int64)
    if sizes.size == 0:
        raise MeshError("empty mesh: no faces", name)
    if verts.shape[0] == 0:
        raise MeshError("empty mesh: no vertices", name)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)

    small = np.flatnonzero(sizes < 3)
    if small.size:
        f = int(small[0])
        raise MeshError(f"face {f} has {int(sizes[f])} vertices, at least 3 needed", where("face", f))
    out = np.flatnonzero((flat < 0) | (flat >= verts.shape[0]))
    if out.size:
        f = int(np.searchsorted(offsets, out[0], side="right") - 1)
        raise MeshError(
            f"face {f} uses vertex {int(flat[out[0]])}, but there are {verts.shape[0]} vertices",
            where("face", f),
        )
    face_of = np.repeat(np.arange(sizes.size), sizes)
    order = np.lexsort((flat, face_of))
    pairs = np.stack([face_of[order], flat[order]], axis=1)
    dup = np.flatnonzero(np.all(pairs[1:] == pairs[:-1], axis=1))
    if dup.size:
        f, v = (int(x) for x in pairs[dup[0]])
        raise MeshError(f"face {f} repeats vertex {v}", where("face", f))

    used = np.zeros(verts.shape[0], dtype=bool)
    used[flat] = True
    if not used.all():
        isolated = np.flatnonzero(~used)
        warnings.warn(
            NupatchWarning(
                f"{isolated.size} isolated vertices ignored (first: vertex {int(isolated[0])}, "
                f"{where('vertex', int(isolated[0]))})"
            ),
            stacklevel=2,
        )

    def edges_of(tag: Mapping, kind: str, error) -> dict[tuple[int, int], float]:
        clean: dict[tuple[int, int], float] = {}
        for (a, b), value in (tag or {}).items():
            a, b = int(a), int(b)
            key = _edge_key(a, b)
            loc = locations.get((kind, (a, b))) or locations.get((kind, key))
            if loc:
                locations[(kind, key)] = loc
            value = float(value)
            if not _finite_nonnegative(value) and not (kind == "crease" and value == math.inf):
                raise error(f"{kind} {value} of edge {a}-{b} must be finite and >= 0", where(kind, key))
            if a == b or not (0 <= a < verts.shape[0] and 0 <= b < verts.shape[0]):
                raise TagError(f"{kind} tag names edge {a}-{b}, which does not exist", where(kind, key))
            clean[key] = value
        return clean

    clean_intervals = edges_of(intervals, "interval", KnotError)
    clean_creases = edges_of(creases, "crease", TagError)
    clean_corners: dict[int, float] = {}
    for v, s in (corners or {}).items():
        v, s = int(v), float(s)
        if not (0 <= v < verts.shape[0]):
            raise TagError(f"corner tag names vertex {v}, which does not exist", where("corner", v))
        if not (_finite_nonnegative(s) or s == math.inf):
            raise TagError(f"corner sharpness {s} of vertex {v} must be >= 0", where("corner", v))
        clean_corners[v] = s
    clean_holes = frozenset(int(f) for f in holes)
    for f in clean_holes:
        if not (0 <= f < sizes.size):
            raise TagError(f"hole tag names face {f}, which does not exist", where("hole", f))
    if interpolate_boundary not in (0, 1, 2):
        raise TagError(f"interpolateboundary must be 0, 1 or 2, got {interpolate_boundary}", name)
    if triangle_subdivision not in TRIANGLE_SUBDIVISIONS:
        raise TagError(f"triangle_subdivision must be 'catmark' or 'smooth', not {triangle_subdivision!r}", "triangle_subdivision")
    if crease_method not in CREASE_METHODS:
        raise TagError(f"crease_method must be 'uniform' or 'chaikin', not {crease_method!r}", "crease_method")

    return ControlMesh(
        vertices=verts,
        face_vertices=flat,
        face_offsets=offsets,
        intervals=clean_intervals,
        creases=clean_creases,
        corners=clean_corners,
        holes=clean_holes,
        interpolate_boundary=int(interpolate_boundary),
        name=name,
        locations=locations,
        triangle_subdivision=triangle_subdivision,
        crease_method=crease_method,
    )
