"""Control vectors on surfaces ([KSD] sec. 5): the Catmull-Clark form against the tensor
product of the curve scheme, linearity and locality of a vector, the fallback to the
semi-sharp Catmull-Clark rules at extraordinary vertices, and the OBJ tags / CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest

from patching.curves.curve import Curve
from patching.curves.surface_vectors import CROSS, LINE, SurfaceVector, operators, parse_vector_tags, tensor_operators
from patching.mesh.primitives import torus_grid
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
