"""Control vectors on subdivision surfaces ([KSD] sec. 5, eq. (15)).

    s(u, v) = sum_ij B_i(u) B_j(v) P_ij + B_i(u) C_j(v) U_ij + C_i(u) B_j(v) V_ij + C_i(u) C_j(v) X_ij

with B the uniform B-splines and C the crease function N^_d of [KSD] sec. 4
(``control_vectors.crease_function``).  Two forms, both linear operators built from topology
and tags only, with the vectors as a second linear term (refined points = A @ P + C @ W,
W the stacked vectors):

- ``tensor_operators``: a regular m x n grid (open with free ends, or closed, per direction)
  of any bi-degree d1 x d2: the Kronecker products of the curve scheme's operators in each
  direction, ``kron(A_u, A_v)`` for the points, ``kron(A_u e_i, C_v e)`` for a U vector,
  ``kron(C_u e, A_v e_j)`` for V and ``kron(C_u e, C_v e)`` for X (a vector's sharpness s
  acts in each of its crease directions as on the curve, so a fractional X is scaled by s^2:
  the tensor product of the two curve rules);
- ``vector_step`` / ``refine``: Catmull-Clark (d = 3) on quad meshes of any topology.  The
  points follow ``subdivision.catmark.subdivision_operator`` (Catmull-Clark, with
  OpenSubdiv's / Pixar's semi-sharp crease and corner rules, [DKT98]), and the vectors add
  the tensor products of the univariate cubic stencils ([KSD] Fig. 8, 12): a vector at v
  gives 36/64 of itself to v's vertex point; a *line* vector (U or V: the crease runs along
  the grid line w - v - w' through v) also 24/64 to the two edge points on that line and
  6/64 to the vertex points of w and w'; its children are 3/8 at v, 1/4 at the two edge
  points, 1/16 at w and w' (each a line vector along the same line, sharpness s - 1); a
  *cross* vector (X) gives only the 36/64 and has children X/4 and, as line vectors along
  the two lines through v, 3/8 each.  These weights are not typed in: they are the products
  of ``uniform.uniform_mask(3)`` and ``crease_function(3).mask`` (6/8), and 1/2 for a
  vector's own child (Table 1's caption).

Where [KSD] sec. 5 is silent and what is chosen here:

- "Control vectors are not attached to extraordinary vertices": a vector must sit on an
  interior valence-4 vertex whose faces are quads and which has no corner tag and no sharp
  edge (else TagError).  Its contribution to a point whose rule is *not* the regular
  Catmull-Clark one (the vertex point of an extraordinary, boundary, corner or crease vertex,
  the edge point of a sharp or boundary edge) is dropped, and so is a child that would land on
  such a vertex: there the Catmull-Clark / semi-sharp rule holds unchanged (the fallback of
  [KSD] sec. 5: "new vertex and edge stencils are replaced by Pixar (semi-sharp) crease,
  dart, and corner rules").  The paper gives no rule that lets a crease run through an
  extraordinary point (it names the needed change of natural configuration as future work).
- Sharpness: s >= 1 takes part in the step and its children get s - 1 (inf stays inf);
  0 < s < 1 scales the contribution by s (line) or s^2 (cross, both directions) and drops
  the vector, as on the curve; the paper initialises sharpness to zero and shows a few values
  (Fig. 10) without a formula.
- Higher degrees on general meshes (the paper shows only biquintic examples on grids, Fig.
  11) are not built: ``tensor_operators`` covers regular grids of any degree.

The exact limit (``tensor_limit``): on a regular grid the surface is the tensor product of
the curve limits, so it is one B-spline surface of bi-degree d1 x d2 (exported as a STEP
B-spline face, ``export.curves.to_face``).  On a general Catmull-Clark mesh there is no such
form: at an extraordinary vertex the limit has infinitely many polynomial pieces ([Sta98]),
and the Pixar rules near EVs and semi-sharp creases do not give a finite knot structure
either; that surface is exported as a refined mesh (``refine``) or through the G1 patch
construction of ``nupatch build`` (which does not see the vectors).  An open grid has free
ends (the full spans only, as the curves without end tags), not Catmull-Clark's boundary
rules: there ``tensor_limit`` and ``refine`` differ near the boundary; on a torus grid they
are the same surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import TagError, UnsupportedError
from ..mesh.control_mesh import ControlMesh
from ..subdivision.catmark import subdivision_operator
from ..topology.tables import Topology
from .control_vectors import crease_function
from .curve import Curve
from .knots import insert_knots_matrix
from .uniform import uniform_mask

__all__ = [
    "SurfaceVector", "LINE", "CROSS", "check_vectors", "vector_step", "refine", "operators", "tensor_operators",
    "parse_vector_tags", "format_vector_tags", "BSplineSurface", "tensor_limit_operator", "tensor_limit",
    "grid_of", "grid_vectors",
]

LINE = "line"
CROSS = "cross"


@dataclass(frozen=True)
class SurfaceVector:
    """A control vector's place: ``kind`` LINE (crease along the grid line through ``vertex``
    and its neighbour ``toward``: a U or V vector) or CROSS (X, ``toward`` = -1), and its
    sharpness (inf: for ever)."""

    kind: str
    vertex: int
    toward: int
    sharpness: float


def _regular_vertices(topo: Topology, mesh: ControlMesh) -> np.ndarray:
    """Vertices whose Catmull-Clark vertex rule is the regular tensor stencil."""
    ok = topo.vertex_is_used & ~topo.vertex_is_boundary & (topo.valence == 4)
    sizes = np.diff(mesh.face_offsets)
    bad_face = np.repeat(sizes != 4, sizes)
    ok[topo.origin[bad_face]] = False
    sharp_e = topo.edge_sharpness > 0
    ok[topo.edges[sharp_e].ravel()] = False
    for v, s in mesh.corners.items():
        if s > 0:
            ok[int(v)] = False
    return ok


def _regular_edges(topo: Topology, mesh: ControlMesh) -> np.ndarray:
    sizes = np.diff(mesh.face_offsets)
    ok = ~topo.edge_is_boundary & ~(topo.edge_sharpness > 0)
    bad_face = np.repeat(sizes != 4, sizes)
    ok[topo.edge_of[bad_face]] = False
    return ok


def _line(topo: Topology, v: int, w: int) -> tuple[int, int]:
    """The neighbours (w, w') of valence-4 vertex v on the grid line through v and w."""
    ring = topo.one_ring(v)
    dest = topo.dest[ring]
    hit = np.flatnonzero(dest == w)
    if len(hit) != 1 or len(ring) != 4:
        raise TagError(f"control vector at vertex {v}: {w} is not a neighbour of it on a quad grid", f"vertex {v}")
    return int(w), int(dest[(hit[0] + 2) % 4])


def check_vectors(mesh: ControlMesh, vectors: list[SurfaceVector], topo: Topology | None = None) -> None:
    """Refuse vectors the construction does not define (module docstring), naming the vertex."""
    topo = topo or Topology(mesh)
    regular = _regular_vertices(topo, mesh)
    for vec in vectors:
        v = vec.vertex
        if not 0 <= v < mesh.n_vertices:
            raise TagError(f"control vector on vertex {v}, which is not in the mesh ({mesh.n_vertices} vertices)", f"vertex {v}")
        if math.isnan(vec.sharpness) or vec.sharpness < 0:
            raise TagError(f"bad sharpness {vec.sharpness} of the control vector at vertex {v}", f"vertex {v}")
        if not regular[v]:
            raise TagError(
                f"control vector on vertex {v}: [KSD] sec. 5 attaches control vectors only to interior valence-4 "
                "vertices of quads without corner or crease tags (there the Catmull-Clark / semi-sharp rules apply)",
                f"vertex {v}",
            )
        if vec.kind == LINE:
            _line(topo, v, vec.toward)
        elif vec.kind != CROSS:
            raise TagError(f"unknown control vector kind {vec.kind!r}", f"vertex {v}")


def vector_step(
    mesh: ControlMesh, vectors: list[SurfaceVector], rules: str = "opensubdiv"
) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix, ControlMesh, list[SurfaceVector]]:
    """One Catmull-Clark step with control vectors: ``(A, C, H, child_mesh, child_vectors)``.

    New points = A @ P + C @ W (A = ``subdivision_operator(mesh, rules)``, unchanged by the
    vectors), new vectors = H @ W; child numbering as ``subdivision.catmark`` (face points,
    edge points, vertex points).  Built from topology and tags only.
    """
    topo = Topology(mesh)
    check_vectors(mesh, vectors, topo)
    A, child = subdivision_operator(mesh, rules=rules)
    nf, ne = mesh.n_faces, topo.n_edges
    regular_v = _regular_vertices(topo, mesh)
    regular_e = _regular_edges(topo, mesh)
    child_topo = Topology(child)
    regular_child = _regular_vertices(child_topo, child)
    b = uniform_mask(3)  # [1, 4, 6, 4, 1] / 8: vertex 6/8, edge 4/8, next vertex 1/8
    m = float(crease_function(3).mask[0])  # 6/8

    def vp(u: int) -> int:  # the vertex point of vertex u
        return nf + ne + u

    def ep(e: int) -> int:  # the edge point of edge e
        return nf + e

    rows, cols, vals = [], [], []
    hkeys: dict[tuple, int] = {}
    hrows, hcols, hvals = [], [], []
    children: list[SurfaceVector] = []

    def give(point: int, ok: bool, e: int, w: float) -> None:
        if ok and w:
            rows.append(point)
            cols.append(e)
            vals.append(w)

    def child_vec(kind: str, at: int, toward: int, s: float, e: int, w: float) -> None:
        if not regular_child[at]:
            return  # not attached to extraordinary / tagged vertices: dropped
        if kind == LINE:
            toward = min(toward, _line(child_topo, at, toward)[1])  # one key per line
        key = (kind, at, toward, s)
        if key not in hkeys:
            hkeys[key] = len(children)
            children.append(SurfaceVector(kind, at, toward, s))
        hrows.append(hkeys[key])
        hcols.append(e)
        hvals.append(w)

    for e, vec in enumerate(vectors):
        v, s = vec.vertex, float(vec.sharpness)
        if s <= 0:
            continue
        g = min(s, 1.0)
        s2 = s - 1.0 if math.isfinite(s) else math.inf
        if vec.kind == CROSS:
            give(vp(v), True, e, g * g * m * m)
            if s > 1:
                child_vec(CROSS, vp(v), -1, s2, e, 0.25)
                ring = topo.one_ring(v)
                for k in (0, 1):  # the two grid lines through v
                    ed = int(topo.edge_of[ring[k]])
                    child_vec(LINE, vp(v), ep(ed), s2, e, 0.5 * m)
            continue
        w0, w1 = _line(topo, v, vec.toward)
        e0, e1 = topo.edge_id(v, w0), topo.edge_id(v, w1)
        give(vp(v), True, e, g * b[2] * m)
        for ed, w in ((e0, w0), (e1, w1)):
            give(ep(ed), bool(regular_e[ed]), e, g * b[1] * m)
            give(vp(w), bool(regular_v[w]), e, g * b[0] * m)
        if s > 1:
            child_vec(LINE, vp(v), ep(e0), s2, e, 0.5 * b[2])
            for ed, w in ((e0, w0), (e1, w1)):
                if regular_e[ed]:
                    child_vec(LINE, ep(ed), vp(v), s2, e, 0.5 * b[1])
                child_vec(LINE, vp(w), ep(ed), s2, e, 0.5 * b[0])
    n2 = A.shape[0]
    C = sp.coo_matrix((vals, (rows, cols)), shape=(n2, len(vectors))).tocsr()
    H = sp.coo_matrix((hvals, (hrows, hcols)), shape=(len(children), len(vectors))).tocsr()
    return A, C, H, child, children


