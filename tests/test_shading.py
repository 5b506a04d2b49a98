"""Subdivision shading ([ZBK]) for Loop and Catmull-Clark (patching.shading)."""

from __future__ import annotations


import numpy as np
import pytest

import patching
from patching.shading import shading_operator, subdivide_with_normals
from tests.conftest import shape_files
from tests.test_loop import _angle, _icosahedron

from tests.conftest import SHAPES  # noqa: E402
LOOP = shape_files("loop_") or sorted(SHAPES.glob("loop_*.obj"))
CATMARK = [p for p in (shape_files("catmark_") or sorted(SHAPES.glob("catmark_*.obj")))
           if p.stem in ("catmark_cube_creases1", "catmark_cube_corner3", "catmark_hole_test1",
                         "catmark_edgeonly", "catmark_tent_creases0", "catmark_dart_edgeonly")]


def _cases():
    return [(p, "loop") for p in LOOP] + [(p, "catmark") for p in CATMARK]


@pytest.mark.skipif(not LOOP, reason="OpenSubdiv shapes absent")
@pytest.mark.parametrize("path,scheme", _cases(), ids=lambda x: getattr(x, "stem", x))
def test_unit_length_and_limit_where_b_is_zero(path, scheme):
    mesh = patching.read_mesh(path)
    for variant in ("a", "b"):
        op = shading_operator(mesh, 2, scheme, variant=variant)
        out = op.evaluate(mesh.vertices)
        assert np.all(np.isfinite(out.normals))
        assert np.abs(np.linalg.norm(out.normals, axis=1) - 1).max() < 1e-14
        assert out.corner_normal.shape == out.faces.shape
        nl = op.limit.normals(op.mesh.vertices)
        zero = op.blend[op.region_vertex] == 0
        assert np.abs(out.normals[zero] - nl[zero]).max(initial=0) < 1e-15
        lim = subdivide_with_normals(mesh, 2, scheme, normals="limit")
        assert np.abs(lim.normals - nl).max() < 1e-15


def _creased(scheme):
    if scheme == "loop":
        v, f = _icosahedron()
        loop = [(0, 5), (5, 11), (11, 10), (10, 7), (7, 1), (1, 0)]  # not a face boundary
        return patching.from_arrays(v, f, creases={e: 10.0 for e in loop})
    v = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    f = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return patching.from_arrays(v, f, creases={(4, 5): 10.0, (5, 7): 10.0, (6, 7): 10.0, (4, 6): 10.0})


@pytest.mark.parametrize("scheme", ["loop", "catmark"])
@pytest.mark.parametrize("levels", [1, 2, 3])
def test_sharp_crease_one_normal_per_side(scheme, levels):
    """Variant B: at an infinitely sharp crease vertex of the refined mesh, one normal per
    side, each the limit normal of that side."""
    mesh = _creased(scheme)
    op = shading_operator(mesh, levels, scheme, variant="b")
    out = op.evaluate(mesh.vertices)
    topo = patching.Topology(op.mesh)
    sharp = (topo.edge_sharpness >= 10) | topo.edge_is_boundary
    count = np.bincount(topo.edges[sharp].ravel(), minlength=topo.n_vertices)
    crease = np.flatnonzero((count == 2) & ~topo.vertex_is_boundary)
    assert crease.size >= 4
    nregions = np.bincount(op.region_vertex, minlength=topo.n_vertices)
    assert np.all(nregions[crease] == 2)
    assert np.all(nregions[count == 0] == 1)
    nl = op.limit.normals(op.mesh.vertices)
    sel = np.isin(op.region_vertex, crease)
    assert np.array_equal(out.normals[sel], nl[sel])
    # the two sides of a crease vertex are different normals (a real crease)
    pairs = np.stack([np.flatnonzero(op.region_vertex == v) for v in crease])
    assert _angle(out.normals[pairs[:, 0]], out.normals[pairs[:, 1]]).min() > 1e-3
    # and each side's normal is that side's: it agrees with the faces of its own region
    k = out.faces.shape[1]
    corner = np.flatnonzero(sel[op.region_of_corner])
    face = corner // k
    tri = out.points[out.faces[face][:, :3]]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("ij,ij->i", fn, out.normals[op.region_of_corner[corner]]) > 0)


