"""Loop subdivision (patching.loop): positions against the independent reference in
tests/reference_loop.py on [OSD]'s shapes and on generated meshes with random creases,
corners and boundaries; limit points and normals against the 1-ring refined on its own."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import patching
from patching.errors import KnotError, UnsupportedError
from patching.loop import loop_operator, loop_subdivide
from tests.conftest import shape_files
from tests.reference_loop import RefMesh

# conftest looks beside the checkout; a worktree elsewhere falls back to the shared folder
LOOP_SHAPES = shape_files("loop_")


def _ref_of(mesh, method="uniform"):
    faces = [mesh.face(f).tolist() for f in range(mesh.n_faces)]
    return RefMesh(mesh.vertices, faces, mesh.creases, mesh.corners, mesh.interpolate_boundary, method)


def _compare(mesh, levels, method="uniform"):
    ref = _ref_of(mesh, method)
    cur = mesh
    for level in range(1, levels + 1):
        S, cur = loop_operator(cur, method)
        ref = ref.step()
        got = cur.vertices
        want = np.array(ref.P)
        assert got.shape == want.shape
        scale = max(1.0, float(np.abs(want).max()))
        assert np.abs(got - want).max() <= 1e-12 * scale, (level, np.abs(got - want).max())
        assert np.allclose(np.asarray(S.sum(axis=1)).ravel(), 1.0, atol=1e-14)
        # the child topology and tags are the reference's too
        assert [tuple(cur.face(f).tolist()) for f in range(cur.n_faces)] == ref.faces
        mine = {k: v for k, v in cur.creases.items() if v < 10}
        theirs = {k: v for k, v in ref.creases.items() if v < 10}
        assert mine.keys() == theirs.keys() and all(abs(mine[k] - theirs[k]) < 1e-12 for k in mine)


@pytest.mark.skipif(not LOOP_SHAPES, reason="OpenSubdiv shapes absent")
@pytest.mark.parametrize("path", LOOP_SHAPES, ids=lambda p: p.stem)
@pytest.mark.parametrize("method", ["uniform", "chaikin"])
def test_shapes_equal_reference(path, method):
    _compare(patching.read_mesh(path), 3, method)


def _icosahedron():
    t = (1 + 5**0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    return v, f


def _tri_grid(n, m):
    v = np.array([[i, j, 0.1 * ((i * 7 + j * 3) % 5)] for j in range(m + 1) for i in range(n + 1)], float)
    f = []
    for j in range(m):
        for i in range(n):
            a, b, c, d = j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i
            f += [[a, b, c], [a, c, d]] if (i + j) % 2 else [[a, b, d], [b, c, d]]
    return v, f


def _fan(k):
    ang = 2 * np.pi * np.arange(k) / k
    v = np.vstack([[0, 0, 0.3], np.stack([np.cos(ang), np.sin(ang), 0.2 * np.cos(2 * ang)], 1)])
    return v, [[0, 1 + i, 1 + (i + 1) % k] for i in range(k)]


BASES = {"ico": _icosahedron(), "grid": _tri_grid(3, 3), "fan5": _fan(5), "fan7": _fan(7),
         "tet": (np.array([[1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1]], float), [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])}
SHARPNESS = st.sampled_from([0.0, 0.0, 0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 2.75, 10.0])


@settings(max_examples=25, deadline=None)
@given(base=st.sampled_from(sorted(BASES)), data=st.data(), mode=st.sampled_from([0, 1, 2]),
       method=st.sampled_from(["uniform", "chaikin"]), levels=st.integers(1, 3))
def test_generated_equal_reference(base, data, mode, method, levels):
    mesh = random_tagged_mesh(base, data, mode)
    _compare(mesh, levels if mesh.n_faces < 30 else min(levels, 2), method)


def random_tagged_mesh(base, data, mode):
    """BASES[base] jittered, with random crease and corner sharpness drawn from ``data``."""
    v, f = BASES[base]
    rng = np.random.default_rng(data.draw(st.integers(0, 2**31)))
    v = v + 0.05 * rng.standard_normal(v.shape)
    edges = sorted({(min(a, b), max(a, b)) for tri in f for a, b in zip(tri, tri[1:] + tri[:1])})
    creases = {e: s for e in edges if (s := data.draw(SHARPNESS)) > 0}
    corners = {i: s for i in range(len(v)) if rng.random() < 0.15 and (s := data.draw(SHARPNESS)) > 0}
    return patching.from_arrays(v, f, creases=creases, corners=corners, interpolate_boundary=mode)


DATA = Path(__file__).parent / "data"


def _mixed_transitions(mesh, method):
    """Vertices of ``mesh`` whose crease/corner rule turns smooth-ward in this step through two
    or more halves of different parent sharpness that all turn smooth ([OSD]
    ``ComputeFractionalWeightAtVertex`` averaging unequal values)."""
    from patching.loop.refine import LoopLevel

    L = LoopLevel.of(mesh, method)
    found = []
    for v in np.flatnonzero(L.rule != L.child_rule):
        turning = [L.es[e] for e in range(L.topo.n_edges) for k in (0, 1)
                   if L.topo.edges[e, k] == v and L.es[e] > 0 and L.child_es[e, k] <= 0]
        if len(turning) >= 2 and max(turning) - min(turning) > 1e-9:
            found.append(int(v))
    return found


def test_chaikin_mixed_sharpness_vertex():
    """Chaikin creasing where a sharpness-1 and a sharpness-0.25 half meet and both turn smooth:
    [OSD] Far (``Crease::SubdivideEdgeSharpnessAtVertex`` gives both children 0, so the child
    rule is smooth) blends the crease mask with weight mean(1, 0.25) = 0.625; the legacy Hbr
    takes 0.25 (the mean of the sharpness values below 1 only; benchmarks/osd_hbr_baseline.py).
    Positions equal the reference for 3 levels, and the vertex's row shows Far's weight."""
    from patching.loop.rules import loop_beta

    v, f = _fan(7)
    mesh = patching.from_arrays(v, f, creases={(0, 1): 1.0, (0, 4): 0.25})
    assert _mixed_transitions(mesh, "chaikin") == [0]
    _compare(mesh, 3, "chaikin")
    S, _ = loop_operator(mesh, "chaikin")
    smooth_self = 1.0 - 7 * float(loop_beta(7))
    w = (S[0, 0] - smooth_self) / (0.75 - smooth_self)
    assert abs(w - 0.625) < 1e-14
    assert abs(S[0, 1] - (0.625 * 0.125 + 0.375 * float(loop_beta(7)))) < 1e-14
    assert abs(S[0, 2] - 0.375 * float(loop_beta(7))) < 1e-14


def test_chaikin_regression_shape():
    """[OSD]'s loop_chaikin1 (integer creases 1-5 meeting at corners, Chaikin creasing): from
    level 1 on it has vertices where unequal halves turn smooth together (the ones where the Hbr
    baseline differs by 8e-3); equal to the reference for 3 levels (compiled Far agrees to
    5.6e-17 at 4 levels with its float32 weights, benchmarks/osd_far_reference.py)."""
    mesh = patching.read_mesh(DATA / "loop_chaikin1.obj")
    cur, mixed = mesh, []
    for _ in range(3):
        mixed.append(len(_mixed_transitions(cur, "chaikin")))
        cur = loop_operator(cur, "chaikin")[1]
    assert mixed[0] == 0 and min(mixed[1:]) >= 4, mixed
    _compare(mesh, 3, "chaikin")


def test_non_triangle_refused():
    mesh = patching.from_arrays(np.eye(4, 3), [[0, 1, 2, 3]])
    with pytest.raises(UnsupportedError, match="face 0 has 4 vertices"):
        loop_operator(mesh)


def test_non_uniform_refused():
    v, f = _fan(5)
    mesh = patching.from_arrays(v, f, intervals={(0, 1): 2.0})
    with pytest.raises(KnotError, match="edge 0-1"):
        loop_subdivide(mesh, 1)


# ------------------------------------------------------------------------------------------
# Limit points and normals: each vertex's 1-ring refined on its own with the reference rules


def _fan_of(ref: RefMesh, v: int, faces_idx):
    """The faces ``faces_idx`` around v as a RefMesh of their own, v renumbered 0."""
    faces = [ref.faces[j] for j in faces_idx]
    verts = [v] + sorted({x for f in faces for x in f} - {v})
    loc = {x: i for i, x in enumerate(verts)}
    creases = {(min(loc[a], loc[b]), max(loc[a], loc[b])): s for (a, b), s in ref.creases.items() if a in loc and b in loc and v in (a, b)}
    corners = {0: ref.corners[v]} if v in ref.corners else {}
    P = [ref.P[x] for x in verts]
    return RefMesh(P, [tuple(loc[x] for x in f) for f in faces], creases, corners, ref.mode, ref.method)


def _refine_ring(ref: RefMesh, v: int, steps: int):
    """(limit point of v, (k, 3) facet normals and their conditioning |a x b| / (|a| |b|) of
    the k faces around v after ``steps`` steps of the ring alone, rescaled every step; faces
    in the order of ``ref.faces``).  In 60-digit arithmetic (mpmath): on a crease side the
    modes that span the tangent plane decay at different rates (1/2 along the crease, 3/8
    across a side of two faces), so after 160 steps the facets are cross products of vectors
    parallel to 1e-20, which double precision cannot resolve."""
    import mpmath

    import tests.reference_loop as rl

    mpmath.mp.dps = 60
    rl.COS, rl.PI = mpmath.cos, mpmath.pi
    try:
        around = [j for j, f in enumerate(ref.faces) if v in f]
        fan = _fan_of(ref, v, around)
        fan.P = [tuple(mpmath.mpf(float(x)) for x in p) for p in fan.P]
        offset, scale = [mpmath.mpf(0)] * 3, mpmath.mpf(1)
        for _ in range(steps):
            child = fan.step()
            keep = [4 * j + fan.faces[j].index(0) for j in range(len(fan.faces))]
            fan = _fan_of(child, 0, keep)
            c = fan.P[0]
            m = max(abs(x - y) for p in fan.P for x, y in zip(p, c))
            offset = [o + scale * x for o, x in zip(offset, c)]
            scale = scale * m
            fan.P = [tuple((x - y) / m for x, y in zip(p, c)) for p in fan.P]
        normals, conditioning = [], []
        for f in fan.faces:
            i = f.index(0)
            a, b = (mpmath.matrix(fan.P[f[(i + d) % 3]]) for d in (1, 2))
            n = mpmath.matrix([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
            ln = mpmath.norm(n)
            normals.append([float(x / ln) for x in n])
            conditioning.append(float(ln / (mpmath.norm(a) * mpmath.norm(b))))
        point = np.array([float(o + scale * x) for o, x in zip(offset, fan.P[0])])
    finally:
        rl.COS, rl.PI = math.cos, math.pi
    return point, np.array(normals), np.array(conditioning), around


def _angle(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.einsum("...i,...i", a, b))


def _fan_mesh(k, sharp_spokes=(), boundary=False):
    ang = (np.pi if boundary else 2 * np.pi) * np.arange(k + boundary) / k
    rim = np.stack([np.cos(ang), np.sin(ang), 0.3 * np.cos(2 * ang) + 0.1 * np.sin(3 * ang)], 1)
    v = np.vstack([[0.05, -0.02, 0.2], rim])
    f = [[0, 1 + i, 1 + (i + 1) % (k + boundary)] for i in range(k)]
    creases = {(0, 1 + i): 10.0 for i in sharp_spokes}
    return v, f, creases


LIMIT_CASES = {
    "smooth3": _fan_mesh(3), "smooth5": _fan_mesh(5), "smooth6": _fan_mesh(6), "smooth9": _fan_mesh(9),
    "dart5": _fan_mesh(5, (0,)), "dart6": _fan_mesh(6, (0,)), "dart8": _fan_mesh(8, (2,)),
    "crease_1_5": _fan_mesh(6, (0, 1)), "crease_2_4": _fan_mesh(6, (0, 2)), "crease_3_3": _fan_mesh(6, (0, 3)),
    "crease_3_5": _fan_mesh(8, (0, 3)), "crease_4_4": _fan_mesh(8, (0, 4)), "crease_2_7": _fan_mesh(9, (1, 3)),
    "boundary2": _fan_mesh(2, (), True), "boundary3": _fan_mesh(3, (), True), "boundary5": _fan_mesh(5, (), True),
    "corner_2_3": _fan_mesh(5, (2,), True),  # a boundary vertex with a sharp spoke: a corner
}


@pytest.mark.parametrize("case", sorted(LIMIT_CASES))
def test_limit_point_and_normal_equal_refined_ring(case):
    from patching.loop.limit import loop_limit_masks

    v, f, creases = LIMIT_CASES[case]
    mesh = patching.from_arrays(v, f, creases=creases, interpolate_boundary=2)
    masks = loop_limit_masks(mesh)
    lim = masks.points(mesh.vertices)
    normals = masks.corner_normals(mesh.vertices)
    ref = _ref_of(mesh)
    # a side of 7 faces: the second interior mode (0.531) follows the first (0.600) closely
    point, fd, cond, around = _refine_ring(ref, 0, 320 if case == "crease_2_7" else 160)
    assert np.abs(lim[0] - point).max() < 1e-12
    corners = np.array([mesh.face_offsets[j] + list(mesh.face(j)).index(0) for j in around])
    assert not masks.stationary.approximate[masks.index[masks.region_of_corner[corners]]].any()
    # per region, the finite-difference normal of its best-conditioned facet
    region = masks.region_of_corner[corners]
    for r in np.unique(region):
        mine = region == r
        best = np.flatnonzero(mine)[np.argmax(cond[mine])]
        if case == "corner_2_3" and mine.sum() == 3:
            # A corner sector of three faces: its inner mode and both crease tangents share the
            # eigenvalue 1/2 (a Jordan block), so the facets turn towards the limit normal
            # (E_a - V) x (E_b - V) like 1/N only: the angle halves when the steps double.
            far = _angle(normals[corners[mine]], _refine_ring(ref, 0, 80)[1][best])
            near = _angle(normals[corners[mine]], fd[best])
            assert near.max() < 3e-3 and near.max() < 0.55 * far.max(), (near, far)
            continue
        assert _angle(normals[corners[mine]], fd[best]).max() < 1e-9, (r, _angle(normals[corners[mine]], fd[best]))


def test_dart_centre_weight():
    """[OSD]'s smooth mask would give 1/2 at valence 6; the dart's own 1-ring gives more."""
    from patching.loop.limit import loop_limit_masks

    v, f, creases = _fan_mesh(6, (0,))
    w = loop_limit_masks(patching.from_arrays(v, f, creases=creases)).position[0, 0]
    smooth = loop_limit_masks(patching.from_arrays(*_fan_mesh(6)[:2])).position[0, 0]
    assert abs(smooth - 0.5) < 1e-14
    assert abs(w - 0.516) < 5e-4


@settings(max_examples=8, deadline=None)
@given(data=st.data(), method=st.sampled_from(["uniform", "chaikin"]))
def test_limit_points_semi_sharp(data, method):
    """Semi-sharp tags: refined until decayed, then the ring on its own (positions)."""
    from patching.loop.limit import loop_limit_masks

    v, f = _icosahedron()
    edges = sorted({(min(a, b), max(a, b)) for tri in f for a, b in zip(tri, tri[1:] + tri[:1])})
    creases = {e: s for e in edges if (s := data.draw(st.sampled_from([0.0, 0.0, 0.0, 0.5, 1.0, 1.5, 2.0, 10.0]))) > 0}
    mesh = patching.from_arrays(v, f, creases=creases, corners={0: data.draw(st.sampled_from([0.0, 1.5, 10.0]))})
    lim = loop_limit_masks(mesh, method).points(mesh.vertices)
    ref = RefMesh(mesh.vertices, [list(x) for x in f], mesh.creases, mesh.corners, mesh.interpolate_boundary, method)
    steps = int(math.ceil(max([s for s in list(creases.values()) + list(mesh.corners.values()) if s < 10], default=0)))
    for _ in range(steps):
        ref = ref.step()
    for vid in (0, 3, 7):
        point = _refine_ring(ref, vid, 90)[0]
        assert np.abs(lim[vid] - point).max() < 1e-12
