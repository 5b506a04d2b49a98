"""Sharp features of the input: its sharp edges, carried onto the quad control mesh as creases.

An input edge is sharp when the angle between the normals of its two triangles exceeds
``sharp_angle`` (degrees).  The sharp edges form feature curves: chains of sharp edges,
cut at vertices where other than two sharp edges meet (corners, junctions); a closed loop with
no such vertex is cut into ``LOOP_PIECES`` pieces of equal vertex counts.  Each piece is
carried onto the control mesh as the cheapest path of control edges between the control
vertices nearest its two ends (Dijkstra), an edge costing its length times
1 + (d / h)^2, d the distance of the edge's midpoint to the piece and h the mean control edge
length: the nearest edge chain that follows the curve.  The chain's edges are tagged as
infinitely sharp creases (OpenSubdiv's sharpness 10, docs/input.md) and its vertices moved to
their nearest points on the feature curve, so the fit starts with the crease in place.  A
vertex where three or more creases meet is a corner by the crease rules.

This is not in [FSLYJ] sec. 4.1, which fits smooth inputs only.  The remesher is not told of
the features (Instant Meshes' crease option, tried, did not align the pure-quad output's edges
to a cylinder's rims), so the chains follow whatever edges lie nearest: on a mesh whose edges
cross a feature at 45 degrees the chain is a staircase.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

__all__ = ["sharp_edges", "feature_chains", "crease_chains", "CREASE_SHARPNESS"]

#: The sharpness of the crease tags (infinitely sharp, docs/input.md).
CREASE_SHARPNESS = 10.0
#: A closed feature loop without corners is carried over in this many pieces.
LOOP_PIECES = 4


def sharp_edges(vertices: np.ndarray, triangles: np.ndarray, angle: float) -> np.ndarray:
    """(k, 2) int64 vertex pairs (a < b) of the interior edges whose two triangles' normals
    differ by more than ``angle`` degrees (the dihedral angle's supplement)."""
    f = triangles
    n = np.cross(vertices[f[:, 1]] - vertices[f[:, 0]], vertices[f[:, 2]] - vertices[f[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    directed = np.stack([f, np.roll(f, -1, axis=1)], axis=-1).reshape(-1, 2)
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    key = lo * vertices.shape[0] + hi
    order = np.argsort(key, kind="stable")
    k = key[order]
    pair = np.flatnonzero(k[1:] == k[:-1])
    a, b = order[pair] // 3, order[pair + 1] // 3
    cosine = np.einsum("ij,ij->i", n[a], n[b])
    sharp = cosine < np.cos(np.radians(angle))
    edges = np.stack([lo[order[pair]], hi[order[pair]]], axis=1)[sharp]
    return edges.astype(np.int64)


def feature_chains(edges: np.ndarray) -> list[np.ndarray]:
    """The sharp edges as vertex chains (module docstring): each an int64 array of input
    vertex ids, end to end; a loop's pieces share their ends."""
    if edges.size == 0:
        return []
    nbrs: dict[int, list[int]] = {}
    for a, b in edges.tolist():  # feature curves: a small graph, walked once
        nbrs.setdefault(a, []).append(b)
        nbrs.setdefault(b, []).append(a)
    stops = {v for v, around in nbrs.items() if len(around) != 2}
    used: set[tuple[int, int]] = set()
    chains = []

    def walk(start: int, nxt: int) -> list[int]:
        chain = [start, nxt]
        used.add((min(start, nxt), max(start, nxt)))
        while chain[-1] not in stops and chain[-1] != start:
            here, before = chain[-1], chain[-2]
            step = [w for w in nbrs[here] if w != before and (min(here, w), max(here, w)) not in used]
            if not step:
                break
            chain.append(step[0])
            used.add((min(here, step[0]), max(here, step[0])))
        return chain

    for s in sorted(stops):
        for w in nbrs[s]:
            if (min(s, w), max(s, w)) not in used:
                chains.append(walk(s, w))
    for a, b in edges.tolist():  # loops without stops
        if (min(a, b), max(a, b)) not in used:
            loop = walk(a, b)
            cuts = np.linspace(0, len(loop) - 1, LOOP_PIECES + 1).round().astype(int)
            chains += [loop[i : j + 1] for i, j in zip(cuts[:-1], cuts[1:]) if j > i]
    return [np.asarray(c, dtype=np.int64) for c in chains]


def _nearest_on_polyline(points: np.ndarray, polyline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distance (m,), nearest point (m, 3)) of each point to the polyline (k, 3), k >= 2."""
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    t = np.einsum("mkc,kc->mk", points[:, None, :] - a[None], ab) / np.maximum(np.einsum("kc,kc->k", ab, ab), 1e-300)
    t = np.clip(t, 0.0, 1.0)
    q = a[None] + t[:, :, None] * ab[None]
    d = np.linalg.norm(q - points[:, None, :], axis=2)
    best = np.argmin(d, axis=1)
    rows = np.arange(points.shape[0])
    return d[rows, best], q[rows, best]


def crease_chains(control_vertices: np.ndarray, control_edges: np.ndarray, vertices: np.ndarray,
                  chains: list[np.ndarray]) -> tuple[dict[tuple[int, int], float], np.ndarray]:
    """({(a, b): CREASE_SHARPNESS} for the control edges carrying the feature chains, control
    vertices with the chains' vertices moved onto the features) (module docstring)."""
    cv = np.asarray(control_vertices, dtype=np.float64).copy()
    e = np.asarray(control_edges, dtype=np.int64)
    n = cv.shape[0]
    length = np.linalg.norm(cv[e[:, 0]] - cv[e[:, 1]], axis=1)
    h = float(length.mean()) if length.size else 1.0
    mid = 0.5 * (cv[e[:, 0]] + cv[e[:, 1]])
    tree = cKDTree(cv)
    creases: dict[tuple[int, int], float] = {}
    moved: dict[int, np.ndarray] = {}
    for chain in chains:
        polyline = vertices[chain]
        # only edges near the piece matter: the others get the plain cost times a large factor
        # the distance of every edge midpoint to the piece's vertices, exact to its segments
        # for the edges within 3 h (the only ones a cheap path uses)
        d_mid = cKDTree(polyline).query(mid)[0]
        near = np.flatnonzero(d_mid < 3.0 * h)
        if near.size:
            d_mid[near] = _nearest_on_polyline(mid[near], polyline)[0]
        cost = length * (1.0 + (d_mid / h) ** 2) + 1e-12 * h
        graph = sp.coo_matrix((np.concatenate([cost, cost]), (np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]]))), shape=(n, n)).tocsr()
        start, end = (int(tree.query(vertices[chain[i]])[1]) for i in (0, -1))
        if start == end:
            continue
        _, pred = dijkstra(graph, indices=start, return_predecessors=True)
        path = [end]
        while path[-1] != start and pred[path[-1]] >= 0:
            path.append(int(pred[path[-1]]))
        if path[-1] != start:
            continue
        path = path[::-1]
        for a, b in zip(path[:-1], path[1:]):
            creases[(min(a, b), max(a, b))] = CREASE_SHARPNESS
        _, on = _nearest_on_polyline(cv[path], polyline)
        for v, p in zip(path, on):
            moved[v] = p
    for v, p in moved.items():
        cv[v] = p
    return creases, cv
