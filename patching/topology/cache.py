"""One Topology per mesh object for the few meshes a refinement touches (derived
tables computed once; a ControlMesh never changes after construction)."""

from __future__ import annotations

from collections import OrderedDict

from patching.topology.tables import Topology

__all__ = ["remember", "topology_of"]

_CACHE: OrderedDict[int, tuple] = OrderedDict()
_SIZE = 8


def topology_of(mesh) -> Topology:
    """``Topology(mesh)``, cached by object identity (the mesh is kept with it, so the id
    cannot be reused while the entry lives)."""
    key = id(mesh)
    hit = _CACHE.get(key)
    if hit is not None and hit[0] is mesh:
        _CACHE.move_to_end(key)
        if callable(hit[1]):
            _CACHE[key] = (mesh, hit[1]())
        return _CACHE[key][1]
    return remember(mesh, Topology(mesh))


def remember(mesh, topo) -> Topology:
    """Store ``topo`` as the mesh's Topology, or a callable that builds it when first asked
    for (one built from the parent's tables: ``loop.refine.child_topology``, ``subdivision.child_topology``)."""
    _CACHE[id(mesh)] = (mesh, topo)
    _CACHE.move_to_end(id(mesh))
    while len(_CACHE) > _SIZE:
        _CACHE.popitem(last=False)
    return topo