def operators(
    mesh: ControlMesh, vectors: list[SurfaceVector], steps: int, rules: str = "opensubdiv"
) -> tuple[sp.csr_matrix, sp.csr_matrix, ControlMesh, list[SurfaceVector], sp.csr_matrix]:
    """``steps`` steps at once: ``(A, C, mesh_k, vectors_k, H)``, points after k steps =
    A @ P + C @ W, vectors after k steps = H @ W."""
    n, mv = mesh.n_vertices, len(vectors)
    A_tot = sp.identity(n, format="csr")
    C_tot = sp.csr_matrix((n, mv))
    H_tot = sp.identity(mv, format="csr")
    for _ in range(int(steps)):
        A, C, H, mesh, vectors = vector_step(mesh, vectors, rules)
        C_tot = A @ C_tot + C @ H_tot
        A_tot = A @ A_tot
        H_tot = H @ H_tot
    return A_tot.tocsr(), sp.csr_matrix(C_tot), mesh, vectors, sp.csr_matrix(H_tot)


def refine(
    mesh: ControlMesh, vectors: list[SurfaceVector], values, steps: int, rules: str = "opensubdiv"
) -> tuple[ControlMesh, list[SurfaceVector], np.ndarray]:
    """The mesh after ``steps`` steps with its points moved by the vectors, the surviving
    vectors and their values (``values``: (m, 3), one row per vector)."""
    W = np.asarray(values, dtype=np.float64).reshape(len(vectors), 3)
    A, C, mesh_k, vectors_k, H = operators(mesh, vectors, steps, rules)
    return mesh_k.with_positions(A @ mesh.vertices + C @ W), vectors_k, H @ W


