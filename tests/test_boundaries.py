"""Open boundaries as creases (docs/input.md: interpolateboundary 1 by default)."""

import numpy as np
import pytest

import patching
from patching.mesh.primitives import open_grid
from patching.subdivision import limit_points, subdivide
from tests.helpers import distances_to_surface
from tests.helpers import shared_edge_normal_jumps


def jittered_grid(m, n, mode, seed=0, u=None, v=None):
    grid = open_grid(m, n, u, v)
    rng = np.random.default_rng(seed)
    points = grid.vertices + rng.normal(scale=0.1, size=grid.vertices.shape)
    return patching.from_arrays(points, grid.quads(), intervals=dict(grid.intervals), interpolate_boundary=mode, name="grid")


def test_uniform_open_grid_is_catmull_clarks_limit_with_interpolated_corners():
    mesh = jittered_grid(7, 6, mode=1)
    surface = patching.build(mesh)
    assert surface.n_patches == 6 * 5  # every face, boundary faces included
    refined = subdivide(mesh, 3, rules="opensubdiv")
    worst = distances_to_surface(surface, limit_points(refined)).max()
    assert worst <= 1e-12 * surface.size
    # corners interpolated: the patch corners at the grid corners are the control points
    corners = [0, 5, 36, 41]
    pts = np.concatenate([net[[0, -1]][:, [0, -1]].reshape(-1, 3) for _, _, _, net in surface.patches()])
    for c in corners:
        assert np.min(np.linalg.norm(pts - mesh.vertices[c], axis=1)) <= 1e-14 * surface.size


@pytest.mark.parametrize("seed", [1, 2])
def test_non_uniform_open_grid_is_a_valid_g1_shell(seed):
    from export import check_continuity, to_shape

    rng = np.random.default_rng(seed)
    mesh = jittered_grid(7, 6, 1, seed, rng.uniform(1, 20, 6), rng.uniform(1, 20, 5))
    surface = patching.build(mesh)
    angle, gap = shared_edge_normal_jumps(surface)
    assert angle <= 1e-7 and gap <= 1e-12 * surface.size
    report = check_continuity(to_shape(surface))
    assert report.valid and report.n_solids == 0 and report.n_shells == 1
    assert report.n_free_edges == 2 * (6 + 5)


@pytest.mark.parametrize("ratio", [1.0, 6.0])
def test_mode_2_smooths_the_corners_the_boundary_is_one_closed_bspline(ratio):
    """interpolateboundary 2: a boundary vertex with one face is a crease vertex, not a corner,
    so the whole boundary is one closed cubic B-spline of the boundary polygon (OpenSubdiv's
    boundary curve in that mode), and the patches are G1 inside."""
    from tests.edge_checks import crease_deviation, edge_jumps

    from tests.helpers import with_random_intervals

    mesh = with_random_intervals(jittered_grid(5, 5, mode=2), ratio, seed=4)
    surface = patching.build(mesh)
    _, gaps, angles, sharp = edge_jumps(mesh, surface)
    assert angles[~sharp].max() <= 1e-7 and gaps.max() <= 1e-12 * surface.size
    assert crease_deviation(mesh, surface) <= 1e-12 * surface.size
    corner = surface.groups[0].coefficients[0][0, 0]
    assert np.linalg.norm(corner - mesh.vertices[0]) > 1e-3 * surface.size  # not interpolated


def test_hole_faces_give_no_patch_and_leave_their_neighbours_unchanged():
    """OpenSubdiv's `t hole`: the face is not drawn, the rules around it do not change."""
    from tests.helpers import quad_mesh_with_eps, with_random_intervals

    base = with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, 2)
    faces = [list(base.face(f)) for f in range(base.n_faces)]
    holed = patching.from_arrays(base.vertices, faces, intervals=dict(base.intervals), holes=[0, 7], name="holed")
    full, part = patching.build(base), patching.build(holed)
    assert part.n_patches == full.n_patches - 2
    nets = {f: net for _, _, f, net in full.patches()}
    for _, _, f, net in part.patches():
        np.testing.assert_array_equal(net, nets[f])
    assert not part.topology.is_closed and part.topology.edge_use_count.min() == 1
    angle, gap = shared_edge_normal_jumps(part)
    assert angle <= 1e-7 and gap <= 1e-12 * part.size


@pytest.mark.parametrize("ratio", [1.0, 6.0])
def test_mode_0_drops_the_faces_at_the_boundary_and_keeps_the_rest(ratio):
    """interpolateboundary 0 (OpenSubdiv's "none"): faces with a vertex on the open boundary
    give no surface; every other face keeps exactly the patch it has under mode 1 (its
    stencil never reaches the boundary rules), so the surface is the non-uniform bicubic
    B-spline of the inner control points, a G1 shell."""
    from tests.helpers import with_random_intervals

    one = with_random_intervals(jittered_grid(8, 7, mode=1), ratio, seed=5)
    zero = patching.from_arrays(one.vertices, one.quads(), intervals=dict(one.intervals), interpolate_boundary=0, name="none")
    full, inner = patching.build(one), patching.build(zero)
    assert inner.n_patches == (8 - 3) * (7 - 3)
    nets = {f: net for _, _, f, net in full.patches()}
    for _, _, f, net in inner.patches():
        np.testing.assert_array_equal(net, nets[f])
    angle, gap = shared_edge_normal_jumps(inner)
    assert angle <= 1e-7 and gap <= 1e-12 * inner.size


def test_mode_0_with_an_extraordinary_point_next_to_the_boundary():
    """bipyramid-5 without one face at a pole, mode 0: the faces around the open pole give no
    surface; the rest is G1, and faces far from the opening equal the closed mesh's."""
    from tests.helpers import quad_mesh_with_eps, with_random_intervals

    base = with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, seed=3)
    topo = patching.Topology(base)
    pole = base.n_vertices - 2
    drop = int(topo.face[topo.outgoing[pole]])
    faces = [list(base.face(f)) for f in range(base.n_faces) if f != drop]
    mesh = patching.from_arrays(base.vertices, faces, intervals=dict(base.intervals), interpolate_boundary=0, name="open")
    surface = patching.build(mesh)
    open_topo = patching.Topology(mesh)
    touching = {int(f) for f in open_topo.face[open_topo.vertex_is_boundary[open_topo.origin]]}
    assert {f for _, _, f, _ in surface.patches()} == set(range(mesh.n_faces)) - touching
    angle, gap = shared_edge_normal_jumps(surface)
    assert angle <= 1e-7 and gap <= 1e-12 * surface.size
