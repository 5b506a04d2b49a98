"""Topology tables of a control mesh (``tables``: half-edges, edges, strips and their knot
intervals), its sharp features as the patch construction sees them (``features``), and which
patch corners and sides coincide in the B-rep (``patch_topology``)."""

from patching.topology.features import Features, features, sharp_edges
from patching.topology.tables import Topology

__all__ = ["Topology", "Features", "features", "sharp_edges"]
