"""Evaluating patches: points, normals, blending functions, and a quality report per EP.

All vectorised over patches with Bernstein matrices; nets as in ``surface`` (net[i, j] times
B_i(s) B_j(t)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bernstein import bernstein
from .operator import SurfaceOperator
from .surface import BezierSurface

__all__ = [
    "evaluate_nets",
    "sample_surface",
    "blending_function",
    "EPQuality",
    "ep_quality",
    "count_local_maxima",
]


def evaluate_nets(nets: np.ndarray, s: np.ndarray, t: np.ndarray, derivatives: bool = False):
    """Points of (k, d+1, d+1, c) nets at parameters (m,) s and t (pairs): (k, m, c).

    With derivatives=True also returns S_s and S_t, each (k, m, c)."""
    d = nets.shape[1] - 1
    bs, bt = bernstein(d, s), bernstein(d, t)
    points = np.einsum("mi,mj,kijc->kmc", bs, bt, nets)
    if not derivatives:
        return points
    ds = d * np.einsum("mi,mj,kijc->kmc", bernstein(d - 1, s), bt, nets[:, 1:] - nets[:, :-1])
    dt = d * np.einsum("mi,mj,kijc->kmc", bs, bernstein(d - 1, t), nets[:, :, 1:] - nets[:, :, :-1])
    return points, ds, dt


def sample_surface(surface: BezierSurface, samples: int = 9):
    """Points and unit normals on a samples x samples grid of every patch.

    Returns (faces (p,), points (p, samples^2, 3), normals (p, samples^2, 3))."""
    u = np.linspace(0.0, 1.0, samples)
    s, t = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    faces, points, normals = [], [], []
    for g in surface.groups:
        p, ds, dt = evaluate_nets(g.coefficients, s, t, derivatives=True)
        n = np.cross(ds, dt)
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
        faces.append(g.faces)
        points.append(p)
        normals.append(n)
    return np.concatenate(faces), np.concatenate(points), np.concatenate(normals)


def blending_function(operator: SurfaceOperator, control_point: int, samples: int = 17):
    """The blending function of one control point (column of M) as heights over every patch
    it touches: returns (faces (k,), values (k, samples, samples)) on a uniform grid."""
    column = operator.matrix[:, control_point].toarray().ravel()
    u = np.linspace(0.0, 1.0, samples)
    faces, values = [], []
    for g in operator.groups:
        d = g.degree
        block = column[g.row_offset : g.row_offset + g.n_rows].reshape(-1, d + 1, d + 1)
        touched = np.flatnonzero(np.abs(block).max(axis=(1, 2)) > 0)
        if touched.size == 0:
            continue
        b = bernstein(d, u)
        values.append(np.einsum("si,tj,kij->kst", b, b, block[touched]))
        faces.append(g.faces[touched])
    if not faces:
        return np.zeros(0, np.int64), np.zeros((0, samples, samples))
    return np.concatenate(faces), np.concatenate(values)


def count_local_maxima(values: np.ndarray, neighbours: list[list[int]], tol: float = 1e-12) -> int:
    """Strict local maxima of a function sampled at nodes with given neighbour lists."""
    count = 0
    for i, nb in enumerate(neighbours):
        if nb and values[i] > tol and all(values[i] > values[j] + tol * max(1.0, abs(values[i])) for j in nb):
            count += 1
    return count


@dataclass(frozen=True)
class EPQuality:
    """Per EP: vertex id, valence, largest normal jump (degrees) across its spoke edges,
    and the number of local maxima of the blending function of each anchor-ring point
    (the EP and its edge neighbours) over the EP's patches."""

    vertex: int
    valence: int
    max_normal_jump_deg: float
    local_maxima: dict[int, int]
