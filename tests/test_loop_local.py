"""Local refinement for semi-sharp limits (patching.loop.local) against the global path (the
whole mesh refined until no semi-sharp tag is left) to 1e-12, for Loop and Catmull-Clark; the
child topology built from the parent's tables against Topology; the region table against the
plain connected components of the corner graph."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse.csgraph import connected_components

import patching
from patching.loop.refine import LoopLevel, child_topology, loop_operator
from patching.loop.stationary import corner_regions, level_rules
from patching.shading.limit import limit_masks
from patching.topology import Topology
from tests.conftest import shape_files
from tests.test_loop import BASES, SHARPNESS, random_tagged_mesh

# small shapes with semi-sharp or sharp features, boundaries, non-quads, back-to-back faces
NAMES = {"loop_icos_semisharp", "loop_cube_creases0", "loop_saddle_edgecorner", "loop_triangle_edgeonly",
         "catmark_cube_creases0", "catmark_cube_corner3", "catmark_tent_creases1", "catmark_pyramid_creases0",
         "catmark_dart_edgeonly", "catmark_val2_back2back", "catmark_nonquads", "catmark_flap"}
SHAPES = [p for p in shape_files("") if p.stem in NAMES]


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return patching.read_mesh(path)


def _same(mesh, scheme, **kw):
    a = limit_masks(mesh, scheme, refine="global", **kw)
    b = limit_masks(mesh, scheme, refine="local", **kw)
    P = mesh.vertices
    scale = max(1.0, float(np.abs(P).max()))
    assert np.abs(a.points(P) - b.points(P)).max() <= 1e-12 * scale
    assert np.array_equal(a.region_of_corner, b.region_of_corner)
    na, nb = a.corner_normals(P), b.corner_normals(P)
    assert np.abs(np.linalg.norm(nb, axis=1) - 1).max() < 1e-12
    assert np.abs(na - nb).max() <= 1e-12


@pytest.mark.skipif(not SHAPES, reason="OpenSubdiv shapes absent")
@pytest.mark.parametrize("path", SHAPES, ids=lambda p: p.stem)
def test_shapes_local_equals_global(path):
    scheme = "loop" if path.stem.startswith("loop") else "catmark"
    _same(_read(path), scheme)


@settings(max_examples=12, deadline=None)
@given(base=st.sampled_from(sorted(BASES)), data=st.data(), mode=st.sampled_from([0, 1, 2]),
       method=st.sampled_from(["uniform", "chaikin"]))
def test_generated_loop_local_equals_global(base, data, mode, method):
    _same(random_tagged_mesh(base, data, mode), "loop", crease_method=method)


def _quad_grid(n):
    v = np.array([[i, j, 0.2 * ((i * 5 + j * 3) % 4)] for j in range(n + 1) for i in range(n + 1)], float)
    f = [[j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i]
         for j in range(n) for i in range(n)]
    return v, f


@settings(max_examples=8, deadline=None)
@given(data=st.data(), mode=st.sampled_from([0, 1, 2]), rules=st.sampled_from(["opensubdiv", "seed"]))
def test_generated_catmark_local_equals_global(data, mode, rules):
    v, f = _quad_grid(3)
    rng = np.random.default_rng(data.draw(st.integers(0, 2**31)))
    v = v + 0.05 * rng.standard_normal(v.shape)
    edges = sorted({(min(a, b), max(a, b)) for q in f for a, b in zip(q, q[1:] + q[:1])})
    creases = {e: s for e in edges if (s := data.draw(SHARPNESS)) > 0}
    mesh = patching.from_arrays(v, f, creases=creases, interpolate_boundary=mode)
    _same(mesh, "catmark", rules=rules)


def test_sharpness_beyond_the_global_cap():
    """A crease of sharpness 9 on a mesh whose global refinement would pass the cap: the local
    path refines only the crease's neighbourhood.  Away from it the limit is the smooth one;
    at the crease vertex it is the infinitely sharp crease's up to the nine steps' decay."""
    v, f = BASES["ico"]
    mesh = patching.from_arrays(v, f, creases={(0, 5): 9.0, (0, 11): 9.0})
    with pytest.raises(patching.NupatchError, match="more than"):
        limit_masks(mesh, "loop", refine="global")
    m = limit_masks(mesh, "loop")
    smooth = limit_masks(patching.from_arrays(v, f), "loop").points(mesh.vertices)
    got = m.points(mesh.vertices)
    far = [3, 6, 8]  # no spoke near the crease
    assert np.abs(got[far] - smooth[far]).max() < 1e-12
    # after 9 crease steps the ring has shrunk by the crease vertex's subdominant eigenvalues
    # (1/2 along the crease, 3/8 + cos(pi/4)/4 < 5/8 across its side of 4 faces), and so has
    # what the smooth steps after it can move
    sharp = limit_masks(patching.from_arrays(v, f, creases={(0, 5): 10.0, (0, 11): 10.0}), "loop").points(v)
    assert np.linalg.norm(got[0] - sharp[0]) < (5 / 8) ** 9 * np.linalg.norm(smooth[0] - sharp[0])
    assert np.abs(np.linalg.norm(m.corner_normals(mesh.vertices), axis=1) - 1).max() < 1e-12


def test_child_topology_equals_topology():
    meshes = [patching.from_arrays(*BASES[k], interpolate_boundary=1) for k in sorted(BASES)]
    meshes += [_read(p) for p in shape_files("loop_")]
    for m in meshes:
        for _ in range(2):
            level = LoopLevel.of(m)
            _, child = loop_operator(m)
            a, b = child_topology(level.topo, child), Topology(child)
            for name in ("n_faces", "n_vertices", "n_edges", "origin", "face", "next", "prev", "dest", "edges",
                         "edge_of", "twin", "edge_halfedge", "edge_is_boundary"):
                assert np.array_equal(getattr(a, name), getattr(b, name)), (m.name, name)
            m = child


def test_corner_regions_equal_connected_components():
    for k in sorted(BASES):
        v, f = BASES[k]
        edges = sorted({(min(a, b), max(a, b)) for t in f for a, b in zip(t, t[1:] + t[:1])})
        mesh = patching.from_arrays(v, f, creases={e: 10.0 for e in edges[::3]})
        topo = Topology(mesh)
        sharp, _ = level_rules(mesh, topo)
        label, rv = corner_regions(topo, sharp)
        h = np.arange(topo.origin.size)
        nb = topo.twin[topo.prev]
        ok = (nb >= 0) & ~sharp[topo.edge_of[topo.prev]]
        g = sp.coo_matrix((np.ones(int(ok.sum())), (h[ok], nb[ok])), shape=(h.size, h.size))
        n, want = connected_components(g, directed=False)
        assert np.array_equal(label, want) and rv.size == n
        assert np.array_equal(rv[label], topo.origin)


def test_limit_normal_oriented_by_the_ring_where_the_ring_folds():
    """Three edges of sharpness 4 around a tetrahedron's face, 4 steps: the crease has just
    decayed and the corners' rings fold over.  Their limit normals point to the faces' side
    of the surface refined further (the mean of the refined ring's face normals), not to
    the side a single folded facet of the level would pick."""
    from patching.loop import loop_subdivide
    from patching.shading import shading_operator

    v = np.array([[1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1]], float)
    tet = patching.from_arrays(v, [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
                               creases={(0, 1): 4.0, (1, 2): 4.0, (0, 2): 4.0})
    op = shading_operator(tet, 4, "loop", "limit")
    nl = op.limit.normals(op.mesh.vertices)
    fine = loop_subdivide(op.mesh, 3)
    t = Topology(fine)
    for vid in range(4):
        h = np.flatnonzero(t.origin == vid)
        p = fine.vertices
        n = np.cross(p[t.dest[h]] - p[vid], p[t.origin[t.prev[h]]] - p[vid]).sum(axis=0)
        assert nl[op.region_vertex == vid] @ (n / np.linalg.norm(n)) > 0.999


def test_folded_corner_ring_keeps_the_global_orientation():
    """The case hypothesis found: a jittered open grid, a corner of three sharp edges whose
    level-0 ring folds over, a semi-sharp edge elsewhere.  Its normal (oriented by a facet)
    is taken at the global path's level, not at level 0 where the facet points the other way."""
    v, f = _quad_grid(3)
    v = v + 0.05 * np.random.default_rng(30544).standard_normal(v.shape)
    mesh = patching.from_arrays(v, f, creases={(1, 5): 10.0, (4, 5): 10.0, (5, 9): 10.0, (14, 15): 0.25},
                                interpolate_boundary=0)
    _same(mesh, "catmark")


def test_catmark_dart_normal_any_ring_order():
    """A Catmull-Clark dart of valence 4 (one infinitely sharp spoke): its subdominant
    eigenvalue 1/2 is double, and for some orders of the ring numpy's eig returns it as a
    conjugate pair (imaginary parts ~1e-16) whose vectors' real parts coincide, which once
    gave a zero normal.  Every rotation of every face's vertex list (other fans' start, other
    ring order) must give the same unit normals at every corner (the first hypothesis case of
    test_generated_catmark_local_equals_global that found it, seed 0, edge 9-10)."""
    v, f = _quad_grid(3)
    v = v + 0.05 * np.random.default_rng(0).standard_normal(v.shape)
    want = None
    for r in range(4):
        for order in (1, -1):
            faces = [q[r:] + q[:r] for q in f][::order]
            mesh = patching.from_arrays(v, faces, creases={(9, 10): 10.0}, interpolate_boundary=2)
            N = limit_masks(mesh, "catmark").corner_normals(mesh.vertices)
            assert np.abs(np.linalg.norm(N, axis=1) - 1).max() < 1e-12, (r, order)
            # per (vertex, face of the original list), independent of the numbering
            got = {}
            for j, q in enumerate(faces):
                orig = f.index(q[-r:] + q[:-r] if r else q)
                for c, x in enumerate(q):
                    got[(x, orig)] = N[mesh.face_offsets[j] + c]
            if want is None:
                want = got
            assert max(np.abs(got[k] - want[k]).max() for k in want) < 1e-12, (r, order)
