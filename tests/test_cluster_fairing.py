"""The joint G1 solve of EP clusters (``cluster_fairing``): which EPs it takes, that its
solution is the minimiser it claims to be, that it keeps G1 and affine invariance, and that it
removes the folds the seed's per-EP steps make on catmark_lefthanded."""

import dataclasses

import numpy as np
import pytest

import patching
from patching.extraordinary import cluster_fairing
from patching.extraordinary.anchor_fairing import thin_plate_matrices
from patching.evaluation.sampling import normal_turning
from patching.subdivision.catmark import subdivide
from patching.topology.tables import Topology
from tests.conftest import shape_files
from tests.helpers import quad_mesh_with_eps, shared_edge_normal_jumps, with_random_intervals
from tests.helpers import boundary_ep, reference_matrix
from tests.helpers import clusters_of

CUBE = quad_mesh_with_eps("cube")


def test_clusters_are_the_components_of_ep_ep_spokes():
    assert clusters_of(CUBE) == [list(range(8))]  # every cube vertex is a valence-3 EP
    assert clusters_of(CUBE, max_eps=7) == []  # too large: the per-EP steps
    # one subdivision step leaves no two EPs adjacent
    assert clusters_of(subdivide(CUBE, 1)) == []


def joint_objective(mesh, seed: int):
    """(J, c_joint, c_seed): the objective the joint solve minimises (module docstring),
    assembled here from its definition, not from the module's bookkeeping: the unknowns are the
    coefficients the joint and the seed's steps set differently (random intervals: no
    coincidence), one per distinct row of M (a coefficient shared by two patches has one row
    per patch, equal); u_hat their degree-elevated extraction."""
    joint = patching.build_operator(mesh).matrix.toarray()
    seed_m = patching.build_operator(mesh, g1_solve="seed").matrix.toarray()
    extraction = reference_matrix(mesh, g1_steps=())
    unknown = np.flatnonzero(np.abs(joint - seed_m).max(axis=1) > 1e-12)
    _, first, label = np.unique(np.round(joint[unknown], 10), axis=0, return_index=True, return_inverse=True)
    label = label.ravel()
    iss, ist, itt = thin_plate_matrices(5)
    q = iss + 2.0 * ist + itt
    diag = np.bincount(label, weights=np.diag(q)[unknown % 36])
    mu = cluster_fairing.MU * diag.mean()
    points = np.random.default_rng(seed).normal(size=(mesh.n_vertices, 3))
    target = extraction[unknown[first]] @ points

    def objective(c):
        nets = c.reshape(-1, 36, 3)
        energy = np.einsum("fic,ij,fjc->", nets, q, nets)
        return energy + mu * np.sum((c[unknown[first]] - target) ** 2)

    return objective, joint @ points, seed_m @ points


def creased_cube(edges) -> patching.ControlMesh:
    return patching.from_arrays(CUBE.vertices, CUBE.quads(), creases={e: 10.0 for e in edges}, name="creased")


#: Meshes with clusters: smooth rings; a crease (its spokes pinned to the crease curve, sector
#: angles); a boundary fan (a ring with a gap).  Not a dart between two EPs (the cube with one
#: sharp edge): there the seed's black step sets P30 from both ends at once, so its curve is
#: not quartic and d below is not feasible; the joint solve keeps it quartic.
CLUSTER_MESHES = {
    "cube": lambda: CUBE,
    "cube with a creased corner": lambda: creased_cube([(0, 1), (1, 3)]),
    "bipyramid-5 with a boundary EP": lambda: boundary_ep(1),
}