def _torus(n, m, tri):
    u, w = np.meshgrid(2 * np.pi * np.arange(n) / n, 2 * np.pi * np.arange(m) / m, indexing="ij")
    P = np.stack([(2 + np.cos(w)) * np.cos(u), (2 + np.cos(w)) * np.sin(u), np.sin(w)], -1).reshape(-1, 3)
    idx = lambda i, j: (i % n) * m + (j % m)
    faces = []
    for i in range(n):
        for j in range(m):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            faces += [[a, b, c], [a, c, d]] if tri else [[a, b, c, d]]
    return patching.from_arrays(P, faces)


@pytest.mark.parametrize("scheme", ["loop", "catmark"])
def test_regular_mesh_gives_limit_normals(scheme):
    """No sharp feature, no extraordinary vertex: b = 0 everywhere and the output is N_L."""
    mesh = _torus(8, 6, scheme == "loop")
    op = shading_operator(mesh, 2, scheme)
    out = op.evaluate(mesh.vertices)
    assert np.all(op.blend == 0)
    assert np.abs(out.normals - op.limit.normals(op.mesh.vertices)).max() == 0


@pytest.mark.parametrize("scheme", ["loop", "catmark"])
@pytest.mark.parametrize("variant", ["a", "b"])
def test_flat_mesh_gives_plane_normal(scheme, variant):
    """A planar control mesh with extraordinary vertices, a crease and a boundary: every
    normal (subdivided, limit, blended) is the plane's."""
    rng = np.random.default_rng(3)
    ang = 2 * np.pi * np.arange(5) / 5
    inner = np.stack([np.cos(ang), np.sin(ang), 0 * ang], 1)
    outer = 2.2 * np.stack([np.cos(ang + 0.6), np.sin(ang + 0.6), 0 * ang], 1)
    P = np.vstack([[0, 0, 0], inner, outer]) + np.c_[rng.normal(0, 0.05, (11, 2)), np.zeros(11)]
    if scheme == "loop":
        f = [[0, 1 + i, 1 + (i + 1) % 5] for i in range(5)]
        f += [[1 + i, 6 + i, 1 + (i + 1) % 5] for i in range(5)] + [[1 + (i + 1) % 5, 6 + i, 6 + (i + 1) % 5] for i in range(5)]
    else:
        f = [[0, 1 + i, 6 + i, 1 + (i + 1) % 5] for i in range(5)]
    mesh = patching.from_arrays(P, f, creases={(0, 1): 10.0, (0, 3): 10.0})
    out = subdivide_with_normals(mesh, 3, scheme, variant=variant)
    assert np.abs(np.abs(out.normals[:, 2]) - 1).max() < 1e-12


def test_semi_sharp_crease_turns_smooth():
    """Loop: a crease of sharpness 1 leaves no sharp edge after one step, so at levels 2 and 3
    every vertex has one normal; an infinitely sharp one keeps two."""
    v, f = _icosahedron()
    mesh = patching.from_arrays(v, f, creases={(0, 5): 1.0, (5, 11): 1.0, (0, 11): 1.0})
    for levels in (2, 3):
        op = shading_operator(mesh, levels, "loop")
        assert op.region_vertex.size == op.mesh.n_vertices
    op1 = shading_operator(patching.from_arrays(v, f, creases={(0, 5): 10.0, (5, 11): 10.0, (0, 11): 10.0}), 3, "loop")
    assert op1.region_vertex.size > op1.mesh.n_vertices


