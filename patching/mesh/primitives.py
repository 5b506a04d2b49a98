"""Control meshes made from parameters: torus grids and open grids, for models, tests and
benchmarks.  Vertex (a, b) of an m x n grid has id ``a * n + b``; a runs along u."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from patching.mesh.control_mesh import ControlMesh, from_arrays

__all__ = ["torus_grid", "open_grid", "polycube"]


def torus_grid(
    m: int,
    n: int,
    u_intervals: Sequence[float] | None = None,
    v_intervals: Sequence[float] | None = None,
    major_radius: float = 3.0,
    minor_radius: float = 1.0,
    name: str = "torus",
) -> ControlMesh:
    """Closed m x n quad grid on a torus; u_intervals[a] is the interval of the strip of
    edges (a, b)-(a+1, b), v_intervals[b] of (a, b)-(a, b+1) (default 1)."""
    a, b = np.meshgrid(np.arange(m), np.arange(n), indexing="ij")
    u = 2 * np.pi * a / m
    w = 2 * np.pi * b / n
    ring = major_radius + minor_radius * np.cos(w)
    vertices = np.stack([ring * np.cos(u), ring * np.sin(u), minor_radius * np.sin(w)], -1).reshape(-1, 3)
    faces, intervals = _grid(m, n, m, n, lambda i, j: (i % m) * n + (j % n), u_intervals, v_intervals)
    return from_arrays(vertices, faces, intervals=intervals, name=name)


def _grid(m, n, cols, rows, idx, u_intervals, v_intervals):
    """Quads (a, b), (a+1, b), (a+1, b+1), (a, b+1) for a < cols, b < rows, and the interval
    tags of the strips (one edge each: (i, 0)-(i+1, 0) in u, (0, j)-(0, j+1) in v)."""
    aa, bb = (x.ravel() for x in np.meshgrid(np.arange(cols), np.arange(rows), indexing="ij"))
    faces = np.stack([idx(aa, bb), idx(aa + 1, bb), idx(aa + 1, bb + 1), idx(aa, bb + 1)], axis=1)
    intervals = {}
    if u_intervals is not None:
        intervals.update({(int(idx(i, 0)), int(idx(i + 1, 0))): float(d) for i, d in enumerate(u_intervals)})
    if v_intervals is not None:
        intervals.update({(int(idx(0, j)), int(idx(0, j + 1))): float(d) for j, d in enumerate(v_intervals)})
    return faces, intervals


def open_grid(
    m: int,
    n: int,
    u_intervals: Sequence[float] | None = None,
    v_intervals: Sequence[float] | None = None,
    height: float = 0.5,
    name: str = "grid",
) -> ControlMesh:
    """Open m x n vertex grid over [0, m-1] x [0, n-1], a gentle bump in z.

    u_intervals has m-1 entries (strip between columns a and a+1), v_intervals n-1.  Zero outer
    strips give the clamped NURBS (docs/knots.md)."""
    a, b = np.meshgrid(np.arange(m, dtype=float), np.arange(n, dtype=float), indexing="ij")
    z = height * np.sin(np.pi * a / (m - 1)) * np.sin(np.pi * b / (n - 1))
    vertices = np.stack([a, b, z], -1).reshape(-1, 3)
    faces, intervals = _grid(m, n, m - 1, n - 1, lambda i, j: i * n + j, u_intervals, v_intervals)
    return from_arrays(vertices, faces, intervals=intervals, name=name)


def polycube(voxels, divisions: int = 2, name: str = "polycube") -> ControlMesh:
    """The boundary of a union of unit cubes as a closed quad mesh, each cube face divided
    into divisions x divisions quads.  voxels: iterable of integer (x, y, z) cells.

    Convex corners become valence-3 EPs, concave ones valence 5 or 6; faces are oriented
    outwards.  Shared boundary edges between voxels that meet only along an edge or a corner
    make a non-manifold surface: such voxel sets are refused by the topology checks."""
    cells = {tuple(int(c) for c in v) for v in voxels}
    k = int(divisions)
    index: dict[tuple[int, int, int], int] = {}
    vertices: list[tuple[float, float, float]] = []
    faces: list[list[int]] = []

    def vid(p):
        if p not in index:
            index[p] = len(vertices)
            vertices.append(tuple(c / k for c in p))
        return index[p]

    for cell in sorted(cells):
        for axis in range(3):
            for sign in (-1, 1):
                nb = list(cell)
                nb[axis] += sign
                if tuple(nb) in cells:
                    continue
                u, w = [a for a in range(3) if a != axis]
                if sign < 0:
                    u, w = w, u  # keep the quads counter-clockwise seen from outside
                if axis == 1:
                    u, w = w, u  # (x, y, z) is right-handed: the y normal flips the pair
                base = [c * k for c in cell]
                base[axis] += k if sign > 0 else 0
                for i in range(k):
                    for j in range(k):
                        quad = []
                        for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                            p = list(base)
                            p[u] += i + di
                            p[w] += j + dj
                            quad.append(vid(tuple(p)))
                        faces.append(quad)
    return from_arrays(np.array(vertices, dtype=np.float64), faces, name=name)
