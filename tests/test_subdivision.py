"""Subdivision: the sparse operator S against small, loop-based references written
here from the rules as published (classic Catmull-Clark; OpenSubdiv's documented Catmark,
crease and boundary rules; Biermann-Levin-Zorin as [TLC] sec. 2 states them), against
OpenCASCADE's knot insertion for non-uniform regular regions, and on the OpenSubdiv shapes.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections import defaultdict

import numpy as np
import pytest

from patching.errors import KnotError, MeshError, UnsupportedError
from patching.mesh.control_mesh import from_arrays
from export import write_obj
from patching.mesh.obj import read_obj
from patching.mesh.primitives import open_grid, torus_grid
from patching.subdivision import limit_points, limit_tangents, subdivide, subdivision_operator
from tests.conftest import SHAPES as SHAPES_DIR, shape_files
from tests.reference_refinement import occ_periodic_bicubic, occ_refined_poles, polar_disk, refined_ids, ring_ids

# Round-off: every reference point is a short sum of O(1) weights times coordinates of size
# O(10); both sides add the same terms in a different order.
TIGHT = 1e-12


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # creasemethod, smoothtriangles ... tags
        return read_obj(path)


def _manifold_shapes():
    out = []
    for path in shape_files("catmark_"):
        try:
            from patching.topology.tables import Topology

            Topology(_read(path))
        except MeshError:
            continue
        out.append(path)
    return out


SHAPES = _manifold_shapes()
NONMANIFOLD = [p for p in shape_files("catmark_") if p not in SHAPES]


# ---------------------------------------------------------------------------------------------
# The reference: one subdivision step computed point by point with dicts and loops.


def reference_step(mesh, rules: str, creasing: str = "uniform", triangles: str = "catmark"):
    """New points (face points, edge points by sorted (a, b), vertex points) by the rules as
    published; ``rules`` is "cc" (classic, tags ignored), "opensubdiv" or "blz"; ``creasing``
    "uniform" or "chaikin" (OpenSubdiv's Sdc::Options::CREASE_CHAIKIN, as sdc/crease.cpp and
    vtr/refinement.cpp apply it); ``triangles`` "catmark" or "smooth" (Sdc::Options::
    TRI_SUB_SMOOTH: catmarkScheme.h's smooth edge mask beside a triangle, Hbr's 0.470)."""
    P = mesh.vertices
    faces = [list(map(int, mesh.face(f))) for f in range(mesh.n_faces)]
    edge_faces = defaultdict(list)
    vert_faces = defaultdict(list)
    vert_nbrs = defaultdict(set)
    for f, fv in enumerate(faces):
        for i, v in enumerate(fv):
            w = fv[(i + 1) % len(fv)]
            edge_faces[(min(v, w), max(v, w))].append(f)
            vert_faces[v].append(f)
            vert_nbrs[v].add(w)
            vert_nbrs[w].add(v)
    tags = rules != "cc"

    def edge_sharp(key):
        if len(edge_faces[key]) == 1:
            return math.inf
        s = mesh.creases.get(key, 0.0) if tags else 0.0
        return math.inf if s >= 10 else s

    def vertex_sharp(v):
        s = mesh.corners.get(v, 0.0) if tags else 0.0
        if mesh.interpolate_boundary == 1 and len(vert_faces[v]) == 1 and len(vert_nbrs[v]) == 2:
            s = math.inf
        return math.inf if s >= 10 else s

    def dec(s):
        return s if math.isinf(s) else max(s - 1.0, 0.0) if s > 1 else 0.0

    def rule(vs, sharp_count):
        if vs > 0 or sharp_count > 2:
            return "corner"
        return ["smooth", "dart", "crease"][sharp_count]

    def child_sharp(a, b):
        """Sharpness of the half of edge a-b at a: Crease::SubdivideEdgeSharpnessAtVertex."""
        s = edge_sharp(key(a, b))
        if creasing == "uniform":
            return dec(s)
        if s <= 0 or math.isinf(s):
            return s
        semi = [x for x in (edge_sharp(key(a, w)) for w in vert_nbrs[a]) if 0 < x < math.inf]
        if len(semi) > 1:  # "3/4 original sharpness + 1/4 average of the others"
            s = 0.75 * s + 0.25 * (sum(semi) - s) / (len(semi) - 1)
        return s - 1.0 if s > 1.0 else 0.0

    fp = [P[fv].mean(axis=0) for fv in faces]

    def key(a, b):
        return (min(a, b), max(a, b))

    def theta(a, b, child: bool):
        """BLZ theta at tagged vertex a for the untagged edge a-b ([TLC] sec. 2)."""
        sharp = lambda k: (dec(edge_sharp(k)) if child else edge_sharp(k)) > 0  # noqa: E731
        n_sharp = sum(sharp(key(a, w)) for w in vert_nbrs[a])
        vs = dec(vertex_sharp(a)) if child else vertex_sharp(a)
        r = rule(vs, n_sharp)
        if r == "smooth":
            return None
        # sector of the edge: faces around a reached without crossing a sharp edge
        sector = set(edge_faces[key(a, b)])
        todo = list(sector)
        while todo:
            f = todo.pop()
            fv = faces[f]
            i = fv.index(a)
            for w in (fv[i - 1], fv[(i + 1) % len(fv)]):
                if sharp(key(a, w)):
                    continue
                for g in edge_faces[key(a, w)]:
                    if g not in sector:
                        sector.add(g)
                        todo.append(g)
        m = len(sector)
        if r == "dart":
            return 2 * math.pi / m
        if r == "crease":
            return math.pi / m
        alpha = sum(math.pi * (len(faces[f]) - 2) / len(faces[f]) for f in sector)
        return alpha / m

    def tagged(v, child):
        sharp = lambda k: (dec(edge_sharp(k)) if child else edge_sharp(k)) > 0  # noqa: E731
        vs = dec(vertex_sharp(v)) if child else vertex_sharp(v)
        return rule(vs, sum(sharp(key(v, w)) for w in vert_nbrs[v])) != "smooth"

    ep = {}
    for (a, b), fs in edge_faces.items():
        s = edge_sharp((a, b))
        mid = (P[a] + P[b]) / 2
        # Far::PrimvarRefiner: the child vertex is a crease when both halves stay sharp; else
        # the crease mask is blended with the parent sharpness s (unclamped, Scheme's
        # ComputeEdgeVertexMask), which is 1 for s = 1 under uniform creasing.
        if min(child_sharp(a, b), child_sharp(b, a)) > 0 or s == 1:
            ep[(a, b)] = mid
            continue
        smooth = (P[a] + P[b] + fp[fs[0]] + fp[fs[1]]) / 4
        if triangles == "smooth" and any(len(faces[f]) == 3 for f in fs):
            # each face point weighs the mean of 0.47 (triangle) and 0.25 (other face)
            fw = sum(0.47 if len(faces[f]) == 3 else 0.25 for f in fs) / 2
            smooth = (0.5 - fw) * (P[a] + P[b]) + fw * (fp[fs[0]] + fp[fs[1]])
        if rules == "blz":
            child = s > 0
            ta, tb = tagged(a, child), tagged(b, child)
            k = 0.5 if (ta and tb) else 1.0
            for x, y, t in ((a, b, ta), (b, a, tb)):
                if t:
                    gamma = 3 / 8 - math.cos(theta(x, y, child)) / 4
                    smooth = smooth + k * (3 / 8 - gamma) * (P[x] - P[y])
        ep[(a, b)] = s * mid + (1 - s) * smooth

    vp = np.array(P, copy=True)
    for v in range(len(P)):
        if not vert_faces[v]:
            continue
        nb = sorted(vert_nbrs[v])
        ps = [edge_sharp(key(v, w)) for w in nb]
        cs = [child_sharp(v, w) for w in nb]
        pv, cv = vertex_sharp(v), dec(vertex_sharp(v))
        pr = rule(pv, sum(s > 0 for s in ps))
        cr = rule(cv, sum(s > 0 for s in cs))

        def mask(r, sharpness):
            if r in ("smooth", "dart"):
                n = len(nb)
                return (n - 2) / n * P[v] + sum(P[w] for w in nb) / n**2 + sum(fp[f] for f in vert_faces[v]) / n**2
            if r == "crease":
                ends = [w for w, s in zip(nb, sharpness) if s > 0]
                return 0.75 * P[v] + 0.125 * (P[ends[0]] + P[ends[1]])
            return P[v]

        pm = mask(pr, ps)
        if pr in ("smooth", "dart") or cr == pr:
            vp[v] = pm
            continue
        # Crease::ComputeFractionalWeightAtVertex
        total, count = 0.0, 0
        if pv > 0 and cv <= 0:
            total, count = pv, 1
        for s, c in zip(ps, cs):
            if (0 < s <= 1) if creasing == "uniform" else (s > 0 and c <= 0):
                total += s
                count += 1
        pw = min(1.0, total / count) if count else 0.0
        vp[v] = pw * pm + (1 - pw) * mask(cr, cs)
    return np.array(fp), ep, vp


def reference_points(mesh, rules, creasing="uniform", triangles="catmark"):
    fp, ep, vp = reference_step(mesh, rules, creasing, triangles)
    edges = sorted(ep)
    return np.concatenate([fp, np.array([ep[k] for k in edges]), vp])


def _untagged(mesh):
    return from_arrays(mesh.vertices, [list(mesh.face(f)) for f in range(mesh.n_faces)], name=mesh.name)


def _is_closed(mesh):
    from patching.topology.tables import Topology

    return not Topology(mesh).edge_is_boundary.any()


def _size(mesh):
    return float(np.ptp(mesh.vertices, axis=0).max())


# ---------------------------------------------------------------------------------------------
# 1. Uniform Catmull-Clark on closed meshes without tags


@pytest.mark.skipif(not SHAPES, reason="opensubdiv-shapes folder absent")
@pytest.mark.parametrize("rules", ["seed", "opensubdiv"])
@pytest.mark.parametrize("path", SHAPES, ids=lambda p: p.stem)
def test_uniform_catmull_clark_on_closed_shapes(path, rules):
    mesh = _untagged(_read(path))
    if not _is_closed(mesh):
        pytest.skip("open mesh: boundary rules are tested below")
    for step in range(2):  # the first step turns n-gons into quads; the second is all-quad
        S, child = subdivision_operator(mesh, rules=rules)
        expected = reference_points(mesh, "cc")
        assert np.abs(S @ mesh.vertices - expected).max() <= TIGHT * _size(mesh)
        assert np.allclose(child.vertices, expected, rtol=0, atol=TIGHT * _size(mesh))
        mesh = _untagged(child)


def test_operator_rows_sum_to_one_and_depend_on_topology_only():
    mesh = torus_grid(5, 6)
    S, _ = subdivision_operator(mesh)
    moved = mesh.with_positions(np.random.default_rng(1).normal(size=mesh.vertices.shape))
    S2, child = subdivision_operator(moved)
    assert (S != S2).nnz == 0
    assert np.abs(np.asarray(S.sum(axis=1)).ravel() - 1).max() < 1e-15
    assert np.allclose(child.vertices, S @ moved.vertices, atol=0)


# ---------------------------------------------------------------------------------------------
# 2. OpenSubdiv rules: boundaries, creases, corners, semi-sharp, on every manifold shape


@pytest.mark.skipif(not SHAPES, reason="opensubdiv-shapes folder absent")
@pytest.mark.parametrize("path", SHAPES, ids=lambda p: p.stem)
def test_opensubdiv_rules_on_shapes(path):
    mesh = _read(path)
    for step in range(2):  # the second step sees the decremented, fractional sharpness
        S, child = subdivision_operator(mesh, rules="opensubdiv")
        expected = reference_points(mesh, "opensubdiv")
        assert np.abs(S @ mesh.vertices - expected).max() <= TIGHT * _size(mesh), f"step {step}"
        mesh = child


@pytest.mark.parametrize("mode", [0, 1, 2])
@pytest.mark.parametrize("sharpness", [0.0, 0.4, 1.0, 1.7, 2.5, 10.0])
def test_opensubdiv_semi_sharp_and_boundary_modes(mode, sharpness):
    grid = open_grid(5, 4)
    faces = [list(grid.face(f)) for f in range(grid.n_faces)]
    creases = {(5, 6): sharpness, (6, 7): sharpness, (6, 10): sharpness / 2} if sharpness else {}
    corners = {9: sharpness * 0.6} if sharpness else {}
    mesh = from_arrays(grid.vertices, faces, creases=creases, corners=corners, interpolate_boundary=mode)
    for _ in range(3):
        for rules, ref in (("opensubdiv", "opensubdiv"), ("seed", "blz")):
            S, _ = subdivision_operator(mesh, rules=rules)
            assert np.abs(S @ mesh.vertices - reference_points(mesh, ref)).max() <= TIGHT * 5
        mesh = subdivide(mesh, rules="opensubdiv")


def test_opensubdiv_refuses_nonuniform_intervals():
    mesh = torus_grid(4, 5, [1, 2, 1, 1])
    with pytest.raises(KnotError) as err:
        subdivision_operator(mesh, rules="opensubdiv")
    assert "\n" not in str(err.value) and "uniform" in str(err.value)


def _semi_sharp(mesh):
    return any(0 < x < 10 for x in list(mesh.creases.values()) + list(mesh.corners.values()))


SEMI_SHARP_SHAPES = [p for p in SHAPES if _semi_sharp(_read(p))]


@pytest.mark.skipif(not SEMI_SHARP_SHAPES, reason="opensubdiv-shapes folder absent")
@pytest.mark.parametrize("path", SEMI_SHARP_SHAPES, ids=lambda p: p.stem)
def test_chaikin_creasing_on_semi_sharp_shapes(path):
    """CREASE_CHAIKIN against the reference, three steps: each step reads the child halves'
    sharpness that the previous one wrote into the refined mesh's tags."""
    mesh = _read(path)
    for step in range(3 if mesh.n_faces < 200 else 2):
        S, child = subdivision_operator(mesh, rules="opensubdiv", crease_method="chaikin")
        expected = reference_points(mesh, "opensubdiv", "chaikin")
        assert np.abs(S @ mesh.vertices - expected).max() <= TIGHT * _size(mesh), f"step {step}"
        assert np.abs(np.asarray(S.sum(axis=1)).ravel() - 1).max() < 1e-14
        mesh = child


