"""Semi-sharp creases: ceil(s) steps of the sharp subdivision rules, then patches."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import patching
from patching.evaluation.sampling import sample_surface
from tests.helpers import shared_edge_normal_jumps

CUBE_V = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
CUBE_F = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
CUBE_EDGES = sorted({tuple(sorted((q[i], q[(i + 1) % 4]))) for q in CUBE_F for i in range(4)})


def creased_cube(s: float, intervals=None) -> patching.ControlMesh:
    return patching.from_arrays(CUBE_V, CUBE_F, creases={e: s for e in CUBE_EDGES}, intervals=intervals, name="cube")


def distance_to_cube_edge(surface) -> float:
    """Distance from the middle of a cube edge to the surface (dense samples)."""
    _, points, _ = sample_surface(surface, 33)
    return float(cKDTree(points.reshape(-1, 3)).query([[0.5, 0.0, 0.0]])[0][0])


def test_sharper_creases_come_closer_to_the_cube_and_fractions_lie_between():
    d = {s: distance_to_cube_edge(patching.build(creased_cube(s))) for s in (0.0, 1.0, 1.5, 2.0, 2.5, 3.0)}
    assert d[0.0] > d[1.0] > d[2.0] > d[3.0] > 0
    assert d[1.0] > d[1.5] > d[2.0] and d[2.0] > d[2.5] > d[3.0]


@pytest.mark.parametrize("s", [1.0, 2.5])
def test_semi_sharp_cube_is_a_g1_solid_acting_on_the_original_points(s):
    mesh = creased_cube(s, intervals={(0, 1): 2.0})
    op = patching.build_operator(mesh)
    assert op.matrix.shape[1] == 8
    np.testing.assert_allclose(op.row_sums, 1.0, atol=1e-12)
    surface = op.evaluate(mesh.vertices)
    assert surface.topology.is_closed
    angle, gap = shared_edge_normal_jumps(surface)
    assert angle <= 1e-7 and gap <= 1e-12 * surface.size


def test_infinitely_sharp_cube_is_where_the_semi_sharp_ones_converge():
    """Sharpness 10: every vertex a corner with single-face sectors, the patches are the cube's
    squares (tests/test_sharp_features.py), so the edge midpoint lies on the surface; the
    semi-sharp cubes approach it monotonically."""
    sharp = distance_to_cube_edge(patching.build(creased_cube(10.0)))
    assert sharp <= 1e-12
    d = [distance_to_cube_edge(patching.build(creased_cube(s))) for s in (1.0, 2.0, 3.0)]
    assert d[0] > d[1] > d[2] > sharp


def test_deep_semi_sharp_creases_are_refined_adaptively():
    """Sharpness 6.5 needs 7 steps, more than the 6 done globally, so
    the refinement is adaptive (patching.operator.adaptive): patches of several levels meeting at
    T-junctions, the cube's edges closer still than at sharpness 3, a valid G1 solid."""
    from export import check_continuity, to_shape

    surface = patching.build(creased_cube(6.5))
    assert surface.topology.has_split_sides and surface.n_patches < 6 * 4**7 // 4
    assert distance_to_cube_edge(surface) < distance_to_cube_edge(patching.build(creased_cube(3.0)))
    report = check_continuity(to_shape(surface))
    assert report.valid and report.n_solids == 1 and report.max_normal_jump_deg <= 1e-6


def crease_torus(s: float, intervals=None) -> patching.ControlMesh:
    """The 5 x 4 torus grid with one semi-sharp edge (0-4, along u): the fuzzed case that
    wrote 20,480 patches for 20 faces at s = 5 on the global path."""
    import dataclasses

    from patching.mesh.primitives import torus_grid

    return dataclasses.replace(torus_grid(5, 4, intervals, name="ring"), creases={(0, 4): s})


def test_a_small_mesh_with_a_sharpness_5_crease_is_refined_adaptively():
    """Five global steps would make 20 x 4^5 = 20,480 patches (more than
    MAX_AUTO_GLOBAL_FACES), so build refines adaptively: far fewer patches (632), with
    T-junctions, pointwise the global construction's surface (test_adaptive's check, against
    refinement="global"), which "global" still gives in one mesh (what --pack takes)."""
    from patching.operator.adaptive import adaptive_operator
    from tests.helpers import TOL, surface_differences

    mesh = crease_torus(5.0)
    surface = patching.build(mesh)
    assert surface.topology.has_split_sides
    assert surface.n_patches == adaptive_operator(mesh).n_patches < 20 * 4**5 // 20
    _, n_global, worst = surface_differences(mesh)
    assert n_global == 20 * 4**5 and worst <= TOL
    whole = patching.build(mesh, refinement="global")
    assert whole.n_patches == n_global and not whole.topology.has_split_sides


def test_the_global_path_stays_where_the_adaptive_one_cannot_go_or_gains_nothing():
    """Still refined globally (one mesh, no split sides): a zero interval anywhere (the
    adaptive path refuses them), one step for triangles without semi-sharp tags (it refines
    every face on either path), and a small refinement (a 6-face cube at s = 3: 384 faces,
    no more than MAX_AUTO_GLOBAL_FACES)."""
    from patching.operator.refinement import MAX_AUTO_GLOBAL_FACES
    from patching.mesh.primitives import torus_grid

    zero_strip = crease_torus(5.0, intervals=[1, 1, 0, 1, 1])  # the zero strip is 2 edges from the crease
    split = torus_grid(20, 16)
    a, b, c, d = (int(x) for x in split.face(0))
    triangles = patching.from_arrays(split.vertices, [[a, b, c], [a, c, d]] + [list(split.face(f)) for f in range(1, split.n_faces)])
    assert 4 * triangles.n_faces > MAX_AUTO_GLOBAL_FACES and 6 * 4**3 <= MAX_AUTO_GLOBAL_FACES
    # (mesh, faces of the globally refined mesh, patches: the zero strip's 4 x 4^5 faces have none)
    cases = ((zero_strip, 20 * 4**5, 16 * 4**5), (triangles, 4 * (split.n_faces - 1) + 6, None), (creased_cube(3.0), 6 * 4**3, None))
    for mesh, faces, patches in cases:
        assert patching.patched_mesh(mesh).n_faces == faces
        surface = patching.build(mesh)
        assert not surface.topology.has_split_sides and surface.n_patches == (patches or faces)


def test_an_unknown_refinement_is_refused_by_patched_mesh_too():
    """patched_mesh(refinement=...) is public beside build_operator(refinement=...): a typo
    ("globl") raised nothing and silently meant "global"."""
    for call in (patching.patched_mesh, patching.build_operator):
        with pytest.raises(ValueError, match="refinement must be one of"):
            call(creased_cube(3.0), refinement="globl")
