"""Sharp features through extraordinary points, corners and boundary EPs ([FSLYJ] sec. 4.2).

Each case is measured with numpy on the patches (tests/edge_checks.py): the normal angle across
every smooth mesh edge (G1), the gap across every edge, and the distance from every patch side
on a sharp edge to the crease B-spline of its polygon (tests/reference_bspline.py)."""

import numpy as np
import pytest

import patching
from patching.topology.features import features
from patching.subdivision.catmark import subdivide
from patching.topology.tables import Topology
from tests.edge_checks import crease_deviation, edge_jumps
from tests.helpers import CUBE_FACES, CUBE_VERTICES, quad_mesh_with_eps, with_random_intervals
from tests.helpers import meridian_crease


def assert_g1_with_exact_creases(mesh, surface, angle_deg=1e-7):
    _, gaps, angles, sharp = edge_jumps(mesh, surface)
    assert gaps.max() <= 1e-12 * surface.size
    if (~sharp).any():
        assert angles[~sharp].max() <= angle_deg
    assert crease_deviation(mesh, surface) <= 1e-12 * surface.size


def sharp_cube(intervals=(1.0, 1.0, 1.0), tagged=False) -> patching.ControlMesh:
    edges = {tuple(sorted((f[k], f[(k + 1) % 4]))) for f in CUBE_FACES for k in range(4)}
    # one edge per direction sets its strip's interval (x: 0-4, y: 0-2, z: 0-1)
    iv = {(0, 4): intervals[0], (0, 2): intervals[1], (0, 1): intervals[2]}
    corners = {v: np.inf for v in range(8)} if tagged else {}
    return patching.from_arrays(CUBE_VERTICES, CUBE_FACES, intervals=iv, creases={e: np.inf for e in edges}, corners=corners)


def corner_point(net: np.ndarray, corner: int) -> np.ndarray:
    """The patch's point at its face corner ``corner`` (0..3)."""
    d = net.shape[0] - 1
    return net[((0, 0), (d, 0), (d, d), (0, d))[corner]]