def test_chaikin_halves_on_cube_creases1():
    """catmark_cube_creases1: edge 3-5 (s = 0.1) meets two edges of s = 5 at each end, so
    Chaikin keeps both halves sharp, 3/4 0.1 + 1/4 5 - 1 = 0.325 (uniform creasing clears
    them), and the edges of 5 at vertex 3 get 3/4 5 + 1/4 (5 + 0.1)/2 - 1 = 3.3875; the
    edge point of 3-5 is then the midpoint, and the surface differs from uniform creasing."""
    path = [p for p in SEMI_SHARP_SHAPES if p.stem == "catmark_cube_creases1"]
    if not path:
        pytest.skip("opensubdiv-shapes folder absent")
    mesh = _read(path[0])
    S, child = subdivision_operator(mesh, rules="opensubdiv", crease_method="chaikin")
    Su, child_u = subdivision_operator(mesh, rules="opensubdiv")
    nf, ne = mesh.n_faces, S.shape[0] - mesh.n_faces - mesh.n_vertices
    from patching.topology.tables import Topology

    edges = [tuple(e) for e in Topology(mesh).edges.tolist()]
    e35, e13 = edges.index((3, 5)), edges.index((1, 3))
    tags = child.creases
    assert tags[(nf + e35, nf + ne + 3)] == pytest.approx(0.325, abs=1e-15)
    assert tags[(nf + e35, nf + ne + 5)] == pytest.approx(0.325, abs=1e-15)
    assert tags[(nf + e13, nf + ne + 3)] == pytest.approx(3.3875, abs=1e-15)
    assert tags[(nf + e13, nf + ne + 1)] == pytest.approx(4.0, abs=1e-15)  # three edges of 5 at 1
    assert (nf + e35, nf + ne + 3) not in child_u.creases
    mid = (mesh.vertices[3] + mesh.vertices[5]) / 2
    assert np.abs((S @ mesh.vertices)[nf + e35] - mid).max() <= TIGHT
    assert np.abs((Su @ mesh.vertices)[nf + e35] - mid).max() > 1e-2


@pytest.mark.parametrize("sharpness", [(1.2, 0.3, 0.5), (0.9, 2.0, 0.2), (2.5, 1.5, 3.0), (0.4, 0.4, 7.0)])
def test_chaikin_creasing_mixed_sharpness_on_open_grid(sharpness):
    """Crease chains whose sharpness changes along them and at a branch, in the three boundary
    modes: an edge of s > 1 whose half decays (OpenSubdiv's unclamped blend weight s), an edge
    of s < 1 kept sharp by sharper neighbours, and a corner tag, three steps."""
    a, b, c = sharpness
    grid = open_grid(6, 5)
    faces = [list(grid.face(f)) for f in range(grid.n_faces)]
    creases = {(11, 12): a, (12, 13): b, (13, 14): a, (12, 17): c, (17, 22): b}  # 6 x 5 points
    for mode in (0, 1, 2):
        mesh = from_arrays(grid.vertices, faces, creases=creases, corners={16: b}, interpolate_boundary=mode)
        for _ in range(3):
            S, child = subdivision_operator(mesh, rules="opensubdiv", crease_method="chaikin")
            assert np.abs(S @ mesh.vertices - reference_points(mesh, "opensubdiv", "chaikin")).max() <= TIGHT * 6
            mesh = child


def test_chaikin_limit_points_invariant_and_option_checks():
    mesh = from_arrays(
        open_grid(6, 5).vertices,
        [list(open_grid(6, 5).face(f)) for f in range(20)],
        creases={(11, 12): 1.2, (12, 13): 0.3, (12, 17): 2.5},
    )
    lim = limit_points(mesh, rules="opensubdiv", crease_method="chaikin")
    child = subdivide(mesh, rules="opensubdiv", crease_method="chaikin")
    ids = child.n_vertices - mesh.n_vertices + np.arange(mesh.n_vertices)
    assert np.abs(limit_points(child, rules="opensubdiv", crease_method="chaikin")[ids] - lim).max() < 1e-13
    assert np.abs(limit_points(mesh, rules="opensubdiv") - lim).max() > 1e-3
    with pytest.raises(UnsupportedError, match="opensubdiv"):
        subdivide(mesh, crease_method="chaikin")  # seed rules decrement uniformly
    with pytest.raises(UnsupportedError, match="crease method"):
        subdivision_operator(mesh, rules="opensubdiv", crease_method="hbr")


def _pyramid(**tags):
    """A closed square pyramid: one quad and four triangles (quad-triangle and
    triangle-triangle edges)."""
    v = [[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 1.5]]
    return from_arrays(v, [[3, 2, 1, 0], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]], **tags)


def _grid_with_triangles(**tags):
    """An open 3 x 3 grid whose middle quad is split into two triangles, jittered."""
    g = open_grid(4, 4)
    faces = [list(map(int, g.face(f))) for f in range(g.n_faces)]
    a, b, c, d = faces.pop(4)
    faces += [[a, b, c], [a, c, d]]
    jitter = np.random.default_rng(3).normal(scale=0.1, size=g.vertices.shape)
    return from_arrays(g.vertices + jitter, faces, **tags)


_SMOOTHTRIS = [
    pytest.param(lambda: _pyramid(triangle_subdivision="smooth"), "uniform", id="pyramid"),
    pytest.param(
        lambda: _pyramid(triangle_subdivision="smooth", creases={(0, 4): 0.6, (1, 4): 1.5, (2, 4): 2.25}, corners={2: 0.5}),
        "chaikin", id="pyramid-semi-sharp-chaikin",
    ),
    pytest.param(lambda: _grid_with_triangles(triangle_subdivision="smooth", creases={(5, 10): 0.4}), "uniform", id="grid"),
    pytest.param(
        lambda: dataclasses.replace(_read(SHAPES_DIR / "catmark_smoothtris0.obj"), triangle_subdivision="smooth"),
        "uniform", id="catmark_smoothtris0",
        marks=pytest.mark.skipif(not (SHAPES_DIR / "catmark_smoothtris0.obj").exists(), reason="opensubdiv-shapes folder absent"),
    ),
]


@pytest.mark.parametrize("make, creasing", _SMOOTHTRIS)
def test_smooth_triangles_against_reference(make, creasing):
    """OpenSubdiv's TRI_SUB_SMOOTH: the first step against the loop reference's triangle edge
    mask (semi-sharp edges beside triangles blend it with the crease mask); the second step
    (all quads) is plain Catmull-Clark again; and the rule does change the points."""
    mesh = make()
    S, child = subdivision_operator(mesh, rules="opensubdiv", crease_method=creasing)
    expected = reference_points(mesh, "opensubdiv", creasing, triangles="smooth")
    assert np.abs(S @ mesh.vertices - expected).max() <= TIGHT * _size(mesh)
    plain = reference_points(mesh, "opensubdiv", creasing)
    assert np.abs(expected - plain).max() > 1e-3 * _size(mesh)
    assert child.triangle_subdivision == "smooth"
    S2, _ = subdivision_operator(child, rules="opensubdiv", crease_method=creasing)
    assert np.abs(S2 @ child.vertices - reference_points(child, "opensubdiv", creasing)).max() <= TIGHT * _size(mesh)


def test_smooth_triangles_quads_only_and_refusals():
    """On quads the option changes nothing; rules seed/nurss and build refuse it beside
    triangles (they would silently use Catmull-Clark's triangle rule)."""
    quads = from_arrays(open_grid(3, 3).vertices, [list(open_grid(3, 3).face(f)) for f in range(4)], triangle_subdivision="smooth")
    S, _ = subdivision_operator(quads, rules="opensubdiv")
    S0, _ = subdivision_operator(dataclasses.replace(quads, triangle_subdivision="catmark"), rules="opensubdiv")
    assert (S != S0).nnz == 0
    subdivision_operator(quads)  # seed rules: nothing to refuse on quads
    mesh = _pyramid(triangle_subdivision="smooth")
    for rules in ("seed", "nurss"):
        with pytest.raises(UnsupportedError, match="TRI_SUB_SMOOTH"):
            subdivision_operator(mesh, rules=rules)
    from patching.operator.build import build_operator

    with pytest.raises(UnsupportedError, match="nupatch subdivide --rules opensubdiv"):
        build_operator(mesh)
    from patching.errors import TagError

    with pytest.raises(TagError, match="triangle_subdivision"):
        _pyramid(triangle_subdivision="loop")


