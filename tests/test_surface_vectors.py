"""Control vectors on surfaces ([KSD] sec. 5): the Catmull-Clark form against the tensor
product of the curve scheme, linearity and locality of a vector, the fallback to the
semi-sharp Catmull-Clark rules at extraordinary vertices, and the OBJ tags / CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest

from patching.curves.curve import Curve
from patching.curves.surface_vectors import CROSS, LINE, SurfaceVector, operators, parse_vector_tags, tensor_operators
from patching.errors import UnsupportedError
from patching.mesh.primitives import open_grid, torus_grid
from patching.subdivision.catmark import subdivision_operator
from patching.topology.tables import Topology
from tests.conftest import shape_files

pytestmark = pytest.mark.filterwarnings("ignore:vn normals ignored")


def _fine_grid(mesh, grid, m, n):
    """Grid coordinates (mod 2m, 2n) of the child points of one step of an m x n torus grid
    whose vertex v sits at grid[v] = (a, b)."""
    topo = Topology(mesh)
    nf, ne = mesh.n_faces, topo.n_edges
    out = np.zeros((nf + ne + mesh.n_vertices, 2), dtype=int)
    out[nf + ne :] = 2 * grid
    for e, (p, q) in enumerate(topo.edges):
        dp = (grid[q] - grid[p] + 1) % np.array([m, n]) - 1  # -1, 0 or 1 per coordinate
        out[nf + e] = (2 * grid[p] + dp) % (2 * np.array([m, n]))
    for f in range(nf):
        corners = grid[mesh.face_vertices[mesh.face_offsets[f] : mesh.face_offsets[f + 1]]]
        for c in corners:
            rel = {tuple(x) for x in (corners - c) % np.array([m, n])}
            if rel == {(0, 0), (1, 0), (0, 1), (1, 1)}:
                out[f] = 2 * c + 1
    return out


def _grid_order(m, n, steps):
    """Permutation: row r of the tensor-product grid (r = a * N + b) -> child id after
    ``steps`` Catmull-Clark steps of the torus grid."""
    mesh = torus_grid(m, n)
    grid = np.stack(np.meshgrid(np.arange(m), np.arange(n), indexing="ij"), -1).reshape(-1, 2)
    for _ in range(steps):
        grid = _fine_grid(mesh, grid, m, n)
        mesh = subdivision_operator(mesh, rules="opensubdiv")[1]
        m, n = 2 * m, 2 * n
    perm = np.empty(m * n, dtype=int)
    perm[grid[:, 0] * n + grid[:, 1]] = np.arange(m * n)
    return perm


@pytest.mark.parametrize("s", [math.inf, 2.0, 0.5])
def test_catmull_clark_with_vectors_is_the_tensor_product_of_the_curve_scheme(s):
    """On a torus grid (regular everywhere) the Catmull-Clark form with U, V, X vectors equals
    the Kronecker products of the cubic curve scheme's operators, to 1e-12, after 1 and 2 steps."""
    m, n = 9, 8
    mesh = torus_grid(m, n)

    def vid(a, b):
        return (a % m) * n + (b % n)

    vecs = [
        SurfaceVector(LINE, vid(3, 3), vid(4, 3), s),  # the u line through (3, 3): U
        SurfaceVector(LINE, vid(5, 2), vid(5, 3), s),  # the v line through (5, 2): V
        SurfaceVector(CROSS, vid(6, 6), -1, s),  # X
    ]
    for k in (1, 2):
        A, C, _, _, _ = operators(mesh, vecs, k)
        At, Ct, shape = tensor_operators((m, n), (3, 3), (True, True), [("U", 3, 3, s), ("V", 5, 2, s), ("X", 6, 6, s)], k)
        perm = _grid_order(m, n, k)
        assert shape == (m * 2**k, n * 2**k)
        assert abs(A.toarray()[perm] - At.toarray()).max() < 1e-12
        assert abs(C.toarray()[perm] - Ct.toarray()).max() < 1e-12
        assert abs(Ct).max() > 0.1


