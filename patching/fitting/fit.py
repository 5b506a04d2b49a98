"""Fitting the G1 spline to a triangle mesh ([FSLYJ] sec. 4.1).

Pipeline: a quad control mesh from the triangle mesh (``remesh.quad_remesh``; or a given one),
uniform knot intervals (the paper's choice), the operator M (``build_operator``), foot points
of the data points on the patches (``projection.project``), then alternation of least-squares
solves for the control points with the foot points fixed (``solve.LeastSquares``) and foot-point
updates with the control points fixed, until the error stops falling.

The error of an alternation is E = sum_k w_k |S(foot_k) - x_k|^2 (weighted squared point
distance, the foot points re-projected).  The first steps minimise the point distance (PDM),
which can only lower E: the solve minimises E plus a step fairing that is 0 at the old points,
and the projection keeps each old foot point unless it finds a nearer one.  Later steps use
the squared-distance model SDM ([PLH02], [FSLYJ]'s [31]; in the form of [WPL06]: the
second-order approximation with the principal curvatures at the foot point,
``solve.distance_model``) or its first-order part, the tangent distance TDM; they converge much
faster but are no descent method for E: such a step is kept only when it lowers E, else a PDM
step is taken.  So the recorded errors never increase.

Stopping: when an alternation lowers the RMS distance sqrt(E / sum w) by less than
``tolerance`` of it (default 1%, i.e. E by about 2%), or after ``max_iterations``.  E tends to
the approximation error of the control mesh, not to 0, so the rule measures progress against
the error that is left, in the unit the report uses; the error falls roughly linearly in the
last alternations (by 10 to 40% per SDM step on the benchmark, then by a few per cent), and an
alternation that moves the RMS distance by less than 1% is not worth its cost.

Data points: the input vertices, and the triangle centroids while the triangles are fewer
than ``CENTROIDS_BELOW`` per control face; weights are the triangles' areas shared out
(a vertex gets a twelfth of each incident triangle's area, a centroid three quarters, an
exact quadrature for linear functions; vertices alone get a third).
"""

from __future__ import annotations

import time
import json
from dataclasses import asdict, dataclass, field
from typing import Optional

import numpy as np

from ..errors import MeshError, NupatchError
from ..mesh import ControlMesh, from_arrays
from ..operator import SurfaceOperator, build_operator
from ..surface import BezierSurface
from ..topology import Topology
from ..topology.intervals import INTERVAL_RULES, with_intervals
from ..validation import as_faces, as_points
from .distance import mesh_distance
from .projection import FootPoints, PatchLayout, boundary_sides, evaluate, project, project_to_boundary
from .features import crease_chains, feature_chains, sharp_edges
from .remesh import Remesher, polygon_edges, quad_remesh
from .solve import LeastSquares, distance_model, umbrella_laplacian

__all__ = ["FitReport", "FitResult", "InputLabels", "fit", "check_triangles", "default_faces"]

#: Triangle centroids join the data points while there are fewer triangles than this per control face.
CENTROIDS_BELOW = 30
#: Data points asked for per control face, at least (coarse triangles are sampled more).
POINTS_PER_FACE = 16
#: The tangential weight alpha of TDM (``solve``): its start, floor and ceiling.
ALPHA_START, ALPHA_MIN, ALPHA_MAX = 1e-2, 1e-8, 1.0
#: Surface samples per patch side for the surface -> input distance of the report.
REPORT_SAMPLES = 8