def test_smoothtriangles_obj_tag():
    """``t smoothtriangles``: OpenSubdiv 3's string form, Hbr's 2 (its k_New, the same rule),
    Hbr's 1 (k_Old, not in OpenSubdiv 3) warned and ignored, anything else an error naming the
    line; format_obj writes the tag back."""
    from patching.errors import TagError
    from patching.mesh.obj import format_obj, parse_obj

    base = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    assert parse_obj(base).triangle_subdivision == "catmark"
    assert parse_obj(base + "t smoothtriangles 0/0/1 catmark\n").triangle_subdivision == "catmark"
    smooth = parse_obj(base + "t smoothtriangles 0/0/1 smooth\n")
    assert smooth.triangle_subdivision == "smooth"
    assert parse_obj(base + "t smoothtriangles 1/0/0 2\n").triangle_subdivision == "smooth"
    with pytest.warns(Warning, match="Hbr's old triangle rule"):
        assert parse_obj(base + "t smoothtriangles 1/0/0 1\n").triangle_subdivision == "catmark"
    with pytest.raises(TagError, match="smoothtriangles") as err:
        parse_obj(base + "t smoothtriangles 0/0/1 yes\n", source="x.obj")
    assert "x.obj:5" in str(err.value)
    text = format_obj(smooth)
    assert "t smoothtriangles 0/0/1 smooth" in text and parse_obj(text).triangle_subdivision == "smooth"
    assert "smoothtriangles" not in format_obj(parse_obj(base))


@pytest.mark.parametrize("creases", [{}, {(11, 12): 10.0, (12, 13): 10.0}, {(11, 12): 1.5}])
def test_limit_face_budget_refused_in_one_line_with_or_without_finite_sharpness(monkeypatch, creases):
    """The face budget of ``limit_operator`` is its own refusal: a mesh with no finite
    sharpness (none, or only infinitely sharp creases, as a semi-sharp mesh refined until its
    tags decayed, which ``anchors='limit-fit'`` hands over) used to raise a bare ValueError
    from ``max()`` of no sharpness while building the message.  20 faces need 20 * 4 = 80
    faces for one step (4^3 = 64 x for sharpness 1.5); a budget of 79 refuses each, naming
    the faces and the budget; the step limit still names the sharpness."""
    import patching.subdivision.limit as limit

    grid = open_grid(6, 5)
    mesh = from_arrays(grid.vertices, [list(grid.face(f)) for f in range(20)], creases=creases)
    monkeypatch.setattr(limit, "MAX_LIMIT_FACES", 79)
    with pytest.raises(UnsupportedError, match=r"needs \d subdivision step.*at most 79 faces"):
        limit.limit_operator(mesh)
    with pytest.raises(UnsupportedError, match="faces"):
        limit_tangents(mesh)
    monkeypatch.setattr(limit, "MAX_LIMIT_FACES", 20 * 4**3)
    assert limit.limit_operator(mesh).shape == (mesh.n_vertices, mesh.n_vertices)
    monkeypatch.setattr(limit, "MAX_LIMIT_STEPS", 1)
    if creases.get((11, 12), 10.0) < 10.0:
        with pytest.raises(UnsupportedError, match="sharpness 1.5 needs 3 steps"):
            limit.limit_operator(mesh)


@pytest.mark.skipif(not NONMANIFOLD, reason="opensubdiv-shapes folder absent")
@pytest.mark.parametrize("path", NONMANIFOLD, ids=lambda p: p.stem)
def test_nonmanifold_refused_naming_the_place(path):
    with pytest.raises(MeshError) as err:
        subdivision_operator(_read(path))
    assert "non-manifold" in str(err.value) or "repeats" in str(err.value)


# ---------------------------------------------------------------------------------------------
# 4. Seed rules with uniform intervals: Biermann-Levin-Zorin ([TLC] sec. 2)


@pytest.mark.skipif(not SHAPES, reason="opensubdiv-shapes folder absent")
@pytest.mark.parametrize("path", SHAPES, ids=lambda p: p.stem)
def test_seed_rules_uniform_equal_blz(path):
    mesh = _read(path)
    for step in range(2):
        S, child = subdivision_operator(mesh, rules="seed")
        expected = reference_points(mesh, "blz")
        assert np.abs(S @ mesh.vertices - expected).max() <= TIGHT * _size(mesh), f"step {step}"
        mesh = child


def test_blz_gamma_differs_from_opensubdiv_only_next_to_irregular_tags():
    """A crease vertex with 3 faces on one side: theta = pi/3, gamma = 1/4 (not 3/8)."""
    mesh = _read_shape("catmark_cube_creases0") if SHAPES else None
    if mesh is None:
        pytest.skip("opensubdiv-shapes folder absent")
    s_seed, _ = subdivision_operator(mesh, rules="seed")
    s_osd, _ = subdivision_operator(mesh, rules="opensubdiv")
    nf = mesh.n_faces
    diff = np.abs((s_seed - s_osd).toarray()).max(axis=1)
    assert diff[:nf].max() == 0  # face points agree
    assert diff.max() > 0.01  # some edge next to a tagged vertex differs


def _read_shape(stem):
    for p in SHAPES:
        if p.stem == stem:
            return _read(p)
    return None


# ---------------------------------------------------------------------------------------------
# Tags carried over and read back


def test_refined_mesh_tags_and_obj_round_trip(tmp_path):
    grid = open_grid(4, 5, u_intervals=[1, 2, 3], v_intervals=[1, 1, 2, 1])
    faces = [list(grid.face(f)) for f in range(grid.n_faces)]
    mesh = from_arrays(
        grid.vertices, faces, intervals=grid.intervals, creases={(5, 6): 2.5, (6, 7): 10.0},
        corners={12: 1.5}, holes=[0], interpolate_boundary=2,
    )
    S, child = subdivision_operator(mesh)
    from patching.topology.tables import Topology

    pt, ct = Topology(mesh), Topology(child)
    nf, ne = mesh.n_faces, pt.n_edges
    # every child half of parent edge e carries d_e / 2
    for e, (a, b) in enumerate(pt.edges):
        for v in (a, b):
            ce = ct.edge_id(nf + ne + int(v), nf + e)
            assert ct.edge_interval[ce] == pt.edge_interval[e] / 2
    assert child.creases[(min(nf + ne + 5, nf + pt.edge_id(5, 6)), max(nf + ne + 5, nf + pt.edge_id(5, 6)))] == 1.5
    assert child.creases[(min(nf + ne + 7, nf + pt.edge_id(6, 7)), max(nf + ne + 7, nf + pt.edge_id(6, 7)))] == 10.0
    assert child.corners == {nf + ne + 12: 0.5}
    assert child.holes == frozenset(range(4))  # the four children of face 0
    assert child.interpolate_boundary == 2
    path = tmp_path / "child.obj"
    write_obj(child, path)
    back = read_obj(path)
    assert np.array_equal(back.face_vertices, child.face_vertices)
    assert np.allclose(back.vertices, child.vertices, atol=0)
    assert np.array_equal(Topology(back).edge_interval, ct.edge_interval)
    assert back.creases == child.creases and back.corners == child.corners
    S2, _ = subdivision_operator(back)  # the next step reads it fine
    assert S2.shape[1] == child.n_vertices


def test_subdivide_steps_and_bad_options():
    mesh = torus_grid(4, 4)
    assert subdivide(mesh, steps=2).n_faces == 16 * 16
    assert subdivide(mesh, steps=0) is mesh
    with pytest.raises(UnsupportedError):
        subdivide(mesh, rules="loop")
    with pytest.raises(UnsupportedError):
        subdivide(mesh, angles="odd")


# ---------------------------------------------------------------------------------------------
# 3. Non-uniform regular regions: midpoint knot insertion, checked against OpenCASCADE


@pytest.mark.parametrize("seed,m,n,ratio", [(0, 5, 6, 20.0), (1, 6, 5, 5.0), (2, 7, 7, 100.0)])
def test_nonuniform_torus_equals_occ_knot_insertion(seed, m, n, ratio):
    rng = np.random.default_rng(seed)
    du, dv = rng.uniform(1, ratio, m), rng.uniform(1, ratio, n)
    mesh = torus_grid(m, n, du, dv)
    mesh = mesh.with_positions(mesh.vertices + rng.normal(scale=0.2, size=mesh.vertices.shape))
    vid = np.arange(m * n).reshape(m, n)  # torus_grid numbering, faces likewise
    fid = vid  # before the first step the faces are numbered like the grid points
    reference = mesh.vertices.reshape(m, n, 3)
    for step in range(2):  # the second step reads the child's own (halved) interval tags
        S, child = subdivision_operator(mesh, rules="seed")
        reference = occ_refined_poles(reference, du, dv)
        vid, fid = refined_ids(mesh, vid, fid)
        # OCC's knot insertion (Boehm) and our masks are both exact rational formulas in the
        # intervals: the difference is round-off of a few operations on coordinates of size 4.
        assert np.abs(child.vertices[vid] - reference).max() <= 1e-12 * _size(mesh), f"step {step}"
        mesh, du, dv = child, np.repeat(du / 2, 2), np.repeat(dv / 2, 2)


def test_knot_insertion_check_can_fail():
    """Swapping two intervals changes the reference: the comparison above is not vacuous."""
    du, dv = np.array([1.0, 3.0, 1.0, 2.0, 5.0]), np.array([1.0, 2.0, 1.0, 4.0])
    mesh = torus_grid(5, 4, du, dv)
    _, child = subdivision_operator(mesh)
    vid, _ = refined_ids(mesh, np.arange(20).reshape(5, 4), np.arange(20).reshape(5, 4))
    wrong = occ_refined_poles(mesh.vertices.reshape(5, 4, 3), du[[1, 0, 2, 3, 4]], dv)
    assert np.abs(child.vertices[vid] - wrong).max() > 1e-3


# ---------------------------------------------------------------------------------------------
# 4-5. Non-uniform extraordinary points: the eigen-polyhedron rules inside S


@pytest.mark.parametrize("n", [3, 5, 6, 9])
def test_ep_rows_are_the_eigen_polyhedron_matrix(n):
    from patching.rules import eigen_polyhedron as eig

    rng = np.random.default_rng(n)
    mesh = polar_disk(n, spoke_intervals=rng.uniform(1, 4, n))
    S1, child = subdivision_operator(mesh)
    assert np.abs(np.asarray(S1.sum(axis=1)).ravel() - 1).max() < 1e-14
    # Level 0 and level 1: rows of the EP's 1-ring are the local matrix of the spoke intervals.
    ep = 0
    for m_ in (mesh, child):
        S, nxt = subdivision_operator(m_)
        parent, kids, d = ring_ids(m_, ep)
        block = S[kids][:, parent].toarray()
        assert np.abs(np.asarray(S[kids].sum(axis=1)).ravel() - 1).max() < 1e-14
        # the same rule: S solves all EPs of a valence at once from the exact intervals, the
        # cached single-vertex matrix from intervals rounded to 14 digits (its cache key)
        assert np.abs(block - eig.local_subdivision_matrix(d)).max() < 1e-14
        assert abs(S[kids].toarray().sum() - block.sum()) < 1e-12  # closed: nothing outside the ring
        ep = int(kids[0])