def test_tensor_product_of_any_degree_is_the_curve_scheme_per_direction():
    """Biquintic x cubic open grid: a U vector's refined contribution, read along each grid
    row / column, is the curve scheme's (the v curve of the vector, scaled by the u weights)."""
    nu, nv, du, dv = 14, 12, 5, 3
    A, C, (mu, mv) = tensor_operators((nu, nv), (du, dv), (False, False), [("U", 6, 5, math.inf)], 2)
    Au, _ = Curve(np.zeros((nu, 2)), du).operators(2)
    cv = Curve(np.zeros((nv, 2)), dv, vectors={5: (np.zeros(2), math.inf)}).operators(2)[1].toarray()[:, 0]
    col = C.toarray()[:, 0].reshape(mu, mv)
    assert np.abs(col - np.outer(Au.toarray()[:, 6], cv)).max() < 1e-14
    assert A.shape == (mu * mv, nu * nv)


def test_a_vector_acts_linearly_and_locally_on_a_mesh_with_extraordinary_vertices():
    """On a subdivided cube (8 extraordinary vertices): the refined points are linear in the
    vector, and only points within the vector's 2-ring (its tensor-product support) move."""
    files = [p for p in shape_files() if p.name == "catmark_cube.obj"]
    if not files:
        pytest.skip("OpenSubdiv shapes absent")
    import patching

    mesh = subdivision_operator(patching.read_mesh(files[0]), rules="opensubdiv")[1]
    topo = Topology(mesh)
    v = int(np.flatnonzero((topo.valence == 4) & ~topo.vertex_is_boundary)[0])
    w = int(topo.dest[topo.one_ring(v)[0]])
    rng = np.random.default_rng(1)
    V1, V2 = rng.normal(size=3), rng.normal(size=3)
    vecs = [SurfaceVector(LINE, v, w, 3.0)]
    A, C, _, _, _ = operators(mesh, vecs, 2)
    base = A @ mesh.vertices
    f1, f2, f12 = (base + C @ x[None] for x in (V1, V2, V1 - 2 * V2))
    assert np.abs((f12 - base) - (f1 - base) + 2 * (f2 - base)).max() < 1e-13
    moved = np.flatnonzero(np.abs(f1 - base).max(axis=1) > 0)
    # support: the points that the points of v's 2-ring produce after two steps
    ring = np.zeros(mesh.n_vertices)
    ring[v] = 1
    for _ in range(2):
        near = np.isin(np.arange(mesh.n_vertices), topo.edges[np.isin(topo.edges, np.flatnonzero(ring)).any(1)].ravel())
        ring = ring + near
    reach = np.flatnonzero(np.abs(A) @ (ring > 0).astype(float) > 0)
    assert len(moved) > 10 and np.isin(moved, reach).all()


def test_fallback_at_extraordinary_vertices_is_the_semi_sharp_catmull_clark_rule():
    """A vector next to extraordinary and semi-sharp tagged vertices: A is OpenSubdiv's
    semi-sharp Catmull-Clark operator, and the vector adds nothing to the vertex points of
    the extraordinary and tagged vertices nor to sharp edges' points (those rows of C are 0);
    a vector on an extraordinary vertex is refused."""
    files = [p for p in shape_files() if p.name == "catmark_cube_creases1.obj"]
    if not files:
        pytest.skip("OpenSubdiv shapes absent")
    import patching

    mesh = subdivision_operator(patching.read_mesh(files[0]), rules="opensubdiv")[1]
    topo = Topology(mesh)
    ev = topo.extraordinary
    sharp_v = np.unique(topo.edges[topo.edge_sharpness > 0])
    regular = np.flatnonzero((topo.valence == 4) & ~topo.vertex_is_boundary & ~np.isin(np.arange(mesh.n_vertices), sharp_v))
    # a regular vertex with an extraordinary or sharp neighbour on its line
    nbrs = {int(v): topo.dest[topo.one_ring(int(v))] for v in regular}
    v = next(v for v, ns in nbrs.items() if np.isin(ns, np.r_[ev, sharp_v]).any())
    w = int(nbrs[v][np.isin(nbrs[v], np.r_[ev, sharp_v])][0])
    vecs = [SurfaceVector(LINE, v, w, 2.0), SurfaceVector(CROSS, v, -1, 1.5)]
    A, C, _, _, _ = operators(mesh, vecs, 1)
    S, _ = subdivision_operator(mesh, rules="opensubdiv")
    assert abs(A - S).max() == 0
    nf, ne = mesh.n_faces, topo.n_edges
    fixed = nf + ne + np.r_[ev, sharp_v]
    fixed = np.r_[fixed, nf + np.flatnonzero(topo.edge_sharpness > 0)]
    assert abs(C.toarray()[fixed]).max() == 0
    assert abs(C).max() > 0.5
    from patching.errors import TagError

    with pytest.raises(TagError, match="valence-4"):
        operators(mesh, [SurfaceVector(CROSS, int(ev[0]), -1, math.inf)], 1)


