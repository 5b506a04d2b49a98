"""Split patch sides (T-junctions): patching.operator.split_sides builds the PatchTopology, and
export.brep.to_shape turns it into one valid shared-topology B-rep.

The surfaces are made by de Casteljau splitting, so the exact answer is known: a ring of
bicubic patches (the uniform periodic B-spline of a torus-like control grid, C2 everywhere)
in which one patch is replaced by its 2 x 2 and one by its 4 x 4 sub-patches is the same
surface as the ring itself; only its B-rep topology changes (sides of the neighbours split
into 2 and 4 edges).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Curve2d, BRepAdaptor_Surface
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SOLID, TopAbs_VERTEX
from OCP.TopExp import TopExp
from export.ocp_compat import TopoDS
from export.ocp_compat import TopTools_IndexedDataMapOfShapeListOfShape

from export.brep import BrepError, to_shape
from export.continuity import check_continuity
from export.pack import find_blocks, to_packed_shape
from export.step import read_step, write_step
from patching.errors import UnsupportedError
from patching.evaluation.sampling import sample_graph
from patching.operator.split_sides import split_side_topology
from patching.surface import CORNER_PARAMETERS, BezierSurface, PatchGroup

try:
    from tests.helpers import count, topology_from_quads, volume
except ImportError:  # tests/ on sys.path rather than a package
    from tests.helpers import count, topology_from_quads, volume

# The split patches are the coarse ones to round-off (de Casteljau on coordinates of size ~4:
# a few ulps): measured 2e-16 of the size; 1e-14 leaves a factor 50.
GAP = 1e-14
# Normals across C2 joins and across T-junctions agree to round-off: measured 1e-12 deg on
# the split ring (2.5e-13 deg unsplit); 1e-10 deg leaves a factor 100.
ANGLE_DEG = 1e-10
# Volume by OCC's Gauss integration on the same surface cut into other faces: measured 3e-16
# relative; 1e-12 leaves room for other integration orders, far below the 1e-9 asked for.
VOLUME = 1e-12

# Uniform cubic B-spline segment to Bézier (The NURBS Book, eq. 5.? / Boehm's rule):
# Bézier points b_0..b_3 of the span between P_1 and P_2 of P_0..P_3.
B_TO_BEZIER = np.array([[1, 4, 1, 0], [0, 4, 2, 0], [0, 2, 4, 0], [0, 1, 4, 1]]) / 6.0


# --------------------------------------------------------------------------- surfaces


def ring_nets(m: int = 6, n: int = 5) -> dict[tuple[int, int], np.ndarray]:
    """{(i, j): (4, 4, 3) net} of the periodic uniform bicubic B-spline on an m x n torus-like
    control grid (radii 3 and 1, a little twisted so that no two patches are congruent)."""
    a, b = np.meshgrid(2 * np.pi * np.arange(m) / m, 2 * np.pi * np.arange(n) / n, indexing="ij")
    b = b + 0.2 * np.sin(a)
    r = 1.0 + 0.15 * np.cos(2 * a)
    P = np.stack([(3 + r * np.cos(b)) * np.cos(a), (3 + r * np.cos(b)) * np.sin(a), r * np.sin(b)], -1)
    nets = {}
    for i in range(m):
        for j in range(n):
            local = P[np.ix_(np.arange(i - 1, i + 3) % m, np.arange(j - 1, j + 3) % n)]
            nets[i, j] = np.einsum("ia,abc,jb->ijc", B_TO_BEZIER, local, B_TO_BEZIER)
    return nets


def halve(net: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """De Casteljau at 1/2 along ``axis`` (0: s, 1: t): the nets of the two halves."""
    net = np.moveaxis(net, axis, 0)
    left, right = [net[0]], [net[-1]]
    level = net
    while len(level) > 1:
        level = 0.5 * (level[:-1] + level[1:])
        left.append(level[0])
        right.append(level[-1])
    return np.moveaxis(np.array(left), 0, axis), np.moveaxis(np.array(right[::-1]), 0, axis)


def subdivide(net: np.ndarray, times: int) -> dict[tuple[int, int], np.ndarray]:
    """{(a, b): sub-net} of the 2^times x 2^times de Casteljau pieces, (a, b) along (s, t)."""
    pieces = {(0, 0): net}
    for _ in range(times):
        finer = {}
        for (a, b), q in pieces.items():
            lo, hi = halve(q, 0)
            for da, half in enumerate((lo, hi)):
                for db, quarter in enumerate(halve(half, 1)):
                    finer[2 * a + da, 2 * b + db] = quarter
        pieces = finer
    return pieces


def ring_patches(m: int = 6, n: int = 5, split=()) -> list[tuple[tuple[float, float, float], np.ndarray]]:
    """[((x0, y0, w), net)]: square patches on the ring's parameter domain [0, m) x [0, n),
    cell (i, j) replaced by its 2^times x 2^times pieces for every ((i, j), times) in split."""
    split = dict(split)
    out = []
    for (i, j), net in ring_nets(m, n).items():
        times = split.get((i, j), 0)
        w = 0.5**times
        for (a, b), q in sorted(subdivide(net, times).items()):
            out.append(((i + a * w, j + b * w, w), q))
    return out


def junctions(patches, m: int, n: int) -> np.ndarray:
    """The junction table of square patches on the periodic domain (as patching.operator.adaptive
    gives it): rows (coarse, side, fine, side, u0, u1) for every pair of sides on one grid
    line that overlap and run opposite ways; equal sides listed once."""
    sides = []
    for r, ((x0, y0, w), _) in enumerate(patches):
        corners = [(x0 + w * c[0], y0 + w * c[1]) for c in CORNER_PARAMETERS]
        for k in range(4):
            (xa, ya), (xb, yb) = corners[k], corners[(k + 1) % 4]
            if k % 2 == 0:  # along s: the line y, coordinate x
                sides.append((r, k, ("y", ya % n), xa, xb))
            else:
                sides.append((r, k, ("x", xa % m), ya, yb))
    rows = []
    for ra, ka, line_a, a0, a1 in sides:
        for rb, kb, line_b, b0, b1 in sides:
            if line_a != line_b or (ra, ka) == (rb, kb) or abs(a1 - a0) < abs(b1 - b0):
                continue
            if abs(a1 - a0) == abs(b1 - b0) and (ra, ka) > (rb, kb):
                continue  # same-level pairs once
            if (a1 - a0) * (b1 - b0) > 0 or max(min(a0, a1), min(b0, b1)) >= min(max(a0, a1), max(b0, b1)):
                continue  # same way round, or no common length
            u = lambda x: (x - a0) / (a1 - a0)  # noqa: E731
            rows.append((ra, ka, rb, kb, u(b1), u(b0)))  # b runs the other way: its end is at u0
    return np.array(rows, dtype=np.float64)


def surface_of(patches, table, name="ring") -> BezierSurface:
    nets = np.array([q for _, q in patches])
    size = float(np.linalg.norm(np.ptp(nets.reshape(-1, 3), axis=0)))
    group = PatchGroup(3, np.arange(len(patches)), nets)
    return BezierSurface((group,), split_side_topology(len(patches), table), name, size)


SPLIT = (((1, 2), 1), ((4, 0), 2))  # a 2 x 2 and a 4 x 4 patch; 4 x 4 on the ring's seam j = 0


@pytest.fixture(scope="module")
def ring():
    patches = ring_patches()
    return surface_of(patches, junctions(patches, 6, 5))


@pytest.fixture(scope="module")
def split_ring():
    patches = ring_patches(split=SPLIT)
    return surface_of(patches, junctions(patches, 6, 5), "split_ring")


# --------------------------------------------------------------------------- the topology


def test_unsplit_table_gives_the_one_edge_per_side_topology(ring):
    """Same-level junctions only: no split side, and the ids, directions and counts that
    ``topology_from_quads`` (ids and directions by first use) gives on the ring's grid."""
    topo = ring.topology
    assert not topo.has_split_sides
    quads = [[(i % 6) * 5 + j % 5, ((i + 1) % 6) * 5 + j % 5, ((i + 1) % 6) * 5 + (j + 1) % 5, (i % 6) * 5 + (j + 1) % 5]
             for i in range(6) for j in range(5)]
    expected = topology_from_quads(quads)
    assert np.array_equal(topo.corner_vertex, _first_use(np.asarray(quads)))  # ids by first use
    assert np.array_equal(topo.side_edge, expected.side_edge)
    assert np.array_equal(topo.side_reversed, expected.side_reversed)
    assert (topo.n_vertices, topo.n_edges) == (30, 60) and topo.is_closed