def test_ep_with_equal_spoke_intervals_is_catmull_clark():
    """A non-uniform mesh (other strips random) whose EP has equal spokes: the EP's vertex,
    edge and face points are Catmull-Clark's."""
    mesh = polar_disk(5, spoke_intervals=[2.0] * 5, seed=3)
    S, _ = subdivision_operator(mesh)
    parent, kids, _ = ring_ids(mesh, 0)
    fp, ep, vp = reference_step(mesh, "cc")
    from patching.topology.tables import Topology

    t = Topology(mesh)
    expected = {0 + mesh.n_faces + t.n_edges: vp[0]}
    for k in kids[1:]:
        if k < mesh.n_faces:
            expected[k] = fp[k]
        else:
            a, b = t.edges[k - mesh.n_faces]
            expected[k] = ep[(int(a), int(b))]
    got = S @ mesh.vertices
    for k, x in expected.items():
        assert np.abs(got[k] - x).max() < 1e-13


def _subdominance(matrix):
    ev = np.linalg.eigvals(matrix)
    mods = np.sort(np.abs(ev))[::-1]
    return mods


@pytest.mark.parametrize("n", range(3, 17))
def test_ep_eigenvalues_double_subdominant(n):
    """The EP block of S (level 1, stationary) has 1 > lambda = lambda > |others|, for random
    spoke intervals with ratio up to 5 ([FSLYJ] sec. 3.6's range)."""
    from patching.rules import eigen_polyhedron as eig

    lam = eig.characteristic_scale(n).lam
    rng = np.random.default_rng(100 + n)
    for trial in range(3):
        mesh = polar_disk(n, rings=2, spoke_intervals=rng.uniform(1, 5, n), seed=trial)
        _, child = subdivision_operator(mesh)
        S, _ = subdivision_operator(child)
        parent, kids, _ = ring_ids(child, ring_ids(mesh, 0)[1][0])
        mods = _subdominance(S[kids][:, parent].toarray())
        assert abs(mods[0] - 1) < 1e-12
        assert abs(mods[1] - lam) < 1e-9 and abs(mods[2] - lam) < 1e-9
        assert mods[3] < lam - 1e-6


@pytest.mark.parametrize("n", [3, 5, 8])
def test_limit_point_from_left_eigenvector_matches_repeated_subdivision(n):
    from patching.rules import eigen_polyhedron as eig

    rng = np.random.default_rng(7 * n)
    mesh = polar_disk(n, rings=2, spoke_intervals=rng.uniform(1, 5, n), seed=n)
    _, child = subdivision_operator(mesh)
    S, _ = subdivision_operator(child)
    parent, kids, d = ring_ids(child, ring_ids(mesh, 0)[1][0])
    local = S[kids][:, parent].toarray()
    limit = eig.limit_point_weights(d) @ child.vertices[parent]
    ring = child.vertices[parent]
    lam = eig.characteristic_scale(n).lam
    steps = int(np.ceil(np.log(1e-7) / np.log(lam)))  # lambda^steps < 1e-7
    for _ in range(8):
        ring = local @ ring
    # after 8 steps the ring is within lambda^8 of the limit point, and the left eigenvector
    # applied to it still gives the same point (to round-off)
    size = _size(mesh)
    assert np.abs(eig.limit_point_weights(d) @ ring - limit).max() < 1e-13 * size
    assert np.abs(ring - limit).max() < 4 * lam**8 * size
    for _ in range(steps - 8):
        ring = local @ ring
    assert np.abs(ring[0] - limit).max() < 1e-6 * size


# ---------------------------------------------------------------------------------------------
# Non-uniform sharp features (seed rules): crease curves are non-uniform cubic B-splines


def _occ_refined_curve(points, d):
    """Poles of OCC's periodic cubic B-spline curve (docs/knots.md mapping) after midpoint insertion."""
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Pnt
    from export.ocp_compat import TColgp_Array1OfPnt
    from export.ocp_compat import TColStd_Array1OfInteger, TColStd_Array1OfReal

    m = len(points)
    poles = TColgp_Array1OfPnt(1, m)
    for k in range(1, m + 1):
        poles.SetValue(k, gp_Pnt(*map(float, points[(k - 2) % m])))
    values = np.concatenate([[0.0], np.cumsum(d)])
    kk, mm = TColStd_Array1OfReal(1, values.size), TColStd_Array1OfInteger(1, values.size)
    for i, v in enumerate(values):
        kk.SetValue(i + 1, float(v))
        mm.SetValue(i + 1, 1)
    curve = Geom_BSplineCurve(poles, kk, mm, 3, True)
    for u in (values[:-1] + values[1:]) / 2:
        curve.InsertKnot(float(u), 1, 1e-12)
    out = np.empty((2 * m, 3))
    for k in range(1, 2 * m + 1):
        p = curve.Pole(k)
        out[(k - 2) % (2 * m)] = p.X(), p.Y(), p.Z()
    return out


@pytest.mark.parametrize("sharpness", [10.0, 3.0])
def test_nonuniform_crease_curve_equals_occ_curve_knot_insertion(sharpness):
    rng = np.random.default_rng(5)
    m, n = 7, 6
    du, dv = rng.uniform(1, 10, m), rng.uniform(1, 10, n)
    grid = torus_grid(m, n, du, dv)
    grid = grid.with_positions(grid.vertices + rng.normal(scale=0.2, size=grid.vertices.shape))
    faces = [list(grid.face(f)) for f in range(grid.n_faces)]
    ring = [a * n for a in range(m)]  # the loop b = 0 along u
    creases = {(ring[a], ring[(a + 1) % m]): sharpness for a in range(m)}
    mesh = from_arrays(grid.vertices, faces, intervals=grid.intervals, creases=creases)
    vid = np.arange(m * n).reshape(m, n)
    fid = vid
    curve = mesh.vertices[ring]
    d = du
    for step in range(2):  # the semi-sharp crease (s = 3) is still sharp in both steps
        _, child = subdivision_operator(mesh)
        vid, fid = refined_ids(mesh, vid, fid)
        curve = _occ_refined_curve(curve, d)
        assert np.abs(child.vertices[vid[:, 0]] - curve).max() <= 1e-12 * _size(mesh), f"step {step}"
        mesh, d = child, np.repeat(d / 2, 2)


def test_nonuniform_open_grid_boundary_interpolates_corners_and_is_c0():
    """interpolateboundary 1: corners stay, boundary points depend on boundary points only."""
    mesh = open_grid(6, 5, u_intervals=[1, 3, 2, 5, 1], v_intervals=[2, 1, 4, 1])
    S, child = subdivision_operator(mesh)
    from patching.topology.tables import Topology

    t = Topology(mesh)
    nf, ne = mesh.n_faces, t.n_edges
    for c in (0, 4, 25, 29):
        assert S[nf + ne + c].toarray().ravel().tolist() == np.eye(30)[c].tolist()
    boundary = np.flatnonzero(t.vertex_is_boundary)
    rows = np.concatenate([nf + ne + boundary, nf + np.flatnonzero(t.edge_is_boundary)])
    assert set(S[rows].indices.tolist()) <= set(boundary.tolist())
    ct = Topology(child)
    # the refined boundary is a boundary again, with the halved intervals
    assert ct.edge_is_boundary.sum() == 2 * t.edge_is_boundary.sum()


# ---------------------------------------------------------------------------------------------
# Limit points and tangents


def test_limit_points_and_tangents_equal_occ_nurbs_on_nonuniform_torus():
    from OCP.gp import gp_Pnt, gp_Vec

    from patching.subdivision import limit_points, limit_tangents

    m, n = 5, 6
    rng = np.random.default_rng(0)
    du, dv = rng.uniform(1, 5, m), rng.uniform(1, 5, n)
    mesh = torus_grid(m, n, du, dv)
    mesh = mesh.with_positions(mesh.vertices + rng.normal(scale=0.2, size=mesh.vertices.shape))
    surf, uval, vval = occ_periodic_bicubic(mesh.vertices.reshape(m, n, 3), du, dv)
    L = limit_points(mesh).reshape(m, n, 3)
    T = limit_tangents(mesh).reshape(m, n, 2, 3)
    for a in range(m):
        for b in range(n):
            p, su, sv = gp_Pnt(), gp_Vec(), gp_Vec()
            surf.D1(float(uval[a]), float(vval[b]), p, su, sv)
            su, sv = np.array([su.X(), su.Y(), su.Z()]), np.array([sv.X(), sv.Y(), sv.Z()])
            assert np.abs(L[a, b] - [p.X(), p.Y(), p.Z()]).max() < 1e-13 * _size(mesh)
            # the two tangents are +-S_u and +-S_v (which spoke comes first is the rotation's
            # choice), and their cross product is along S_u x S_v (the faces' orientation)
            t0, t1 = T[a, b]
            scale = max(np.abs(su).max(), np.abs(sv).max())
            assert min(np.abs(t0 - s * x).max() for s in (1, -1) for x in (su, sv)) < 1e-12 * scale
            assert min(np.abs(t1 - s * x).max() for s in (1, -1) for x in (su, sv)) < 1e-12 * scale
            assert np.dot(np.cross(t0, t1), np.cross(su, sv)) > 0


def _limit_cases():
    cases = [
        ("torus-nonuniform", lambda: torus_grid(6, 7, [1, 3, 2, 1, 5, 1], [1, 1, 4, 2, 1, 3, 2])),
        ("disk5-nonuniform", lambda: polar_disk(5, rings=2, spoke_intervals=[1, 2, 3, 1, 4])),
    ]
    cases += [(p.stem, (lambda p=p: _read(p))) for p in SHAPES]
    return cases


@pytest.mark.parametrize("rules", ["seed", "opensubdiv"])
@pytest.mark.parametrize("name,make", _limit_cases(), ids=[c[0] for c in _limit_cases()])
def test_limit_points_invariant_under_subdivision(name, make, rules):
    """The limit masks are left eigenvectors of the stationary rules: the limit of a vertex
    computed on the mesh and on its refinement agree to round-off."""
    from patching.subdivision import limit_points
    from patching.topology.tables import Topology

    mesh = make()
    if rules == "opensubdiv" and "nonuniform" in name:
        pytest.skip("opensubdiv rules are uniform only")
    try:
        L = limit_points(mesh, rules)
    except UnsupportedError as err:
        assert "semi-sharp" in str(err)
        pytest.skip(str(err))
    _, child = subdivision_operator(mesh, rules)
    ids = mesh.n_faces + Topology(mesh).n_edges + np.arange(mesh.n_vertices)
    L2 = limit_points(child, rules)[ids]
    assert np.abs(L2 - L).max() <= 1e-13 * _size(mesh)


@pytest.mark.parametrize("name,make", _limit_cases()[:2] + [c for c in _limit_cases() if c[0] in ("catmark_tent_creases0", "catmark_cube_corner3", "catmark_pyramid")])
def test_repeated_subdivision_converges_to_limit_points(name, make):
    from patching.subdivision import limit_points
    from patching.topology.tables import Topology

    mesh = make()
    size = _size(mesh)
    L = limit_points(mesh)
    ids = np.arange(mesh.n_vertices)
    errors = [np.abs(mesh.vertices - L).max() / size]
    for _ in range(5):
        _, child = subdivision_operator(mesh)
        ids = mesh.n_faces + Topology(mesh).n_edges + ids
        mesh = child
        errors.append(np.abs(mesh.vertices[ids] - L).max() / size)
    # vertex points converge at least like lambda^k, lambda <= 0.6 (Catmull-Clark's largest
    # subdominant eigenvalue for these valences; 1/2 at regular vertices)
    assert errors[-1] < 0.6 ** 5 * errors[0] + 1e-14
    assert errors[-1] < errors[-2]