def test_vector_tags_parse_and_bad_ones_are_refused():
    text = "t controlvector 2/3/0 5 6 0 0 1\nt controlvector 1/4/0 7 1 2 3 2.5\n"
    vecs, W = parse_vector_tags(text, "m.obj")
    assert vecs == [SurfaceVector(LINE, 5, 6, math.inf), SurfaceVector(CROSS, 7, -1, 2.5)]
    assert W.tolist() == [[0, 0, 1], [1, 2, 3]]
    from patching.errors import TagError

    from patching.mesh.obj import parse_obj

    with pytest.warns(UserWarning, match="only 'nupatch subdivide'"):
        parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nt controlvector 1/3/0 0 0 0 1\n")
    for bad in ("t controlvector 1/4/0 7 1 2 3 nan", "t controlvector 3/3/0 1 2 3 0 0 1", "t controlvector 1/4/0 7 1 2 3 -1"):
        with pytest.raises(TagError):
            parse_vector_tags(bad, "m.obj")


def test_subdivide_honours_control_vector_tags(run_cli, tmp_path):
    """``nupatch subdivide`` moves the refined points by the vectors, writes the surviving
    vectors as tags (so the result reads back), and refuses a vector on a missing vertex."""
    mesh = torus_grid(6, 6)
    from patching.mesh import format_obj

    src = tmp_path / "t.obj"
    src.write_text(format_obj(mesh, "torus") + "t controlvector 2/4/0 14 20 0 0 0.5 2\n")
    out = tmp_path / "o.obj"
    r = run_cli("subdivide", src, "-n", "1", "-o", out, "--rules", "opensubdiv")
    assert r.returncode == 0, r.stderr
    assert "control vector ignored" not in r.stderr  # the mesh reader's warning is for other commands
    text = out.read_text()
    vecs, W = parse_vector_tags(text, "o.obj")
    assert np.allclose(np.sort(W[:, 2]), 0.5 * np.array([1 / 16, 1 / 16, 1 / 4, 1 / 4, 3 / 8]))  # the children 1/2 A_u e_i
    assert np.abs(W[:, :2]).max() == 0
    assert len(vecs) == 5 and all(v.sharpness == 1.0 for v in vecs)
    A, C, _, _, _ = operators(mesh, [SurfaceVector(LINE, 14, 20, 2.0)], 1)
    import warnings

    from patching.mesh.obj import parse_obj

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        back = parse_obj(text)
    expect = A @ mesh.vertices + C @ np.array([[0, 0, 0.5]])
    assert np.abs(back.vertices - expect).max() < 1e-9
    bad = tmp_path / "b.obj"
    bad.write_text(format_obj(mesh, "torus") + "t controlvector 1/3/0 99 0 0 1\n")
    r = run_cli("subdivide", bad, "-n", "1", "-o", tmp_path / "b2.obj")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "vertex 99" in r.stderr
    assert not (tmp_path / "b2.obj").exists()


def _uniform_reference(P, degrees, u, v):
    """scipy's tensor-product uniform B-spline of the grid P (m, n, 3) with free open ends
    (domain: the n - d full spans, parameters from 0 in spans), independent of the curves."""
    from scipy.interpolate import BSpline

    out = P
    for axis, (d, t) in enumerate(zip(degrees, (u, v))):
        out = np.moveaxis(out, axis, 0)
        knots = np.arange(len(out) + d + 1, dtype=np.float64)
        Bm = BSpline.design_matrix(np.asarray(t) + d, knots, d).toarray()
        out = np.moveaxis(np.tensordot(Bm, out, axes=(1, 0)), 0, axis)
    return out