def _first_use(ids: np.ndarray) -> np.ndarray:
    _, first, inverse = np.unique(ids.ravel(), return_index=True, return_inverse=True)
    rank = np.empty(first.size, np.int64)
    rank[np.argsort(first)] = np.arange(first.size)
    return rank[inverse].reshape(ids.shape)


def test_split_table_counts(split_ring):
    """28 coarse + 4 + 16 fine patches.  Vertices: 30 grid vertices, +5 inside the 2 x 2 (1
    centre, 4 side midpoints) and +21 inside the 4 x 4 (9 inner, 12 on its sides).  Edges:
    60 - 4 - 4 ring edges, + 12 of the 2 x 2 and + 40 of the 4 x 4; every edge used twice.
    The neighbours' sides facing the 2 x 2 have 2 pieces, those facing the 4 x 4 have 4."""
    topo = split_ring.topology
    assert topo.has_split_sides and topo.is_closed
    assert split_ring.n_patches == 28 + 4 + 16
    assert topo.n_vertices == 30 + 5 + 21
    assert topo.n_edges == 60 - 8 + 12 + 40
    per_side = np.diff(topo.side_indptr)
    assert sorted(per_side[per_side > 1].tolist()) == [2] * 4 + [4] * 4
    split_rows = np.flatnonzero((per_side > 1).reshape(-1, 4).any(axis=1))
    assert np.all(topo.side_edge.ravel()[per_side > 1] == -1)
    assert len(split_rows) == 8
    # Piece vertices chain along each side: T-vertices are fine corners, not coarse ones.
    pieces = topo.pieces
    t_vertices = set(pieces.vertex[pieces.range[:, 0] > 0, 0].tolist())
    coarse_corners = set(topo.corner_vertex[split_rows].ravel().tolist())
    assert len(t_vertices) == 4 * 1 + 4 * 3 and not t_vertices & coarse_corners


