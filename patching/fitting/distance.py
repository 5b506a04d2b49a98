"""Point-to-triangle-mesh distances for the fit report (surface -> input).

Closest point on a triangle by its Voronoi regions (Ericson, Real-Time Collision Detection,
sec. 5.1.5), vectorised; the candidate triangles of a query point are those around its nearest
mesh vertices (a k-d tree), so the distance returned is that to the nearest candidate: never
below the true distance, and equal to it unless the nearest triangle touches none of those
vertices (a sliver far longer than its neighbours).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

__all__ = ["closest_on_triangles", "mesh_distance"]


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(m, 3) closest points on triangles (a[k], b[k], c[k]) to points p[k] (all (m, 3))."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    denom = np.where(np.abs(denom) > 1e-300, denom, 1e-300)
    v = vb / denom
    w = vc / denom
    out = a + ab * v[:, None] + ac * w[:, None]  # inside the face
    with np.errstate(divide="ignore", invalid="ignore"):
        # edge BC
        sel = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
        tt = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        out = np.where(sel[:, None], b + (c - b) * np.nan_to_num(tt)[:, None], out)
        # edge AC
        sel = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        tt = d2 / (d2 - d6)
        out = np.where(sel[:, None], a + ac * np.nan_to_num(tt)[:, None], out)
        # edge AB
        sel = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        tt = d1 / (d1 - d3)
        out = np.where(sel[:, None], a + ab * np.nan_to_num(tt)[:, None], out)
    out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, out)
    return out


def mesh_distance(vertices: np.ndarray, triangles: np.ndarray, points: np.ndarray, nearest_vertices: int = 4) -> np.ndarray:
    """(m,) distance from each point to the triangle mesh (module docstring for the candidates)."""
    tree = cKDTree(vertices)
    _, near = tree.query(points, k=min(nearest_vertices, vertices.shape[0]))
    near = near.reshape(points.shape[0], -1)
    t = triangles.shape[0]
    incidence = sp.csr_matrix(
        (np.ones(3 * t), (triangles.ravel(), np.repeat(np.arange(t), 3))), shape=(vertices.shape[0], t)
    )
    best = np.full(points.shape[0], np.inf)
    for col in range(near.shape[1]):
        sub = incidence[near[:, col]].tocoo()
        q = points[sub.row]
        tri = triangles[sub.col]
        cp = closest_on_triangles(q, vertices[tri[:, 0]], vertices[tri[:, 1]], vertices[tri[:, 2]])
        dist = np.linalg.norm(cp - q, axis=1)
        np.minimum.at(best, sub.row, dist)
    return best