def tensor_operators(
    shape: tuple[int, int],
    degrees: tuple[int, int],
    closed: tuple[bool, bool],
    vectors: list[tuple[str, int, int, float]],
    steps: int,
) -> tuple[sp.csr_matrix, sp.csr_matrix, tuple[int, int]]:
    """[KSD] eq. (15) on a regular grid: ``(A, C, fine_shape)`` after ``steps`` steps.

    Grid point (i, j) is row ``i * n + j`` (i along u); ``vectors``: (kind, i, j, s) with kind
    "U" (B_i(u) C_j(v): a crease along the u line through (i, j)), "V" (C_i(u) B_j(v)) or "X"
    (C_i(u) C_j(v)).  Refined points = A @ P + C @ W.  Each factor is the curve scheme of that
    direction (``Curve.operators``): a Kronecker product per vector.
    """
    (nu, nv), (du, dv), (cu, cv) = shape, degrees, closed
    k = int(steps)
    zu, zv = np.zeros((nu, 2)), np.zeros((nv, 2))
    Au = Curve(zu, du, cu).operators(k)[0]
    Av = Curve(zv, dv, cv).operators(k)[0]

    def crease_column(z, d, c, i, s) -> sp.csr_matrix:
        return Curve(z, d, c, vectors={i: (np.zeros(2), s)}).operators(k)[1]

    cols = []
    for kind, i, j, s in vectors:
        if kind == "U":
            cols.append(sp.kron(Au[:, i], crease_column(zv, dv, cv, j, s)))
        elif kind == "V":
            cols.append(sp.kron(crease_column(zu, du, cu, i, s), Av[:, j]))
        elif kind == "X":
            cols.append(sp.kron(crease_column(zu, du, cu, i, s), crease_column(zv, dv, cv, j, s)))
        else:
            raise UnsupportedError(f"control vector kind {kind!r} is not U, V or X")
    A = sp.kron(Au, Av).tocsr()
    C = sp.hstack(cols).tocsr() if cols else sp.csr_matrix((A.shape[0], 0))
    return A, C, (Au.shape[0], Av.shape[0])


