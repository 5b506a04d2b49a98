"""How sharpness decays from one subdivision step to the next, for every scheme ([OSD]
``sdc/crease.cpp``, shared there by Catmull-Clark and Loop as here by ``subdivision`` and
``loop``), vectorised over the edges of a mesh; no mesh, no positions.

* ``decrement`` ([OSD] ``decrementSharpness``, uniform creasing): ``s -> max(s - 1, 0)``;
  smooth (0) stays smooth, infinitely sharp (``s >= 10``, or ``inf``) stays as it is.
* ``child_edge_sharpness`` with ``method="chaikin"`` ([OSD]
  ``Crease::SubdivideEdgeSharpnessesAroundVertex`` under ``CREASE_CHAIKIN``): each edge splits
  into two halves, and the half at end v reads v's neighbourhood.  With c the number of
  semi-sharp edges at v (``0 < s < 10``), a semi-sharp edge's half gets

      s' = 3/4 s + 1/4 (mean of the other c - 1 semi-sharp sharpnesses at v) - 1

  (0 if that is <= 0) when c >= 2, and ``decrement(s)`` when c = 1 or v has fewer than two
  edges ([OSD]'s ``edgeCount < 2``); smooth and infinite halves keep their sharpness.  The two
  halves of an edge may differ.  A half is never sharper than the largest sharpness at its end
  minus one, so ``ceil(max s)`` steps still clear every semi-sharp tag.
"""

from __future__ import annotations

import numpy as np

from patching.mesh.control_mesh import CREASE_METHODS, ControlMesh

__all__ = ["INFINITE", "CREASE_METHODS", "decrement", "child_edge_sharpness", "crease_method_of"]

#: Sharpness at or above which a feature is infinitely sharp ([OSD] ``SHARPNESS_INFINITE``).
INFINITE = 10.0


def crease_method_of(mesh: ControlMesh, crease_method: str | None) -> str:
    """The crease method a subdivision function uses: ``crease_method`` when given, else the
    mesh's own (``ControlMesh.crease_method``, the OBJ tag ``t creasemethod``)."""
    return mesh.crease_method if crease_method is None else crease_method


def decrement(s) -> np.ndarray:
    """[OSD] ``decrementSharpness``: 0 stays 0, infinite (>= 10 or ``inf``) stays, else
    ``max(s - 1, 0)``."""
    s = np.asarray(s, dtype=np.float64)
    return np.where(s >= INFINITE, s, np.where(s > 1.0, s - 1.0, 0.0))


def child_edge_sharpness(es: np.ndarray, edges: np.ndarray, n_vertices: int, method: str) -> np.ndarray:
    """(e, 2) sharpness of the child half of every edge at its end ``edges[:, k]``.

    es: (e,) parent edge sharpness (infinite as ``>= 10`` or ``inf``, kept as given); edges:
    (e, 2) vertex ids; method: ``"uniform"`` (both halves ``decrement(s)``) or ``"chaikin"``
    (the module docstring's rule)."""
    d = decrement(es)
    if method == "uniform":
        return np.stack([d, d], axis=1)
    if method != "chaikin":
        raise ValueError(f"unknown crease method {method!r} (choose {' or '.join(CREASE_METHODS)})")
    semi = (es > 0) & (es < INFINITE)
    total = np.zeros(n_vertices)
    count = np.zeros(n_vertices)
    degree = np.bincount(edges.ravel(), minlength=n_vertices)
    for k in (0, 1):
        np.add.at(total, edges[semi, k], es[semi])
        np.add.at(count, edges[semi, k], 1.0)
    out = np.empty((es.size, 2))
    own = np.where(semi, es, 0.0)
    for k in (0, 1):
        v = edges[:, k]
        c, t = count[v], total[v]
        ch = 0.75 * own + 0.25 * (t - own) / np.maximum(c - 1.0, 1.0) - 1.0
        ch = np.where(ch > 0, ch, 0.0)
        out[:, k] = np.where(semi & (c > 1) & (degree[v] >= 2), ch, d)
    return out
