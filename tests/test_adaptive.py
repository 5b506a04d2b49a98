"""Feature-adaptive refinement (patching.operator.adaptive,): the adaptive
patches are the global construction's surface, and T-junctions are G1 (positions and normals)."""

import dataclasses
import itertools

import numpy as np
import pytest
import scipy.sparse as sp

import patching
from patching.operator.adaptive import adaptive_operator, child_parameters, global_steps
from patching.evaluation.sampling import evaluate_nets
from patching.subdivision.catmark import subdivision_operator
from patching.surface import CORNER_PARAMETERS
from tests.conftest import SHAPES

# Positions agree to round-off of a few de Casteljau-like products on coordinates of size ~1;
# 1e-10 of the size leaves room for the level-N operator's longer sums.
TOL = 1e-10


def torus(m, n, rng=None):
    """m x n torus grid (regular, closed), random strip intervals when rng is given."""
    a, b = np.meshgrid(2 * np.pi * np.arange(m) / m, 2 * np.pi * np.arange(n) / n, indexing="ij")
    v = np.stack([(3 + np.cos(b)) * np.cos(a), (3 + np.cos(b)) * np.sin(a), np.sin(b)], -1).reshape(-1, 3)
    idx = lambda i, k: (i % m) * n + (k % n)  # noqa: E731
    f = [[idx(i, k), idx(i + 1, k), idx(i + 1, k + 1), idx(i, k + 1)] for i in range(m) for k in range(n)]
    iv = {}
    if rng is not None:
        for i in range(m):
            iv[tuple(sorted((idx(i, 0), idx(i + 1, 0))))] = float(rng.uniform(0.4, 2.5))
        for k in range(n):
            iv[tuple(sorted((idx(0, k), idx(0, k + 1))))] = float(rng.uniform(0.4, 2.5))
    return v, f, iv


def grid(m, n, rng=None):
    """Open m x n grid of quads in the plane, bumped in z."""
    x, y = np.meshgrid(np.arange(m + 1, dtype=float), np.arange(n + 1, dtype=float), indexing="ij")
    z = 0.3 * np.sin(x) * np.cos(0.7 * y)
    v = np.stack([x, y, z], -1).reshape(-1, 3)
    idx = lambda i, k: i * (n + 1) + k  # noqa: E731
    f = [[idx(i, k), idx(i + 1, k), idx(i + 1, k + 1), idx(i, k + 1)] for i in range(m) for k in range(n)]
    iv = {}
    if rng is not None:
        for i in range(m):
            iv[(idx(i, 0), idx(i + 1, 0))] = float(rng.uniform(0.4, 2.5))
        for k in range(n):
            iv[(idx(0, k), idx(0, k + 1))] = float(rng.uniform(0.4, 2.5))
    return v, f, iv


def cube_level2(s, rng=None):
    """A cube subdivided twice (EPs of valence 3 at its corners, 96 faces), with semi-sharp
    edges along a loop through the middle of four sides."""
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    f = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    mesh = patching.subdivision.catmark.subdivide(patching.from_arrays(v, f), 2)
    topo = patching.Topology(mesh)
    pts = mesh.vertices
    # Edges on the plane z = 0.5 (both ends there): a loop around the cube.
    ends = pts[topo.edges]
    loop = np.flatnonzero(np.all(np.abs(ends[:, :, 2] - 0.5) < 1e-9, axis=1))
    creases = {tuple(int(x) for x in topo.edges[e]): s for e in loop}
    intervals = {}
    if rng is not None:
        for strip in range(topo.n_strips):
            e = int(np.flatnonzero(topo.edge_strip == strip)[0])
            intervals[tuple(int(x) for x in topo.edges[e])] = float(rng.uniform(0.5, 2.0))
    return patching.from_arrays(pts, [list(q) for q in mesh.quads()], intervals=intervals, creases=creases, name="cube2")