# ---------------------------------------------------------------------------------------------
# Properties: relabelling and face rotation do not change the refined surface


def _relabel(mesh, seed):
    """The same mesh with vertices permuted and every face's starting corner rotated."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(mesh.n_vertices)  # new id of old vertex
    verts = np.empty_like(mesh.vertices)
    verts[perm] = mesh.vertices
    faces = []
    for f in range(mesh.n_faces):
        fv = [int(perm[v]) for v in mesh.face(f)]
        k = int(rng.integers(len(fv)))
        faces.append(fv[k:] + fv[:k])
    key = lambda a, b: (int(perm[a]), int(perm[b]))  # noqa: E731
    return from_arrays(
        verts, faces,
        intervals={key(a, b): d for (a, b), d in mesh.intervals.items()},
        creases={key(a, b): s for (a, b), s in mesh.creases.items()},
        corners={int(perm[v]): s for v, s in mesh.corners.items()},
        interpolate_boundary=mesh.interpolate_boundary,
    )


def _sorted_points(points):
    return points[np.lexsort(np.round(points, 9).T[::-1])]


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize(
    "make",
    [
        lambda: polar_disk(5, rings=2, spoke_intervals=[1, 2, 3, 1, 4]),
        lambda: torus_grid(5, 6, [1, 3, 2, 1, 5], [1, 1, 4, 2, 1, 3]),
        lambda: _read_shape("catmark_cube_creases0"),
        lambda: _read_shape("catmark_nonquads"),
    ],
    ids=["disk-nonuniform", "torus-nonuniform", "cube_creases0", "nonquads"],
)
def test_relabelling_and_face_rotation_invariance(make, seed):
    mesh = make()
    if mesh is None:
        pytest.skip("opensubdiv-shapes folder absent")
    rng = np.random.default_rng(seed + 10)
    mesh = mesh.with_positions(mesh.vertices + rng.normal(scale=0.05, size=mesh.vertices.shape))
    other = _relabel(mesh, seed)
    for rules in ("seed", "opensubdiv") if mesh.intervals == {} else ("seed",):
        a = subdivide(mesh, 2, rules).vertices
        b = subdivide(other, 2, rules).vertices
        assert np.abs(_sorted_points(a) - _sorted_points(b)).max() < 1e-12 * _size(mesh)


# ---------------------------------------------------------------------------------------------
# [TLC] sec. 4: generalised eigen-polyhedra at tagged vertices (non-uniform)


def _random_strip_intervals(mesh, ratio=3.0, seed=0):
    """The same mesh with a random interval in [1, ratio] on every strip."""
    from dataclasses import replace

    from patching.topology.tables import Topology

    t = Topology(mesh)
    rng = np.random.default_rng(seed)
    first = np.full(t.n_strips, -1)
    first[t.edge_strip[::-1]] = np.arange(t.n_edges)[::-1]
    return replace(mesh, intervals={tuple(map(int, t.edges[e])): float(rng.uniform(1, ratio)) for e in first})


@pytest.mark.parametrize(
    "kind,n,sharp,boundary",
    [
        ("crease", 5, (0, 3), False), ("crease", 6, (0, 2), False), ("crease", 4, (0, 3), True),
        ("crease", 5, (0, 4), True), ("dart", 5, (0,), False), ("dart", 4, (0,), False),
        ("dart", 7, (0,), False), ("corner", 5, (0, 2, 3), False), ("corner", 3, (0, 2), True),
        ("corner", 6, (0, 1, 4), False),
    ],
)
def test_tagged_vertex_rules_satisfy_the_generalised_eigen_relation(kind, n, sharp, boundary):
    from patching.rules.catmark import CORNER, CREASE, DART, tagged_vertex_rules

    k = {"crease": CREASE, "dart": DART, "corner": CORNER}[kind]
    rng = np.random.default_rng(n)
    for trial in range(3):
        d = tuple(rng.uniform(1, 4, n)) if trial else (1.0,) * n
        m, defined, p0, t = tagged_vertex_rules(k, d, sharp, boundary)
        # rows sum to one; defined rows map P^0 to P^0 / 2 + T ([TLC] eqs. 17, 22)
        assert np.abs(m[defined].sum(axis=1) - 1).max() < 1e-14
        if kind != "corner":  # a corner's relation holds per sector frame (p0 is the first's)
            assert np.abs(m[defined] @ p0 - (0.5 * p0[defined] + t)).max() < 1e-13
        nf = n - 1 if boundary else n
        faces = np.arange(1 + n, 1 + n + nf)
        assert defined[faces].all()
        if trial == 0:
            # equal intervals: face points are centroids, a dart's vertex is Catmull-Clark's
            for r in faces:
                i = r - 1 - n
                assert np.allclose(m[r][[0, 1 + i, 1 + (i + 1) % n, r]], 0.25, atol=1e-14)
            if kind == "dart":
                # Catmull-Clark on old points ([TLC] sec. 2: beta_1 = 3/2n, beta_2 = 1/4n)
                cc = np.concatenate([[1 - 7 / (4 * n)], np.full(n, 3 / (2 * n**2)), np.full(n, 1 / (4 * n**2))])
                assert np.abs(m[0] - cc).max() < 1e-14


def test_tagged_rules_with_equal_intervals_are_not_blz_off_pi_over_2():
    """Recorded finding: [TLC]'s section 4 edge form (27) with equal intervals gives, next to
    a crease vertex of sector size 3 (theta = pi/3), weights (3/4 - g, g) on the ends with
    g = 3/8 - 3 cos(theta)/16 = 9/32 and (1/8 - g/6, g/6) on the far points, not section 2's
    (BLZ) g = 3/8 - cos(theta)/4 = 1/4 with 1/16 on the far points; both satisfy the
    eigen relation.  So seed rules keep BLZ where the spoke intervals are equal."""
    from patching.rules.catmark import CREASE, tagged_vertex_rules

    m, defined, _, _ = tagged_vertex_rules(CREASE, (1.0,) * 5, (0, 3), False)
    row = m[2]  # spoke 1, inside the 3-face sector
    g = 3 / 8 - 3 * math.cos(math.pi / 3) / 16
    assert abs(row[0] - (3 / 4 - g)) < 1e-14 and abs(row[2] - g) < 1e-14
    assert abs(row[1] - (1 / 8 - g / 6)) < 1e-14 and abs(row[6] - g / 6) < 1e-14


@pytest.mark.skipif(not SHAPES, reason="opensubdiv-shapes folder absent")
@pytest.mark.parametrize("path", SHAPES, ids=lambda p: p.stem)
def test_nonuniform_seed_rules_on_shapes(path):
    """Every manifold shape, refined once (quads) and given random strip intervals: S is affine,
    crease curves are decoupled (a crease point depends on crease points only), and the limit
    points are invariant under refinement."""
    from patching.subdivision import limit_points
    from patching.topology.tables import Topology

    mesh = _random_strip_intervals(subdivide(_read(path)), seed=1)
    try:
        S, child = subdivision_operator(mesh)
    except UnsupportedError as err:
        assert "valence 2" in str(err)  # catmark_val2_back2back: no eigen-polyhedron for n = 2
        pytest.skip(str(err))
    assert np.abs(np.asarray(S.sum(axis=1)).ravel() - 1).max() < 1e-13
    t = Topology(mesh)
    inf_sharp = np.flatnonzero(t.edge_is_boundary | (t.edge_sharpness >= 10))
    crease_pts = np.unique(t.edges[inf_sharp])
    rows = mesh.n_faces + inf_sharp
    assert set(S[rows].indices.tolist()) <= set(crease_pts.tolist())
    finite = [x for x in list(mesh.creases.values()) + list(mesh.corners.values()) if x < 10]
    steps = 2 + math.ceil(max(finite, default=0))  # limit_points(child) refines this far
    if mesh.n_faces * 4**steps > 3e5:
        return  # keep the test fast: catmark_pawn's sharpness 5 would mean 10M faces
    try:
        L = limit_points(mesh)
    except UnsupportedError as err:
        pytest.skip(str(err))
    ids = mesh.n_faces + t.n_edges + np.arange(mesh.n_vertices)
    assert np.abs(limit_points(child)[ids] - L).max() <= 1e-12 * _size(mesh)


@pytest.mark.parametrize("n", [3, 5, 7])
def test_modified_angles_option_reaches_the_ep_rows(n):
    """angles="modified" ([ZTL]) changes the EP rows for unequal spokes, and they are
    eigen_polyhedron's modified local matrix; equal spokes give Catmull-Clark either way."""
    from patching.rules import eigen_polyhedron as eig

    rng = np.random.default_rng(n)
    mesh = polar_disk(n, spoke_intervals=rng.uniform(1, 10, n))
    parent, kids, d = ring_ids(mesh, 0)
    s_std, _ = subdivision_operator(mesh, angles="standard")
    s_mod, _ = subdivision_operator(mesh, angles="modified")
    block = s_mod[kids][:, parent].toarray()
    assert np.abs(block - eig.local_subdivision_matrix(d, angles="modified")).max() < 1e-15
    assert np.abs(block - s_std[kids][:, parent].toarray()).max() > 1e-3
    assert np.abs(np.asarray(s_mod.sum(axis=1)).ravel() - 1).max() < 1e-14
    equal = polar_disk(n, spoke_intervals=[2.0] * n)
    a, _ = subdivision_operator(equal, angles="standard")
    b, _ = subdivision_operator(equal, angles="modified")
    assert abs(a - b).max() < 1e-14


@pytest.mark.skipif(not SHAPES, reason="opensubdiv-shapes folder absent")
@pytest.mark.parametrize("path", SHAPES, ids=lambda p: p.stem)
def test_refined_shapes_read_back(path, tmp_path):
    mesh = _read(path)
    _, child = subdivision_operator(mesh)
    write_obj(child, tmp_path / "out.obj")
    back = read_obj(tmp_path / "out.obj")
    assert np.array_equal(back.face_vertices, child.face_vertices)
    assert np.array_equal(back.vertices, child.vertices)  # repr() round-trips floats exactly
    assert back.creases == child.creases and back.corners == child.corners
    assert back.holes == child.holes and back.interpolate_boundary == child.interpolate_boundary
    S1, _ = subdivision_operator(child)
    S2, _ = subdivision_operator(back)
    assert (S1 != S2).nnz == 0


@pytest.mark.parametrize("stem", ["catmark_cube", "catmark_torus", "catmark_pole8", "catmark_gregory_test6"])
def test_limit_normals_point_like_the_faces(stem):
    """t0 x t1 agrees in sign with the control mesh's face normals around each vertex."""
    from patching.subdivision import limit_tangents

    mesh = _read_shape(stem)
    if mesh is None:
        pytest.skip("opensubdiv-shapes folder absent")
    T = limit_tangents(mesh)
    normal = np.zeros((mesh.n_vertices, 3))
    for f in range(mesh.n_faces):
        fv = mesh.face(f)
        p = mesh.vertices[fv]
        nrm = sum(np.cross(p[i], p[(i + 1) % len(fv)]) for i in range(len(fv)))
        normal[fv] += nrm
    ok = ~np.isnan(T).any(axis=(1, 2))
    assert ok.sum() > 0
    n = np.cross(T[ok, 0], T[ok, 1])
    assert np.all(np.einsum("ij,ij->i", n, normal[ok]) > 0)


