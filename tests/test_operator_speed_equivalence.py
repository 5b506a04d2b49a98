"""The fast assembly of M (``operator.build_operator``: one row space for cubic and quintic rows,
the G1 steps' mixers written straight into CSR and composed before they meet the extraction,
anchors folded in by one product with [I; anchors]) against a slow, dense reference that
applies the same steps one at a time to the rows, as the module docstring of ``g1_patches``
describes them.  Both read the same local solves (``G1Assembly``), the same extraction and the
same anchors; what is compared is the bookkeeping: which rows, in which order, composed how.

Also: a warm build solves nothing again (the per-configuration caches hit), which is what made
warm builds of EP-rich meshes slow when a NaN in a cache key never matched."""

import numpy as np
import pytest

import patching
from patching.extraordinary import g1_patches
from patching.extraordinary.g1_patches import _green_weights, _red_operator
from patching.mesh.primitives import torus_grid
from patching.topology.tables import Topology
from tests.helpers import quad_mesh_with_eps, with_random_intervals
from tests.helpers import meridian_crease
from tests.helpers import boundary_ep, reference_matrix

# Sums of a few hundred products of O(1) weights, in another order than the fast path's.
RELATIVE = 1e-13
# The same through the monotone-spoke QP (its amplification of round-off, measured below 1e3).
MONOTONE_RELATIVE = 1e-11


def with_hole_at_an_ep() -> patching.ControlMesh:
    """bipyramid-5 with random intervals and a hole on a face at a pole: an irregular face
    without a patch, whose rows the G1 steps around the pole still read."""
    mesh = with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, seed=2)
    topo = Topology(mesh)
    pole = mesh.n_vertices - 2
    hole = int(topo.face[topo.outgoing[pole]])
    faces = [list(mesh.face(f)) for f in range(mesh.n_faces)]
    return patching.from_arrays(mesh.vertices, faces, intervals=dict(mesh.intervals), holes=[hole], name="hole")


CASES = {
    "bipyramid-5, intervals up to 5": lambda: (with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, seed=1), {}),
    "bipyramid-7, uniform angles": lambda: (with_random_intervals(quad_mesh_with_eps("bipyramid-7"), 20.0, seed=3), {"angles": "uniform"}),
    "cube: four EPs a face": lambda: (with_random_intervals(quad_mesh_with_eps("cube"), 5.0, seed=4), {}),
    "cube, extraction anchors": lambda: (with_random_intervals(quad_mesh_with_eps("cube"), 5.0, seed=5), {"anchors": "extraction"}),
    "bipyramid-5, the seed's blue rule": lambda: (with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, seed=1), {"interior": "cubic-isocurves"}),
    "bipyramid-5, faired anchors": lambda: (with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, seed=6), {"anchors": "faired"}),
    "crease through two EPs": lambda: (meridian_crease(6, 0, 2, 5.0, seed=8), {}),
    "crease with a corner tag at a pole": lambda: (meridian_crease(5, 0, 2, 5.0, seed=9, corners={0: np.inf}), {}),
    "boundary EP, interpolateboundary 1": lambda: (boundary_ep(1), {}),
    "boundary EP, interpolateboundary 2": lambda: (boundary_ep(2), {}),
    "hole at an EP": lambda: (with_hole_at_an_ep(), {}),
    "torus, no EP": lambda: (torus_grid(6, 5, [1, 2, 3, 1, 5, 1], [1, 4, 1, 2, 1]), {}),
}


@pytest.mark.parametrize("monotone", [False, True], ids=["plain-red", "monotone-spokes"])
@pytest.mark.parametrize("case", list(CASES))
def test_fast_assembly_equals_the_dense_step_by_step_reference(case, monotone, monkeypatch):
    """The bookkeeping to 1e-13 with the plain red solve; with the monotone-spoke step (the
    default) to MONOTONE_RELATIVE: that step's active-set QP reads the blending functions
    before the G1 steps, which the two paths sum in other orders, and it amplifies their
    1e-16 differences by up to ~1e3 (bipyramid-5: 1.4e-13 of 0.63)."""
    monkeypatch.setattr(g1_patches, "MONOTONE_SPOKES", monotone)
    mesh, options = CASES[case]()
    op = patching.build_operator(mesh, g1_solve="seed", **options)
    expected = reference_matrix(mesh, **options)
    assert op.matrix.shape == expected.shape
    scale = np.abs(expected).max()
    assert np.abs(op.matrix.toarray() - expected).max() <= (MONOTONE_RELATIVE if monotone else RELATIVE) * scale
    if case != "torus, no EP":
        assert op.groups[-1].degree == 5


@pytest.mark.parametrize("case", list(CASES))
def test_joint_solve_changes_only_the_patches_of_ep_clusters(case):
    """g1_solve="joint" (the default) only acts on clusters of EPs joined by spokes
    (``cluster_fairing``): M's rows of every other patch are the seed's (to round-off: the
    steps of the EPs outside clusters are composed as other sparse matrices)."""
    from tests.helpers import clusters_of

    mesh, options = CASES[case]()
    op = patching.build_operator(mesh, **options)
    seed = patching.build_operator(mesh, g1_solve="seed", **options)
    changed = np.flatnonzero(abs(op.matrix - seed.matrix).max(axis=1).toarray().ravel() > RELATIVE)
    cluster_eps = [v for c in clusters_of(mesh) for v in c]
    patch_faces = np.concatenate([g.faces for g in op.groups])
    rows_per_patch = np.concatenate([np.full(len(g.faces), (g.degree + 1) ** 2) for g in op.groups])
    patch_of_row = np.repeat(np.arange(patch_faces.size), rows_per_patch)
    touches = np.isin(mesh.quads()[patch_faces], cluster_eps).any(axis=1)
    assert touches[patch_of_row[changed]].all()
    assert (changed.size > 0) == bool(cluster_eps)


def test_forced_valence_4_ep_equals_the_reference():
    mesh = torus_grid(8, 7, [1, 2, 1, 3, 1, 1, 2, 1], [1, 1, 2, 1, 4, 1, 1])
    op = patching.build_operator(mesh, force_extraordinary=[17], anchors="extraction")
    expected = reference_matrix(mesh, anchors="extraction", force=[17])
    assert np.abs(op.matrix.toarray() - expected).max() <= RELATIVE * np.abs(expected).max()


def test_a_warm_build_solves_no_configuration_again():
    """The local solves are cached by configuration (by configuration); keys holding "no far
    EP" (NaN) must hit too, or every build re-solves every EP."""
    mesh = with_random_intervals(quad_mesh_with_eps("bipyramid-6"), 5.0, seed=11)
    patching.build_operator(mesh)
    red, green = _red_operator.cache_info().misses, _green_weights.cache_info().misses
    patching.build_operator(mesh)
    assert _red_operator.cache_info().misses == red
    assert _green_weights.cache_info().misses == green
