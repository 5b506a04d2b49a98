"""Invariance of the EP construction: affine invariance, relabelling, orientation
reversal, mirroring, and symmetry, on closed meshes with EPs of valence 3 to 6."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import patching
from patching.mesh.primitives import polycube
from tests.strategies import relabelled, reversed_orientation
from tests.helpers import quad_mesh_with_eps, with_random_intervals
from tests.helpers import dihedral

# Local solves (SVD, pseudo-inverse) at ratio <= 20: a few hundred ulps of the mesh size.
TOL = 1e-10

MESHES = {
    "cube": lambda: quad_mesh_with_eps("cube"),
    "l-shape": lambda: polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0)], 1),
    "bipyramid-5": lambda: quad_mesh_with_eps("bipyramid-5"),
    "bipyramid-6": lambda: quad_mesh_with_eps("bipyramid-6"),
}


def nets_by_face(surface):
    return {int(f): net for g in surface.groups for f, net in zip(g.faces, g.coefficients)}


def assert_same_patches(a, b, face_map=None, point_map=lambda x: x):
    """Every patch of b equals the patch of a on the corresponding face, up to re-parametrisation."""
    na, nb = nets_by_face(a), nets_by_face(b)
    assert len(na) == len(nb)
    for f, net in nb.items():
        ref = point_map(na[face_map[f] if face_map is not None else f])
        best = min(np.abs(t - net).max() for t in dihedral(ref) if t.shape == net.shape)
        assert best <= TOL * a.size, f"face {f}: {best:.3e}"


@settings(max_examples=12, deadline=None)
@given(st.sampled_from(sorted(MESHES)), st.floats(1.0, 20.0), st.integers(0, 2**31))
def test_rows_sum_to_one_and_affine_maps_commute(name, ratio, seed):
    mesh = with_random_intervals(MESHES[name](), ratio, seed)
    op = patching.build_operator(mesh)
    np.testing.assert_allclose(op.row_sums, 1.0, atol=1e-12)
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    p = mesh.vertices
    np.testing.assert_allclose(op.coefficients(2.5 * p @ q.T + 1.0), 2.5 * op.coefficients(p) @ q.T + 1.0, atol=1e-11)


@settings(max_examples=10, deadline=None)
@given(st.sampled_from(sorted(MESHES)), st.floats(1.0, 20.0), st.integers(0, 2**31))
def test_relabelling_gives_the_same_surface(name, ratio, seed):
    mesh = with_random_intervals(MESHES[name](), ratio, seed)
    new, _, fperm, _ = relabelled(mesh, seed)
    assert_same_patches(patching.build(mesh), patching.build(new), face_map=fperm)


@settings(max_examples=10, deadline=None)
@given(st.sampled_from(sorted(MESHES)), st.floats(1.0, 20.0), st.integers(0, 2**31))
def test_reversed_orientation_gives_the_same_surface(name, ratio, seed):
    mesh = with_random_intervals(MESHES[name](), ratio, seed)
    assert_same_patches(patching.build(mesh), patching.build(reversed_orientation(mesh)))


@settings(max_examples=10, deadline=None)
@given(st.sampled_from(sorted(MESHES)), st.floats(1.0, 20.0), st.integers(0, 2**31))
def test_mirrored_mesh_gives_the_mirrored_surface(name, ratio, seed):
    mesh = with_random_intervals(MESHES[name](), ratio, seed)
    flip = np.diag([-1.0, 1.0, 1.0])
    mirrored = reversed_orientation(mesh.with_positions(mesh.vertices @ flip))
    assert_same_patches(patching.build(mesh), patching.build(mirrored), point_map=lambda net: net @ flip)


def test_symmetric_mesh_with_symmetric_intervals_gives_a_symmetric_surface():
    """The L-shape is symmetric in the plane x = y; intervals chosen symmetric too."""
    mesh = polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 0, 0), (0, 2, 0)], 2)
    topo = patching.Topology(mesh)
    p = mesh.vertices[topo.edges]
    mid = p.mean(axis=1)
    rng = np.random.default_rng(0)
    # A strip's interval is a function of the set of its edges' midpoints, made symmetric
    # under x <-> y by sorting each midpoint's (x, y): mirror strips get the same value.
    key = np.round(np.stack([np.minimum(mid[:, 0], mid[:, 1]), np.maximum(mid[:, 0], mid[:, 1]), mid[:, 2]], 1), 6)
    strip_key: dict[int, tuple] = {}
    for e, k in enumerate(map(tuple, key)):
        s = int(topo.edge_strip[e])
        strip_key[s] = min(strip_key.get(s, k), k)
    table = {k: rng.uniform(1, 5) for k in sorted(set(strip_key.values()))}
    iv = {tuple(int(x) for x in topo.edges[e]): table[strip_key[int(topo.edge_strip[e])]] for e in range(len(p))}
    faces = [list(mesh.face(f)) for f in range(mesh.n_faces)]
    mesh = patching.from_arrays(mesh.vertices, faces, intervals={k: v for k, v in iv.items()}, name="sym")
    swap = np.array([[0.0, 1, 0], [1, 0, 0], [0, 0, 1]])
    surface = patching.build(mesh)
    assert_same_patches(surface, patching.build(reversed_orientation(mesh.with_positions(mesh.vertices @ swap))), point_map=lambda net: net @ swap)
    # the mirrored mesh is the same mesh: so the surface maps onto itself
    points = np.concatenate([net.reshape(-1, 3) for net in nets_by_face(surface).values()])
    mirrored = points @ swap
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(points).query(mirrored)
    assert dist.max() <= TOL * surface.size


def cube_with_a_hole():
    """The cube (one cluster of eight valence-3 EPs) with face 0 a hole: four of the
    cluster's EPs have the hole in their ring."""
    return dataclasses.replace(quad_mesh_with_eps("cube"), holes=frozenset({0}))


#: Meshes whose EPs form clusters (joined by spokes), so that the joint G1 solve of
#: cluster_fairing (the default) sets their G1 coefficients.
CLUSTER_MESHES = {
    "cube": lambda: quad_mesh_with_eps("cube"),
    "cube with a hole": cube_with_a_hole,
    "l-shape": MESHES["l-shape"],
    "polycube-4": lambda: polycube([(0, 0, 0), (1, 0, 0), (1, 1, 0), (1, 1, 1)], 1),
}


@pytest.mark.parametrize("name", sorted(CLUSTER_MESHES))
def test_the_joint_solve_of_clusters_is_invariant(name):
    """Relabelling, reversed orientation and mirroring on meshes with EP clusters, at the
    interval ratio where the joint and the seed's solves differ most (20)."""
    from patching.extraordinary import cluster_fairing
    from patching.topology.features import features
    from patching.extraordinary.g1_patches import ep_groups

    mesh = with_random_intervals(CLUSTER_MESHES[name](), 20.0, seed=3)
    topo = patching.Topology(mesh)
    assert cluster_fairing.ep_clusters(ep_groups(topo, topo.extraordinary, features(topo)), topo)
    surface = patching.build(mesh)
    new, _, fperm, _ = relabelled(mesh, 3)
    assert_same_patches(surface, patching.build(new), face_map=fperm)
    assert_same_patches(surface, patching.build(reversed_orientation(mesh)))
    flip = np.diag([-1.0, 1.0, 1.0])
    mirrored = reversed_orientation(mesh.with_positions(mesh.vertices @ flip))
    assert_same_patches(surface, patching.build(mirrored), point_map=lambda net: net @ flip)
