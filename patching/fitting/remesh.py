"""The quad remesher behind one function (``quad_remesh``), so that another can be plugged in.

[FSLYJ] sec. 4.1 extracts the quadrilateral control mesh from the triangle mesh with QuadriFlow
([HZN18], its reference [10]).  Here the default is Instant Meshes (Jakob, Tarini, Panozzo,
Sorkine-Hornung 2015, the field-aligned method that QuadriFlow builds on) through ``pynanoinstantmeshes`` (the ``[fit]`` extra; the choice is
justified in docs/fitting.md): its extraction ends with one regular subdivision step, so the
output is pure quads, which is what the patching wants.

A remesher is any callable ``(vertices (n, 3) float64, triangles (t, 3) int64, faces int) ->
(vertices (k, 3), faces (f, 4) or a list of polygons)``; ``quad_remesh`` checks and cleans what
it returns (unused vertices dropped, collapsed quads turned into triangles, orientation made to
agree with the input's) and raises ``MeshError`` naming the remesher when the output is empty,
non-finite or non-manifold.
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import Callable, Sequence

import numpy as np

from ..errors import MeshError, UnsupportedError

__all__ = ["Remesher", "REMESHERS", "instant_meshes", "quad_remesh", "polygon_edges"]

Remesher = Callable[[np.ndarray, np.ndarray, int], tuple]

EXTRA_HINT = "pip install 'nupatch[fit]'"


@contextlib.contextmanager
def _quiet_stdout():
    """Silence a C++ library's progress printing on file descriptor 1 (``--json`` owns stdout)."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # pytest capture or no real stdout
        yield
        return
    sys.stdout.flush()
    saved = os.dup(fd)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)


def instant_meshes(vertices: np.ndarray, triangles: np.ndarray, faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Instant Meshes (``pynanoinstantmeshes``), pure quads, deterministic.  Its last step
    splits every face of the quad-dominant mesh into quads (4 per quad), so about ``faces / 4``
    vertices are asked for before that step."""
    try:
        import pynanoinstantmeshes
    except ImportError:
        raise UnsupportedError(
            "fitting needs the quad remesher pynanoinstantmeshes, the optional extra [fit]", EXTRA_HINT
        ) from None
    v = np.ascontiguousarray(vertices, dtype=np.float32)
    f = np.ascontiguousarray(triangles, dtype=np.uint32)
    with _quiet_stdout():
        out_v, out_f = pynanoinstantmeshes.remesh(v, f, max(int(faces) // 4, 8), rosy=4, posy=4, deterministic=True)
    return np.asarray(out_v, dtype=np.float64), np.asarray(out_f, dtype=np.int64)


#: Remeshers by name (``fit(remesher=...)`` takes a name or a callable).
REMESHERS: dict[str, Remesher] = {"instant-meshes": instant_meshes}


def polygon_edges(polygons: Sequence[np.ndarray]) -> np.ndarray:
    """(e, 2) int64 directed edges (a, b) of every polygon, in order."""
    if not len(polygons):
        return np.zeros((0, 2), dtype=np.int64)
    flat = np.concatenate(polygons)
    sizes = np.array([len(p) for p in polygons])
    starts = np.repeat(np.cumsum(sizes) - sizes, sizes)
    pos = np.arange(flat.size) - starts
    nxt = starts + (pos + 1) % np.repeat(sizes, sizes)
    return np.stack([flat, flat[nxt]], axis=1)


def _clean_polygons(faces) -> list[np.ndarray]:
    """Polygons without repeated consecutive vertices (a collapsed quad becomes a triangle);
    faces left with fewer than 3 vertices are dropped."""
    out = []
    for face in faces:
        face = np.asarray(face, dtype=np.int64)
        keep = face != np.roll(face, 1)
        face = face[keep]
        if face.size >= 3 and np.unique(face).size == face.size:
            out.append(face)
    return out


def quad_remesh(
    vertices: np.ndarray,
    triangles: np.ndarray,
    faces: int,
    remesher: str | Remesher = "instant-meshes",
    face_normals: np.ndarray | None = None,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """A manifold, consistently oriented polygon (mostly quad) control mesh of about ``faces``
    faces over the triangle mesh: (vertices (k, 3) float64, polygons, each (s,) int64).

    Orientation: the remesher's face normals are compared with the input's at the nearest
    input triangle centroid; when most disagree, every polygon is reversed.
    MeshError when the remesher fails or returns an empty, non-finite or non-manifold mesh."""
    name = remesher if isinstance(remesher, str) else getattr(remesher, "__name__", "remesher")
    if isinstance(remesher, str):
        if remesher not in REMESHERS:
            raise ValueError(f"remesher must be one of {tuple(REMESHERS)} or a callable, not {remesher!r}")
        remesher = REMESHERS[remesher]
    try:
        out_v, out_f = remesher(vertices, triangles, faces)
    except (MeshError, UnsupportedError):
        raise
    except Exception as exc:  # the remesher's own failure, whatever its type
        raise MeshError(f"the quad remesher failed: {type(exc).__name__}: {exc}", name) from None
    out_v = np.asarray(out_v, dtype=np.float64).reshape(-1, 3)
    polygons = _clean_polygons(out_f if not isinstance(out_f, np.ndarray) else list(out_f))
    if not polygons or out_v.shape[0] < 4:
        raise MeshError("the quad remesher returned no faces (input too small or degenerate for the target size)", name)
    if not np.all(np.isfinite(out_v)):
        raise MeshError("the quad remesher returned non-finite vertices", name)
    flat = np.concatenate(polygons)
    if flat.min() < 0 or flat.max() >= out_v.shape[0]:
        raise MeshError("the quad remesher returned faces with vertex ids out of range", name)
    used = np.unique(flat)
    remap = np.full(out_v.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    out_v = out_v[used]
    polygons = [remap[p] for p in polygons]
    edges = polygon_edges(polygons)
    _, counts = np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)
    if counts.max() > 2:
        raise MeshError(f"the quad remesher returned a non-manifold mesh ({int((counts > 2).sum())} edges of 3 or more faces)", name)
    if face_normals is not None:
        polygons = _orient_like(out_v, polygons, vertices, triangles, face_normals)
    edges = polygon_edges(polygons)
    _, dcounts = np.unique(edges, axis=0, return_counts=True)
    if dcounts.max() > 1:
        raise MeshError("the quad remesher returned an inconsistently oriented mesh", name)
    return out_v, polygons


def _orient_like(out_v, polygons, vertices, triangles, face_normals) -> list[np.ndarray]:
    from scipy.spatial import cKDTree

    centres = np.array([out_v[p].mean(axis=0) for p in polygons])
    normals = np.array([_polygon_normal(out_v[p]) for p in polygons])
    tri_centres = vertices[triangles].mean(axis=1)
    _, nearest = cKDTree(tri_centres).query(centres)
    agree = np.einsum("ij,ij->i", normals, face_normals[nearest])
    if np.sum(agree < 0) > np.sum(agree > 0):
        return [p[::-1].copy() for p in polygons]
    return polygons


def _polygon_normal(points: np.ndarray) -> np.ndarray:
    """Newell's normal of a polygon (area-weighted)."""
    nxt = np.roll(points, -1, axis=0)
    return 0.5 * np.cross(points, nxt).sum(axis=0)