def _occ_clamped(grid, du, dv):
    """OCC's clamped B-spline surface of an open grid whose outer strips carry 0 (docs/knots.md):
    the zero intervals are the end knots' extra multiplicity."""
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt
    from export.ocp_compat import TColgp_Array2OfPnt
    from export.ocp_compat import TColStd_Array1OfInteger, TColStd_Array1OfReal

    def knots(d):
        values, mults = np.unique(np.concatenate([[0.0], np.cumsum(d)]), return_counts=True)
        mults[0] += 2
        mults[-1] += 2
        kk, mm = TColStd_Array1OfReal(1, values.size), TColStd_Array1OfInteger(1, values.size)
        for i, (v, mu) in enumerate(zip(values, mults)):
            kk.SetValue(i + 1, float(v))
            mm.SetValue(i + 1, int(mu))
        return kk, mm

    m, n = grid.shape[:2]
    poles = TColgp_Array2OfPnt(1, m, 1, n)
    for k in range(m):
        for l in range(n):
            poles.SetValue(k + 1, l + 1, gp_Pnt(*map(float, grid[k, l])))
    (uk, um), (vk, vm) = knots(du), knots(dv)
    return Geom_BSplineSurface(poles, uk, vk, um, vm, 3, 3, False, False)


def _occ_insert_midpoints(surf):
    """Midpoint knot insertion in every non-empty span, both directions; the new poles."""
    for n_knots, knot, insert in ((surf.NbUKnots(), surf.UKnot, surf.InsertUKnot),
                                  (surf.NbVKnots(), surf.VKnot, surf.InsertVKnot)):
        values = [knot(i) for i in range(1, n_knots + 1)]
        for a, b in zip(values[:-1], values[1:]):
            insert(0.5 * (a + b), 1, 1e-12)
    return np.array([[[surf.Pole(i, j).X(), surf.Pole(i, j).Y(), surf.Pole(i, j).Z()]
                      for j in range(1, surf.NbVPoles() + 1)] for i in range(1, surf.NbUPoles() + 1)])


def _openrefined_ids(mesh, vid):
    """Child ids (2m-1, 2n-1) of an open grid whose points have parent ids vid (m, n): vertex
    points at even (a, b), edge points at one odd index, face points at two."""
    from patching.topology.tables import Topology

    t = Topology(mesh)
    nf, ne = mesh.n_faces, t.n_edges
    face_of = {frozenset(map(int, mesh.face(f))): f for f in range(nf)}
    m, n = vid.shape
    G = np.empty((2 * m - 1, 2 * n - 1), np.int64)
    for a in range(m):
        for b in range(n):
            G[2 * a, 2 * b] = nf + ne + vid[a, b]
            if a + 1 < m:
                G[2 * a + 1, 2 * b] = nf + t.edge_id(int(vid[a, b]), int(vid[a + 1, b]))
            if b + 1 < n:
                G[2 * a, 2 * b + 1] = nf + t.edge_id(int(vid[a, b]), int(vid[a, b + 1]))
            if a + 1 < m and b + 1 < n:
                corners = vid[a, b], vid[a + 1, b], vid[a + 1, b + 1], vid[a, b + 1]
                G[2 * a + 1, 2 * b + 1] = face_of[frozenset(map(int, corners))]
    return G


def _clamped_grids():
    from pathlib import Path

    rng = np.random.default_rng(3)
    mesh = open_grid(7, 6, [0, 1, 2.5, 1, 4, 0], [0, 3, 1, 1, 0])
    yield "open_grid", mesh.with_positions(mesh.vertices + rng.normal(scale=0.2, size=mesh.vertices.shape)), (7, 6)
    model = Path(__file__).resolve().parent.parent / "models" / "clamped_grid.obj"
    if model.exists():
        yield "models/clamped_grid.obj", read_obj(model), (9, 7)


@pytest.mark.parametrize("name,mesh,shape", list(_clamped_grids()), ids=lambda x: x if isinstance(x, str) else "")
def test_clamped_open_grid_steps_equal_occ_knot_insertion(name, mesh, shape):
    """Zero outer strips (docs/knots.md: the clamped NURBS), three steps: every step is OpenCASCADE's
    midpoint knot insertion on the clamped surface, and the extra points of the zero strips
    (a zero interval splits into two zero halves) all lie on the boundary curve, so that the
    zero-width faces stay degenerate and the next step reads the same clamped NURBS.  Before
    the boundary lines were continued in ``_Context.ahead``, the edge points of the spokes into
    the boundary read other knots than the boundary curve: the extra points left the boundary
    and the second step's poles next to it were off by 5e-2."""
    from patching.topology.tables import Topology

    m, n = shape
    vid = np.arange(m * n).reshape(m, n)  # open_grid's and the model's numbering
    t = Topology(mesh)
    du = [t.edge_interval[t.edge_id(int(vid[a, 0]), int(vid[a + 1, 0]))] for a in range(m - 1)]
    dv = [t.edge_interval[t.edge_id(int(vid[0, b]), int(vid[0, b + 1]))] for b in range(n - 1)]
    assert du[0] == du[-1] == dv[0] == dv[-1] == 0 and min(du[1:-1] + dv[1:-1]) > 0
    surf = _occ_clamped(mesh.vertices[vid], du, dv)
    zeros = 1  # zero edges at each end of a row or column
    for step in range(3):
        ref = _occ_insert_midpoints(surf)
        G = _openrefined_ids(mesh, vid)
        _, mesh = subdivision_operator(mesh)
        zeros *= 2
        P = mesh.vertices[G]
        # the NURBS poles: the boundary row and everything from the last zero edge inwards
        keep_u = [0] + list(range(zeros, P.shape[0] - zeros)) + [P.shape[0] - 1]
        keep_v = [0] + list(range(zeros, P.shape[1] - zeros)) + [P.shape[1] - 1]
        assert ref.shape == (len(keep_u), len(keep_v), 3)
        # both sides are short exact rational formulas in the knots: round-off on coordinates
        # of size 8, a few dozen operations deep after three steps
        assert np.abs(P[np.ix_(keep_u, keep_v)] - ref).max() < 1e-13 * _size(mesh), f"step {step}"
        for k in range(1, zeros):  # extra points: on the boundary row or column
            assert np.abs(P[k] - P[0]).max() < 1e-13 * _size(mesh)
            assert np.abs(P[-1 - k] - P[-1]).max() < 1e-13 * _size(mesh)
            assert np.abs(P[:, k] - P[:, 0]).max() < 1e-13 * _size(mesh)
            assert np.abs(P[:, -1 - k] - P[:, -1]).max() < 1e-13 * _size(mesh)
        vid = G


def test_local_solves_are_vectorised_over_vertices(monkeypatch):
    """Building S solves the bilinear rules (face and edge points) of all EPs of one valence, and
    of all tagged vertices of one kind and shape, in one vectorised call each: the number of
    calls does not grow with the number of vertices (the cold construction speed of
    benchmarks/subdivide.py rests on it)."""
    from patching.rules import eigen_polyhedron as eig
    from patching.mesh.primitives import polycube
    from patching.subdivision.context import _Context
    from patching.rules.catmark import SMOOTH

    calls = []
    solve = eig.bilinear_inverse
    monkeypatch.setattr(eig, "bilinear_inverse", lambda *a, **k: calls.append(1) or solve(*a, **k))
    rng = np.random.default_rng(4)
    # EPs: a polycube (valence 3 and 5) with random strip intervals
    cube = polycube([(x, y, 0) for x in range(3) for y in range(3)] + [(0, 0, 1)], divisions=2)
    cube = _random_strip_intervals(cube, seed=2)
    # tagged vertices: a non-uniform torus with three crease loops across it
    m, n = 12, 8
    grid = torus_grid(m, n, rng.uniform(1, 4, m), rng.uniform(1, 4, n))
    creases = {(a * n + b, ((a + 1) % m) * n + b): 10.0 for a in range(m) for b in (0, 3, 5)}
    faces = [list(grid.face(f)) for f in range(grid.n_faces)]
    torus = from_arrays(grid.vertices, faces, intervals=grid.intervals, creases=creases)
    for mesh in (cube, torus):
        ctx = _Context(mesh)
        eps = (ctx.valence != 4) & ~ctx.v_boundary & (ctx.parent.rule == SMOOTH)
        tagged = ctx.parent.rule != SMOOTH
        assert eps.sum() + tagged.sum() >= 14  # many local solves (14 EPs, 36 crease vertices)
        groups = len(np.unique(ctx.valence[eps])) + len(np.unique(ctx.valence[tagged]))
        calls.clear()
        S, _ = subdivision_operator(mesh)
        assert 0 < len(calls) <= 2 * groups  # faces and edges, once per group
        assert np.abs(np.asarray(S.sum(axis=1)).ravel() - 1).max() < 1e-13


def test_tagged_rules_batch_equals_one_vertex_at_a_time():
    from patching.rules.catmark import CORNER, CREASE, DART, tagged_rules_batch, tagged_vertex_rules

    rng = np.random.default_rng(8)
    for kind, n, sharp, boundary in [(DART, 5, (0,), False), (CREASE, 6, (0, 3), False),
                                     (CREASE, 4, (0, 3), True), (CORNER, 6, (0, 2, 4), False)]:
        d = rng.uniform(1, 4, size=(7, n))
        batch = tagged_rules_batch(kind, d, sharp, boundary)
        for k in range(7):
            one = tagged_vertex_rules(kind, tuple(d[k]), sharp, boundary)
            assert np.array_equal(batch.defined, one.defined)
            # the same arithmetic on the same numbers, batched: round-off only
            assert np.abs(batch.matrix[k] - one.matrix).max() < 1e-14


def _valence2_square(intervals, creases=None):
    """Open square A B C D split by an interior vertex X into two quads (A, B, C, X) and
    (A, X, C, D): X (vertex 4) has valence 2.  intervals: (strip of AB, CX, DA; strip of BC,
    XA, CD)."""
    v = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1.2, 0.8, 0.3]], float)
    faces = [[0, 1, 2, 4], [0, 4, 2, 3]]
    return from_arrays(v, faces, intervals={(0, 1): intervals[0], (1, 2): intervals[1]}, creases=creases or {})


