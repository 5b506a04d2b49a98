"""Helpers that several test modules share: meshes, references and checks (each defined
once here, imported where used)."""

from __future__ import annotations

import dataclasses
import itertools
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from OCP.Bnd import Bnd_Box

from export.ocp_compat import box_bounds
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
from OCP.TopExp import TopExp
from export.ocp_compat import TopoDS
from export.ocp_compat import TopTools_IndexedMapOfShape

import patching
from patching.bernstein import elevation_matrix_2d, evaluate_pairs
from patching.evaluation.sampling import evaluate_nets
from patching.extraordinary import cluster_fairing
from patching.extraordinary.anchor_fairing import faired_anchors
from patching.extraordinary.auxiliary_points import anchor_matrix
from patching.extraordinary.extraction import cubic_extraction
from patching.extraordinary import g1_patches
from patching.extraordinary.g1_patches import G1Assembly, RowMixer, ep_groups
from patching.operator.adaptive import adaptive_operator, child_parameters
from patching.operator.assembly import _sector_anchors
from patching.subdivision import subdivide
from patching.surface import BezierSurface, PatchGroup, PatchTopology
from patching.topology.features import features
from patching.topology.tables import Topology
from tests.conftest import SHAPES

# --- meshes and surface differences of the adaptive path

# Positions agree to round-off of a few de Casteljau-like products on coordinates of size ~1;
# 1e-10 of the size leaves room for the level-N operator's longer sums.
TOL = 1e-10


def torus_mesh(m, n, rng=None):
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


def adaptive_grid(m, n, rng=None):
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


def adaptive_meshes():
    rng = np.random.default_rng(7)
    v, f, iv = torus_mesh(12, 10, rng)
    yield "torus_random", patching.from_arrays(v, f, intervals=iv, creases={(0, 1): 2.5, (1, 2): 2.5, (2, 3): 1.0})
    v, f, iv = adaptive_grid(10, 9)
    yield "grid_uniform", patching.from_arrays(v, f, creases={(44, 45): 3.0, (45, 46): 3.0}, corners={60: 2.0})
    v, f, iv = adaptive_grid(10, 9, rng)
    yield "grid_random", patching.from_arrays(v, f, intervals=iv, creases={(44, 45): 2.0, (45, 46): 2.0})
    # One interval tag: every tag value is 2, but the untagged strips keep 1, so the knots are
    # not uniform and the boundary vertices are no regular crease vertices (seeds).
    v, f, _ = adaptive_grid(10, 9)
    yield "grid_one_tag", patching.from_arrays(v, f, intervals={(20, 30): 2.0}, creases={(44, 45): 3.0, (45, 46): 3.0})
    v, f, _ = torus_mesh(10, 8)
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


CASES = list(adaptive_meshes())


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




# --- Bézier surfaces made by hand and B-rep counts

def topology_from_quads(quads) -> PatchTopology:
    """Shared corners and sides of quads given by vertex ids (v0 v1 v2 v3, counter-clockwise).

    Edge ids in order of first use (row, then side); an edge's own direction is its first side's.
    """
    quads = np.asarray(quads, dtype=np.int64)
    side_edge = np.zeros(quads.shape, np.int64)
    side_reversed = np.zeros(quads.shape, bool)
    edges: dict[tuple[int, int], tuple[int, tuple[int, int]]] = {}
    for r, quad in enumerate(quads):
        for k in range(4):
            a, b = int(quad[k]), int(quad[(k + 1) % 4])
            eid, own = edges.setdefault((min(a, b), max(a, b)), (len(edges), (a, b)))
            side_edge[r, k] = eid
            side_reversed[r, k] = own != (a, b)
    return PatchTopology(quads, side_edge, side_reversed, int(quads.max()) + 1, len(edges))


def elevate(net: np.ndarray, degree: int) -> np.ndarray:
    """Degree-elevate a (d+1, d+1, 3) Bézier net to ``degree`` in both directions (exact)."""
    for _ in range(degree - (net.shape[0] - 1)):
        for axis in (0, 1):
            net = np.moveaxis(net, axis, 0)
            n = net.shape[0] - 1  # b'_i = i/(n+1) b_{i-1} + (1 - i/(n+1)) b_i
            a = (np.arange(n + 2) / (n + 1))[:, None, None]
            lower = np.concatenate([net[:1], net])
            upper = np.concatenate([net, net[-1:]])
            net = np.moveaxis(a * lower + (1 - a) * upper, 0, axis)
    return net