def test_share_of_vertices_needing_subdivided_normals():
    """[ZBK] sec. 5: N_S is needed only near extraordinary vertices (b > 0).  An icosphere
    control mesh (12 valence-5 vertices among 162) at level 4 of Loop: with blending seeded at
    level 4 (the paper's count) the share is that of the EVs' 1-rings, 72 of 40962 vertices;
    seeded at level 1 (the default) b spreads over the EVs' neighbourhoods of level 1, about a
    third of this coarse sphere."""
    from patching.loop import loop_subdivide

    v, f = _icosahedron()
    sphere = loop_subdivide(patching.from_arrays(v, f), 2)
    late = shading_operator(sphere, 4, "loop", blend_level=4)
    assert np.count_nonzero(late.blend > 0) == 12 * 6
    op = shading_operator(sphere, 4, "loop")
    share = float(np.mean(op.blend > 0))
    assert 0.05 < share < 0.5
    out = op.evaluate(sphere.vertices)
    far = op.blend[op.region_vertex] == 0
    assert np.array_equal(out.normals[far], op.limit.normals(op.mesh.vertices)[far])


@pytest.mark.skipif(not CATMARK, reason="OpenSubdiv shapes absent")
@pytest.mark.parametrize("name", ["catmark_cube_creases1", "catmark_tent_creases0", "catmark_dart_edgeonly", "catmark_hole_test1"])
@pytest.mark.parametrize("rules", ["opensubdiv", "seed"])
def test_catmark_limit_agrees_with_subdivision_module(name, rules):
    """Catmull-Clark limit points from the 1-ring eigenvectors equal patching.subdivision's
    limit masks; at smooth vertices the normal is the cross product of its limit tangents."""
    from patching.shading.limit import catmark_limit_masks
    from patching.subdivision import limit_points, limit_tangents, subdivide

    mesh = subdivide(patching.read_mesh(SHAPES / f"{name}.obj"), 1, rules=rules)
    masks = catmark_limit_masks(mesh, rules)
    assert np.abs(masks.points(mesh.vertices) - limit_points(mesh, rules)).max() < 1e-12
    t = limit_tangents(mesh, rules)
    n = np.cross(t[:, 0], t[:, 1])
    ok = np.isfinite(n).all(axis=1) & (np.linalg.norm(n, axis=1) > 1e-12)
    topo = patching.Topology(mesh)
    smooth = ok & (np.bincount(topo.edges[(topo.edge_sharpness > 0) | topo.edge_is_boundary].ravel(), minlength=mesh.n_vertices) == 0)
    mine = masks.normals(mesh.vertices)
    first = np.zeros(mesh.n_vertices, np.int64)
    first[topo.origin[::-1]] = masks.region_of_corner[::-1]
    v = np.flatnonzero(smooth)
    assert v.size
    assert _angle(mine[first[v]], n[v] / np.linalg.norm(n[v], axis=1)[:, None]).max() < 1e-9


def test_catmark_semi_sharp_crease_turns_smooth():
    """Catmull-Clark: a cube's top ring of sharpness 2 is still sharp (1) at level 1, so its
    vertices have two normals there and one from level 2 on; of sharpness 10, two at every
    level."""
    def cube(s):
        v = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
        f = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
        return patching.from_arrays(v, f, creases={(4, 5): s, (5, 7): s, (6, 7): s, (4, 6): s})

    one = shading_operator(cube(2.0), 1, "catmark")
    assert one.region_vertex.size > one.mesh.n_vertices
    for levels in (2, 3):
        op = shading_operator(cube(2.0), levels, "catmark")
        assert op.region_vertex.size == op.mesh.n_vertices
        assert np.abs(np.linalg.norm(op.evaluate(cube(2.0).vertices).normals, axis=1) - 1).max() < 1e-14
    sharp = shading_operator(cube(10.0), 3, "catmark")
    assert sharp.region_vertex.size > sharp.mesh.n_vertices


def _tet(sharp_edges, s=4.0):
    v = np.array([[1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1]], float)
    return patching.from_arrays(v, [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]], creases={e: s for e in sharp_edges})


