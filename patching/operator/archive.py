"""The operator M as plain arrays, and the key of everything it depends on.

M reads the mesh's topology, knot intervals, tags and the build's options, never its
positions (``operator`` package docstring), so a process that builds a mesh again after its
control points moved may take M from an earlier build instead of assembling it again, as
OpenSubdiv computes a ``Far::StencilTable`` once per topology and applies it to every new set
of positions.  This module is the pure half of that: ``operator_key`` digests what M depends
on, ``operator_arrays`` / ``operator_from_arrays`` turn a ``SurfaceOperator`` into named
arrays and scalars and back without copying the arrays.  Where the arrays are kept (files,
memory maps) is ``export.operator_cache``'s business; ``patching`` writes nothing.

The key is a SHA-256 of: this module's format number, the package's source digest
(``util.solve_cache.source_digest``: any change to the code misses every old entry), the
options, the G1 step's module settings that tests and benchmarks switch (``Q_WEIGHT``,
``MONOTONE_SPOKES``, ``MONOTONE_MAX_VALENCE``), and the mesh without its positions, name and
source locations: vertex count, the flat faces, intervals, creases, corners, holes, boundary
interpolation, triangle subdivision and creasing method, floats as their exact IEEE bytes.
The one choice that reads positions, ``anchors="limit-fit"`` (least squares against the
limit surface of the control points), has no key.
"""

from __future__ import annotations

import hashlib
from dataclasses import astuple, fields

import numpy as np
import scipy.sparse as sp

from patching.extraordinary import g1_patches
from patching.mesh.control_mesh import ControlMesh
from patching.options import BuildOptions
from patching.surface import OperatorGroup, PatchTopology, SurfaceOperator
from patching.util.solve_cache import source_digest

__all__ = ["ARCHIVE_FORMAT", "operator_key", "operator_arrays", "operator_from_arrays"]

#: Bumped when the arrays or the key change meaning.
ARCHIVE_FORMAT = 1
#: PatchTopology's optional split-side arrays (all set or none).
_PIECES = ("side_indptr", "piece_edge", "piece_reversed", "piece_range", "piece_vertex")


def operator_key(mesh: ControlMesh, options: BuildOptions) -> str | None:
    """The hexadecimal key of ``build_operator(mesh, options)`` (module docstring), or None
    when that operator reads the control points (``anchors="limit-fit"``)."""
    if options.anchors == "limit-fit":
        return None
    h = hashlib.sha256()

    def text(value: object) -> None:
        h.update(repr(value).encode() + b"\0")

    def array(a: np.ndarray, dtype: str) -> None:
        a = np.ascontiguousarray(a, dtype=dtype)
        text((dtype, a.shape))
        h.update(a.reshape(-1).view(np.uint8))

    def floats(mapping, arity: int) -> None:
        items = sorted(mapping.items())
        keys = np.array([k for k, _ in items], dtype=np.int64).reshape(len(items), arity)
        array(keys, "<i8")
        array(np.array([v for _, v in items], dtype=np.float64), "<f8")  # exact bits, not repr

    text(("nupatch-operator", ARCHIVE_FORMAT, source_digest()))
    text(tuple(zip((f.name for f in fields(options)), astuple(options))))
    text((g1_patches.Q_WEIGHT, g1_patches.MONOTONE_SPOKES, g1_patches.MONOTONE_MAX_VALENCE))
    text((mesh.n_vertices, mesh.interpolate_boundary, mesh.triangle_subdivision, mesh.crease_method))
    array(mesh.face_offsets, "<i8")
    array(mesh.face_vertices, "<i8")
    floats({tuple(k): v for k, v in mesh.intervals.items()}, 2)
    floats({tuple(k): v for k, v in mesh.creases.items()}, 2)
    floats({(int(k),): v for k, v in mesh.corners.items()}, 1)
    array(np.array(sorted(mesh.holes), dtype=np.int64), "<i8")
    return h.hexdigest()


def operator_arrays(op: SurfaceOperator) -> tuple[dict[str, np.ndarray], dict[str, int | list]]:
    """(arrays, scalars) of an operator: M's CSR arrays, each group's faces (and spans), the
    patch topology's arrays; scalars M's shape, the groups' degrees, row offsets and whether
    they carry spans, and the topology's vertex and edge counts.  The arrays are M's and the
    topology's own (no copies); ``name`` is not kept (the mesh being built gives it)."""
    m = op.matrix.tocsr()
    arrays = {"m_data": m.data, "m_indices": m.indices, "m_indptr": m.indptr}
    for k, g in enumerate(op.groups):
        arrays[f"group{k}_faces"] = np.asarray(g.faces)
        if g.spans is not None:
            arrays[f"group{k}_spans"] = np.asarray(g.spans)
    t = op.topology
    for name in ("corner_vertex", "side_edge", "side_reversed") + _PIECES:
        value = getattr(t, name)
        if value is not None:
            arrays[f"topology_{name}"] = np.asarray(value)
    scalars = {
        "shape": [int(s) for s in m.shape],
        "degrees": [int(g.degree) for g in op.groups],
        "row_offsets": [int(g.row_offset) for g in op.groups],
        "spans": [int(g.spans is not None) for g in op.groups],
        "n_vertices": int(t.n_vertices),
        "n_edges": int(t.n_edges),
    }
    return arrays, scalars


def operator_from_arrays(arrays: dict[str, np.ndarray], scalars: dict, name: str) -> SurfaceOperator:
    """The operator ``operator_arrays`` took apart, on the given arrays (no copies; memory
    maps stay memory maps), named ``name``.  KeyError or ValueError when they do not fit
    together (a reader then treats the entry as missing)."""
    shape = tuple(int(s) for s in scalars["shape"])
    data, indices, indptr = arrays["m_data"], arrays["m_indices"], arrays["m_indptr"]
    if len(shape) != 2 or indptr.shape != (shape[0] + 1,) or data.shape != indices.shape or indptr[-1] != data.size:
        raise ValueError("the matrix arrays do not fit its shape")
    matrix = sp.csr_matrix((shape[0], shape[1]), dtype=data.dtype)  # set, not passed: no copy, no re-check
    matrix.data, matrix.indices, matrix.indptr = data, indices, indptr
    groups = tuple(
        OperatorGroup(int(d), arrays[f"group{k}_faces"], int(r), arrays[f"group{k}_spans"] if s else None)
        for k, (d, r, s) in enumerate(zip(scalars["degrees"], scalars["row_offsets"], scalars["spans"], strict=True))
    )
    pieces = {p: arrays.get(f"topology_{p}") for p in _PIECES}
    topology = PatchTopology(
        arrays["topology_corner_vertex"], arrays["topology_side_edge"], arrays["topology_side_reversed"],
        int(scalars["n_vertices"]), int(scalars["n_edges"]), **pieces,
    )
    return SurfaceOperator(matrix, groups, topology, name)

