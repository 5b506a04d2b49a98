"""The Topology cache, shared with Catmull-Clark subdivision: now ``patching.topology.cache``
(kept here for the Loop and shading modules that import it by this name)."""

from ..topology.cache import remember, topology_of

__all__ = ["remember", "topology_of"]