def test_overlapping_junctions_are_refused():
    patches = ring_patches(split=SPLIT)
    table = junctions(patches, 6, 5)
    bad = table.copy()
    row = np.flatnonzero(table[:, 5] - table[:, 4] < 1)[0]
    bad[row, 5] = min(1.0, bad[row, 5] + 0.125)  # the piece now overlaps its neighbour
    with pytest.raises(ValueError, match="gaps or overlaps"):
        split_side_topology(len(patches), bad)
    with pytest.raises(ValueError, match="gaps or overlaps"):
        split_side_topology(len(patches), np.delete(table, row, axis=0)[:-1])


def test_to_shape_checks_the_pieces(split_ring):
    """A split side whose pieces leave a gap, or a side_edge out of step, is a BrepError."""
    topo = split_ring.topology
    piece_range = topo.piece_range.copy()
    i = int(np.flatnonzero(piece_range[:, 0] > 0)[0])
    piece_range[i, 0] += 1e-3
    bad = dataclasses.replace(split_ring, topology=dataclasses.replace(topo, piece_range=piece_range))
    with pytest.raises(BrepError, match="gap or overlap"):
        to_shape(bad)
    side_edge = topo.side_edge.copy()
    side_edge[side_edge == -1] = 0
    bad = dataclasses.replace(split_ring, topology=dataclasses.replace(topo, side_edge=side_edge))
    with pytest.raises(BrepError, match="out of step"):
        to_shape(bad)