def _valence2_grid(k=7):
    """Open k x k grid whose middle face (a, b, c, d) is split by an interior vertex X (the last
    vertex, lifted off the plane) into (a, b, c, X) and (a, X, c, d): X has valence 2 and its
    two spokes lie in different strips (on a closed grid the strips would merge)."""
    grid = open_grid(k, k)
    faces = [list(map(int, grid.face(f))) for f in range(grid.n_faces)]
    a, b, c, d = faces[len(faces) // 2]
    x = grid.vertices[[a, b, c, d]].mean(0) + np.array([0.1, -0.05, 0.3])
    x_id = grid.n_vertices
    faces[len(faces) // 2] = [a, b, c, x_id]
    faces.append([a, x_id, c, d])
    return from_arrays(np.vstack([grid.vertices, x]), faces)


def _cc_valence2_block():
    """Catmull-Clark's one-step matrix on the 1-ring [V, E_0, E_1, F_0, F_1] of a valence-2
    vertex, faces (V, E_0, F_0, E_1) and (V, E_1, F_1, E_0), written from the classic rules."""
    m = np.zeros((5, 5))
    m[0] = [1 / 8, 3 / 8, 3 / 8, 1 / 16, 1 / 16]  # (n-2)/n V + (sum E + sum face points)/n^2
    m[1] = [3 / 8, 3 / 8, 1 / 8, 1 / 16, 1 / 16]  # (V + E_0 + two face points) / 4
    m[2] = [3 / 8, 1 / 8, 3 / 8, 1 / 16, 1 / 16]
    m[3] = [1 / 4, 1 / 4, 1 / 4, 1 / 4, 0]  # centroids
    m[4] = [1 / 4, 1 / 4, 1 / 4, 0, 1 / 4]
    return m


@pytest.mark.parametrize("seed", range(3))
def test_valence2_with_nonuniform_intervals(seed):
    """An interior valence-2 vertex with spoke intervals d_0 != d_1 (ratio up to 5): rows sum to
    one and are non-negative (so every limit point is a convex combination of control
    points); V's row is Catmull-Clark's whatever the intervals, and after one step the whole
    1-ring block of S is Catmull-Clark's valence-2 matrix (the intervals drop out once both
    halves of a spoke carry one interval: module docstring); the limit point (CC's mask) is
    that of repeated subdivision, whose error falls by the subdominant 1/4 a step."""
    from patching.subdivision import limit_operator
    from patching.topology.tables import Topology

    mesh = _random_strip_intervals(_valence2_grid(5), ratio=5.0, seed=seed)
    x = mesh.n_vertices - 1
    t = Topology(mesh)
    ring = t.one_ring(x)
    assert t.valence[x] == 2 and t.halfedge_interval[ring][0] != t.halfedge_interval[ring][1]
    S, child = subdivision_operator(mesh)
    assert np.abs(np.asarray(S.sum(axis=1)).ravel() - 1).max() < 1e-15
    assert S.data.min() > 0
    cols = [x, *t.dest[ring], *t.dest[t.next[ring]]]
    assert np.abs(S[S.shape[0] - mesh.n_vertices + x, cols].toarray().ravel() - _cc_valence2_block()[0]).max() < 1e-15
    # stationary level: the 1-ring block is Catmull-Clark's
    xc = child.n_vertices - mesh.n_vertices + x
    tc = Topology(child)
    rc = tc.one_ring(xc)
    assert len(set(tc.halfedge_interval[rc].tolist())) == 2
    Sc, _ = subdivision_operator(child)
    nfc, nec = child.n_faces, tc.n_edges
    rows = [nfc + nec + xc, *(nfc + tc.edge_of[rc]), *tc.face[rc]]
    cols = [xc, *tc.dest[rc], *tc.dest[tc.next[rc]]]
    assert np.abs(Sc[rows][:, cols].toarray() - _cc_valence2_block()).max() < 1e-15
    # the limit point: a convex combination, equal to repeated subdivision
    L = limit_operator(mesh)
    assert L[x].toarray().min() >= 0 and abs(L[x].sum() - 1) < 1e-15
    limit = L[x] @ mesh.vertices
    level, ids, errors = mesh, np.arange(mesh.n_vertices), []
    for _ in range(6):
        S, level = subdivision_operator(level)
        ids = S.shape[0] - S.shape[1] + ids
        errors.append(np.abs(level.vertices[ids[x]] - limit).max())
    assert errors[-1] < 1e-4 * _size(mesh)
    assert 3.9 < errors[-2] / errors[-1] < 4.1  # the subdominant eigenvalue 1/4
    assert np.isnan(limit_tangents(mesh)[x]).all()  # CC's -1/4: no single tangent plane


def test_valence2_uniform_equals_catmull_clark_and_tags_pass():
    """Uniform intervals: the whole step equals the BLZ/Catmull-Clark reference (the valence-2
    vertex included); non-uniform with a crease through the valence-2 vertex (the crease
    curve's rules), or a dart or corner there (knot insertion with BLZ's edge correction):
    affine rows, no refusal."""
    mesh = _valence2_grid(5)
    S, _ = subdivision_operator(mesh)
    assert np.abs(S @ mesh.vertices - reference_points(mesh, "blz")).max() <= TIGHT * _size(mesh)
    x = mesh.n_vertices - 1
    a, c = [int(v) for v in mesh.face(mesh.n_faces - 1)][::2]
    for creases, corners in (({(a, x): 10.0, (x, c): 10.0}, {}), ({(a, x): 10.0}, {}), ({}, {x: 10.0})):
        tagged = _random_strip_intervals(from_arrays(mesh.vertices, [list(mesh.face(f)) for f in range(mesh.n_faces)], creases=creases, corners=corners), seed=3)
        S, _ = subdivision_operator(tagged)
        assert np.abs(np.asarray(S.sum(axis=1)).ravel() - 1).max() < 1e-15
        if len(creases) == 2:  # crease vertex: the curve rule along a - X - c, whose ends a and
            # c are darts (valence 5, one sharp edge): the mirror interval beyond them
            from patching.rules.catmark import curve_vertex_weights
            from patching.topology.tables import Topology

            t = Topology(tagged)
            da, dc = (float(t.edge_interval[t.edges.tolist().index(sorted(e))]) for e in ([a, x], [x, c]))
            assert da != dc
            row = S[S.shape[0] - tagged.n_vertices + x].toarray().ravel()
            assert np.abs(row[[a, x, c]] - np.array(curve_vertex_weights(da, da, dc, dc))).max() < 1e-15
            assert np.count_nonzero(row) == 3


def test_ep_block_of_s_and_the_local_matrix_agree_at_extreme_ratios():
    """The reconciliation of the two eigenvalue checks (benchmarks/eigen.py's docstring): at a
    true spoke ratio of 1e4 where eigen_polyhedron finds 1 > lambda = lambda > |others| broken
    (test_eigen_polyhedron::test_extreme_ratio_loses_the_eigen_structure), S's own EP block on a
    mesh is the same matrix and is broken the same way; the earlier S-side check only drew
    intervals uniformly in [1, r], whose true ratio max/min is about n + 1."""
    from patching.rules import eigen_polyhedron as eig

    d = [10000.0, 107.5090358880951, 3152.15105974721, 258.1861017480902, 1.0]
    mesh = polar_disk(5, rings=2, spoke_intervals=d, outer="spoke")
    _, child = subdivision_operator(mesh)
    S, _ = subdivision_operator(child)
    parent, kids, dc = ring_ids(child, ring_ids(mesh, 0)[1][0])
    block = S[kids][:, parent].toarray()
    local = eig.local_subdivision_matrix(dc)
    # entries up to ~10 at this ratio; S's batch solve and the cached single solve differ by
    # the cache key's rounding to 14 digits
    assert np.abs(block - local).max() < 1e-12
    ev = np.linalg.eigvals(block)
    ev = ev[np.argsort(-np.abs(ev))]
    lam = eig.characteristic_scale(5).lam
    assert ev[1].real < -lam and abs(ev[1].imag) < 1e-9  # a negative eigenvalue beyond lambda
    np.testing.assert_allclose(np.sort_complex(ev), np.sort_complex(eig.subdivision_eigenvalues(dc)), atol=1e-9)
    rng = np.random.default_rng(0)  # the old S-side draw: the true ratio stays near n + 1
    true_ratio = [np.ptp(x) / x.min() + 1 for x in rng.uniform(1, 1000, (200, 5))]
    assert np.median(true_ratio) < 12


def test_concave_corner_sector_takes_blz_concave_rule_without_a_tag():
    """[TLC] sec. 2 (BLZ): next to a corner, an untagged edge's point uses
    gamma = 3/8 - cos(theta)/4 with theta = alpha/m (convex) or (2 pi - alpha)/m (concave),
    alpha the angle between the sector's two crease edges.  The L's inner top corner is
    concave: its top sector has m = 3 squares and alpha = pi/2 between the rim edges, so BLZ
    gives theta = pi/2, gamma = 3/8 (the standard weights), while the convex reading would give
    theta = pi/6, gamma = 0.158.  The seed rules' topological sector angle (pi/2 per quad,
    patching.subdivision.catmark's docstring) reproduces the concave rule without any tag."""
    from patching.mesh.primitives import polycube
    from patching.topology.tables import Topology

    base = polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0)], 1)
    topo = Topology(base)
    at = lambda p: int(np.flatnonzero((base.vertices == p).all(axis=1))[0])  # noqa: E731
    v, e = at((1, 1, 1)), at((0, 1, 1))
    rim = {tuple(sorted((at(a), at(b)))): np.inf for a, b in (((1, 1, 1), (2, 1, 1)), ((1, 1, 1), (1, 2, 1)))}
    mesh = from_arrays(base.vertices, base.quads(), creases=rim, corners={v: np.inf})
    s, _ = subdivision_operator(mesh, rules="seed")
    edge = topo.edge_id(v, e)
    row = s[mesh.n_faces + edge].toarray().ravel()
    faces = [f for f in range(mesh.n_faces) if {v, e} <= set(mesh.face(f))]
    others = {int(x) for f in faces for x in mesh.face(f)} - {v, e}
    expected = np.zeros(mesh.n_vertices)
    gamma = 3 / 8 - math.cos((2 * math.pi - math.pi / 2) / 3) / 4  # concave BLZ
    expected[v], expected[e] = 3 / 4 - gamma, gamma
    expected[list(others)] = 1 / 16
    np.testing.assert_allclose(row, expected, atol=1e-15)
    assert abs(gamma - (3 / 8 - math.cos(math.pi / 6) / 4)) > 0.2  # the convex reading differs


# ---------------------------------------------------------------------------------------------
# Interior valence-2 vertices under OpenSubdiv's rules (OpenSubdiv's regression shape
# catmark_val2_interior has these configurations: a val-2 vertex inside a grid, two faces
# sharing a chain of edges through val-2 vertices, semi-sharp chains s = 5 through them).


def _val2_in_grid(s_ax, s_xc, s_cb, corner, mode):
    """A 4 x 4 open grid whose interior quad (a, b, c, d) is split into (a, b, c, x) and
    (a, x, c, d): x is an interior vertex of valence 2; a-x, x-c and c-b may be creased."""
    grid = open_grid(4, 4)
    rng = np.random.default_rng(7)
    verts = np.array(grid.vertices, float)
    verts[:, 2] += rng.uniform(-0.2, 0.2, len(verts))
    faces = [list(map(int, grid.face(f))) for f in range(grid.n_faces)]
    a, b, c, d = faces.pop(5)
    x = len(verts)
    verts = np.vstack([verts, (verts[a] + verts[c]) / 2 + [0.05, -0.03, 0.3]])
    faces += [[a, b, c, x], [a, x, c, d]]
    creases = {tuple(sorted(k)): s for k, s in (((a, x), s_ax), ((x, c), s_xc), ((c, b), s_cb)) if s}
    return from_arrays(verts, faces, creases=creases, corners={x: corner} if corner else {}, interpolate_boundary=mode)


