"""Feature-adaptive refinement (patching.operator.adaptive,): the adaptive
patches are the global construction's surface, and T-junctions are G1 (positions and normals)."""


import numpy as np
import pytest
import scipy.sparse as sp

import patching
from patching.operator.adaptive import adaptive_operator, global_steps
from patching.subdivision.catmark import subdivision_operator
from patching.surface import CORNER_PARAMETERS
from tests.helpers import CASES, TOL, points_normals, surface_differences, torus_mesh as torus


@pytest.mark.parametrize("radius", [2, 3])
@pytest.mark.parametrize("name,mesh", CASES, ids=[c[0] for c in CASES])
def test_adaptive_surface_is_the_global_surface(name, mesh, radius):
    """Every global level-N patch lies inside exactly one adaptive leaf, and there the two
    agree pointwise (positions and unit normals on a 5 x 5 grid, relative to the size);
    leaves at level N have the global operator's rows themselves; fewer patches."""
    ap, n_global, worst = surface_differences(mesh, radius)
    assert worst <= TOL, name
    assert ap.n_patches < n_global


def test_radius_one_is_not_the_global_surface():
    """One ring is too few: a leaf's 4 x 4 points then reach the seeds (the check above can
    fail)."""
    _, _, worst = surface_differences(CASES[0][1], radius=1)
    assert worst > 1e-6


def side_points(net, side, w):
    c0, c1 = CORNER_PARAMETERS[side], CORNER_PARAMETERS[(side + 1) % 4]
    st = c0[None] + w[:, None] * (c1 - c0)[None]
    return points_normals(net, st[:, 0], st[:, 1])


@pytest.mark.parametrize("name,mesh", CASES, ids=[c[0] for c in CASES])
def test_t_junctions_are_g1_and_cover_every_side(name, mesh):
    """Across every junction the coarse side's piece [u0, u1] and the fine side (run the other
    way) are the same curve with the same unit normals; every inner side of every leaf is
    covered exactly once (closed meshes: all sides)."""
    ap = adaptive_operator(mesh)
    size = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    nets = {}
    for d, (ids, arr) in ap.nets(mesh.vertices).items():
        nets.update(zip(ids.tolist(), arr))
    w = np.linspace(0, 1, 9)
    cover = np.zeros((ap.n_patches, 4))
    transitions = 0
    for pc, kc, pf, kf, u0, u1 in ap.junctions:
        pc, kc, pf, kf = int(pc), int(kc), int(pf), int(kf)
        pa, na = side_points(nets[pc], kc, u0 + w * (u1 - u0))
        pb, nb = side_points(nets[pf], kf, w[::-1])
        assert np.abs(pa - pb).max() <= TOL * size
        assert np.abs(na - nb).max() <= 1e-9  # unit normals: G1 (C2 in fact) across the junction
        cover[pc, kc] += u1 - u0
        cover[pf, kf] += 1.0
        transitions += ap.level[pc] != ap.level[pf]
    if ap.level.min() < ap.steps:
        assert transitions > 0
    if name.startswith(("torus", "cube2")):
        np.testing.assert_allclose(cover, 1.0, atol=1e-12)
    elif name.startswith("grid"):
        # Open grids over [0, 10] x [0, 9] with boundary vertices on those lines, so the
        # boundary curves too: exactly the sides on them are in no junction, all others in
        # junctions covering them once (a missing row would open a hole in the shell).
        on_boundary = np.zeros_like(cover, dtype=bool)
        for p, net in nets.items():
            for k in range(4):
                xy = side_points(net, k, np.linspace(0, 1, 3))[0][:, :2]
                on_boundary[p, k] = any(np.all(np.abs(xy[:, a] - x) < 1e-12) for a, x in ((0, 0), (0, 10), (1, 0), (1, 9)))
        assert on_boundary.any()
        np.testing.assert_allclose(cover, np.where(on_boundary, 0.0, 1.0), atol=1e-12)
    else:
        assert cover.max() <= 1.0 + 1e-12