# --------------------------------------------------------------------------- the B-rep


def t_edges(shape):
    """(edge -> faces map, number of distinct edges at every vertex) of ``shape``."""
    edge_faces = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, edge_faces)
    vertex_edges = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndUniqueAncestors_s(shape, TopAbs_VERTEX, TopAbs_EDGE, vertex_edges)
    valence = [vertex_edges.FindFromIndex(i).Size() for i in range(1, vertex_edges.Extent() + 1)]
    return edge_faces, valence


@pytest.fixture(scope="module")
def split_shape(split_ring):
    return to_shape(split_ring)


def test_split_ring_is_one_valid_solid_with_the_ring_volume(ring, split_shape):
    """One solid (to_shape has run BRepCheck_Analyzer), every edge on two faces, 3-valent
    T-vertices where the split sides break, the unsplit ring's volume."""
    assert count(split_shape, TopAbs_SOLID) == 1 and count(split_shape, TopAbs_FACE) == 48
    edge_faces, valence = t_edges(split_shape)
    assert edge_faces.Extent() == 104
    assert all(edge_faces.FindFromIndex(i).Size() == 2 for i in range(1, edge_faces.Extent() + 1))
    # 30 grid vertices and the 9 + 1 inner ones of the blocks are 4-valent; the 4 + 12
    # T-vertices on the blocks' borders have 3 edges (2 fine sides, 1 fine side across).
    assert sorted(valence) == [3] * 16 + [4] * 40
    reference = volume(to_shape(ring))
    assert volume(split_shape) == pytest.approx(reference, rel=VOLUME)


def test_split_ring_is_g1_with_round_off_gaps(split_shape):
    report = check_continuity(split_shape, samples_per_edge=9)
    assert report.valid and report.n_solids == 1 and report.n_free_edges == 0
    assert report.n_shared_edges == 104 and report.n_g1_edges == 104
    assert report.max_gap_relative < GAP
    assert report.max_normal_jump_deg < ANGLE_DEG


def split_ring_size(shape) -> float:
    return check_continuity(shape).diagonal


def test_split_edges_are_same_parameter_exactly(split_shape):
    """On every edge the 3D curve and both faces' pcurve points coincide at 9 samples: the
    coarse face's segment pcurve is the de Casteljau piece of its side (round-off only)."""
    edge_faces, _ = t_edges(split_shape)
    worst = 0.0
    for i in range(1, edge_faces.Extent() + 1):
        edge = TopoDS.Edge_s(edge_faces.FindKey(i))
        assert BRep_Tool.SameParameter_s(edge) and BRep_Tool.SameRange_s(edge)
        curve = BRepAdaptor_Curve(edge)
        for face in edge_faces.FindFromIndex(i):
            face = TopoDS.Face_s(face)
            pcurve, surf = BRepAdaptor_Curve2d(edge, face), BRepAdaptor_Surface(face)
            for w in np.linspace(0.0, 1.0, 9):
                uv = pcurve.Value(float(w))
                worst = max(worst, curve.Value(float(w)).Distance(surf.Value(uv.X(), uv.Y())))
    assert worst < GAP * split_ring_size(split_shape)  # measured 1.4e-15 absolute