@pytest.mark.parametrize("case", list(CLUSTER_MESHES))
@pytest.mark.parametrize("seed", range(3))
def test_the_joint_solution_minimises_its_objective(seed, case):
    """Along the feasible direction d = (seed's solution - joint's), which changes only the
    unknowns and keeps every G1 equation, the quadratic J has no linear term at the joint
    solution (J(c + d) = J(c - d)), and the seed's solution costs more."""
    mesh = with_random_intervals(CLUSTER_MESHES[case](), 5.0, seed=seed)
    assert clusters_of(mesh)
    objective, c_joint, c_seed = joint_objective(mesh, seed)
    d = c_seed - c_joint
    assert np.abs(d).max() > 1e-3  # the two solves differ
    plus, minus, at = objective(c_joint + d), objective(c_joint - d), objective(c_joint)
    assert abs(plus - minus) <= 1e-9 * (plus + minus - 2 * at)
    assert at < objective(c_seed)


def test_a_hole_in_a_cluster_has_no_energy(monkeypatch):
    """A hole face has rows (the G1 equations of its spokes read them) but no surface: its
    energy must not shape the cluster's patches, so no unknown may depend on the hole's four
    inner coefficients, which only its own energy reads.  Before, they weighed up to ~0.1."""
    mesh = dataclasses.replace(with_random_intervals(CUBE, 5.0, seed=1), holes=frozenset({0}))
    solved, rows = [], {}
    solve = cluster_fairing.ClusterFairing.solve

    def spy(self, cluster):
        rows["hole"] = self.g1.face_row[0] + np.array([14, 15, 20, 21])  # net[2..3, 2..3]
        out = solve(self, cluster)
        solved.append(out)
        return out

    monkeypatch.setattr(cluster_fairing.ClusterFairing, "solve", spy)
    patching.build_operator(mesh)
    (_, sources, weights), = solved
    inner = np.isin(sources, rows["hole"])
    assert inner.sum() == 4
    assert np.abs(weights[:, inner]).max() == 0.0


@pytest.mark.parametrize("seed", range(4))
def test_joint_solve_keeps_g1_and_affine_invariance(seed):
    mesh = with_random_intervals(CUBE, 20.0, seed=seed)
    op = patching.build_operator(mesh)
    np.testing.assert_allclose(op.row_sums, 1.0, rtol=0, atol=1e-13)
    angle, gap = shared_edge_normal_jumps(op.evaluate(mesh.vertices))
    assert angle <= 1e-6 and gap <= 1e-12


#: Every cube vertex a dart: the four x-parallel edges sharp.  Without them the G1 spokes join
#: only the two x = const faces' EPs, so only the dart spokes tie the two clusters together.
FOUR_DARTS = [(0, 4), (1, 5), (2, 6), (3, 7)]
DART_MESHES = {"cube with two darts": lambda: creased_cube([(0, 1)]), "cube with eight darts": lambda: creased_cube(FOUR_DARTS)}


def test_a_dart_spoke_between_two_eps_joins_their_clusters():
    """Both ends of a dart's sharp spoke set its inner coefficients (P10..P30 of their own
    frame), so its two EPs are solved together; in two clusters both solves set the middle
    rows and the mixing summed them (row sums 2)."""
    assert clusters_of(creased_cube(FOUR_DARTS)) == [list(range(8))]


@pytest.mark.parametrize("case", list(CLUSTER_MESHES) + list(DART_MESHES))
@pytest.mark.parametrize("seed", range(2))
def test_clusters_with_sharp_spokes_stay_g1_across_smooth_edges(case, seed):
    """Clusters holding crease, dart and boundary EPs: G1 across every edge that is not sharp,
    C0 everywhere (the sharp edges' own jumps are the creases), rows of M summing to 1."""
    from patching.topology.features import sharp_edges

    base = {**CLUSTER_MESHES, **DART_MESHES}[case]()
    mesh = with_random_intervals(base, 20.0, seed=seed)
    assert clusters_of(mesh)
    op = patching.build_operator(mesh)
    np.testing.assert_allclose(op.row_sums, 1.0, rtol=0, atol=1e-13)
    surface = op.evaluate(mesh.vertices)
    topo = Topology(mesh)
    faces = np.concatenate([g.faces for g in surface.groups])
    # side k of a patch runs along its face's half-edge k
    on_sharp = sharp_edges(topo)[topo.edge_of[mesh.face_offsets[faces][:, None] + np.arange(4)]]
    angle, gap = shared_edge_normal_jumps(surface, skip=set(surface.topology.side_edge[on_sharp].tolist()))
    assert on_sharp.any() == (case != "cube")
    assert angle <= 1e-6 and gap <= 1e-12


