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
from patching.extraordinary.anchor_fairing import faired_anchors
from patching.extraordinary.auxiliary_points import anchor_matrix
from patching.bernstein import elevation_matrix_2d
from patching.extraordinary.extraction import cubic_extraction
from patching.topology.features import features
from patching.extraordinary.g1_patches import G1Assembly, RowMixer, _green_weights, _red_operator, ep_groups
from patching.operator.assembly import _sector_anchors
from patching.mesh.primitives import torus_grid
from patching.topology.tables import Topology
from tests.test_g1_patches import quad_mesh_with_eps, with_random_intervals
from tests.test_sharp_features import meridian_crease

# Sums of a few hundred products of O(1) weights, in another order than the fast path's.
RELATIVE = 1e-13


def reference_matrix(
    mesh, angles="optimized", anchors="eigen-polyhedron", force=(), interior="extraction", g1_steps=("red", "black", "green")
) -> np.ndarray:
    """Dense M of ``g1_solve="seed"``: every irregular face's 16 extraction rows degree-elevated
    one face at a time, the G1 steps (red, black, green, and blue for
    interior="cubic-isocurves") applied to those rows in turn (a target row = its weights times
    the previous step's source rows), the anchors replaced by their rows over control points.
    g1_steps=(): the degree-elevated extraction itself."""
    topo = Topology(mesh)
    feats = features(topo)
    spans = topo.face_spans
    has_patch = np.all(spans > 0, axis=1)
    has_patch[list(mesh.holes)] = False
    smooth = (feats.count == 0) & ~feats.corner
    eps = np.union1d(topo.extraordinary[smooth[topo.extraordinary]], np.asarray(force, dtype=np.int64))
    eps = np.union1d(eps, np.flatnonzero(feats.sector_vertex))
    is_ep = np.zeros(topo.n_vertices, dtype=bool)
    is_ep[eps] = True
    ext = cubic_extraction(topo, is_ep, sharp_edge=feats.sharp, corner_vertex=feats.corner)
    n = ext.n_points
    nets = ext.nets.toarray()
    irregular = is_ep[mesh.quads()].any(axis=1)
    cubic = [f for f in range(mesh.n_faces) if has_patch[f] and not irregular[f]]
    quintic = [f for f in range(mesh.n_faces) if has_patch[f] and irregular[f]]
    all_irregular = np.flatnonzero(irregular)
    face_row = np.full(mesh.n_faces, -1, dtype=np.int64)
    face_row[all_irregular] = 36 * np.arange(all_irregular.size)
    elevate = elevation_matrix_2d(3, 5)
    rows = np.vstack([elevate @ nets[16 * f : 16 * f + 16] for f in all_irregular] or [np.zeros((0, nets.shape[1]))])
    groups = ep_groups(topo, eps, feats)
    anchor_rows = np.zeros((ext.n_anchors, n))
    if quintic:
        g1 = G1Assembly(topo, groups, face_row, angles)
        for step in [getattr(g1, name) for name in g1_steps] + ([g1.blue] if interior == "cubic-isocurves" else []):
            mixer = RowMixer(rows.shape[0])
            step(mixer)
            new = rows.copy()
            for targets, _, _ in mixer.blocks:
                new[targets.ravel()] = 0.0
            for targets, sources, weights in mixer.blocks:
                for e in range(targets.shape[0]):
                    for t in range(targets.shape[1]):
                        new[targets[e, t]] += weights[e, t] @ rows[sources[e]]
            rows = new
        rule = "eigen-polyhedron" if anchors == "faired" else anchors
        smooth_groups = [g for g in groups if g.theta is None]
        anchor_rows = anchor_matrix(topo, smooth_groups, ext.anchor_column, n, rule=rule).toarray()
        anchor_rows += _sector_anchors(topo, feats, groups, ext.anchor_column, n).toarray()
    blocks = [nets[16 * f : 16 * f + 16] for f in cubic] + [rows[face_row[f] : face_row[f] + 36] for f in quintic]
    stacked = np.vstack(blocks)
    if anchors == "faired" and ext.n_anchors:
        import scipy.sparse as sp

        degrees = np.array([3] * len(cubic) + [5] * len(quintic))
        sets = [ext.anchor_column[g.h[e]] - n for g in groups if g.theta is None for e in range(len(g.vertices))]
        faired = faired_anchors(sp.csr_matrix(stacked), n, sp.csr_matrix(anchor_rows), sets, degrees, spans[cubic + quintic])
        anchor_rows = faired.toarray()
    return stacked[:, :n] + stacked[:, n:] @ anchor_rows


def with_hole_at_an_ep() -> patching.ControlMesh:
    """bipyramid-5 with random intervals and a hole on a face at a pole: an irregular face
    without a patch, whose rows the G1 steps around the pole still read."""
    mesh = with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, seed=2)
    topo = Topology(mesh)
    pole = mesh.n_vertices - 2
    hole = int(topo.face[topo.outgoing[pole]])
    faces = [list(mesh.face(f)) for f in range(mesh.n_faces)]
    return patching.from_arrays(mesh.vertices, faces, intervals=dict(mesh.intervals), holes=[hole], name="hole")


def boundary_ep(mode: int) -> patching.ControlMesh:
    """bipyramid-5 without one face at a pole: a boundary EP of valence 5 (a ring with a gap)."""
    base = quad_mesh_with_eps("bipyramid-5")
    topo = Topology(base)
    drop = int(topo.face[topo.outgoing[base.n_vertices - 2]])
    faces = [list(base.face(f)) for f in range(base.n_faces) if f != drop]
    return with_random_intervals(patching.from_arrays(base.vertices, faces, interpolate_boundary=mode, name="open"), 5.0, seed=7)


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


@pytest.mark.parametrize("case", list(CASES))
def test_fast_assembly_equals_the_dense_step_by_step_reference(case):
    mesh, options = CASES[case]()
    op = patching.build_operator(mesh, g1_solve="seed", **options)
    expected = reference_matrix(mesh, **options)
    assert op.matrix.shape == expected.shape
    scale = np.abs(expected).max()
    assert np.abs(op.matrix.toarray() - expected).max() <= RELATIVE * scale
    if case != "torus, no EP":
        assert op.groups[-1].degree == 5


@pytest.mark.parametrize("case", list(CASES))
def test_joint_solve_changes_only_the_patches_of_ep_clusters(case):
    """g1_solve="joint" (the default) only acts on clusters of EPs joined by spokes
    (``cluster_fairing``): M's rows of every other patch are the seed's (to round-off: the
    steps of the EPs outside clusters are composed as other sparse matrices)."""
    from tests.test_cluster_fairing import clusters_of

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
