"""What ``nupatch info`` reports of a control mesh: counts of vertices, faces and edges,
extraordinary points by valence, strips and their knot intervals, sharp and semi-sharp edges,
boundaries, and what the patch construction makes of the tags."""

from __future__ import annotations

from typing import Any

import numpy as np

from patching.mesh.control_mesh import INFINITELY_SHARP, ControlMesh
from patching.topology.features import features
from patching.topology.tables import Topology

__all__ = ["mesh_summary"]


def mesh_summary(mesh: ControlMesh, topology: Topology | None = None) -> dict[str, Any]:
    """A JSON-ready dict: ``name``, ``vertices``, ``faces``, ``face_sizes`` (size: count),
    ``edges``, ``extraordinary_points`` (count, by_valence), ``strips``, ``intervals``
    (distinct (first 20), min, max), ``sharp_edges``, ``semi_sharp_edges``, ``boundary_edges``,
    ``closed``, ``interpolate_boundary``, ``holes``, ``corner_tags``; for an all-quad mesh without semi-sharp tags also
    ``sharp_features`` (corners, darts, sector vertices; meshes subdivided first are classified
    only after those steps, so they have none here)."""
    topo = topology or Topology(mesh)
    ep = topo.extraordinary
    valences = {int(v): int(c) for v, c in zip(*np.unique(topo.valence[ep], return_counts=True))}
    strips = topo.strips_summary()
    intervals = sorted({d for _, _, d in strips})
    info: dict[str, Any] = {
        "name": mesh.name,
        "vertices": mesh.n_vertices,
        "faces": mesh.n_faces,
        "face_sizes": {int(k): int(c) for k, c in zip(*np.unique(mesh.face_sizes, return_counts=True))},
        "edges": topo.n_edges,
        "extraordinary_points": {"count": int(ep.size), "by_valence": valences},
        "strips": len(strips),
        "intervals": {"distinct": intervals[:20], "min": min(intervals), "max": max(intervals)},
        "sharp_edges": int(np.count_nonzero(topo.edge_sharpness >= INFINITELY_SHARP)),
        "semi_sharp_edges": int(np.count_nonzero((topo.edge_sharpness > 0) & (topo.edge_sharpness < INFINITELY_SHARP))),
        "boundary_edges": int(np.count_nonzero(topo.edge_is_boundary)),
        "closed": bool(not topo.edge_is_boundary.any()),
        "interpolate_boundary": mesh.interpolate_boundary,
        "holes": len(mesh.holes),
        "corner_tags": len(mesh.corners),
    }
    if info["semi_sharp_edges"] == 0 and mesh.is_quad_mesh:
        feats = features(topo)
        info["sharp_features"] = {
            "corners": int(np.count_nonzero(feats.corner)),
            "darts": int(np.count_nonzero(feats.dart)),
            "sector_vertices": int(np.count_nonzero(feats.sector_vertex)),
        }
    return info