def bilinear(corners: np.ndarray, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    c0, c1, c2, c3 = corners
    s, t = s[:, None], t[:, None]
    return (1 - s) * (1 - t) * c0 + s * (1 - t) * c1 + s * t * c2 + (1 - s) * t * c3


@pytest.mark.parametrize("intervals", [(1.0, 1.0, 1.0), (1.0, 3.0, 7.0)])
@pytest.mark.parametrize("tagged", [False, True])
def test_sharp_cube_reproduces_the_cube(intervals, tagged):
    """All 12 edges infinitely sharp (and optionally corner tags): every vertex is a corner
    whose sectors are single faces, so each face is the bilinear square of its corners: planar,
    with straight edges, whatever the intervals."""
    from patching.evaluation.sampling import evaluate_nets

    mesh = sharp_cube(intervals, tagged)
    surface = patching.build(mesh)
    g = np.linspace(0, 1, 7)
    s, t = np.repeat(g, 7), np.tile(g, 7)
    assert surface.n_patches == 6
    for _, _, face, net in surface.patches():
        corners = mesh.vertices[list(mesh.face(face))]
        assert np.abs(evaluate_nets(net[None], s, t)[0] - bilinear(corners, s, t)).max() <= 1e-14


def test_refined_sharp_cube_with_non_uniform_intervals_is_still_the_cube():
    """One sharp subdivision step gives 2 x 2 quads per side; with random strip intervals every
    patch stays in its side's plane and the patches tile the six unit squares (area 6 by
    Gauss-Legendre, exact for these polynomial integrands)."""
    mesh = with_random_intervals(subdivide(sharp_cube(), 1, rules="opensubdiv"), 7.0, seed=5)
    surface = patching.build(mesh)
    x, w = np.polynomial.legendre.leggauss(10)
    x, w = (x + 1) / 2, w / 2
    s, t, ww = np.repeat(x, 10), np.tile(x, 10), np.outer(w, w).ravel()
    from patching.evaluation.sampling import evaluate_nets

    area = 0.0
    for _, _, _, net in surface.patches():
        flat = net.reshape(-1, 3)
        axis = int(np.argmin(np.ptp(flat, axis=0)))  # the side's normal direction
        assert np.ptp(flat[:, axis]) <= 1e-14 and flat[0, axis] in (0.0, 1.0) or abs(flat[0, axis] - round(flat[0, axis])) <= 1e-14
        _, ds, dt = evaluate_nets(net[None], s, t, derivatives=True)
        area += float((np.linalg.norm(np.cross(ds[0], dt[0]), axis=1) * ww).sum())
    assert area == pytest.approx(6.0, abs=1e-12)
    assert_g1_with_exact_creases(mesh, surface)


@pytest.mark.parametrize("n, i, j", [(5, 0, 2), (6, 0, 3), (6, 0, 2), (3, 0, 1), (8, 1, 4)])
@pytest.mark.parametrize("ratio", [1.0, 5.0, 20.0])
def test_crease_through_extraordinary_points(n, i, j, ratio):
    mesh = meridian_crease(n, i, j, ratio, seed=n + j)
    poles = [mesh.n_vertices - 2, mesh.n_vertices - 1]
    assert features(Topology(mesh)).sector_vertex[poles].all() == (max(j - i, n - j + i) >= 3)
    assert_g1_with_exact_creases(mesh, patching.build(mesh))


def test_crease_through_an_ep_exports_a_valid_solid():
    from export import check_continuity, to_shape

    mesh = meridian_crease(5, 0, 2, 5.0, seed=1)
    report = check_continuity(to_shape(patching.build(mesh)))
    assert report.valid and report.n_solids == 1 and report.n_free_edges == 0
    assert report.max_gap_relative <= 1e-9
    assert report.n_sharp_edges == 8  # the crease loop: 4 edges down, 4 up
    assert report.max_smooth_normal_jump_deg <= 1e-6


@pytest.mark.parametrize("ratio", [1.0, 5.0, 20.0])
def test_crease_turning_at_regular_vertices(ratio):
    """A rectangular crease loop on a torus turns at four valence-4 vertices: a one-face and a
    three-face sector there, the latter built as a sector EP with angle pi."""
    from patching.mesh.primitives import torus_grid

    m, n = 8, 6
    grid = torus_grid(m, n)
    ids = lambda a, b: (a % m) * n + (b % n)  # noqa: E731
    loop = [ids(2, b) for b in range(1, 4)] + [ids(a, 4) for a in range(2, 5)] + [ids(5, b) for b in range(4, 1, -1)] + [ids(a, 1) for a in range(5, 2, -1)]
    creases = {(loop[k], loop[(k + 1) % len(loop)]): np.inf for k in range(len(loop))}
    rng = np.random.default_rng(2)
    points = grid.vertices + rng.normal(scale=0.05, size=grid.vertices.shape)
    mesh = patching.from_arrays(points, grid.quads(), creases=creases, name="turning")
    mesh = with_random_intervals(mesh, ratio, seed=3) if ratio > 1 else mesh
    feats = features(Topology(mesh))
    assert feats.sector_vertex[[ids(2, 1), ids(2, 4), ids(5, 4), ids(5, 1)]].all()
    assert not feats.sector_vertex[ids(2, 2)]
    assert_g1_with_exact_creases(mesh, patching.build(mesh))


@pytest.mark.parametrize("mode", [1, 2])
@pytest.mark.parametrize("ratio", [1.0, 5.0, 20.0])
def test_boundary_extraordinary_points(mode, ratio):
    """bipyramid-5 without one face at a pole: the pole is a boundary vertex of valence 5
    (four faces), the face's other corners boundary vertices of valence 4: boundary EPs with
    a sector of angle pi.  The boundary is the B-spline of its polygon (corners at
    valence-2 boundary vertices in mode 1; none here), the inside G1."""
    base = quad_mesh_with_eps("bipyramid-5")
    topo = Topology(base)
    pole = base.n_vertices - 2
    drop = int(topo.face[topo.outgoing[pole]])
    faces = [list(base.face(f)) for f in range(base.n_faces) if f != drop]
    mesh = patching.from_arrays(base.vertices, faces, interpolate_boundary=mode, name="open")
    mesh = with_random_intervals(mesh, ratio, seed=7) if ratio > 1 else mesh
    topo = Topology(mesh)
    assert topo.vertex_is_boundary[pole] and topo.valence[pole] == 5 and features(topo).sector_vertex[pole]
    surface = patching.build(mesh)
    assert surface.n_patches == base.n_faces - 1
    assert_g1_with_exact_creases(mesh, surface)


@pytest.mark.parametrize("where", ["equator", "pole"])
@pytest.mark.parametrize("ratio", [1.0, 5.0])
def test_corner_tags_on_a_crease(where, ratio):
    """A corner tag ends the crease chains at the vertex (mirrored legs): at a regular crease
    vertex it leaves two two-face corner sectors, at the pole a two- and a three-face sector,
    each built as a sector EP of angle pi / 2; the patches interpolate the vertex."""
    v = 25 if where == "equator" else 30  # original vertex 0 and the top pole (listed last)
    mesh = meridian_crease(5, 0, 2, ratio, seed=9, corners={v: np.inf})
    feats = features(Topology(mesh))
    assert feats.corner[v] and feats.sector_vertex[v]
    surface = patching.build(mesh)
    assert_g1_with_exact_creases(mesh, surface)
    at_vertex = [net[0, 0] for _, _, face, net in surface.patches() if mesh.face(face)[0] == v]
    at_vertex += [net[-1, 0] for _, _, face, net in surface.patches() if mesh.face(face)[1] == v]
    assert at_vertex and np.abs(np.array(at_vertex) - mesh.vertices[v]).max() <= 1e-14


def test_corner_tag_without_sharp_edges_interpolates_a_smooth_vertex():
    """A corner tag on a vertex with no sharp edge: the surface passes through the control
    point and stays G1 there (a tangent plane, not OpenSubdiv's cone; issue note)."""
    base = with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, seed=1)
    pole = base.n_vertices - 2
    mesh = patching.from_arrays(base.vertices, base.quads(), intervals=dict(base.intervals), corners={pole: 10.0})
    surface = patching.build(mesh)
    assert_g1_with_exact_creases(mesh, surface)
    corners = [net[0, 0] for _, _, face, net in surface.patches() if mesh.face(face)[0] == pole]
    assert corners and np.abs(np.array(corners) - mesh.vertices[pole]).max() <= 1e-14
    free = patching.build(base)
    free_corners = [net[0, 0] for _, _, face, net in free.patches() if base.face(face)[0] == pole]
    assert np.linalg.norm(free_corners[0] - base.vertices[pole]) > 1e-3  # the smooth limit is elsewhere