def test_blend_after_semi_sharp_decay():
    """[ZBK] sec. 3.2, Fig. 4 (variant B, blending from level 2): the extraordinary vertices on
    edges of sharpness 4 get b = 0 while the edges are sharp and after 4 steps; after 5 (one
    smooth step after the edges ran out) they are treated as smooth extraordinary vertices:
    b = 1 at them and their 1-rings.  Normals stay unit and N_L where b = 0."""
    tet = _tet([(0, 1), (1, 2), (0, 2)])
    ev = [0, 1, 2]  # valence 3, on the crease loop (vertex points keep their ids)
    for levels, want in ((3, 0.0), (4, 0.0), (5, 1.0), (6, 1.0)):
        op = shading_operator(tet, levels, "loop", blend_level=2)
        assert np.all(op.blend[ev] == want), (levels, op.blend[ev])
        if levels == 5:
            topo = patching.Topology(op.mesh)
            ring = topo.dest[np.isin(topo.origin, ev)]
            assert np.all(op.blend[ring] == 1.0)
            out = op.evaluate(tet.vertices)
            assert np.abs(np.linalg.norm(out.normals, axis=1) - 1).max() < 1e-14
            zero = op.blend[op.region_vertex] == 0
            assert np.array_equal(out.normals[zero], op.limit.normals(op.mesh.vertices)[zero])
    # variant A treats the sharp vertices as smooth from the start: no jump at level 5
    a4 = shading_operator(tet, 4, "loop", variant="a", blend_level=2).blend[ev]
    assert np.all(a4 > 0)
    # Catmull-Clark alike (vertex points at n_faces + n_edges + v): a cube with a crease loop
    v = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
    f = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    cube = patching.from_arrays(v, f, creases={e: 2.0 for e in [(4, 5), (5, 7), (7, 6), (6, 4)]})
    from patching.subdivision import subdivision_operator

    ids, m = [np.array([4, 5, 6, 7])], cube  # the top face's corners at levels 0, 1, 2, 3
    for _ in range(3):
        t = patching.Topology(m)
        ids.append(ids[-1] + t.n_faces + t.n_edges)
        m = subdivision_operator(m)[1]
    b2 = shading_operator(cube, 2, "catmark", blend_level=1)
    b3 = shading_operator(cube, 3, "catmark", blend_level=1)
    assert np.all(b2.blend[ids[2]] == 0.0) and np.all(b3.blend[ids[3]] == 1.0)


def test_darts_sharp_or_smooth():
    """[ZBK] sec. 3.3, 4.3: the tetrahedron with two sharp edges (vertices 1 and 2 darts, both
    extraordinary).  Darts smooth (default, [ZBK] sec. 5): an extraordinary dart seeds 1; darts
    sharp: variant B gives them 0 and they seed nothing; under variant A the two agree."""
    darts = _tet([(0, 1), (0, 2)])
    smooth = shading_operator(darts, 2, "loop", blend_level=2)
    sharp = shading_operator(darts, 2, "loop", blend_level=2, darts="sharp")
    assert np.all(smooth.blend[[1, 2]] == 1.0) and np.all(sharp.blend[[1, 2]] == 0.0)
    assert smooth.blend[3] == sharp.blend[3] == 1.0  # the smooth extraordinary vertex
    assert smooth.blend[0] == sharp.blend[0] == 0.0  # the crease vertex
    for levels in (2, 4):
        s, h = (shading_operator(darts, levels, "loop", variant="a", darts=d).blend for d in ("smooth", "sharp"))
        assert np.array_equal(s, h)
        out = shading_operator(darts, levels, "loop", darts="sharp").evaluate(darts.vertices)
        assert np.abs(np.linalg.norm(out.normals, axis=1) - 1).max() < 1e-14
    with pytest.raises(patching.errors.UnsupportedError, match="darts"):
        shading_operator(darts, 2, "loop", darts="corner")