def _hexagons_sharing_a_chain(s, mode):
    """Two hexagons sharing the chain 0-1-2-3-4 (1, 2, 3 interior vertices of valence 2),
    the chain creased with sharpness s."""
    verts = np.array([[-1.0, 0, 0], [-0.4, 0.1, 0.1], [0, 0.2, 0.3], [0.4, 0.1, 0.1], [1, 0, 0], [0, 0, 1.2], [0, 0, -1.2]])
    faces = [[0, 1, 2, 3, 4, 5], [6, 4, 3, 2, 1, 0]]
    creases = {(i, i + 1): s for i in range(4)} if s else {}
    return from_arrays(verts, faces, creases=creases, interpolate_boundary=mode)


VAL2_CASES = [
    ("grid_smooth", lambda: _val2_in_grid(0, 0, 0, 0, 1)),
    ("grid_chain_s5", lambda: _val2_in_grid(5, 5, 5, 0, 1)),
    ("grid_chain_fractional", lambda: _val2_in_grid(1.5, 0.5, 2.5, 0, 2)),
    ("grid_dart_s1", lambda: _val2_in_grid(1, 0, 0, 0, 1)),
    ("grid_sharp_and_corner", lambda: _val2_in_grid(10, 10, 0, 0.7, 1)),
    ("grid_unequal_chain_corner", lambda: _val2_in_grid(5, 1.5, 0, 2, 2)),
    ("hexagons_s5", lambda: _hexagons_sharing_a_chain(5, 1)),
    ("hexagons_s1_5", lambda: _hexagons_sharing_a_chain(1.5, 2)),
    ("hexagons_smooth", lambda: _hexagons_sharing_a_chain(0, 1)),
]


@pytest.mark.parametrize("creasing", ["uniform", "chaikin"])
@pytest.mark.parametrize("name, make", VAL2_CASES, ids=[c[0] for c in VAL2_CASES])
def test_opensubdiv_rules_at_interior_valence_2(name, make, creasing):
    """Three steps at interior valence-2 vertices (smooth, darts, semi-sharp chains through
    them, corners on them) against the loop reference: OpenSubdiv's smooth mask at n = 2 is
    ``0 V + (E_0 + E_1)/4 + (F_0 + F_1)/4`` (catmarkScheme.h, (n-2)/n and 1/n^2), the crease
    mask ``3/4 V + 1/8 (ends)`` reads both edges of the vertex, and the blend of a decaying
    vertex is ``Crease::ComputeFractionalWeightAtVertex``'s.  (Checked once by hand against
    OpenSubdiv 3.6.0 built from its sources, docs/fidelity.md.)"""
    mesh = make()
    for step in range(3):
        S, child = subdivision_operator(mesh, rules="opensubdiv", crease_method=creasing)
        expected = reference_points(mesh, "opensubdiv", creasing)
        assert np.abs(S @ mesh.vertices - expected).max() <= TIGHT * 10, f"step {step}"
        mesh = child


def test_creasemethod_obj_tag():
    """``t creasemethod 0/0/1 chaikin`` ([OSD]'s regression form; ``uniform``, and ``normal`` as
    OpenSubdiv's own readers call it, give uniform creasing) sets ``ControlMesh.crease_method``;
    anything else is an error naming the line; format_obj writes the tag back only for chaikin."""
    from patching.errors import TagError
    from patching.mesh.obj import format_obj, parse_obj

    base = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"
    assert parse_obj(base).crease_method == "uniform"
    for value, expected in (("uniform", "uniform"), ("normal", "uniform"), ("chaikin", "chaikin")):
        assert parse_obj(base + f"t creasemethod 0/0/1 {value}\n").crease_method == expected
    for bad in ("0/0/1 hbr", "1/0/0 1", "0/0/2 chaikin chaikin", "0/1/1 1.0 chaikin"):
        with pytest.raises(TagError, match="creasemethod takes one string") as err:
            parse_obj(base + "t creasemethod " + bad + "\n", source="x.obj")
        assert "(x.obj:6)" in str(err.value) and "\n" not in str(err.value)
    chaikin = parse_obj(base + "t creasemethod 0/0/1 chaikin\n")
    text = format_obj(chaikin)
    assert text.endswith("t creasemethod 0/0/1 chaikin\n") and parse_obj(text).crease_method == "chaikin"
    assert "creasemethod" not in format_obj(parse_obj(base + "t creasemethod 0/0/1 uniform\n"))
    from patching.errors import TagError as _TagError

    with pytest.raises(_TagError, match="crease_method"):
        from_arrays(open_grid(2, 2).vertices, [[0, 2, 3, 1]], crease_method="hbr")


def _chaikin_grid(tag: str = "chaikin", creases=None):
    grid = open_grid(6, 5)
    faces = [list(grid.face(f)) for f in range(grid.n_faces)]
    creases = creases or {(11, 12): 1.2, (12, 13): 0.3, (12, 17): 2.5}
    return from_arrays(grid.vertices, faces, creases=creases, crease_method=tag)


def test_mesh_crease_method_is_the_default_and_the_argument_wins():
    """subdivision_operator/subdivide/limit_points without crease_method use the mesh's; an
    explicit one wins; the refined mesh carries the method used; rules seed refuse a chaikin
    taken from the mesh naming the tag's line."""
    tagged, plain = _chaikin_grid(), _chaikin_grid("uniform")
    S_tag, child = subdivision_operator(tagged, rules="opensubdiv")
    S_chk, _ = subdivision_operator(plain, rules="opensubdiv", crease_method="chaikin")
    S_uni, _ = subdivision_operator(tagged, rules="opensubdiv", crease_method="uniform")
    assert abs(S_tag - S_chk).max() == 0 and abs(S_uni - subdivision_operator(plain, rules="opensubdiv")[0]).max() == 0
    assert child.crease_method == "chaikin" and child.creases != subdivision_operator(plain, rules="opensubdiv")[1].creases
    assert subdivision_operator(plain, rules="opensubdiv", crease_method="chaikin")[1].crease_method == "chaikin"
    np.testing.assert_array_equal(subdivide(tagged, 3, rules="opensubdiv").vertices,
                                  subdivide(plain, 3, rules="opensubdiv", crease_method="chaikin").vertices)
    assert np.abs(subdivide(tagged, 3, rules="opensubdiv").vertices - subdivide(plain, 3, rules="opensubdiv").vertices).max() > 1e-3
    np.testing.assert_array_equal(limit_points(tagged, rules="opensubdiv"),
                                  limit_points(plain, rules="opensubdiv", crease_method="chaikin"))
    subdivide(tagged, 1, crease_method="uniform")  # rules seed with the tag overridden
    from patching.mesh.obj import format_obj, parse_obj

    obj = parse_obj(format_obj(tagged), source="g.obj")
    with pytest.raises(UnsupportedError, match="chaikin creasing") as err:
        subdivide(obj, 1)
    line = format_obj(tagged).splitlines().index("t creasemethod 0/0/1 chaikin") + 1
    assert f"(g.obj:{line})" in str(err.value)


def test_loop_uses_the_mesh_crease_method():
    from patching.loop import loop_subdivide
    from patching.loop.limit import loop_limit_points

    tet = [(1, 1, 1), (-1, -1, 1), (-1, 1, -1), (1, -1, -1)]
    faces = [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]]
    creases = {(0, 1): 2.0, (1, 2): 0.5, (0, 2): 1.5}
    tagged = from_arrays(tet, faces, creases=creases, crease_method="chaikin")
    plain = from_arrays(tet, faces, creases=creases)
    want = loop_subdivide(plain, 2, crease_method="chaikin")
    got = loop_subdivide(tagged, 2)
    np.testing.assert_array_equal(got.vertices, want.vertices)
    assert got.crease_method == "chaikin" and np.abs(got.vertices - loop_subdivide(plain, 2).vertices).max() > 1e-3
    np.testing.assert_array_equal(loop_subdivide(tagged, 2, crease_method="uniform").vertices, loop_subdivide(plain, 2).vertices)
    np.testing.assert_array_equal(loop_limit_points(tagged), loop_limit_points(plain, crease_method="chaikin"))


def test_build_refuses_chaikin_only_where_it_would_differ():
    """build refines semi-sharp tags with uniform creasing: a chaikin mesh whose first step
    would differ is refused in one line naming the tag; one whose semi-sharp edges are equal at
    every vertex (Chaikin = uniform there, at every step) builds as without the tag."""
    import patching
    from patching.mesh.obj import format_obj, parse_obj

    mixed = parse_obj(format_obj(_chaikin_grid()), source="m.obj")
    with pytest.raises(UnsupportedError, match="CREASE_CHAIKIN") as err:
        patching.build(mixed)
    assert "m.obj:" in str(err.value) and "\n" not in str(err.value)
    equal = {(11, 12): 1.5, (12, 13): 1.5, (13, 14): 1.5}
    a = patching.build(_chaikin_grid("chaikin", equal))
    b = patching.build(_chaikin_grid("uniform", equal))
    np.testing.assert_array_equal(np.concatenate([g.coefficients.ravel() for g in a.groups]),
                                  np.concatenate([g.coefficients.ravel() for g in b.groups]))
    # and Chaikin does equal uniform creasing on that mesh, step after step
    np.testing.assert_array_equal(subdivide(_chaikin_grid("chaikin", equal), 3, rules="opensubdiv").vertices,
                                  subdivide(_chaikin_grid("uniform", equal), 3, rules="opensubdiv").vertices)


def _creasemethod_shapes():
    if not SHAPES_DIR.is_dir():
        return []
    return sorted(p for p in SHAPES_DIR.glob("*.obj") if "t creasemethod" in p.read_text(errors="replace"))


@pytest.mark.skipif(not _creasemethod_shapes(), reason="no OpenSubdiv shape here carries t creasemethod (or the folder is absent)")
@pytest.mark.parametrize("path", _creasemethod_shapes(), ids=lambda p: p.stem)
def test_opensubdiv_shapes_with_the_creasemethod_tag(path):
    mesh = _read(path)
    plain = dataclasses.replace(mesh, crease_method="uniform")
    np.testing.assert_array_equal(subdivide(mesh, 2, rules="opensubdiv").vertices,
                                  subdivide(plain, 2, rules="opensubdiv", crease_method=mesh.crease_method).vertices)


def test_cube_creases1_with_the_tag_appended_equals_the_explicit_method():
    """catmark_cube_creases1 (Chaikin differs there, test_chaikin_halves_on_cube_creases1) with
    OpenSubdiv's ``t creasemethod 0/0/1 chaikin`` appended: two steps equal the explicit
    ``crease_method="chaikin"`` on the file as it is."""
    path = SHAPES_DIR / "catmark_cube_creases1.obj"
    if not path.is_file():
        pytest.skip("opensubdiv-shapes folder absent")
    from patching.mesh.obj import parse_obj

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tagged = parse_obj(path.read_text() + "t creasemethod 0/0/1 chaikin\n", source=str(path))
    plain = _read(path)
    assert tagged.crease_method == "chaikin" and plain.crease_method == "uniform"
    np.testing.assert_array_equal(subdivide(tagged, 2, rules="opensubdiv").vertices,
                                  subdivide(plain, 2, rules="opensubdiv", crease_method="chaikin").vertices)
    assert np.abs(subdivide(tagged, 2, rules="opensubdiv").vertices - subdivide(plain, 2, rules="opensubdiv").vertices).max() > 1e-3