@pytest.mark.parametrize("name,mesh", CASES, ids=[c[0] for c in CASES])
def test_windows_equal_the_global_levels(name, mesh):
    """Restricted subdivision equals global subdivision: every vertex of every domain face of
    every window has the rows (on the input's points) of its vertex in G_j."""
    ap, levels = adaptive_operator(mesh, keep_levels=True)
    g_mesh, g_rows = mesh, sp.identity(mesh.n_vertices, format="csr")
    for j, lev in enumerate(levels):
        faces = np.flatnonzero(lev.status > 0)
        mine = lev.rows[lev.mesh.quads()[faces].ravel()] if lev.mesh.is_quad_mesh else None
        if mine is not None:
            theirs = g_rows[g_mesh.quads()[lev.gid[faces]].ravel()]
            assert abs(mine - theirs).max() <= 1e-13
        if j < len(levels) - 1:
            step, g_mesh = subdivision_operator(g_mesh, rules="seed")
            g_rows = (step @ g_rows).tocsr()


def test_steps_follow_build_operator():
    v, f, _ = torus(6, 6)
    assert global_steps(patching.from_arrays(v, f)) == 0
    assert global_steps(patching.from_arrays(v, f, creases={(0, 1): 2.2})) == 3
    assert global_steps(patching.from_arrays(v, f, creases={(0, 1): 12.0}, corners={3: 1.5})) == 2


def _junctions_by_walking(levels, mesh0):
    """The junctions as a recursive walk finds them: every leaf side into the face across
    it, then down that face's refined descendants (first half of the side, then second)."""
    def child(j, gid, corner):
        return mesh0.face_offsets[gid] + corner if j == 0 else 4 * gid + corner

    def walk(j, gid, side, a, b):
        nxt = levels[j + 1]
        where = {int(g): i for i, g in enumerate(nxt.gid.tolist())}
        mid = 0.5 * (a + b)
        for corner, child_side, lo, hi in ((side, 0, a, mid), ((side + 1) % 4, 3, mid, b)):
            cg = int(child(j, gid, corner))
            f = where[cg]
            if nxt.status[f] == 1:
                if nxt.patch[f] >= 0:
                    yield int(nxt.patch[f]), child_side, lo, hi
            else:
                yield from walk(j + 1, cg, child_side, lo, hi)

    out = []
    for j, lev in enumerate(levels):
        topo, offsets = lev.topo, lev.topo.mesh.face_offsets
        same_level, down = [], []
        for f in np.flatnonzero(lev.status == 1).tolist():
            for k in range(4):
                h = offsets[f] + k
                t = topo.twin[h]
                if t < 0 or lev.patch[f] < 0:
                    continue
                g = topo.face[t]
                if lev.status[g] == 1 and h < t and lev.patch[g] >= 0:
                    same_level.append((lev.patch[f], k, lev.patch[g], t - offsets[g], 0.0, 1.0))
                elif lev.status[g] == 2:
                    down += [(lev.patch[f], k, pg, sg, 1.0 - b, 1.0 - a) for pg, sg, a, b in walk(j, int(lev.gid[g]), int(t - offsets[g]), 0.0, 1.0)]
        out += same_level + down
    return np.array(out, dtype=np.float64).reshape(-1, 6)


@pytest.mark.parametrize("name,mesh", CASES[:7], ids=[c[0] for c in CASES[:7]])
def test_junctions_are_those_a_recursive_walk_finds(name, mesh):
    """The vectorised junctions (``adaptive._junctions``) equal, row for row and in order, those
    of a walk written here: the B-rep's numbering of split sides follows their order."""
    ap, levels = adaptive_operator(mesh, keep_levels=True)
    assert np.array_equal(ap.junctions, _junctions_by_walking(levels, mesh))