@pytest.mark.parametrize("cap", [("MAX_CLUSTER_EPS", 7), ("MAX_CLUSTER_FACES", 5)])
def test_a_cluster_over_the_cap_takes_the_seed_steps(monkeypatch, cap):
    """The cube's cluster has 8 EPs and 6 faces."""
    mesh = with_random_intervals(CUBE, 5.0, seed=1)
    monkeypatch.setattr(cluster_fairing, *cap)
    capped = patching.build_operator(mesh).matrix
    seed = patching.build_operator(mesh, g1_solve="seed").matrix
    assert abs(capped - seed).max() == 0.0


def test_joint_solve_removes_the_lefthanded_folds():
    """catmark_lefthanded with random intervals (ratio 5): 17 folded patches over seeds 0-20
    with the seed's steps, none with the joint solve (measured).  Here the draw
    tests/test_shapes.py builds (seed 18), which folds three patches with the seed's steps."""
    shapes = [p for p in shape_files("catmark_") if p.stem == "catmark_lefthanded"]
    if not shapes:
        pytest.skip("../shared/opensubdiv-shapes is absent")
    mesh = with_random_intervals(patching.read_mesh(shapes[0]), 5.0, seed=len(shapes[0].stem))
    _, seed_turning = normal_turning(patching.build(mesh, g1_solve="seed"), samples=17)
    _, joint_turning = normal_turning(patching.build(mesh), samples=17)
    assert seed_turning.min() < -0.5
    assert joint_turning.min() > 0.5


@pytest.mark.parametrize("unit", [1e-6, 1e6])
def test_the_joint_solve_does_not_depend_on_the_unit_of_the_intervals(unit):
    """Multiplying every interval by the same factor leaves the surface unchanged (the
    connecting functions see ratios only).  On the L-shaped polycube (clusters of valence-3
    and -5 EPs with spokes to regular vertices) intervals of 1e6 once dropped the fifth
    differences as dependent rows, intervals of 1e-6 the G1 equations (normal jumps of 13 and
    113 degrees)."""
    from patching.mesh.primitives import polycube

    mesh = with_random_intervals(polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0)], 1), 20.0, seed=0)
    assert clusters_of(mesh)
    faces = [list(mesh.face(f)) for f in range(mesh.n_faces)]
    scaled = patching.from_arrays(mesh.vertices, faces, intervals={k: unit * d for k, d in mesh.intervals.items()})
    surface, reference = patching.build(scaled), patching.build(mesh)
    angle, _ = shared_edge_normal_jumps(surface)
    assert angle <= 1e-6
    # the same local solves on rows scaled by unit^2: round-off of the dense solve (measured 3e-10)
    for a, b in zip(surface.groups, reference.groups):
        np.testing.assert_allclose(a.coefficients, b.coefficients, rtol=0, atol=1e-9 * reference.size)


def test_a_row_set_by_two_clusters_is_refused_not_summed(monkeypatch):
    """The guard in ClusterFairing.joint: split the cube's one cluster in two halves that share
    spokes (as ep_clusters did across darts before 7f0d700) and the build stops instead of
    summing two rules into one row."""
    from patching.operator import assembly as operator

    def halves(groups, topo, max_eps=None):
        (whole,) = cluster_fairing.ep_clusters(groups, topo, max_eps)
        return [whole[:4], whole[4:]]

    monkeypatch.setattr(operator, "ep_clusters", halves)
    with pytest.raises(AssertionError, match="set by two clusters"):
        patching.build_operator(with_random_intervals(CUBE, 5.0, seed=0))