def test_tensor_limit_without_vectors_is_the_uniform_tensor_b_spline():
    """No vectors, open grids: the exact limit equals scipy's tensor-product uniform
    B-spline of the grid (free ends: the (m - d) x (n - d) full spans), to 1e-12."""
    from patching.curves.surface_vectors import tensor_limit

    rng = np.random.default_rng(3)
    for degrees in ((3, 3), (5, 2), (4, 7)):
        m, n = degrees[0] + 5, degrees[1] + 4
        P = rng.normal(size=(m, n, 3))
        S = tensor_limit(P, degrees)
        (a, b), (c, e) = S.domain
        assert (a, b, c, e) == (0.0, m - degrees[0], 0.0, n - degrees[1])
        u, v = np.linspace(a, b, 23), np.linspace(c, e, 19)
        ref = _uniform_reference(P, degrees, u, v)
        assert np.abs(S.evaluate(u, v) - ref).max() < 1e-12


@pytest.mark.parametrize("closed", [(False, False), (True, False), (False, True)])
def test_tensor_limit_is_the_tensor_product_of_the_curve_limits(closed):
    """[KSD] eq. (15) exactly: surface - plain surface = sum of B_i(u) C_j(v) U + C_i(u) B_j(v) V
    + C_i(u) C_j(v) X, each factor the curve scheme's limit (Curve.evaluate on a unit polygon
    or a unit vector), for U, V, X vectors of sharpness inf, 1.5, 2; and the exact limit equals
    the limit of the net refined by tensor_operators through the vectors' ceil(s) steps."""
    from patching.curves.surface_vectors import tensor_limit

    rng = np.random.default_rng(5)
    (du, dv), (nu, nv) = (3, 4), (12, 13)
    P = rng.normal(size=(nu, nv, 3))
    vecs = [("U", 5, 6, math.inf), ("V", 6, 5, 1.5), ("X", 4, 8, 2.0)]
    vals = rng.normal(size=(3, 3))
    S = tensor_limit(P, (du, dv), closed, vecs, vals)
    plain = tensor_limit(P, (du, dv), closed)
    (a, b), (c, e) = S.domain
    assert plain.domain == S.domain
    u, v = np.linspace(a, b, 41), np.linspace(c, e, 37)

    def basis(n, d, cl, i, t):
        z = np.zeros((n, 2))
        z[i, 0] = 1.0
        return Curve(z, d, cl).evaluate(t)[:, 0]

    def crease(n, d, cl, i, s, t):
        return Curve(np.zeros((n, 2)), d, cl, vectors={i: (np.array([1.0, 0.0]), s)}).evaluate(t)[:, 0]

    expect = plain.evaluate(u, v)
    for (kind, i, j, s), w in zip(vecs, vals):
        fu = basis(nu, du, closed[0], i, u) if kind == "U" else crease(nu, du, closed[0], i, s, u)
        fv = basis(nv, dv, closed[1], j, v) if kind == "V" else crease(nv, dv, closed[1], j, s, v)
        expect = expect + np.einsum("i,j,k->ijk", fu, fv, w)
    got = S.evaluate(u, v)
    assert np.abs(got - expect).max() < 1e-12
    assert np.abs(got - plain.evaluate(u, v)).max() > 0.05
    # the U vector is infinitely sharp: a d_v-fold knot (C0 crease line) in v, none in u
    assert np.unique(S.knots_v, return_counts=True)[1][1:-1].max() == dv
    # against refinement: 2 steps (the finite vectors used up), then the refined net's limit
    # plus the infinitely sharp vector (still a vector after the steps)
    A, C, (mu, mv) = tensor_operators((nu, nv), (du, dv), closed, vecs[1:], 2)
    R = (A @ P.reshape(-1, 3) + C @ vals[1:]).reshape(mu, mv, 3)
    fine = tensor_limit(R, (du, dv), closed)
    U = tensor_limit(np.zeros_like(P), (du, dv), closed, vecs[:1], vals[:1])
    assert np.abs(fine.evaluate(4 * u, 4 * v) + U.evaluate(u, v) - got).max() < 1e-12


