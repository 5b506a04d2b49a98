"""Hypothesis strategies: valid quad meshes with random knot intervals."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from patching.mesh.control_mesh import ControlMesh, from_arrays
from patching.mesh.primitives import torus_grid


@st.composite
def intervals(draw, count: int, ratio: float = 20.0, allow_zero: bool = False):
    """count knot intervals in [1, ratio], optionally some zeros (double knots)."""
    values = draw(st.lists(st.floats(1.0, ratio), min_size=count, max_size=count))
    if allow_zero:
        zeros = draw(st.lists(st.booleans(), min_size=count, max_size=count))
        values = [0.0 if z and i % 3 == 1 else v for i, (v, z) in enumerate(zip(values, zeros))]
    return values


@st.composite
def torus_meshes(draw, min_size: int = 4, max_size: int = 9, ratio: float = 20.0, allow_zero: bool = False):
    """A closed m x n torus grid with random strip intervals and jittered control points."""
    m = draw(st.integers(min_size, max_size))
    n = draw(st.integers(min_size, max_size))
    du = draw(intervals(m, ratio, allow_zero))
    dv = draw(intervals(n, ratio, allow_zero))
    mesh = torus_grid(m, n, du, dv)
    seed = draw(st.integers(0, 2**32 - 1))
    jitter = np.random.default_rng(seed).normal(scale=0.05, size=mesh.vertices.shape)
    return mesh.with_positions(mesh.vertices + jitter)


def relabelled(mesh: ControlMesh, seed: int) -> tuple[ControlMesh, np.ndarray, np.ndarray, np.ndarray]:
    """The same mesh with vertices and faces renumbered and each face's first vertex rotated;
    its tags (intervals, creases, corners, holes, interpolateboundary) follow the new numbers.

    Returns (mesh, vertex_perm, face_perm, rotation): new vertex i is old vertex_perm[i], new
    face k is old face face_perm[k] starting at its vertex rotation[k]."""
    rng = np.random.default_rng(seed)
    nv, quads = mesh.n_vertices, mesh.quads()
    vperm = rng.permutation(nv)
    inverse = np.argsort(vperm)
    fperm = rng.permutation(len(quads))
    rot = rng.integers(0, 4, len(quads))
    faces = np.array([np.roll(quads[f], -r) for f, r in zip(fperm, rot)])

    def edge(a: int, b: int) -> tuple[int, int]:
        return int(inverse[a]), int(inverse[b])

    new = from_arrays(
        mesh.vertices[vperm],
        inverse[faces],
        intervals={edge(a, b): d for (a, b), d in mesh.intervals.items()},
        creases={edge(a, b): s for (a, b), s in mesh.creases.items()},
        corners={int(inverse[v]): s for v, s in mesh.corners.items()},
        holes=sorted(int(k) for k in np.flatnonzero(np.isin(fperm, sorted(mesh.holes)))),
        interpolate_boundary=mesh.interpolate_boundary,
        name=mesh.name,
    )
    return new, vperm, fperm, rot


def reversed_orientation(mesh: ControlMesh) -> ControlMesh:
    """Every face reversed, keeping its first vertex: (v0, v1, v2, v3) -> (v0, v3, v2, v1); the
    tags unchanged."""
    quads = mesh.quads()
    return from_arrays(
        mesh.vertices, quads[:, [0, 3, 2, 1]], intervals=dict(mesh.intervals), creases=dict(mesh.creases),
        corners=dict(mesh.corners), holes=sorted(mesh.holes), interpolate_boundary=mesh.interpolate_boundary,
        name=mesh.name,
    )