def surface_from_nets(quads, nets, degrees=None, name="test") -> BezierSurface:
    """A BezierSurface from per-quad nets (any degrees), one PatchGroup per degree."""
    nets = list(nets)
    degrees = [n.shape[0] - 1 for n in nets] if degrees is None else list(degrees)
    nets = [elevate(n, d) for n, d in zip(nets, degrees)]
    quads = np.asarray(quads)
    order = sorted(range(len(nets)), key=lambda r: degrees[r])  # rows follow the groups
    groups = tuple(
        PatchGroup(d, np.array([r for r in order if degrees[r] == d]), np.array([nets[r] for r in order if degrees[r] == d]))
        for d in sorted(set(degrees))
    )
    points = np.concatenate([n.reshape(-1, 3) for n in nets])
    size = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    return BezierSurface(groups, topology_from_quads(quads[order]), name, size)


def bilinear_net(corners, degree: int = 3) -> np.ndarray:
    """The bilinear patch on 4 corners (v0 v1 v2 v3) as a degree-``degree`` net."""
    c = np.asarray(corners, float)
    s = np.linspace(0.0, 1.0, degree + 1)[:, None, None]
    t = np.linspace(0.0, 1.0, degree + 1)[None, :, None]
    return (1 - s) * (1 - t) * c[0] + s * (1 - t) * c[1] + s * t * c[2] + (1 - s) * t * c[3]


UNIT_CUBE_CORNERS = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float
)


#: Counter-clockwise seen from outside, so S_s x S_t points out.
CUBE_QUADS = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def cube_surface(degrees=(3,) * 6, quads=CUBE_QUADS) -> BezierSurface:
    """The unit cube: 6 flat patches (bilinear, degree-elevated), 8 vertices, 12 edges."""
    return surface_from_nets(quads, [bilinear_net(UNIT_CUBE_CORNERS[q], 1) for q in quads], degrees, "cube")


#: Uniform cubic B-spline segment to Bézier: (b0..b3) = BSPLINE_TO_BEZIER @ (P0..P3).
BSPLINE_TO_BEZIER = np.array([[1, 4, 1, 0], [0, 4, 2, 0], [0, 2, 4, 0], [0, 1, 4, 1]]) / 6.0


def torus_surface(m: int = 8, n: int = 6, degrees=None, big: float = 3.0, small: float = 1.0) -> BezierSurface:
    """Periodic uniform bicubic B-spline on an m x n torus grid, as m*n Bézier patches: C2.

    Patch (i, j) is row i*n + j (when all degrees are equal), s along i, t along j.
    """
    u = 2 * np.pi * np.arange(m) / m
    v = 2 * np.pi * np.arange(n) / n
    uu, vv = np.meshgrid(u, v, indexing="ij")
    ring = big + small * np.cos(vv)
    grid = np.stack([ring * np.cos(uu), ring * np.sin(uu), small * np.sin(vv)], axis=-1)
    quads, nets = [], []
    for i in range(m):
        for j in range(n):
            local = grid[np.ix_((np.arange(4) + i - 1) % m, (np.arange(4) + j - 1) % n)]
            nets.append(np.einsum("ia,jb,abx->ijx", BSPLINE_TO_BEZIER, BSPLINE_TO_BEZIER, local))
            vid = [((i + a) % m) * n + (j + b) % n for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))]
            quads.append(vid)
    return surface_from_nets(quads, nets, degrees, "torus")


def single_patch(degree: int = 3) -> BezierSurface:
    """One open, curved patch."""
    s = np.linspace(0, 1, degree + 1)
    ss, tt = np.meshgrid(s, s, indexing="ij")
    net = np.stack([ss, tt, 0.3 * np.sin(3 * ss) * tt], axis=-1)
    return surface_from_nets([[0, 1, 2, 3]], [net], name="patch")


def seam_tube() -> BezierSurface:
    """One bi-quintic patch closed on itself in s: its sides 1 and 3 are one (seam) edge.

    The s-rows follow a C1 closed quintic loop (P5 = P0, P5 - P4 = P1 - P0); corners 0, 1
    are one vertex and so are 2, 3, so sides 0 and 2 are closed edges.
    """
    loop = np.array([[0, 0], [1, 0], [2, 2], [-2, 2], [-1, 0], [0, 0]], float)
    height = np.linspace(0.0, 1.0, 6)
    net = np.stack(np.broadcast_arrays(loop[:, None, 0], loop[:, None, 1], height[None, :]), axis=-1)
    return surface_from_nets([[0, 0, 1, 1]], [net], name="tube")


