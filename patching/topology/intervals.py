"""Knot intervals for meshes that carry none: ``--intervals tags|uniform|chord|centripetal``.

Intervals live on strips (docs/knots.md: edges linked through opposite edges of quads), so a rule
assigns one value per strip:

- ``tags``: the mesh's own interval tags, 1 elsewhere (docs/knots.md's default; the mesh unchanged);
- ``uniform``: 1 on every strip, interval tags dropped (the classic uniform scheme, e.g. to
  compare with OpenSubdiv);
- ``chord``: every untagged strip gets the mean length of its edges, d_s = (1/|s|) sum_{e in s}
  |P_a - P_b|;
- ``centripetal``: its square root, d_s = sqrt(chord d_s).

Chord and centripetal are the classical parametrisations of interpolating splines (the knot
interval proportional to the chord length or to its square root; [TLC] cites Lee's
centripetal rule and [ZTL] Fig. 12 compares them on a non-uniform mesh).  On a strip they use
the mean over the strip's edges because one strip carries one interval.  Tagged strips keep
their tags under ``chord`` and ``centripetal``.  The rule depends on the control points: it
picks the knots once, before the operator, whose matrix then depends on topology and knots
only as before.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import NupatchError
from ..mesh import ControlMesh
from .tables import Topology

__all__ = ["INTERVAL_RULES", "strip_mean_lengths", "with_intervals"]

#: The rules of ``--intervals``.
INTERVAL_RULES = ("tags", "uniform", "chord", "centripetal")


def strip_mean_lengths(mesh: ControlMesh, topology: Topology | None = None) -> np.ndarray:
    """(strips,) float64 mean length of the edges of every strip (``Topology.edge_strip`` ids)."""
    topo = topology if topology is not None else Topology(mesh)
    lengths = np.linalg.norm(mesh.vertices[topo.edges[:, 0]] - mesh.vertices[topo.edges[:, 1]], axis=1)
    sums = np.bincount(topo.edge_strip, weights=lengths, minlength=topo.n_strips)
    counts = np.bincount(topo.edge_strip, minlength=topo.n_strips)
    return sums / np.maximum(counts, 1)


def with_intervals(mesh: ControlMesh, rule: str = "tags") -> ControlMesh:
    """The mesh with knot intervals chosen by ``rule`` (one of INTERVAL_RULES, see the module
    docstring); returns ``mesh`` itself for ``tags``.  The new intervals are interval tags on
    one edge of each strip, so that ``write_obj`` writes them and they read back."""
    if rule not in INTERVAL_RULES:
        raise NupatchError(f"--intervals must be one of {', '.join(INTERVAL_RULES)}, not '{rule}'", "command line")
    if rule == "tags":
        return mesh
    if rule == "uniform":
        return replace(mesh, intervals={})
    topo = Topology(mesh)
    values = strip_mean_lengths(mesh, topo)
    if rule == "centripetal":
        values = np.sqrt(values)
    tagged = np.zeros(topo.n_strips, dtype=bool)
    for a, b in mesh.intervals:
        e = topo.edge_id(a, b)
        if e >= 0:
            tagged[topo.edge_strip[e]] = True
    # one representative edge per untagged strip: its first edge in edge order
    _, first = np.unique(topo.edge_strip, return_index=True)  # strip ids are 0..n_strips-1
    intervals = dict(mesh.intervals)
    for s in np.flatnonzero(~tagged):
        a, b = (int(x) for x in topo.edges[first[s]])
        intervals[(a, b)] = float(values[s])
    return replace(mesh, intervals=intervals)