def test_tensor_limit_exports_as_an_exact_step_b_spline_face(tmp_path):
    """The B-spline face written to STEP reads back (one face, a B-spline surface) with the
    same poles count and the same points as the exact limit, to 1e-12 of the size."""
    pytest.importorskip("OCP")
    from OCP.BRep import BRep_Tool
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.GeomAdaptor import GeomAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_BSplineSurface
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    from export import read_step
    from export.curves import to_face, write_surface_step
    from export.ocp_compat import TopoDS
    from patching.curves.surface_vectors import tensor_limit

    rng = np.random.default_rng(7)
    P = rng.normal(size=(11, 10, 3)) * 10
    S = tensor_limit(P, (5, 3), (False, False), [("U", 5, 5, math.inf), ("X", 4, 4, 1.0)], rng.normal(size=(2, 3)))
    assert BRepCheck_Analyzer(to_face(S)).IsValid()
    path = write_surface_step(S, tmp_path / "s.step")
    explorer = TopExp_Explorer(read_step(path), TopAbs_FACE)
    faces = []
    while explorer.More():
        faces.append(TopoDS.Face_s(explorer.Current()))
        explorer.Next()
    assert len(faces) == 1
    surf = BRep_Tool.Surface_s(faces[0])
    adaptor = GeomAdaptor_Surface(surf)
    assert adaptor.GetType() == GeomAbs_BSplineSurface
    bs = adaptor.BSpline()
    assert (bs.NbUPoles(), bs.NbVPoles()) == S.poles.shape[:2]
    assert (bs.UDegree(), bs.VDegree()) == (5, 3)
    (a, b), (c, e) = S.domain
    u, v = np.linspace(a, b, 13), np.linspace(c, e, 11)
    ref = S.evaluate(u, v)
    got = np.array([[[*surf.Value(float(x), float(y)).Coord()] for y in v] for x in u])
    size = np.abs(P).max()
    assert np.abs(got - ref).max() < 1e-12 * size


# ------------------------------------------------- nupatch build of a grid with control vectors
def _read_faces(path):
    from export import read_step
    from tests.helpers import faces_of

    shape = read_step(path)
    return shape, faces_of(shape)


def test_build_writes_the_exact_clamped_grid_face(cli_main, tmp_path):
    """``nupatch build GRID.obj`` with a controlvector tag: one B-spline face, the tensor
    limit with clamped ends (interpolateboundary 1, the default) to 1e-12; its boundary is the
    cubic B-spline of the boundary row with the sharp-end rule (scipy on the row extended by
    odd reflection, 2 P_0 - P_1: independent of the curve code), its corners the corner
    vertices; the cross vector adds a C0 crease (triple knots) in both directions."""
    pytest.importorskip("OCP")
    from OCP.BRep import BRep_Tool
    from OCP.GeomAdaptor import GeomAdaptor_Surface
    from scipy.interpolate import BSpline

    from patching.curves.surface_vectors import tensor_limit
    from patching.mesh import format_obj

    m, n = 9, 8
    mesh = open_grid(m, n)
    src = tmp_path / "g.obj"
    src.write_text(format_obj(mesh, "grid") + f"t controlvector 1/3/0 {4 * n + 3} 0 0 0.7\n")
    r = cli_main("build", src, "-o", tmp_path / "g.step")
    assert r.returncode == 0, r.stderr
    assert "ignored" not in r.stderr
    _, faces = _read_faces(tmp_path / "g.step")
    assert len(faces) == 1
    surf = BRep_Tool.Surface_s(faces[0])
    bs = GeomAdaptor_Surface(surf).BSpline()
    assert (bs.UDegree(), bs.VDegree()) == (3, 3) and not bs.IsUPeriodic()
    assert 3 in [bs.UMultiplicity(i) for i in range(2, bs.NbUKnots())]
    P = mesh.vertices.reshape(m, n, 3)
    S = tensor_limit(P, (3, 3), (False, False), [("X", 4, 3, math.inf)], [[0, 0, 0.7]], ends=(True, True))
    (a, b), (c, e) = S.domain
    assert (a, b, c, e) == (0.0, m - 1.0, 0.0, n - 1.0)
    u, v = np.linspace(a, b, 17), np.linspace(c, e, 15)
    got = np.array([[[*surf.Value(float(x), float(y)).Coord()] for y in v] for x in u])
    assert np.abs(got - S.evaluate(u, v)).max() < 1e-12 * np.abs(P).max()
    for corner in ((0, 0), (m - 1, 0), (0, n - 1), (m - 1, n - 1)):
        x, y = (a, b)[corner[0] > 0], (c, e)[corner[1] > 0]
        assert np.abs(np.array(surf.Value(float(x), float(y)).Coord()) - P[corner]).max() < 1e-12
    row = P[:, 0]
    ext = np.r_[[2 * row[0] - row[1]], row, [2 * row[-1] - row[-2]]]
    ref = BSpline(np.arange(len(ext) + 4, dtype=float), ext, 3)(u + 3)
    assert np.abs(got[:, 0] - ref).max() < 1e-12
    # without the tag, 'nupatch build' (Catmull-Clark's G1 patches) is the same surface as the
    # vector-free tensor limit: adding the vector changes nothing but its crease
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.gp import gp_Pnt

    plain_src = tmp_path / "p.obj"
    plain_src.write_text(format_obj(mesh, "grid"))
    assert cli_main("build", plain_src, "-o", tmp_path / "p.step").returncode == 0
    shape, _ = _read_faces(tmp_path / "p.step")
    plain = tensor_limit(P, (3, 3), ends=(True, True)).evaluate(u[::4], v[::4]).reshape(-1, 3)
    for p in plain:
        dist = BRepExtrema_DistShapeShape(BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, p))).Vertex(), shape)
        assert dist.Value() < 1e-9