def volume(shape) -> float:
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return props.Mass()


def bernstein_with_derivatives(d: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(len(x), d+1) values B_i^d(x) and derivatives."""
    from math import comb

    i = np.arange(d + 1)
    x = np.asarray(x, float)[:, None]
    b = np.array([comb(d, k) for k in i]) * x**i * (1 - x) ** (d - i)
    lower = np.array([comb(d - 1, k) for k in range(d)]) * x ** i[:-1] * (1 - x) ** (d - 1 - i[:-1])
    db = d * (np.pad(lower, ((0, 0), (1, 0))) - np.pad(lower, ((0, 0), (0, 1))))
    return b, db


def net_volume(surf: BezierSurface) -> float:
    """Enclosed volume 1/3 sum over patches of the integral of S . (S_s x S_t), by Gauss-Legendre.

    The integrand has degree <= 3d - 1 in each variable, so 10 nodes (exact to degree 19)
    integrate it exactly for d <= 5: an independent reference for BRepGProp.
    """
    x, w = np.polynomial.legendre.leggauss(10)
    x, w = (x + 1) / 2, w / 2
    total = 0.0
    for group in surf.groups:
        b, db = bernstein_with_derivatives(group.degree, x)
        for net in group.coefficients:
            p = np.einsum("ai,bj,ijx->abx", b, b, net)
            ps = np.einsum("ai,bj,ijx->abx", db, b, net)
            pt = np.einsum("ai,bj,ijx->abx", b, db, net)
            total += np.einsum("a,b,abx,abx->", w, w, p, np.cross(ps, pt)) / 3
    return float(total)


def count(shape, kind) -> int:
    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, kind, found)
    return found.Extent()


def edges_of(shape):
    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_EDGE, found)
    return [TopoDS.Edge_s(found.FindKey(i)) for i in range(1, found.Extent() + 1)]


def faces_of(shape):
    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, found)
    return [TopoDS.Face_s(found.FindKey(i)) for i in range(1, found.Extent() + 1)]




# --- a small L-shaped part

def ell_mesh() -> patching.ControlMesh:
    """An L-shaped polycube (EPs of valence 3 and 5) whose strips carry intervals 0.5 to 3, so
    that the angle configuration and the anchor rule change the patches."""
    from patching.mesh.primitives import polycube
    from patching.topology.tables import Topology

    cube = polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0)], 2, name="ell")
    topo = Topology(cube)
    intervals = {}
    for strip in range(topo.n_strips):
        a, b = topo.edges[int(np.flatnonzero(topo.edge_strip == strip)[0])]
        intervals[(int(a), int(b))] = (1, 2, 0.5, 3, 1.5)[strip % 5]
    faces = [list(cube.face(f)) for f in range(cube.n_faces)]
    return patching.from_arrays(cube.vertices, faces, intervals=intervals, name="ell")




# --- the command line's refusals

def assert_refused(result, *fragments: str) -> str:
    assert result.returncode == 2, (result.returncode, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("nupatch: error: "), lines[0]
    assert "Traceback" not in result.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]




# --- clusters of EPs

def clusters_of(mesh, max_eps=None):
    """The EP clusters build_operator solves jointly (its EPs: smooth extraordinary vertices
    and sector vertices)."""
    topo = Topology(mesh)
    feats = features(topo)
    smooth = (feats.count == 0) & ~feats.corner
    eps = np.union1d(topo.extraordinary[smooth[topo.extraordinary]], np.flatnonzero(feats.sector_vertex))
    groups = ep_groups(topo, eps, feats)
    found = cluster_fairing.ep_clusters(groups, topo, max_eps)
    return [sorted(int(groups[k].vertices[e]) for k, e in c) for c in found]




# --- distances to a surface

def distance_to_surface(surface, q) -> float:
    """Distance from q to the patches, by Gauss-Newton from the patch centres."""
    return float(distances_to_surface(surface, np.asarray(q, dtype=np.float64)[None])[0])


def distances_to_surface(surface, qs) -> np.ndarray:
    """Distances from each of the (m, 3) points qs to the patches: (m,).

    Per point: 30 Gauss-Newton steps (least-squares step, clipped to [0, 1]^2) from the centre
    of each of the 4 patches whose net centres are nearest, the smallest distance reached.  The
    same iteration for every (point, patch) pair at once (``evaluate_pairs``, one batched
    pseudo-inverse per step), so thousands of points cost a few hundred array operations."""
    qs = np.asarray(qs, dtype=np.float64).reshape(-1, 3)
    nets = [net for _, _, _, net in surface.patches()]
    centres = np.array([net.mean(axis=(0, 1)) for net in nets])
    near = np.argsort(np.linalg.norm(centres[None] - qs[:, None], axis=2), axis=1)[:, :4]
    dist = np.full(near.shape, np.inf)
    degree = np.array([net.shape[0] for net in nets])
    for d in np.unique(degree):  # stack nets of one degree together
        rows, cols = np.nonzero(degree[near] == d)
        stacked = np.array([nets[c] for c in near[rows, cols]]).reshape(len(rows), d, d, 3)
        q = qs[rows]
        s, t = np.full(len(rows), 0.5), np.full(len(rows), 0.5)
        for _ in range(30):
            p, ds, dt = evaluate_pairs(stacked, s, t, derivatives=True)
            step = np.einsum("kij,kj->ki", np.linalg.pinv(np.stack([ds, dt], 2)), q - p)
            s, t = np.clip(s + step[:, 0], 0.0, 1.0), np.clip(t + step[:, 1], 0.0, 1.0)
        dist[rows, cols] = np.linalg.norm(evaluate_pairs(stacked, s, t) - q, axis=1)
    return dist.min(axis=1)




def prism(n: int, height: float = 1.0) -> patching.ControlMesh:
    """The n-gonal prism of unit circumradius: caps 0 (top, outward up) and 1 (bottom)."""
    a = 2 * np.pi * np.arange(n) / n
    ring = np.stack([np.cos(a), np.sin(a)], axis=1)
    verts = np.vstack([np.c_[ring, np.full(n, height)], np.c_[ring, np.zeros(n)]])
    top = list(range(n))
    bottom = [n + i for i in reversed(range(n))]
    sides = [[n + i, n + (i + 1) % n, (i + 1) % n, i] for i in range(n)]
    return patching.from_arrays(verts, [top, bottom, *sides], name=f"prism{n}")


# --- discs around one EP

def ep_disc(
    n: int, intervals=None, rings: int = 3, name: str | None = None, layout: str = "knots"
) -> patching.ControlMesh:
    """A planar disc of quads around one EP of valence n (vertex 0), for blending functions.

    Sector i (between spokes i and i+1, counter-clockwise) is a (rings + 1) x (rings + 1) grid;
    its vertex (a, b) sits at U_i[a] e_i + U_{i+1}[b] e_{i+1}, e_i the unit vector at angle
    2 pi i / n and U_i the partial sums of the intervals of spoke i, so the layout follows
    the knots (layout="knots"; layout="uniform" spaces the vertices 1 apart, as a picture of a
    control grid would, whatever the intervals).  intervals: (n, rings) knot intervals; intervals[i, j] is the strip crossing
    spoke i at its j-th edge from the EP (j = 0 is the spoke edge d_i of the paper, j = 1 the
    a_i of its Fig. 11).  A last ring of zero-interval strips clamps the boundary (the
    operator builds no patch on open boundaries), so the rings x rings patches per sector hold
    the whole support of every blending function of the EP and its 2n neighbours for
    rings >= 3 (a cubic B-spline spans 4 intervals).
    """
    k = rings + 1
    d = np.ones((n, rings)) if intervals is None else np.asarray(intervals, dtype=np.float64)
    d = np.concatenate([d, np.zeros((n, 1))], axis=1)
    spacing = d if layout == "knots" else np.ones_like(d)
    cum = np.concatenate([np.zeros((n, 1)), np.cumsum(spacing, axis=1)], axis=1)
    ang = 2 * np.pi * np.arange(n) / n
    e = np.stack([np.cos(ang), np.sin(ang), 0 * ang], axis=1)
    ids: dict[tuple, int] = {}
    verts = [np.zeros(3)]

    def vid(i: int, a: int, b: int) -> int:
        i %= n
        if a == 0 and b == 0:
            return 0
        key = ("spoke", i, a) if b == 0 else ("spoke", (i + 1) % n, b) if a == 0 else ("face", i, a, b)
        if key not in ids:
            ids[key] = len(verts)
            if key[0] == "spoke":
                verts.append(cum[key[1], key[2]] * e[key[1]])
            else:
                verts.append(cum[i, a] * e[i] + cum[(i + 1) % n, b] * e[(i + 1) % n])
        return ids[key]

    faces = [
        [vid(i, a, b), vid(i, a + 1, b), vid(i, a + 1, b + 1), vid(i, a, b + 1)]
        for i in range(n)
        for a in range(k)
        for b in range(k)
    ]
    tags = {(vid(i, j, 0), vid(i, j + 1, 0)): float(d[i, j]) for i in range(n) for j in range(k)}
    return patching.from_arrays(np.array(verts), faces, intervals=tags, name=name or f"ep-disc-{n}")


def lifted(mesh: patching.ControlMesh, seed: int = 0, scale: float = 0.3) -> patching.ControlMesh:
    """The same mesh with random heights (the operator does not see positions)."""
    rng = np.random.default_rng(seed)
    v = mesh.vertices.copy()
    v[:, 2] = scale * rng.normal(size=len(v))
    return mesh.with_positions(v)




# --- an exact box

def exact_box(shape) -> np.ndarray:
    """(2, 3) bounding box of the exact surfaces (not of poles, not enlarged by tolerances)."""
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape, box, False, False)
    x0, y0, z0, x1, y1, z1 = box_bounds(box)
    return np.array([[x0, y0, z0], [x1, y1, z1]])




# --- closed quad meshes with EPs, random intervals, normal jumps

CUBE_VERTICES = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)


CUBE_FACES = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]


def quad_mesh_with_eps(kind: str) -> patching.ControlMesh:
    """Closed all-quad meshes with EPs: one Catmull-Clark step of small polyhedra."""
    if kind == "cube":
        return patching.from_arrays(CUBE_VERTICES, CUBE_FACES, name="cube")
    n = int(kind.split("-")[1])  # bipyramid-n: apexes of valence n after one step
    ang = 2 * np.pi * np.arange(n) / n
    v = np.vstack([np.stack([np.cos(ang), np.sin(ang), 0 * ang], 1), [[0, 0, 1.3], [0, 0, -1.3]]])
    f = [[i, (i + 1) % n, n] for i in range(n)] + [[(i + 1) % n, i, n + 1] for i in range(n)]
    tri = patching.from_arrays(v, f, name=kind)
    return subdivide(tri, 1, rules="opensubdiv")


def with_random_intervals(mesh: patching.ControlMesh, ratio: float, seed: int) -> patching.ControlMesh:
    """The same mesh and tags with strip intervals drawn uniformly from [1, ratio]."""
    topo = Topology(mesh)
    rng = np.random.default_rng(seed)
    values = rng.uniform(1.0, ratio, topo.n_strips)
    first = np.unique(topo.edge_strip, return_index=True)[1]
    iv = {tuple(int(x) for x in topo.edges[e]): float(values[topo.edge_strip[e]]) for e in first}
    faces = [list(mesh.face(i)) for i in range(mesh.n_faces)]
    return patching.from_arrays(
        mesh.vertices, faces, intervals=iv, creases=dict(mesh.creases), corners=dict(mesh.corners),
        holes=sorted(mesh.holes), interpolate_boundary=mesh.interpolate_boundary, name=mesh.name,
    )


def shared_edge_normal_jumps(surface, samples: int = 7, skip=()) -> tuple[float, float]:
    """Largest normal angle (degrees) and gap along every shared edge, evaluated with numpy:
    a second implementation beside export.continuity (OpenCASCADE).  skip: edge ids (of the
    patch topology) left out of the angle, e.g. sharp edges."""
    topo = surface.topology
    nets = [net for _, _, _, net in surface.patches()]
    uses: dict[int, list[tuple[int, int]]] = {}
    for row in range(topo.side_edge.shape[0]):
        for side in range(4):
            uses.setdefault(int(topo.side_edge[row, side]), []).append((row, side))
    w = np.linspace(0.02, 0.98, samples)
    worst_angle, worst_gap = 0.0, 0.0
    for e, pair in uses.items():
        if len(pair) != 2:
            continue
        values = []
        for row, side in pair:
            u = 1 - w if topo.side_reversed[row, side] else w
            s, t = {0: (u, 0 * u), 1: (1 + 0 * u, u), 2: (1 - u, 1 + 0 * u), 3: (0 * u, 1 - u)}[side]
            p, ds, dt = evaluate_nets(nets[row][None], s, t, derivatives=True)
            n = np.cross(ds[0], dt[0])
            values.append((p[0], n / np.linalg.norm(n, axis=1, keepdims=True)))
        (p1, n1), (p2, n2) = values
        worst_gap = max(worst_gap, float(np.abs(p1 - p2).max()))
        angle = np.degrees(np.arctan2(np.linalg.norm(np.cross(n1, n2), axis=1), (n1 * n2).sum(1)))
        if e not in skip:
            worst_angle = max(worst_angle, float(angle.max()))
    return worst_angle, worst_gap




# --- dihedral angles

def dihedral(net: np.ndarray):
    """The 8 re-parametrisations of a square net (rotations and reflections)."""
    for k in range(4):
        r = np.rot90(net, k, axes=(0, 1))
        yield r
        yield r.transpose(1, 0, 2)




# --- the dense step-by-step reference of M

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
        rule = "eigen-polyhedron" if anchors == "faired" else anchors
        smooth_groups = [g for g in groups if g.theta is None]
        anchor_rows = anchor_matrix(topo, smooth_groups, ext.anchor_column, n, rule=rule).toarray()
        anchor_rows += _sector_anchors(topo, feats, groups, ext.anchor_column, n).toarray()
        # the blending functions before the G1 steps, which the monotone-spoke step reads
        # (``G1Assembly.reference``): the elevated rows with the anchors' rows folded in
        initial = rows[:, :n] + rows[:, n:] @ anchor_rows
        g1.reference = lambda r: sp.csr_matrix(initial[np.asarray(r)])
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
    blocks = [nets[16 * f : 16 * f + 16] for f in cubic] + [rows[face_row[f] : face_row[f] + 36] for f in quintic]
    stacked = np.vstack(blocks)
    if anchors == "faired" and ext.n_anchors:
        degrees = np.array([3] * len(cubic) + [5] * len(quintic))
        sets = [ext.anchor_column[g.h[e]] - n for g in groups if g.theta is None for e in range(len(g.vertices))]
        faired = faired_anchors(sp.csr_matrix(stacked), n, sp.csr_matrix(anchor_rows), sets, degrees, spans[cubic + quintic])
        anchor_rows = faired.toarray()
    return stacked[:, :n] + stacked[:, n:] @ anchor_rows


def boundary_ep(mode: int) -> patching.ControlMesh:
    """bipyramid-5 without one face at a pole: a boundary EP of valence 5 (a ring with a gap)."""
    base = quad_mesh_with_eps("bipyramid-5")
    topo = Topology(base)
    drop = int(topo.face[topo.outgoing[base.n_vertices - 2]])
    faces = [list(base.face(f)) for f in range(base.n_faces) if f != drop]
    return with_random_intervals(patching.from_arrays(base.vertices, faces, interpolate_boundary=mode, name="open"), 5.0, seed=7)




# --- creases on meridians

def neighbours(topo: Topology, v: int) -> set:
    return {int(x) for e in topo.edges[(topo.edges == v).any(axis=1)] for x in e} - {v}


def meridian_crease(n: int, i: int, j: int, ratio: float, seed: int = 0, corners=None) -> patching.ControlMesh:
    """bipyramid-n after one Catmull-Clark step (two poles of valence n), with a closed crease
    down meridian i and up meridian j: both poles are crease EPs with sectors of j - i and
    n - (j - i) faces."""
    base = quad_mesh_with_eps(f"bipyramid-{n}")
    topo = Topology(base)
    first = base.n_vertices - (n + 2)  # the refinement lists the original vertices last
    top, bottom, i, j = first + n, first + n + 1, first + i, first + j
    loop = []
    for a, b in ((top, i), (i, bottom), (bottom, j), (j, top)):
        (mid,) = neighbours(topo, a) & neighbours(topo, b)
        loop += [a, mid]
    creases = {(loop[k], loop[(k + 1) % len(loop)]): np.inf for k in range(len(loop))}
    mesh = patching.from_arrays(base.vertices, base.quads(), creases=creases, corners=corners or {}, name="meridians")
    return with_random_intervals(mesh, ratio, seed) if ratio > 1 else mesh


def roof_mesh(n: int = 4, slope: float = 0.08, crease: bool = True):
    """A roof z = -slope |x| over [-2, 2]^2 on an n x n grid; the ridge x = 0 creased
    (infinitely sharp: a G0 edge) or not (the subdivision rounds it: G1)."""
    xs = np.linspace(-2, 2, n + 1)
    verts = [[x, y, -slope * abs(x)] for x in xs for y in xs]
    faces = [[i * (n + 1) + j, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1, i * (n + 1) + j + 1] for i in range(n) for j in range(n)]
    ridge = n // 2
    creases = {(ridge * (n + 1) + j, ridge * (n + 1) + j + 1): 10.0 for j in range(n)} if crease else {}
    return patching.from_arrays(verts, faces, creases=creases, name="roof")


def clear_package_caches() -> None:
    """Empty every in-process cache of the package (lru_cache and ``patching.util.memo``), so
    that each local solve runs again or asks the persistent store."""
    for name, module in list(sys.modules.items()):
        if name.startswith("patching.") and module is not None:
            for value in list(vars(module).values()):
                if not isinstance(value, type) and callable(getattr(value, "cache_clear", None)) and hasattr(value, "cache_info"):
                    value.cache_clear()


# --- the monotone spoke step as first shipped (the reference of the dual, batched solve)

def _bounded_least_change(metric: np.ndarray, bmat: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
    """argmin z^T metric z subject to lo <= bmat z <= hi (metric SPD), or None where z = 0
    already satisfies it or no feasible point is found.

    A simplified form of [GI83]'s dual active-set method (full steps: no partial step when a
    multiplier changes sign): z = 0 is the unconstrained minimum; the most violated bound joins
    the active set (as an equality), the equality problem is solved exactly
    (z = A^-1 G^T (G A^-1 G^T)^-1 r), and an active bound whose multiplier has the wrong sign
    (the solution would rather leave it) is dropped; it stops when no bound is violated, so a
    returned z always satisfies every bound (it may not be the exact minimiser).  A few dozen bounds, so a few dozen small solves; SciPy's SLSQP
    took about 40 ms a ring here, this about 1 ms.  Falls back to None after 4 m steps."""
    tol = 1e-12 * max(1.0, float(np.abs(np.concatenate([lo, hi])).max()))
    if np.all(lo <= tol) and np.all(hi >= -tol):
        return None
    a_inv = np.linalg.inv(metric)
    active: dict[int, bool] = {}  # bound -> True: at lo (bmat z >= lo), False: at hi
    z = np.zeros(metric.shape[0])
    for _ in range(4 * bmat.shape[0] + 4):
        value = bmat @ z
        excess = np.maximum(lo - value, value - hi)
        excess[list(active)] = -np.inf
        j = int(np.argmax(excess))
        if excess[j] <= tol:
            return z
        active[j] = bool(lo[j] - value[j] > value[j] - hi[j])
        while True:
            idx = list(active)
            g = bmat[idx]
            r = np.where([active[i] for i in idx], lo[idx], hi[idx])
            schur = g @ a_inv @ g.T
            mu = np.linalg.lstsq(schur, r, rcond=1e-13)[0]
            wrong = [k for k, i in enumerate(idx) if (mu[k] < 0) == active[i] and abs(mu[k]) > 1e-14 * max(1.0, np.abs(mu).max())]
            if not wrong or len(idx) == 1:
                break
            del active[idx[max(wrong, key=lambda k: abs(mu[k]))]]
        z = a_inv @ g.T @ mu
        if np.abs(g @ z - r).max() > 1e-9 * max(1.0, np.abs(r).max()):
            return None  # dependent active bounds that cannot all hold
    return None


def _change_space(n: int, key: tuple, pinned: tuple, skip: tuple):
    """(y, C_y, Z) of one ring configuration: stage 2's unknowns, G_1 over them, and a basis
    Z of the changes D of their rows (vec(D) row-major, D[r, j] at r (1 + 3n) + j) with
    C_y D = 0 and D 1 = 0; None without G_1 rows."""
    rows = g1_patches._red_rows(n, key, skip)
    if not rows[1]:
        return None
    size = 1 + 3 * n
    y = g1_patches._stage2_unknowns(n, pinned, -1)
    cy = np.vstack(rows[1])[:, y]
    fixed = np.vstack([np.kron(cy, np.eye(size)), np.kron(np.eye(y.size), np.ones((1, size)))])
    out = (y, cy, g1_patches._null_space(fixed))
    for a in out:
        a.setflags(write=False)
    return out


def monotone_red_primal(
    n: int, key: tuple, pinned: tuple, skip: tuple, q_weight: float, k: np.ndarray,
    x: np.ndarray, bounds: list[tuple[int, int, float, float]],
) -> np.ndarray | None:
    """The monotone step of one ring as first shipped (issue 19), the reference of
    ``g1_patches._monotone_red``: an explicit basis Z of the changes (``_change_space``, an SVD
    of ~3 n^2 x 6 n^2), the (6 n^2)^2 metric, and the primal active set
    (``_bounded_least_change``).  The red operator K of one closed ring, changed as little as possible so that the
    blending functions keep the monotone spoke curves the extraction gave them (module
    docstring, "monotone spoke curves"); None where no change inside G_1 can.

    ``x``: (1 + 3n, C) the blending functions of the C control points that reach the ring, at
    the red inputs x_hat (columns of the elevated extraction with the anchors folded in:
    topology and intervals only); after the solve they are K x.  ``bounds``: (column c,
    spoke i, lo, hi): the value of function c at q_i must lie in [lo, hi] (the bounds that
    make the black step's P30 lie between q_i and P40 and q_i between s_i and P30).  Stage 2's
    rows y = [f, q] of K change by D with C_y D = 0 (G_1 stays exact for every input), D 1 = 0
    (rows still sum to one: affine invariance), and (D x)[q_i, c] putting the value on the
    bound it broke (active set: a broken bound becomes an equality until none is broken), D
    least in the change of every function it touches, sum_rows w_r |D_r x|^2 (w: 1 on f,
    ``q_weight`` on q, stage 2's metric).  K + D stays linear in the control points."""
    system = _change_space(n, key, pinned, skip)
    if system is None:
        return None
    size = 1 + 3 * n
    y, cy, basis = system
    ny = y.size
    row_of = {int(j): r for r, j in enumerate(y.tolist())}
    w = np.where(y >= 1 + 2 * n, q_weight, 1.0)
    # x x^T is singular where the functions do not span the inputs: a change D with D x = 0
    # alters no function, and left free it lets the solver wander off to weights of 1e9 that
    # break G_1 in rounding; a small ridge (the weights' own size) pins those directions.
    gram = x @ x.T
    gram += (g1_patches.RIDGE * np.trace(gram) / size + 1e-300) * np.eye(size)
    v = k[y] @ x  # (ny, C)
    # D = reshape(Z z): Z a basis of the D that keep G_1 and the row sums; the bounds on
    # (D x)[q_i, c] are rows of B z.  Objective |M^(1/2) Z z|^2, M = W (x) (x x^T).
    metric = basis.T @ np.kron(np.diag(w), gram) @ basis
    b_rows, lo, hi = [], [], []
    for col, i, low, high in bounds:
        r = row_of[1 + 2 * n + i]
        pick = np.zeros(ny * size)
        pick[r * size : (r + 1) * size] = x[:, col]
        b_rows.append(pick @ basis)
        lo.append(low - v[r, col])
        hi.append(high - v[r, col])
    bmat, lo, hi = np.array(b_rows), np.array(lo), np.array(hi)
    z = _bounded_least_change(metric, bmat, lo, hi)
    if z is None:
        return None
    d = (basis @ z).reshape(ny, size)
    if np.abs(d).max() > g1_patches.MAX_CHANGE or np.abs(cy @ d).max() > 1e-12:
        return None
    out = k.copy()
    out[y] += d
    return out


def whole_cache_entries(root) -> list[str]:
    """Names of the files under ``root/solves`` (``export.solve_cache``'s layout), each checked
    to be one whole entry for its name (digests right, no temporary files); fails otherwise."""
    from export.atomic import is_temporary_name
    from patching.util import solve_cache

    names = []
    for bucket in sorted((Path(root) / "solves").glob("*")):
        for f in sorted(bucket.iterdir()):
            assert not is_temporary_name(f.name), f"temporary left: {f}"
            data = f.read_bytes()
            count = int.from_bytes(data[len(b"NPSC1\n") + 64 + 32 :][:4], "little")
            assert solve_cache.decode(f.name, data, count) is not None, f"not a whole entry: {f}"
            names.append(f.name)
    return names