def test_feature_classification():
    """Which vertices need anchors: the cube's corners (single-face sectors) and straight
    creases through regular vertices do not; a crease turning at a valence-4 vertex and a
    crease through an EP do; one sharp edge at an interior vertex is a dart."""
    cube = features(Topology(sharp_cube()))
    assert cube.corner.all() and not cube.sector_vertex.any()
    mesh = meridian_crease(5, 0, 2, 1.0)
    f = features(Topology(mesh))
    poles = [mesh.n_vertices - 2, mesh.n_vertices - 1]
    assert f.sector_vertex[poles].all() and not f.corner.any() and not f.dart.any()
    assert np.count_nonzero(f.count == 2) == 8 and np.count_nonzero(f.sector_vertex) == 2


@pytest.mark.parametrize("ratio", [1.0, 5.0, 20.0])
def test_dart_fades_the_crease_out(ratio):
    """A crease of two edges on a torus ends at two darts.  At a dart the crease fades out: the
    vertex keeps its smooth vertex point, all patches around it share one tangent plane there,
    and only the sharp spoke loses its G1 constraint; every smooth edge stays G1, and the
    crease is a real crease (a normal jump) away from the darts."""
    from patching.mesh.primitives import torus_grid

    m, n = 8, 6
    grid = torus_grid(m, n)
    ids = lambda a, b: (a % m) * n + (b % n)  # noqa: E731
    points = grid.vertices + np.random.default_rng(0).normal(scale=0.05, size=grid.vertices.shape)
    creases = {(ids(2, 0), ids(2, 1)): 10.0, (ids(2, 1), ids(2, 2)): 10.0}
    mesh = patching.from_arrays(points, grid.quads(), creases=creases, name="dart")
    mesh = with_random_intervals(mesh, ratio, seed=1) if ratio > 1 else mesh
    feats = features(Topology(mesh))
    assert feats.dart[[ids(2, 0), ids(2, 2)]].all() and feats.sector_vertex[[ids(2, 0), ids(2, 2)]].all()
    surface = patching.build(mesh)
    _, gaps, angles, sharp = edge_jumps(mesh, surface)
    assert gaps.max() <= 1e-12 * surface.size and angles[~sharp].max() <= 1e-7
    assert angles[sharp].min() > 1.0  # sharp away from the darts
    from patching.evaluation.sampling import evaluate_nets

    for dart in (ids(2, 0), ids(2, 2)):
        normals = []
        for _, _, face, net in surface.patches():
            corners = list(mesh.face(face))
            if dart in corners:
                c = corners.index(dart)
                st = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])[c]
                _, ds, dt = evaluate_nets(net[None], st[:1], st[1:], derivatives=True)
                nrm = np.cross(ds[0, 0], dt[0, 0])
                normals.append(nrm / np.linalg.norm(nrm))
        normals = np.array(normals)
        assert len(normals) == 4 and np.abs(normals - normals[0]).max() <= 1e-9