def meshes():
    rng = np.random.default_rng(7)
    v, f, iv = torus(12, 10, rng)
    yield "torus_random", patching.from_arrays(v, f, intervals=iv, creases={(0, 1): 2.5, (1, 2): 2.5, (2, 3): 1.0})
    v, f, iv = grid(10, 9)
    yield "grid_uniform", patching.from_arrays(v, f, creases={(44, 45): 3.0, (45, 46): 3.0}, corners={60: 2.0})
    v, f, iv = grid(10, 9, rng)
    yield "grid_random", patching.from_arrays(v, f, intervals=iv, creases={(44, 45): 2.0, (45, 46): 2.0})
    # One interval tag: every tag value is 2, but the untagged strips keep 1, so the knots are
    # not uniform and the boundary vertices are no regular crease vertices (seeds).
    v, f, _ = grid(10, 9)
    yield "grid_one_tag", patching.from_arrays(v, f, intervals={(20, 30): 2.0}, creases={(44, 45): 3.0, (45, 46): 3.0})
    v, f, _ = torus(10, 8)
    a, b, c, d = f[44]
    f = f[:44] + [[a, b, c], [a, c, d]] + f[45:]  # two triangles: level 0 is refined everywhere
    yield "torus_triangles", patching.from_arrays(v, f, creases={(0, 1): 2.0, (1, 2): 2.0})
    yield "cube2_random", cube_level2(2.0, rng)
    yield "cube2_uniform", cube_level2(3.0)
    # The shapes that global refinement refuses, at a sharpness the global reference can afford.
    for shape, sharpness in (("hole_test2", 2.0), ("helmet", 2.0), ("gregory_test7", 3.0), ("pawn", 2.0)):
        path = SHAPES / f"catmark_{shape}.obj"
        if path.is_file():
            mesh = patching.read_mesh(path)
            creases = {k: min(v, sharpness) if v < 10 else v for k, v in mesh.creases.items()}
            yield f"{shape}_s{sharpness:g}", dataclasses.replace(mesh, creases=creases)


CASES = list(meshes())


def descendants(mesh, level, gid, steps):
    """Level-N descendants of (level, gid): [(global id, corner path)]."""
    out = []
    for path in itertools.product(range(4), repeat=steps - level):
        g = gid
        for j, c in enumerate(path, start=level):
            g = int(mesh.face_offsets[g]) + c if j == 0 else 4 * g + c
        out.append((g, path))
    return out


def to_leaf(path, s, t):
    """Parameters in the leaf of level-N (s, t) on the face reached by ``path``."""
    for c in reversed(path):
        s, t = child_parameters(c, s, t)
    return s, t


def points_normals(net, s, t):
    p, ds, dt = evaluate_nets(net[None], s, t, derivatives=True)
    n = np.cross(ds[0], dt[0])
    return p[0], n / np.linalg.norm(n, axis=-1, keepdims=True)


def surface_differences(mesh, radius=2):
    """Checks below; returns the largest position and normal differences found."""
    ap = adaptive_operator(mesh, radius=radius)
    n = ap.steps
    glob = patching.build_operator(mesh, refinement="global")
    size = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    gsurf = glob.evaluate(mesh.vertices)
    gnet = {}
    grow = {}
    for grp in glob.groups:
        for k, fc in enumerate(grp.faces.tolist()):
            gnet[fc] = gsurf.groups[[g.degree for g in gsurf.groups].index(grp.degree)].coefficients[k]
            grow[fc] = (grp.degree, grp.row_offset + k * (grp.degree + 1) ** 2)
    nets = ap.nets(mesh.vertices)
    u = np.linspace(0, 1, 5)
    s, t = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    covered = set()
    worst = 0.0
    for d, (ids, arr) in nets.items():
        for p, net in zip(ids.tolist(), arr):
            lev, gid = int(ap.level[p]), int(ap.face[p])
            for g, path in descendants(mesh, lev, gid, n):
                if g not in gnet:  # a hole or a zero span at level N: no global patch
                    continue
                assert g not in covered
                covered.add(g)
                ls, lt = to_leaf(path, s, t)
                pa, na = points_normals(net, ls, lt)
                pg, ng = points_normals(gnet[g], s, t)
                worst = max(worst, np.abs(pa - pg).max() / size, np.abs(na - ng).max())
            if lev == n:
                gd, off = grow[gid]
                assert gd == d
                mine = ap.matrix[ap.row_offset[p] : ap.row_offset[p] + (d + 1) ** 2].toarray()
                theirs = glob.matrix[off : off + (d + 1) ** 2].toarray()
                # Both are sums of the same few products: round-off only.
                assert np.abs(mine - theirs).max() <= 1e-12
    assert covered == set(gnet)
    return ap, len(gnet), worst


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