def test_split_ring_through_step(tmp_path, ring, split_shape):
    """Written and read back: one valid solid, no free edges, G1, the ring's volume.  STEP
    keeps 13 significant digits: measured gap 1e-13 of the size, 1e-9 deg, volume 6e-14
    relative."""
    path = write_step(split_shape, tmp_path / "split_ring.step", "split_ring")
    back = read_step(path)
    report = check_continuity(back)
    assert report.valid and report.n_solids == 1 and report.n_free_edges == 0
    assert report.n_faces == 48 and report.n_shared_edges == 104
    assert report.max_gap_relative < 1e-12
    assert report.max_normal_jump_deg < 1e-7
    assert volume(back) == pytest.approx(volume(to_shape(ring)), rel=1e-11)


# --------------------------------------------------------------------------- guards


def test_readers_of_side_edge_refuse_split_sides(split_ring):
    with pytest.raises(UnsupportedError, match="T-junctions"):
        sample_graph(SimpleNamespace(topology=split_ring.topology), np.arange(3))


def test_packing_keeps_split_sides_shared(split_ring):
    """Packing reads the pieces: a block never crosses a split side, and the split sides stay
    shared edges of the packed faces (one valid solid, no free edge)."""
    from patching.evaluation.packing import block_neighbours

    shape, report = to_packed_shape(split_ring, np.ones((split_ring.n_patches, 2)))
    assert report.packed_faces >= 1 and count(shape, TopAbs_SOLID) == 1
    result = check_continuity(shape)
    assert result.valid and result.n_free_edges == 0 and result.max_gap_relative < 1e-12
    split = np.diff(split_ring.topology.side_indptr).reshape(-1, 4) != 1
    nb = block_neighbours(split_ring)
    assert np.all(nb[split] == -1)
    assert find_blocks(split_ring, np.ones((split_ring.n_patches, 2)))


def test_packing_still_works_on_the_unsplit_table(ring):
    """The piece arrays of an unsplit topology do not disturb packing."""
    shape, report = to_packed_shape(ring, np.ones((ring.n_patches, 2)))
    assert report.packed_faces >= 1 and count(shape, TopAbs_SOLID) == 1


# --------------------------------------------------------------------------- adaptive patches


def adaptive_cases():
    """Meshes of tests/test_adaptive.py: a closed torus with random intervals and semi-sharp
    edges, a torus with two triangles (bi-quintic patches beside the T-junctions), an open
    bumped grid with semi-sharp edges and a corner tag (a shell)."""
    from tests.helpers import CASES

    return [(name, mesh) for name, mesh in CASES if name in ("torus_random", "torus_triangles", "grid_uniform")]


ADAPTIVE_CASES = adaptive_cases()


@pytest.mark.parametrize("name,mesh", ADAPTIVE_CASES, ids=[c[0] for c in ADAPTIVE_CASES])
def test_adaptive_patches_give_a_valid_b_rep(name, mesh):
    """patching.operator.adaptive's leaves and junction table through ``adaptive_surface``: one valid
    solid (closed) or shell (open) with split sides, every inner edge G1 with round-off gaps,
    and for the closed ones the volume of the global construction's surface."""
    import patching
    from patching.operator.adaptive import adaptive_operator
    from patching.operator.split_sides import adaptive_surface

    ap = adaptive_operator(mesh)
    surface = adaptive_surface(ap, mesh.vertices, name)
    assert surface.topology.has_split_sides
    shape = to_shape(surface)
    report = check_continuity(shape)
    closed = name.startswith("torus")
    assert report.valid and (report.n_solids, report.n_shells) == ((1, 1) if closed else (0, 1))
    assert report.n_faces == ap.n_patches
    assert (report.n_free_edges == 0) == closed
    assert report.n_g1_edges == report.n_shared_edges  # no sharp edge left at level N
    # Measured 2e-16 .. 5e-16 and 3e-12 .. 9e-12 deg: round-off of the level-N operator.
    assert report.max_gap_relative < GAP
    assert report.max_normal_jump_deg < 1e-9
    if closed and name == "torus_triangles":
        reference = patching.build_operator(mesh).evaluate(mesh.vertices)
        assert volume(shape) == pytest.approx(volume(to_shape(reference)), rel=VOLUME)