def test_shipped_machined_bracket():
    """models/machined_bracket.obj (a mechanical part): corners (at the concave ones,
    valence-5 EPs, sectors of three faces take the EP path), darts and non-uniform intervals;
    the top is exactly planar, the rest G1 off its creases."""
    from pathlib import Path

    from export import check_continuity, to_shape

    mesh = patching.read_mesh(Path(__file__).resolve().parent.parent / "models" / "machined_bracket.obj")
    feats = features(Topology(mesh))
    assert feats.corner.any() and feats.dart.any() and (feats.sector_vertex & feats.corner).any()
    assert np.unique(Topology(mesh).strip_interval).size > 1  # 0.4 on the outer strips, 1 inside
    surface = patching.build(mesh)
    assert_g1_with_exact_creases(mesh, surface)
    top = mesh.vertices[:, 2].max()
    on_top = [net for _, _, face, net in surface.patches() if (mesh.vertices[list(mesh.face(face)), 2] == top).all()]
    assert on_top and max(np.abs(net[..., 2] - top).max() for net in on_top) <= 1e-14
    # and it does not fold: the Jacobian keeps its sign on every top patch, also at the concave
    # corners, whose three-quad sectors span 3 pi / 2 (g1_patches.corner_sector_angle; pi / 2
    # folded 1% of those patches)
    from patching.evaluation.sampling import evaluate_nets

    g = np.linspace(0, 1, 21)
    _, ds, dt = evaluate_nets(np.array([net for net in on_top if net.shape[0] == 6]), np.repeat(g, 21), np.tile(g, 21), derivatives=True)
    assert np.cross(ds, dt)[..., 2].min() > 0
    report = check_continuity(to_shape(surface))
    assert report.valid and report.n_solids == 1 and report.max_gap_relative <= 1e-9


@pytest.mark.parametrize("n", [64, 100])
def test_high_valence_poles(n):
    """Poles of valence 64 and more: bipyramid-n with random intervals is a valid G1
    solid; the angle configuration and the local solves scale to these rings."""
    from export import check_continuity, to_shape

    mesh = with_random_intervals(quad_mesh_with_eps(f"bipyramid-{n}"), 5.0, seed=n)
    assert Topology(mesh).valence.max() == n
    surface = patching.build(mesh)
    assert_g1_with_exact_creases(mesh, surface)
    report = check_continuity(to_shape(surface))
    assert report.valid and report.n_solids == 1 and report.max_smooth_normal_jump_deg <= 1e-6


@pytest.mark.parametrize("ratio", [1.0, 5.0])
def test_corner_tag_on_a_valence_4_vertex_next_to_eps(ratio):
    """Found by a random stress test of tags: with equal angles a valence-4 ring whose spokes
    reach EPs has no G1 solution (features.refuse_singular_rings); the skewed fan of
    g1_patches.FOUR_FAN gives one, and the tagged vertex is interpolated.  Forcing the EP path
    there (regular angles) is refused in one line naming the vertex."""
    base = quad_mesh_with_eps("bipyramid-5")
    topo = Topology(base)
    pole = base.n_vertices - 2
    beside = int(topo.dest[topo.outgoing[pole]])
    assert topo.valence[beside] == 4 and (topo.valence[topo.dest[topo.one_ring(beside)]] != 4).sum() == 3
    mesh = patching.from_arrays(base.vertices, base.quads(), corners={beside: 10.0})
    mesh = with_random_intervals(mesh, ratio, seed=2) if ratio > 1 else mesh
    surface = patching.build(mesh)
    assert_g1_with_exact_creases(mesh, surface)
    at = [corner_point(net, list(mesh.face(face)).index(beside)) for _, _, face, net in surface.patches() if beside in mesh.face(face)]
    assert len(at) == 4 and np.abs(np.array(at) - mesh.vertices[beside]).max() <= 1e-14
    with pytest.raises(patching.UnsupportedError, match=f"forcing the EP path at vertex {beside}"):
        patching.build_operator(base, force_extraordinary=[beside])