def parse_vector_tags(text: str, source: str = "<string>") -> tuple[list[SurfaceVector], np.ndarray]:
    """The ``t controlvector`` tags of an OBJ control mesh (docs/curves.md, surfaces):

    ``t controlvector 1/3/0 v x y z`` (or ``1/4/0 ... s``): a cross (X) vector at v;
    ``t controlvector 2/3/0 v w x y z`` (or ``2/4/0 ... s``): a line (U/V) vector at v, the
    crease along the grid line through v and its neighbour w.  Without s: infinitely sharp;
    s >= 10 is infinite.  0-based vertex ids as OpenSubdiv's tags.
    """
    from ..errors import InputFileError

    vecs: list[SurfaceVector] = []
    values = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        parts = raw.split("#", 1)[0].split()
        if len(parts) < 3 or parts[0] != "t" or parts[1] != "controlvector":
            continue
        loc = f"{source}:{lineno}"
        try:
            ni, nf, ns = (int(c) for c in parts[2].split("/"))
        except ValueError:
            raise InputFileError(f"cannot read tag counts '{parts[2]}'", loc) from None
        args = parts[3:]
        if ni not in (1, 2) or nf not in (3, 4) or ns != 0 or len(args) != ni + nf:
            raise TagError("controlvector tag needs 1/3/0 (v x y z), 2/3/0 (v w x y z) or the same with /4/ and a sharpness", loc)
        try:
            ids = [int(a) for a in args[:ni]]
            fl = [float(a) for a in args[ni:]]
        except ValueError:
            raise InputFileError("cannot read the controlvector tag's numbers", loc) from None
        if not all(math.isfinite(x) for x in fl[:3]):
            raise TagError(f"non-finite control vector at vertex {ids[0]}", loc)
        s = fl[3] if nf == 4 else math.inf
        if math.isnan(s) or s < 0:
            raise TagError(f"bad sharpness {s} of the control vector at vertex {ids[0]}", loc)
        s = math.inf if s >= 10 else s
        vecs.append(SurfaceVector(LINE if ni == 2 else CROSS, ids[0], ids[1] if ni == 2 else -1, s))
        values.append(fl[:3])
    return vecs, np.array(values, dtype=np.float64).reshape(-1, 3)