@dataclass(frozen=True)
class FitReport:
    """Distances relative to the input's bounding-box diagonal, both ways; errors per alternation.

    max_input_to_surface / rms_input_to_surface: over the data points (input vertices, and
    triangle centroids when used), to their foot points on the spline.
    max_surface_to_input / rms_surface_to_input: over a REPORT_SAMPLES^2 grid of every patch,
    to the input triangles (``distance.mesh_distance``).
    errors: E after each alternation (the first entry: the start), non-increasing.
    steps: "pdm", "sdm" or "tdm" per alternation.
    timings: seconds spent per stage (remesh, operator, project, solve, report).
    repairs: what ``check_triangles`` repaired in the input (flipped triangles, dropped vertices).
    creases: control mesh edges tagged as creases from the input's sharp edges (``sharp_angle``).
    distance: the squared-distance model after the point-distance steps ("sdm" or "tdm").
    """

    diagonal: float
    max_input_to_surface: float
    rms_input_to_surface: float
    max_surface_to_input: float
    rms_surface_to_input: float
    iterations: int
    seconds: float
    remesh_seconds: float
    input_vertices: int
    input_triangles: int
    data_points: int
    control_vertices: int
    control_faces: int
    patches: int
    remesher: str
    errors: list = field(default_factory=list)
    steps: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    repairs: list = field(default_factory=list)
    creases: int = 0
    distance: str = "sdm"

    def as_dict(self) -> dict:
        return asdict(self)

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.as_dict(), indent=indent)

    def summary(self) -> str:
        return "\n".join(
            [
                f"input: {self.input_vertices} vertices, {self.input_triangles} triangles, diagonal {self.diagonal:.6g}",
                f"control mesh: {self.control_vertices} vertices, {self.control_faces} faces ({self.remesher}), {self.patches} patches",
                f"input -> surface: max {self.max_input_to_surface:.3e}, rms {self.rms_input_to_surface:.3e} of the diagonal",
                f"surface -> input: max {self.max_surface_to_input:.3e}, rms {self.rms_surface_to_input:.3e} of the diagonal",
                f"{self.iterations} alternations ({' '.join(self.steps)}), {self.seconds:.2f} s (remesher {self.remesh_seconds:.2f} s)",
            ]
            + ([f"{self.creases} control edges tagged as creases (sharp input edges)"] if self.creases else [])
            + [f"repaired: {r}" for r in self.repairs]
        )


@dataclass(frozen=True)
class FitResult:
    """The fitted control mesh (uniform intervals), its operator, surface and report."""

    control_mesh: ControlMesh
    operator: SurfaceOperator
    surface: BezierSurface
    report: FitReport


@dataclass(frozen=True)
class InputLabels:
    """How error messages name the input's vertices and triangles (``check_triangles``).

    By default (all fields None) by their indices in the arrays given.  A reader that changed
    the indexing (``export.triangles`` merges coincident vertices, and the file's own indices
    are what its user can find) passes, per vertex k of the arrays: ``vertex_ids[k]`` the
    file's index (the first of the coincident vertices merged into k) and ``coincident[k]``
    how many were merged; ``vertex_lines`` / ``triangle_lines`` the 1-based lines that define
    them in ``source`` (then the place is ``source:line``); ``positions`` names vertices by
    their coordinates instead (STL stores no shared vertices, only triangle corners)."""

    vertex_ids: Optional[np.ndarray] = None
    coincident: Optional[np.ndarray] = None
    vertex_lines: Optional[np.ndarray] = None
    triangle_lines: Optional[np.ndarray] = None
    source: Optional[str] = None
    positions: Optional[np.ndarray] = None

    def vertex(self, k: int, merged: bool = True) -> str:
        """The name of vertex k: "12", "12 (merged with 2 coincident vertices)" (``merged``:
        the note, for messages about one vertex) or "(x, y, z)"."""
        k = int(k)
        if self.positions is not None:
            return "(" + ", ".join(f"{float(x):.6g}" for x in self.positions[k]) + ")"
        text = str(int(self.vertex_ids[k])) if self.vertex_ids is not None else str(k)
        extra = int(self.coincident[k]) - 1 if self.coincident is not None and merged else 0
        if extra > 0:
            text += f" (merged with {extra} coincident {'vertex' if extra == 1 else 'vertices'})"
        return text

    def vertex_place(self, k: int, name: str) -> str:
        if self.vertex_lines is not None and self.source is not None:
            return f"{self.source}:{int(self.vertex_lines[int(k)])}"
        return f"{name}, vertex {self.vertex(k)}"

    def triangle_place(self, k: int, name: str) -> str:
        if self.triangle_lines is not None and self.source is not None:
            return f"{self.source}:{int(self.triangle_lines[int(k)])}"
        return f"{name}, triangle {int(k)}"

    def edge(self, a: int, b: int) -> str:
        return f"{self.vertex(a, False)}-{self.vertex(b, False)}"