def test_build_of_a_torus_grid_with_a_vector_is_one_periodic_closed_face(cli_main, tmp_path):
    """Closed grid directions come out periodic (one face, no free edges, a valid closed
    shell's worth of surface), equal to the tensor limit to 1e-12."""
    pytest.importorskip("OCP")
    from OCP.BRep import BRep_Tool
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.GeomAdaptor import GeomAdaptor_Surface
    from OCP.ShapeAnalysis import ShapeAnalysis_FreeBounds
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer

    from patching.curves.surface_vectors import tensor_limit
    from patching.mesh import format_obj

    m, n = 8, 7
    mesh = torus_grid(m, n)
    src = tmp_path / "t.obj"
    src.write_text(format_obj(mesh, "torus") + f"t controlvector 2/4/0 {3 * n + 2} {4 * n + 2} 0 0 0.4 2\n"
                   f"t controlvector 1/3/0 {5 * n + 5} 0 0.3 0\n")
    r = cli_main("build", src, "-o", tmp_path / "t.step")
    assert r.returncode == 0, r.stderr
    shape, faces = _read_faces(tmp_path / "t.step")
    assert len(faces) == 1 and BRepCheck_Analyzer(shape).IsValid()
    surf = BRep_Tool.Surface_s(faces[0])
    bs = GeomAdaptor_Surface(surf).BSpline()
    assert bs.IsUPeriodic() and bs.IsVPeriodic()
    free = ShapeAnalysis_FreeBounds(shape, 1e-7, False, False)
    ex = TopExp_Explorer(free.GetClosedWires(), TopAbs_EDGE)
    assert not ex.More()  # no free boundary: the face closes on itself in both directions
    P = mesh.vertices.reshape(m, n, 3)
    S = tensor_limit(P, (3, 3), (True, True), [("U", 3, 2, 2.0), ("X", 5, 5, math.inf)], [[0, 0, 0.4], [0, 0.3, 0]])
    (a, b), (c, e) = S.domain
    u, v = np.linspace(a, b, 13), np.linspace(c, e, 11)
    got = np.array([[[*surf.Value(float(x), float(y)).Coord()] for y in v] for x in u])
    assert np.abs(got - S.evaluate(u, v)).max() < 1e-12 * np.abs(P).max()


@pytest.mark.parametrize("case,needle", [
    ("ev", "vertex"), ("close", "grid lines from the clamped boundary"), ("ib2", "interpolateboundary 2"),
    ("stl", "OUT.step"),
])
def test_build_with_vectors_refusals(cli_main, tmp_path, case, needle):
    from patching.mesh import format_obj

    m, n = 7, 7
    mesh = open_grid(m, n)
    text = format_obj(mesh, "grid")
    out = tmp_path / ("g.stl" if case == "stl" else "g.step")
    if case == "ev":  # a quad glued onto the boundary edge 0-1: vertex 1 is extraordinary
        text = format_obj(_glued(mesh), "grid") + "t controlvector 1/3/0 24 0 0 1\n"
        needle = "vertex 1 is extraordinary (valence 4, on the boundary) (vertex 1)"
    elif case == "close":
        text += f"t controlvector 1/3/0 {1 * n + 3} 0 0 1\n"
    elif case == "ib2":
        text += "t interpolateboundary 1/0/0 2\nt controlvector 1/3/0 24 0 0 1\n"
    else:
        text += "t controlvector 1/3/0 24 0 0 1\n"
    src = tmp_path / "g.obj"
    src.write_text(text)
    r = cli_main("build", src, "-o", out)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and needle in r.stderr, r.stderr
    assert not out.exists()


