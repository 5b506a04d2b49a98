"""The sparse operator M: affine invariance, relabelling and orientation invariance, zero spans."""

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from patching import build_operator
from patching.mesh.primitives import open_grid, torus_grid
from tests.strategies import relabelled, reversed_orientation, torus_meshes
from tests.helpers import dihedral

# Affine combinations of O(1) numbers: round-off is a few ulps times the number of terms (16).
ROUND_OFF = 1e-13


@settings(max_examples=40, deadline=None)
@given(torus_meshes(allow_zero=True))
def test_rows_sum_to_one(mesh):
    op = build_operator(mesh)
    assert op.matrix.shape[1] == mesh.n_vertices
    np.testing.assert_allclose(op.row_sums, 1.0, atol=ROUND_OFF)
    assert (op.matrix.data >= -ROUND_OFF).all(), "B-spline to Bezier weights are non-negative"


@settings(max_examples=25, deadline=None)
@given(torus_meshes(), st.floats(-10, 10), st.floats(0.1, 10), st.integers(0, 2**31))
def test_affine_maps_commute_with_the_construction(mesh, shift, scale, seed):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    op = build_operator(mesh)
    p = mesh.vertices
    moved = op.coefficients(scale * p @ q.T + shift)
    expected = scale * op.coefficients(p) @ q.T + shift
    np.testing.assert_allclose(moved, expected, atol=ROUND_OFF * 10 * (1 + abs(shift) + scale))


@settings(max_examples=20, deadline=None)
@given(torus_meshes(ratio=5.0), st.integers(0, 2**31))
def test_relabelling_vertices_and_faces_gives_the_same_patches(mesh, seed):
    base = build_operator(mesh).evaluate(mesh.vertices)
    new_mesh, _, fperm, _ = relabelled(mesh, seed)
    new = build_operator(new_mesh).evaluate(new_mesh.vertices)
    old_net = {int(f): net for f, net in zip(base.groups[0].faces, base.groups[0].coefficients)}
    for k, net in zip(new.groups[0].faces, new.groups[0].coefficients):
        ref = old_net[int(fperm[k])]
        assert min(np.abs(t - net).max() for t in dihedral(ref)) < ROUND_OFF * 10


@settings(max_examples=20, deadline=None)
@given(torus_meshes(ratio=5.0))
def test_reversed_orientation_transposes_every_patch(mesh):
    a = build_operator(mesh).evaluate(mesh.vertices)
    rev = reversed_orientation(mesh)
    b = build_operator(rev).evaluate(rev.vertices)
    np.testing.assert_array_equal(a.groups[0].faces, b.groups[0].faces)
    np.testing.assert_allclose(b.groups[0].coefficients, a.groups[0].coefficients.transpose(0, 2, 1, 3), atol=ROUND_OFF)


def test_moving_points_is_one_sparse_product():
    mesh = torus_grid(8, 6, [1, 2, 3, 1, 5, 1, 2, 1], [1, 1, 4, 1, 2, 1])
    op = build_operator(mesh)
    rng = np.random.default_rng(1)
    p = rng.normal(size=mesh.vertices.shape)
    np.testing.assert_array_equal(op.coefficients(p), op.matrix @ p)
    assert np.allclose(build_operator(mesh.with_positions(p)).matrix.toarray(), op.matrix.toarray())


def test_zero_strip_gives_no_patches_and_stays_closed():
    mesh = torus_grid(7, 5, [1, 0, 2, 1, 1, 3, 1], [1, 1, 0, 2, 1])
    op = build_operator(mesh)
    faces = op.groups[0].faces
    assert len(faces) == 6 * 4  # one u strip and one v strip of zero intervals dropped
    quads = mesh.quads()
    # Face (a, b) has id a * 5 + b: no patch in column a = 1 nor row b = 2.
    assert not np.isin(faces // 5, [1]).any() and not np.isin(faces % 5, [2]).any()
    assert op.topology.is_closed
    surf = op.evaluate(mesh.vertices)
    # Patches on both sides of the collapsed strip share their boundary curves exactly.
    nets = {int(f): n for f, n in zip(surf.groups[0].faces, surf.groups[0].coefficients)}
    left, right = nets[0 * 5 + 0], nets[2 * 5 + 0]  # columns 0 and 2 around the zero column 1
    np.testing.assert_allclose(left[3, :], right[0, :], atol=ROUND_OFF)
    assert quads.shape == (35, 4)


def test_clamped_open_grid_is_an_open_shell_topology():
    mesh = open_grid(7, 6, [0, 1, 2, 1, 1, 0], [0, 1, 3, 1, 0])
    op = build_operator(mesh)
    assert len(op.groups[0].faces) == 4 * 3
    assert not op.topology.is_closed
    assert op.topology.edge_use_count.min() == 1


def test_import_patching_loads_no_opencascade():
    code = "import sys, patching, patching.operator.assembly; print(sorted(m for m in sys.modules if m.split('.')[0] in ('OCP', 'OCC', 'cadquery', 'build123d')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_three_zero_intervals_in_a_row_are_refused():
    """Found by tests/test_fuzz_input.py: an interior knot of multiplicity 4 tears the surface,
    which left OpenCASCADE an invalid B-rep; now a one-line KnotError."""
    from patching import KnotError

    with pytest.raises(KnotError, match="three zero knot intervals in a row"):
        build_operator(torus_grid(5, 4, [0, 0, 1, 1, 0], None))
    build_operator(torus_grid(5, 4, [0, 0, 1, 1, 1], None))  # multiplicity 3 (C0) is fine