def check_triangles(vertices, triangles, name: str = "input",
                    labels: InputLabels | None = None) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The input as (n, 3) float64 vertices and (t, 3) int64 triangles, and the list of repairs
    made; MeshError naming the vertex, triangle or edge for what cannot be repaired.

    Refused: vertices or faces of the wrong shape or type, or a non-finite coordinate
    (``validation.as_points`` / ``as_faces``, the checks of every entry point); faces that are
    not triangles; fewer than 4; an index out of range; a triangle repeating a vertex or of
    zero area (collinear vertices); an edge of more than two triangles (non-manifold edge); a
    vertex where two or more fans of triangles meet only at the vertex (a bow-tie,
    non-manifold vertex); triangles that no choice of orientation makes consistent (a Moebius
    band).  Repaired, as CAD tools do on import: unreferenced vertices are dropped, and
    triangles whose orientation disagrees with their neighbours' are flipped (per connected
    piece, the orientation of the majority of its triangles is kept).  ``labels``: how the
    messages name vertices and triangles (``InputLabels``; default their indices here)."""
    L = labels if labels is not None else InputLabels()
    v = as_points(vertices, "vertices", error=MeshError)
    f = as_faces(triangles, "triangles")
    if not isinstance(f, np.ndarray):
        sizes = [len(x) for x in f]
        bad = next((k for k, size in enumerate(sizes) if size != 3), None)
        if bad is not None:
            raise MeshError(f"triangles[{bad}] has {sizes[bad]} vertices: fit takes a triangle mesh", f"{name}, triangle {bad}")
        f = np.array(f, dtype=np.int64).reshape(-1, 3)
    if f.shape[1] != 3:
        raise MeshError(f"faces have {f.shape[1]} vertices: fit takes a triangle mesh", name)
    if f.shape[0] < 4:
        raise MeshError(f"{f.shape[0]} triangles: at least 4 are needed to fit a surface", name)
    if f.min() < 0 or f.max() >= v.shape[0]:
        k = int(np.flatnonzero((f < 0).any(axis=1) | (f >= v.shape[0]).any(axis=1))[0])
        raise MeshError(f"triangle {k} uses a vertex id out of range (there are {v.shape[0]} vertices)", f"{name}, triangle {k}")
    rep = np.flatnonzero((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2]))
    if rep.size:
        k = int(rep[0])
        twice = int(f[k, 0] if f[k, 0] in (f[k, 1], f[k, 2]) else f[k, 1])
        raise MeshError(f"triangle {k} repeats vertex {L.vertex(twice)}", L.triangle_place(k, name))
    # zero area: |cross| below round-off of the longest edge squared
    e0, e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 1]]
    longest = np.max([np.einsum("ij,ij->i", e, e) for e in (e0, e1, e2)], axis=0)
    flat = np.flatnonzero(np.linalg.norm(np.cross(e0, e1), axis=1) <= 1e-12 * longest)
    if flat.size:
        k = int(flat[0])
        raise MeshError(
            f"triangle {k} (vertices {' '.join(L.vertex(i, False) for i in f[k])}) is degenerate: its vertices are collinear, zero area "
            f"({flat.size} such triangles)", L.triangle_place(k, name))
    directed = np.stack([f, np.roll(f, -1, axis=1)], axis=-1).reshape(-1, 2)
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    keys, inverse, counts = np.unique(lo * v.shape[0] + hi, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    if counts.max() > 2:
        a, b = divmod(int(keys[np.argmax(counts)]), v.shape[0])
        users = np.flatnonzero(inverse == np.argmax(counts)) // 3
        raise MeshError(f"non-manifold edge {L.edge(a, b)} shared by {int(counts.max())} triangles "
                        f"({', '.join(map(str, users.tolist()))})", L.triangle_place(int(users[-1]), name))
    pairs = _interior_pairs(inverse, counts)
    _check_vertex_fans(f, directed, pairs, name, L)
    repairs = []
    flips = _orientation_flips(f, directed, pairs, name, L)
    if flips.any():
        f = f.copy()
        f[flips] = f[flips][:, ::-1]
        repairs.append(f"flipped {int(flips.sum())} triangles whose orientation disagreed with their neighbours'")
    used = np.unique(f)
    if used.size < v.shape[0]:
        repairs.append(f"dropped {v.shape[0] - used.size} vertices that no triangle uses")
    remap = np.full(v.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return v[used], remap[f], repairs


def _interior_pairs(inverse: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every edge of two triangles, the two directed-edge slots (3 t + k) that use it."""
    order = np.argsort(inverse, kind="stable")
    start = np.cumsum(counts) - counts
    two = np.flatnonzero(counts == 2)
    return order[start[two]], order[start[two] + 1]