def _glued(mesh):
    from patching.mesh.control_mesh import from_arrays

    V = np.r_[mesh.vertices, [[-1.0, 0.0, 0.0], [-1.0, 1.0, 0.0]]]
    n = mesh.n_vertices
    return from_arrays(V, mesh.face_vertices.reshape(-1, 4).tolist() + [[0, 1, n + 1, n]])


def test_grid_of_names_the_extraordinary_vertex():
    """A grid with a quad glued onto a boundary edge: boundary vertex 1 gets valence 4 (an
    extraordinary boundary vertex), refused with that vertex named."""
    from patching.curves.surface_vectors import grid_of

    mesh = open_grid(5, 5)
    ids, closed = grid_of(mesh)
    assert ids.shape == (5, 5) and closed == (False, False) and sorted(ids.ravel()) == list(range(25))
    ids, closed = grid_of(torus_grid(6, 5))
    assert ids.shape == (6, 5) and closed == (True, True)
    with pytest.raises(UnsupportedError, match="vertex 1 is extraordinary"):
        grid_of(_glued(mesh))


def test_build_of_a_cylinder_grid_is_periodic_one_way_and_free_ends_with_interpolateboundary_0(cli_main, tmp_path):
    """A cylinder (closed around, open along): periodic in u only, clamped in v, equal to the
    tensor limit; the same grid with interpolateboundary 0 has free ends in v: the n - 3 full
    spans of the tensor limit without ends (which the no-vector test above checks against
    scipy's uniform B-spline)."""
    pytest.importorskip("OCP")
    from OCP.BRep import BRep_Tool
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.GeomAdaptor import GeomAdaptor_Surface

    from patching.curves.surface_vectors import grid_of, tensor_limit
    from patching.mesh import format_obj
    from patching.mesh.control_mesh import from_arrays

    m, n = 9, 8
    a, b = np.meshgrid(np.arange(m), np.arange(n), indexing="ij")
    V = np.stack([np.cos(2 * np.pi * a / m), np.sin(2 * np.pi * a / m), b * 0.5 + 0.1 * np.sin(a)], -1).reshape(-1, 3)
    F = [[i * n + j, ((i + 1) % m) * n + j, ((i + 1) % m) * n + j + 1, i * n + j + 1] for i in range(m) for j in range(n - 1)]
    mesh = from_arrays(V, F)
    ids, closed = grid_of(mesh)
    assert closed == (True, False) and ids.shape == (m, n)
    P = mesh.vertices[ids]
    i0, j0 = [int(x[0]) for x in np.nonzero(ids == 4 * n + 4)]
    for ib, ends in ((1, (False, True)), (0, (False, False))):
        src = tmp_path / f"c{ib}.obj"
        src.write_text(format_obj(mesh, "cyl") + f"t interpolateboundary 1/0/0 {ib}\nt controlvector 1/3/0 {4 * n + 4} 0 0 0.3\n")
        r = cli_main("build", src, "-o", tmp_path / f"c{ib}.step")
        assert r.returncode == 0, r.stderr
        shape, faces = _read_faces(tmp_path / f"c{ib}.step")
        assert len(faces) == 1 and BRepCheck_Analyzer(shape).IsValid()
        surf = BRep_Tool.Surface_s(faces[0])
        bs = GeomAdaptor_Surface(surf).BSpline()
        assert bs.IsUPeriodic() and not bs.IsVPeriodic()
        S = tensor_limit(P, (3, 3), (True, False), [("X", i0, j0, math.inf)], [[0, 0, 0.3]], ends=ends)
        (ua, ub), (va, vb) = S.domain
        assert vb - va == (n - 1 if ib else n - 3)
        u, v = np.linspace(ua, ub, 11), np.linspace(va, vb, 9)
        got = np.array([[[*surf.Value(float(x), float(y)).Coord()] for y in v] for x in u])
        assert np.abs(got - S.evaluate(u, v)).max() < 1e-12 * np.abs(P).max()