def format_vector_tags(vectors: list[SurfaceVector], values) -> str:
    """The ``t controlvector`` lines of ``vectors`` (``parse_vector_tags`` reads them back)."""
    lines = []
    for vec, (x, y, z) in zip(vectors, np.asarray(values, dtype=np.float64).reshape(-1, 3).tolist()):
        ids = f"{vec.vertex} {vec.toward}" if vec.kind == LINE else f"{vec.vertex}"
        lines.append(f"t controlvector {2 if vec.kind == LINE else 1}/4/0 {ids} {x!r} {y!r} {z!r} {vec.sharpness!r}")
    return "".join(line + "\n" for line in lines)


@dataclass(frozen=True)
class BSplineSurface:
    """A clamped tensor-product B-spline: ``poles`` (nu, nv, dim), ``knots_u`` (nu + du + 1,),
    ``knots_v`` (nv + dv + 1,), ``degrees`` (du, dv); u runs along the grid's first index."""

    knots_u: np.ndarray
    knots_v: np.ndarray
    poles: np.ndarray
    degrees: tuple[int, int]

    @property
    def domain(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return (float(self.knots_u[0]), float(self.knots_u[-1])), (float(self.knots_v[0]), float(self.knots_v[-1]))

    def evaluate(self, u, v) -> np.ndarray:
        """The points at the grid ``u x v`` (1-D parameter arrays): (len(u), len(v), dim)."""
        from scipy.interpolate import BSpline  # here: scipy.interpolate costs every CLI start ~0.5 s

        (a, b), (c, e) = self.domain
        Bu = BSpline.design_matrix(np.clip(np.atleast_1d(u), a, b), self.knots_u, self.degrees[0]).toarray()
        Bv = BSpline.design_matrix(np.clip(np.atleast_1d(v), c, e), self.knots_v, self.degrees[1]).toarray()
        return np.einsum("ia,abk,jb->ijk", Bu, self.poles, Bv)


def _merge_knots(vectors: list[np.ndarray]) -> np.ndarray:
    """The smallest knot vector containing each of ``vectors`` (each value at its largest
    multiplicity); all share the same clamped ends."""
    mult: dict[float, int] = {}
    for t in vectors:
        values, counts = np.unique(t, return_counts=True)
        for x, c in zip(values.tolist(), counts.tolist()):
            mult[x] = max(mult.get(x, 0), c)
    return np.array([x for x in sorted(mult) for _ in range(mult[x])], dtype=np.float64)


def _onto(knots: np.ndarray, d: int, target: np.ndarray) -> sp.csr_matrix:
    """Knot insertion from ``knots`` to the superset ``target``: coefficients on ``target``."""
    values, counts = np.unique(knots, return_counts=True)
    have = dict(zip(values.tolist(), counts.tolist()))
    tv, tc = np.unique(target, return_counts=True)
    new = [x for x, c in zip(tv.tolist(), tc.tolist()) for _ in range(c - have.get(x, 0))]
    out, A = insert_knots_matrix(knots, d, new, sparse=True)
    assert np.array_equal(out, target)
    return A


def tensor_limit_operator(
    shape: tuple[int, int],
    degrees: tuple[int, int],
    closed: tuple[bool, bool],
    vectors: list[tuple[str, int, int, float]],
    ends: tuple[bool, bool] = (False, False),
) -> tuple[np.ndarray, np.ndarray, sp.csr_matrix, sp.csr_matrix, tuple[int, int]]:
    """The exact limit of ``tensor_operators``' surface: ``(knots_u, knots_v, W, E, poles_shape)``
    with poles (row-major, pole (a, b) at row ``a * Nv + b``) = W @ P + E @ W_vectors.

    Each direction's factors are the curve limits (``Curve.limit_operator``): the plain curve
    of the grid's lines for B_i, and one curve with the single vector for each C_j (its
    crease function after its own ceil(s) steps, d-fold knot if s = inf).  Their knot vectors
    differ (the crease's knots, the refined levels), so each factor is brought onto the union
    of them by knot insertion (exact) before the Kronecker products: B_i(u) C_j(v) U_ij is
    ``kron(Wu e_i, Ev_j)``, and so on.  Built from the grid's size, degrees and tags only.
    The surface is C0 along the crease lines of infinitely sharp vectors and C^(d-1) elsewhere.
    ``ends``: per open direction, sharp (clamped) ends instead of free ones: the curve factors
    get their end vertices tagged infinitely sharp (``Curve`` composes them with the vectors,
    which then need ``curve.VECTOR_CLEARANCE[d]`` lines from that boundary).  For d = 3 both
    ways this is Catmull-Clark's surface with boundary creases and corners (interpolateboundary
    1) on the grid: the cubic sharp-end rule is the odd reflection across the boundary row.
    """
    (nu, nv), (du, dv), (cu, cv) = shape, degrees, closed
    zu, zv = np.zeros((nu, 2)), np.zeros((nv, 2))
    tags = {id(zu): _end_tags(nu, cu, ends[0]), id(zv): _end_tags(nv, cv, ends[1])}

    def plain(z, d, c):
        knots, W, _ = Curve(z, d, c, corners=tags[id(z)]).limit_operator()
        return knots, W

    def crease(z, d, c, i, s):
        knots, _, E = Curve(z, d, c, corners=tags[id(z)], vectors={i: (np.zeros(2), s)}).limit_operator()
        return knots, E

    facs = []  # per vector: ((knots_u, column_u), (knots_v, column_v))
    pu, pv = plain(zu, du, cu), plain(zv, dv, cv)
    for kind, i, j, s in vectors:
        if kind == "U":
            facs.append(((pu[0], pu[1][:, [i]]), crease(zv, dv, cv, j, s)))
        elif kind == "V":
            facs.append((crease(zu, du, cu, i, s), (pv[0], pv[1][:, [j]])))
        elif kind == "X":
            facs.append((crease(zu, du, cu, i, s), crease(zv, dv, cv, j, s)))
        else:
            raise UnsupportedError(f"control vector kind {kind!r} is not U, V or X")
    ku = _merge_knots([pu[0]] + [f[0][0] for f in facs])
    kv = _merge_knots([pv[0]] + [f[1][0] for f in facs])
    Ru, Rv = _onto(pu[0], du, ku), _onto(pv[0], dv, kv)
    W = sp.kron(Ru @ pu[1], Rv @ pv[1]).tocsr()
    cols = [
        sp.kron(_onto(a[0], du, ku) @ sp.csr_matrix(a[1]), _onto(b[0], dv, kv) @ sp.csr_matrix(b[1]))
        for a, b in facs
    ]
    E = sp.hstack(cols).tocsr() if cols else sp.csr_matrix((W.shape[0], 0))
    return ku, kv, W, E, (len(ku) - du - 1, len(kv) - dv - 1)


def _end_tags(n: int, closed: bool, sharp: bool) -> dict[int, float]:
    return {0: math.inf, n - 1: math.inf} if sharp and not closed else {}


def tensor_limit(
    points,
    degrees: tuple[int, int],
    closed: tuple[bool, bool] = (False, False),
    vectors: list[tuple[str, int, int, float]] | None = None,
    values=None,
    ends: tuple[bool, bool] = (False, False),
) -> BSplineSurface:
    """[KSD] eq. (15) on a regular grid, exactly: the B-spline surface of ``tensor_limit_operator``.

    ``points``: (m, n, 3) grid (u along the first index); ``vectors`` as in
    ``tensor_operators`` with ``values`` (k, 3) one row per vector; ``ends`` as in
    ``tensor_limit_operator``.
    """
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 3:
        raise UnsupportedError(f"a regular grid of points is an (m, n, 3) array, not {P.shape}")
    m, n, dim = P.shape
    vectors = list(vectors or [])
    V = np.asarray(values if values is not None else np.zeros((0, dim)), dtype=np.float64).reshape(len(vectors), dim)
    ku, kv, W, E, (Nu, Nv) = tensor_limit_operator((m, n), degrees, closed, vectors, ends)
    poles = W @ P.reshape(m * n, dim) + E @ V
    return BSplineSurface(ku, kv, np.asarray(poles).reshape(Nu, Nv, dim), (int(degrees[0]), int(degrees[1])))


def grid_of(mesh: ControlMesh) -> tuple[np.ndarray, tuple[bool, bool]]:
    """A regular quad grid's vertex ids ``(m, n)`` (u along the first index) and whether each
    direction is closed: a rectangle, a cylinder (closed in one direction) or a torus.

    Every face a quad, every interior vertex of valence 4, every boundary vertex of 3 (the four
    corners of a rectangle 2).  Otherwise UnsupportedError naming the first vertex that breaks
    it (an extraordinary vertex).  The grid is walked face to face across opposite edges
    from one face; a mesh that passes the valence test but does not close up as a grid (a
    twisted strip, two components) is refused too.
    """
    sizes = np.diff(mesh.face_offsets)
    if len(sizes) == 0 or (sizes != 4).any():
        bad = int(np.flatnonzero(sizes != 4)[0]) if len(sizes) else 0
        raise UnsupportedError("the exact grid surface needs a regular quad grid: a face is not a quad", f"face {bad}")
    F = mesh.face_vertices.reshape(-1, 4)
    edge_faces: dict[tuple[int, int], list[int]] = {}
    for f, quad in enumerate(F.tolist()):
        for k in range(4):
            a, b = quad[k], quad[(k + 1) % 4]
            edge_faces.setdefault((min(a, b), max(a, b)), []).append(f)
    nv = mesh.n_vertices
    valence = np.zeros(nv, dtype=int)
    boundary = np.zeros(nv, dtype=int)
    for (a, b), fs in edge_faces.items():
        valence[[a, b]] += 1
        if len(fs) == 1:
            boundary[[a, b]] += 1
        elif len(fs) > 2:
            raise UnsupportedError("the exact grid surface needs a manifold grid: an edge has more than two faces",
                                   f"edge {a}-{b}")
    used = np.zeros(nv, dtype=bool)
    used[F.ravel()] = True
    corner = (boundary == 2) & (valence == 2)
    ok = np.where(boundary > 0, (valence == 3) | corner, valence == 4) | ~used
    if not ok.all():
        v = int(np.flatnonzero(~ok)[0])
        raise UnsupportedError(f"the exact grid surface needs a regular grid: vertex {v} is extraordinary "
                               f"(valence {valence[v]}{', on the boundary' if boundary[v] else ''})", f"vertex {v}")

    def across(f: int, a: int, b: int) -> int:
        """The other face of edge a-b (-1 on the boundary)."""
        other = [g for g in edge_faces[(min(a, b), max(a, b))] if g != f]
        return other[0] if other else -1

    def oriented(g: int, a: int, b: int) -> tuple[int, int, int, int]:
        """Face g's corners as (a, b, c, d) going round from edge a-b (a -> b along g's order or back)."""
        q = F[g].tolist()
        i = q.index(a)
        step = 1 if q[(i + 1) % 4] == b else -1
        return tuple(q[(i + step * k) % 4] for k in range(4))  # type: ignore[return-value]

    face_key = {tuple(sorted(quad)): f for f, quad in enumerate(F.tolist())}

    def face_of(quad) -> int:
        return face_key[tuple(sorted(quad))]

    # start at face 0 with corners (a, b, c, d): u along a -> b, v along a -> d; walk back to a
    # boundary in each direction (or round, closed)
    q = tuple(F[0].tolist())

    def walk(q, forward: bool, along_u: bool):
        """Faces from q stepping +-u or +-v until the boundary or back to q: list of oriented quads."""
        out = [q]
        while True:
            a, b, c, d = out[-1]
            if along_u:
                e0, e1 = (b, c) if forward else (a, d)
            else:
                e0, e1 = (d, c) if forward else (a, b)
            f = face_of(out[-1])
            g = across(f, e0, e1)
            if g < 0:
                return out, False
            if along_u:
                r = oriented(g, e0, e1)  # g = (e0, e1, ., .): e0-e1 is its left (forward) or right edge
                nq = (e0, r[3], r[2], e1) if forward else (r[3], e0, e1, r[2])
            else:
                r = oriented(g, e0, e1)
                nq = (e0, e1, r[2], r[3]) if forward else (r[3], r[2], e1, e0)
            if face_of(nq) == face_of(out[0]):
                return out, True
            if len(out) > len(F):
                raise UnsupportedError("the exact grid surface needs a regular grid: the faces do not close up")
            out.append(nq)

    back_u, cu = walk(q, False, True)
    q = back_u[-1] if not cu else q
    back_v, cv = walk(q, False, False)
    q = back_v[-1] if not cv else q
    first_col, _ = walk(q, True, False)
    rows = [walk(fq, True, True)[0] for fq in first_col]
    fm, fn = len(rows[0]), len(first_col)  # faces along u and v
    if any(len(r) != fm for r in rows) or fm * fn != len(F):
        raise UnsupportedError("the exact grid surface needs a regular grid: the faces do not form one grid")
    m, n = fm + (0 if cu else 1), fn + (0 if cv else 1)
    ids = np.full((m, n), -1, dtype=np.int64)
    for j, row in enumerate(rows):
        for i, (a, b, c, d) in enumerate(row):
            for (di, dj), vert in zip(((0, 0), (1, 0), (1, 1), (0, 1)), (a, b, c, d)):
                x, y = (i + di) % m, (j + dj) % n
                if ids[x, y] not in (-1, vert):
                    raise UnsupportedError("the exact grid surface needs a regular grid: the faces do not close up",
                                           f"vertex {vert}")
                ids[x, y] = vert
    if len(np.unique(ids)) != ids.size or ids.size != int(used.sum()):
        raise UnsupportedError("the exact grid surface needs a regular grid: the faces do not form one grid")
    return ids, (bool(cu), bool(cv))


def grid_vectors(ids: np.ndarray, vectors: list[SurfaceVector]) -> list[tuple[str, int, int, float]]:
    """Mesh vectors as ``tensor_limit``'s (kind, i, j, s): a line vector toward the u neighbour
    is U (its crease runs along u: C in v), toward the v neighbour V, a cross vector X."""
    m, n = ids.shape
    where = {int(v): (i, j) for (i, j), v in np.ndenumerate(ids)}
    out = []
    for vec in vectors:
        if vec.vertex not in where:
            raise TagError(f"control vector on vertex {vec.vertex}, which is not on the grid", f"vertex {vec.vertex}")
        i, j = where[vec.vertex]
        if vec.kind == CROSS:
            out.append(("X", i, j, vec.sharpness))
            continue
        w = where.get(vec.toward)
        if w is not None and w[1] == j and (w[0] - i) % m in (1, m - 1):
            out.append(("U", i, j, vec.sharpness))
        elif w is not None and w[0] == i and (w[1] - j) % n in (1, n - 1):
            out.append(("V", i, j, vec.sharpness))
        else:
            raise TagError(f"line control vector at vertex {vec.vertex} toward {vec.toward}, which is not its grid "
                           "neighbour", f"vertex {vec.vertex}")
    return out