def _check_vertex_fans(f: np.ndarray, directed: np.ndarray, pairs: tuple[np.ndarray, np.ndarray], name: str,
                       labels: InputLabels) -> None:
    """MeshError at the first vertex whose triangles form more than one fan.  Corners
    (vertex, triangle) are linked when the two triangles share an edge at that vertex; a
    manifold vertex's corners are one connected component."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    t = f.shape[0]
    a, b = pairs
    # slot 3 i + k is edge (f[i, k], f[i, k+1]); its corners are 3 i + k and 3 i + (k+1) % 3
    ta, ka, tb, kb = a // 3, a % 3, b // 3, b % 3
    corner_a0, corner_a1 = 3 * ta + ka, 3 * ta + (ka + 1) % 3
    # the same vertex in the other triangle: its slot runs the edge either way
    va = directed[a, 0]
    corner_b_for_a0 = np.where(directed[b, 0] == va, 3 * tb + kb, 3 * tb + (kb + 1) % 3)
    corner_b_for_a1 = np.where(directed[b, 0] == va, 3 * tb + (kb + 1) % 3, 3 * tb + kb)
    rows = np.concatenate([corner_a0, corner_a1])
    cols = np.concatenate([corner_b_for_a0, corner_b_for_a1])
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(3 * t, 3 * t))
    _, component = connected_components(graph, directed=False)
    vertex = f.ravel()
    pairs = np.unique(vertex * (3 * t) + component)
    fans = np.bincount(pairs // (3 * t), minlength=int(vertex.max()) + 1)
    bad = np.flatnonzero(fans > 1)
    if bad.size:
        k = int(bad[0])
        raise MeshError(
            f"vertex {labels.vertex(k)} is non-manifold: its triangles form {int(fans[k])} fans that meet only at this vertex "
            "(a bow-tie)", labels.vertex_place(k, name))


def _orientation_flips(f: np.ndarray, directed: np.ndarray, pairs: tuple[np.ndarray, np.ndarray], name: str,
                       labels: InputLabels) -> np.ndarray:
    """(t,) bool: the triangles to flip so that every interior edge is run both ways, keeping
    the majority's orientation per connected piece; MeshError when no flips do (non-orientable)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    t = f.shape[0]
    a, b = pairs
    ta, tb = a // 3, b // 3
    same = directed[a, 0] == directed[b, 0]  # both triangles run the edge the same way
    if not same.any():
        return np.zeros(t, dtype=bool)
    graph = coo_matrix((np.ones(ta.size), (ta, tb)), shape=(t, t)).tocsr()
    graph = graph + graph.T
    n_pieces, piece = connected_components(graph, directed=False)
    # a spanning forest (breadth-first from each piece's first triangle); a triangle's flip is
    # the parity of "same way" edges on its path to the root, by pointer jumping
    key = np.minimum(ta, tb) * t + np.maximum(ta, tb)
    sort = np.argsort(key)
    parent = np.full(t, -1, dtype=np.int64)
    for root in np.unique(piece, return_index=True)[1]:
        order, pred = breadth_first_order(graph, int(root), directed=False)
        parent[order[1:]] = pred[order[1:]]
    child = np.flatnonzero(parent >= 0)
    tree_key = np.minimum(child, parent[child]) * t + np.maximum(child, parent[child])
    parity = np.zeros(t, dtype=bool)
    parity[child] = same[sort[np.searchsorted(key[sort], tree_key)]]
    up = parent.copy()
    while (up >= 0).any():
        has = up >= 0
        parity[has] ^= parity[up[has]]
        up[has] = up[up[has]]
    flip = parity
    bad = same != (flip[ta] ^ flip[tb])
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        x, y = (int(q) for q in directed[a[k]])
        raise MeshError(f"the triangles cannot be oriented consistently (a non-orientable surface) at edge {labels.edge(x, y)}",
                        labels.triangle_place(int(b[k]) // 3, name))
    for p in range(n_pieces):  # keep each piece's majority orientation
        members = piece == p
        if flip[members].sum() * 2 > members.sum():
            flip[members] = ~flip[members]
    return flip


def default_faces(n_triangles: int) -> int:
    """The control mesh size asked of the remesher when ``faces`` is not given: an eighth of
    the triangles, between 96 and 2000."""
    return int(min(2000, max(96, n_triangles // 8)))


def _data_points(v: np.ndarray, f: np.ndarray, n_faces: int, vertices_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(points, weights) of the module docstring, weights normalised to mean 1."""
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if vertices_only:
        w = np.bincount(f.ravel(), weights=np.repeat(area / 3.0, 3), minlength=v.shape[0])
        w = np.maximum(w, 1e-12 * max(w.max(), 1e-300))
        return v, w / w.mean()
    # a triangle larger than 1 / POINTS_PER_FACE of a control face's share of the area is
    # sampled on a barycentric lattice of order n (n^2 sub-triangles, one point at each one's
    # centroid), so that every patch sees enough points however coarse the input
    share = area.sum() / (POINTS_PER_FACE * n_faces)
    order = np.maximum(1, np.ceil(np.sqrt(area / max(share, 1e-300)))).astype(np.int64)
    points, weights = [v], [np.bincount(f.ravel(), weights=np.repeat(area / 3.0, 3), minlength=v.shape[0])]
    coarse = order > 1
    if f.shape[0] < CENTROIDS_BELOW * n_faces or coarse.any():
        # vertices a twelfth, centroid three quarters of each triangle (exact for linear
        # functions); coarse triangles: vertices a twelfth, the rest over the lattice points
        weights[0] = np.bincount(f.ravel(), weights=np.repeat(area / 12.0, 3), minlength=v.shape[0])
        fine = np.flatnonzero(~coarse)
        points.append(tri[fine].mean(axis=1))
        weights.append(0.75 * area[fine])
        for n in np.unique(order[coarse]).tolist():
            ids = np.flatnonzero(order == n)
            bary = _lattice_centroids(n)
            points.append(np.einsum("kb,tbc->tkc", bary, tri[ids]).reshape(-1, 3))
            weights.append(np.repeat(0.75 * area[ids] / bary.shape[0], bary.shape[0]))
    points, weights = np.concatenate(points), np.concatenate(weights)
    weights = np.maximum(weights, 1e-12 * max(weights.max(), 1e-300))
    return points, weights / weights.mean()


def _lattice_centroids(n: int) -> np.ndarray:
    """(n^2, 3) barycentric centroids of the n^2 sub-triangles of a triangle split n times per side."""
    out = []
    for i in range(n):
        for j in range(n - i):
            out.append([(3 * i + 1) / (3 * n), (3 * j + 1) / (3 * n)])  # upright
            if i + j < n - 1:
                out.append([(3 * i + 2) / (3 * n), (3 * j + 2) / (3 * n)])  # inverted
    ab = np.array(out)
    return np.column_stack([1.0 - ab.sum(axis=1), ab[:, 0], ab[:, 1]])


def _boundary_vertices(f: np.ndarray, n: int) -> np.ndarray:
    """(n,) bool, vertices on an edge of one triangle."""
    e = np.sort(np.stack([f, np.roll(f, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1)
    keys, counts = np.unique(e, axis=0, return_counts=True)
    out = np.zeros(n, dtype=bool)
    out[keys[counts == 1].ravel()] = True
    return out


def _subset(feet: FootPoints, idx: np.ndarray) -> FootPoints:
    return FootPoints(feet.patch[idx].copy(), feet.s[idx].copy(), feet.t[idx].copy(), feet.distance[idx].copy())


def _face_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def fit(
    vertices,
    triangles,
    faces: int | None = None,
    control_mesh: ControlMesh | None = None,
    *,
    remesher: str | Remesher = "instant-meshes",
    max_iterations: int = 30,
    pdm_steps: int = 3,
    tolerance: float = 1e-2,
    fairing: float = 1e-6,
    sampling: str = "auto",
    distance: str = "sdm",
    sharp_angle: float | None = None,
    intervals: str = "tags",
    name: str = "fit",
    labels: InputLabels | None = None,
) -> FitResult:
    """Fit the G1 spline to a triangle mesh ([FSLYJ] sec. 4.1; module docstring).

    vertices: (n, 3) floats; triangles: (t, 3) ints, a manifold, consistently oriented
    triangle mesh (open or closed) of at least 4 triangles.
    faces: the control mesh size asked of the remesher (default ``default_faces``).
    control_mesh: a control mesh to start from instead (its topology, tags and positions;
    the remesher is not called).
    max_iterations: most alternations; tolerance: stop when an alternation lowers the RMS
    distance by less than this fraction of it (module docstring); fairing: weight of the step fairing relative to the data term (solve).
    sampling: "auto" (vertices, centroids and lattice points of coarse triangles, module
    docstring) or "vertices" (the input vertices only, weighted by a third of the incident
    areas: for inputs whose vertices are samples of a surface and whose triangles are not).
    distance: the squared-distance model after the point-distance steps, "sdm" (with the
    curvature terms, ``solve.distance_model``) or "tdm" (tangent distance only).
    sharp_angle: None (every control edge smooth) or degrees: input edges whose triangles'
    normals differ by more than this are carried onto the remeshed control mesh as creases
    (``features``; a given ``control_mesh`` keeps its own tags).
    intervals: the knot intervals of the control mesh (``topology.intervals``): "tags" (a given
    control mesh's own; the remeshed one has none, so all 1: uniform, the paper's choice),
    "uniform", "chord" or "centripetal" (each strip the mean length of its edges, or its square
    root, taken on the control mesh before the fit: the remesher's, or the given one; they are
    then fixed, so M is built once and the fit stays linear in the control points).
    labels: how errors about the input name its vertices and triangles (``InputLabels``).
    Raises MeshError (bad input, remesher failure) or UnsupportedError (the [fit] extra is
    missing)."""
    start = time.perf_counter()
    timings = {"remesh": 0.0, "operator": 0.0, "project": 0.0, "solve": 0.0, "report": 0.0}
    v, f, repairs = check_triangles(vertices, triangles, name, labels)
    diagonal = float(np.linalg.norm(np.ptp(v, axis=0)))
    if not diagonal > 0:
        raise MeshError("all vertices coincide: the input has no extent", name)
    remesh_seconds = 0.0
    creases: dict = {}
    if intervals not in INTERVAL_RULES:
        raise NupatchError(f"intervals must be one of {', '.join(INTERVAL_RULES)}, not {intervals!r}", "intervals")
    if sharp_angle is not None and not (isinstance(sharp_angle, (int, float)) and 0.0 < float(sharp_angle) < 180.0):
        raise NupatchError(f"sharp_angle must be a number of degrees between 0 and 180, not {sharp_angle!r}", "sharp_angle")
    if control_mesh is None:
        target = int(faces) if faces is not None else default_faces(f.shape[0])
        if target < 1:
            raise MeshError(f"the control mesh needs at least 1 face, not {target}", name)
        t0 = time.perf_counter()
        qv, polygons = quad_remesh(v, f, target, remesher, face_normals=_face_normals(v, f))
        remesh_seconds = timings["remesh"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        remesher_name = remesher if isinstance(remesher, str) else getattr(remesher, "__name__", "remesher")
        try:
            faces_list = [p.tolist() for p in polygons]
            if sharp_angle is not None:
                chains = feature_chains(sharp_edges(v, f, sharp_angle))
                if chains:
                    e = np.unique(np.sort(polygon_edges(polygons), axis=1), axis=0)
                    creases, qv = crease_chains(qv, e, v, chains)
            control_mesh = with_intervals(from_arrays(qv, faces_list, creases=creases, name=name), intervals)
            topo = Topology(control_mesh)
            operator = build_operator(control_mesh, topology=topo)
        except NupatchError as exc:
            raise MeshError(f"the quad remesher's output is no usable control mesh: {exc.what}", remesher_name) from None
    else:
        remesher_name = "given"
        t0 = time.perf_counter()
        control_mesh = with_intervals(control_mesh, intervals)
        topo = Topology(control_mesh)
        operator = build_operator(control_mesh, topology=topo)
    timings["operator"] = time.perf_counter() - t0
    layout = PatchLayout.of(operator)
    matrix = operator.matrix.tocsr()
    laplacian = umbrella_laplacian(control_mesh.n_vertices, topo.edges)
    solver = LeastSquares(matrix, layout, laplacian)
    if distance not in ("sdm", "tdm"):
        raise ValueError(f"distance must be 'sdm' or 'tdm', not {distance!r}")
    if sampling not in ("auto", "vertices"):
        raise ValueError(f"sampling must be 'auto' or 'vertices', not {sampling!r}")
    points, weights = _data_points(v, f, control_mesh.n_faces, sampling == "vertices")

    def energy(feet: FootPoints) -> float:
        return float(np.sum(weights * feet.distance**2))

    # Open boundaries: the input's boundary vertices are fitted by the surface's boundary
    # curves (their feet held on the boundary sides, point distance), else the surface could
    # reach past the input's boundary where no data point holds it.
    sides = boundary_sides(operator)
    on_boundary = np.zeros(points.shape[0], dtype=bool)
    if sides.size:
        on_boundary[: v.shape[0]] = _boundary_vertices(f, v.shape[0])
    rim = np.flatnonzero(on_boundary)

    def locate(P: np.ndarray, previous: FootPoints | None = None) -> FootPoints:
        coefficients = matrix @ P
        feet = project(layout, coefficients, points, previous=previous)
        if rim.size:
            before = None if previous is None else _subset(previous, rim)
            edge = project_to_boundary(layout, coefficients, points[rim], sides, previous=before)
            feet.patch[rim], feet.s[rim], feet.t[rim], feet.distance[rim] = edge.patch, edge.s, edge.t, edge.distance
        return feet

    P = np.asarray(control_mesh.vertices, dtype=np.float64).copy()
    t0 = time.perf_counter()
    feet = locate(P)
    timings["project"] += time.perf_counter() - t0
    errors, steps = [energy(feet)], []
    floor = (1e-13 * diagonal) ** 2 * weights.sum()
    pdm_left = pdm_steps
    tried_tdm = False
    alpha = ALPHA_START
    last_step = None
    for _ in range(max_iterations):
        if errors[-1] <= floor:
            break
        method = "pdm" if pdm_left > 0 else distance
        tried_tdm = tried_tdm or method != "pdm"
        while True:
            t0 = time.perf_counter()
            quadratic = None
            if method != "pdm":
                at = evaluate(layout, matrix @ P, feet.patch, feet.s, feet.t, order=2 if method == "sdm" else 1)
                quadratic = distance_model(method, at[0], at[1:], points, alpha, on_boundary)
            newP = solver.solve(feet, points, weights, P, fairing, quadratic, guess=last_step)
            t1 = time.perf_counter()
            newfeet = locate(newP, feet)
            timings["solve"] += t1 - t0
            timings["project"] += time.perf_counter() - t1
            e = energy(newfeet)
            if method == "pdm" or e < errors[-1]:
                break
            # TDM is no descent method: more of the point distance (Levenberg-Marquardt-like),
            # and past ALPHA_MAX a point-distance step, which cannot raise E
            alpha *= 100.0
            if alpha > ALPHA_MAX:
                method, alpha = "pdm", ALPHA_START
        if not e <= errors[-1]:  # cannot happen for PDM but round-off; stop rather than go up
            break
        if method != "pdm":
            alpha = max(alpha / 10.0, ALPHA_MIN)
        pdm_left -= 1
        # the fall of the RMS distance sqrt(E / sum w), relative to it
        drop = 1.0 - np.sqrt(e / errors[-1]) if errors[-1] > 0 else 0.0
        last_step = newP - P
        P, feet = newP, newfeet
        errors.append(e)
        steps.append(method)
        if drop <= tolerance:
            if not tried_tdm:
                pdm_left = 0  # point distance has stalled: go on with tangent distance
                continue
            break
    t0 = time.perf_counter()
    # the report's input -> surface distances from a full search (no previous feet)
    fresh = project(layout, matrix @ P, points)
    feet = FootPoints(feet.patch, feet.s, feet.t, np.minimum(fresh.distance, feet.distance))
    surface = operator.evaluate(P)
    surface = BezierSurface(surface.groups, surface.topology, name, surface.size)
    coefficients = matrix @ P
    u = (np.arange(REPORT_SAMPLES) + 0.5) / REPORT_SAMPLES
    gs, gt = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    sp_ = np.repeat(np.arange(layout.n_patches), gs.size)
    samples = evaluate(layout, coefficients, sp_, np.tile(gs, layout.n_patches), np.tile(gt, layout.n_patches))
    back = mesh_distance(v, f, samples)
    timings["report"] = time.perf_counter() - t0
    report = FitReport(
        diagonal=diagonal,
        max_input_to_surface=float(feet.distance.max() / diagonal),
        rms_input_to_surface=float(np.sqrt(np.mean(feet.distance**2)) / diagonal),
        max_surface_to_input=float(back.max() / diagonal),
        rms_surface_to_input=float(np.sqrt(np.mean(back**2)) / diagonal),
        iterations=len(steps),
        seconds=time.perf_counter() - start,
        remesh_seconds=remesh_seconds,
        input_vertices=int(v.shape[0]),
        input_triangles=int(f.shape[0]),
        data_points=int(points.shape[0]),
        control_vertices=control_mesh.n_vertices,
        control_faces=control_mesh.n_faces,
        patches=layout.n_patches,
        remesher=remesher_name,
        errors=errors,
        steps=steps,
        timings=timings,
        repairs=repairs,
        creases=len(control_mesh.creases) if remesher_name != "given" else 0,
        distance=distance,
    )
    return FitResult(control_mesh.with_positions(P), operator, surface, report)
