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
LOOP_SHAPES = shape_files("loop_") or sorted(Path("/work/shared/opensubdiv-shapes").glob("loop_*.obj"))


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
    v, f = BASES[base]
    rng = np.random.default_rng(data.draw(st.integers(0, 2**31)))
    v = v + 0.05 * rng.standard_normal(v.shape)
    edges = sorted({(min(a, b), max(a, b)) for tri in f for a, b in zip(tri, tri[1:] + tri[:1])})
    creases = {e: s for e in edges if (s := data.draw(SHARPNESS)) > 0}
    corners = {i: s for i in range(len(v)) if rng.random() < 0.15 and (s := data.draw(SHARPNESS)) > 0}
    mesh = patching.from_arrays(v, f, creases=creases, corners=corners, interpolate_boundary=mode)
    _compare(mesh, levels if len(f) < 30 else min(levels, 2), method)


def test_non_triangle_refused():
    mesh = patching.from_arrays(np.eye(4, 3), [[0, 1, 2, 3]])
    with pytest.raises(UnsupportedError, match="face 0 has 4 vertices"):
        loop_operator(mesh)


def test_non_uniform_refused():
    v, f = _fan(5)
    mesh = patching.from_arrays(v, f, intervals={(0, 1): 2.0})
    with pytest.raises(KnotError, match="edge 0-1"):
        loop_subdivide(mesh, 1)
