"""Extraction with anchors: equals the textbook stencil extraction on regular meshes, and the
anchor rules are exact eliminations (anchors set to the regular face points give NURBS)."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings

from patching.extraordinary.extraction import FACE_POINT_POSITION, cubic_extraction
from patching.mesh.primitives import open_grid, torus_grid
from patching.topology.tables import Topology
from tests.reference_extraction import regular_extraction_weights, regular_stencils
from tests.strategies import torus_meshes

ROUND_OFF = 1e-13


def reference_rows(topo, faces):
    stencils, irregular = regular_stencils(topo, faces)
    assert irregular.size == 0
    w = regular_extraction_weights(stencils)  # (k, 4, 4, 4, 4)
    dense = np.zeros((len(faces), 4, 4, topo.n_vertices))
    for k in range(len(faces)):
        for a in range(4):
            for b in range(4):
                dense[k, :, :, stencils.stencil[k, a, b]] += w[k, :, :, a, b]
    return dense.reshape(len(faces) * 16, -1)


@settings(max_examples=30, deadline=None)
@given(torus_meshes(allow_zero=True))
def test_regular_meshes_match_the_stencil_reference(mesh):
    topo = Topology(mesh)
    ex = cubic_extraction(topo)
    faces = np.flatnonzero((topo.halfedge_interval[mesh.face_offsets[:-1]] > 0) & (topo.halfedge_interval[mesh.face_offsets[:-1] + 1] > 0))
    rows = (16 * faces[:, None] + np.arange(16)).ravel()
    np.testing.assert_allclose(ex.nets[rows].toarray(), reference_rows(topo, faces), atol=ROUND_OFF)


def test_clamped_grid_matches_the_stencil_reference():
    mesh = open_grid(7, 6, [0, 1, 2.5, 1, 4, 0], [0, 3, 1, 1, 0])
    topo = Topology(mesh)
    spans = np.stack([topo.halfedge_interval[mesh.face_offsets[:-1]], topo.halfedge_interval[mesh.face_offsets[:-1] + 1]], 1)
    faces = np.flatnonzero((spans > 0).all(axis=1))
    rows = (16 * faces[:, None] + np.arange(16)).ravel()
    np.testing.assert_allclose(cubic_extraction(topo).nets[rows].toarray(), reference_rows(topo, faces), atol=ROUND_OFF)


def _substitute_true_face_points(topo, forced):
    reg = cubic_extraction(topo)
    is_ep = np.zeros(topo.n_vertices, bool)
    is_ep[forced] = True
    ex = cubic_extraction(topo, is_ep)
    hs = np.flatnonzero(ex.anchor_column >= 0)
    f = topo.face[hs]
    k = hs - topo.mesh.face_offsets[f]
    pos = np.array([FACE_POINT_POSITION[kk] for kk in k])
    true_fp = reg.nets[16 * f + 4 * pos[:, 0] + pos[:, 1]]
    order = np.argsort(ex.anchor_column[hs])
    subst = sp.vstack([sp.identity(topo.n_vertices, format="csr"), true_fp[order]]).tocsr()
    return ex, reg, ex.nets @ subst


@pytest.mark.parametrize(
    "forced",
    [[10], [10, 11], [10, 17], [10, 11, 17, 18]],
    ids=["one", "two adjacent along v", "two adjacent along u", "four"],
)
def test_anchor_rules_are_exact_eliminations(forced):
    """Fig. 7a/b and the tensor rule: with anchors at their regular values, the NURBS."""
    rng = np.random.default_rng(1)
    topo = Topology(torus_grid(8, 7, rng.uniform(1, 20, 8), rng.uniform(1, 20, 7)))
    ex, reg, substituted = _substitute_true_face_points(topo, forced)
    assert ex.n_anchors == 4 * len(forced)
    np.testing.assert_allclose(substituted.toarray(), reg.nets.toarray(), atol=ROUND_OFF)
    np.testing.assert_allclose(np.asarray(ex.nets.sum(axis=1)).ravel(), 1.0, atol=ROUND_OFF)


def test_two_opposite_anchors_use_the_averaged_rule_of_eq_2():
    """Eq. (2) is the paper's choice, not an exact elimination: uniform intervals show it."""
    topo = Topology(torus_grid(8, 7))
    ex, reg, substituted = _substitute_true_face_points(topo, [10, 18])
    diff = np.abs((substituted - reg.nets).toarray()).max(axis=1)
    assert diff.max() > 1e-3  # differs somewhere ...
    np.testing.assert_allclose(np.asarray(ex.nets.sum(axis=1)).ravel(), 1.0, atol=ROUND_OFF)
    # ... and the face point next to both anchors is 1/4 A0 + 1/4 A1 + 1/2 P (uniform eq. 2).
    face = int(np.flatnonzero((topo.mesh.quads() == 10).any(1) & (topo.mesh.quads() == 18).any(1))[0])
    quad = topo.mesh.quads()[face]
    k = int(np.flatnonzero((quad != 10) & (quad != 18))[0])
    i, j = FACE_POINT_POSITION[k]
    row = ex.nets[16 * face + 4 * i + j].toarray().ravel()
    assert row[quad[k]] == pytest.approx(0.5)
    assert sorted(row[topo.n_vertices:][row[topo.n_vertices:] > 0]) == pytest.approx([0.25, 0.25])
