"""Catmull-Clark's fast paths give what the general ones give.

* ``child_topology``: a child mesh's Topology derived from the parent's equals
  ``Topology(child)`` built from scratch, array for array (strips and their intervals
  included), on the OpenSubdiv shapes (creases, semi-sharp tags, boundaries, holes, non-quads)
  and on meshes with non-uniform intervals, level after level.
* ``quad_rows``: S written in CSR order equals S gathered as triplets (``_triplet_operator``)
  entry for entry, under both rule sets and both creasing methods; the non-canonical S that
  ``subdivide`` multiplies gives the same points.
* ``subdivide`` (derived topologies, fast rows) against steps on freshly built topologies
  and triplet rows: the same points to 1e-12 and the same tags; the child's interval tags
  give every child edge half its parent edge's interval (the edge it halves, or the parallel
  one for an edge inside a face).
* The OBJ writer's face lines are those of ``"%d"`` formatting, byte for byte.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest

from patching.mesh.control_mesh import ControlMesh
from patching.mesh.obj import format_obj, read_obj
from patching.mesh.primitives import open_grid, torus_grid
from patching.subdivision.catmark import _triplet_operator, _uniform_quads, subdivide, subdivision_operator
from patching.subdivision.child_mesh import _child_mesh
from patching.subdivision.child_topology import child_topology
from patching.subdivision.context import _Context
from patching.topology.cache import topology_of
from patching.topology.tables import Topology
from tests.conftest import shape_files

ARRAYS = ("origin", "face", "next", "prev", "dest", "edges", "edge_of", "twin", "edge_halfedge", "edge_is_boundary",
          "valence", "vertex_is_boundary", "vertex_is_used", "outgoing", "edge_strip", "strip_interval",
          "edge_interval", "halfedge_interval", "edge_sharpness")


def _shapes() -> list[ControlMesh]:
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for path in shape_files():
            try:
                mesh = read_obj(path)
                Topology(mesh)
            except Exception:  # non-manifold shapes: refused before any subdivision
                continue
            out.append(pytest.param(mesh, id=path.stem))
    return out


SHAPES = _shapes()


def _nonuniform() -> list[ControlMesh]:
    rng = np.random.default_rng(3)
    torus = torus_grid(8, 6, rng.uniform(1, 3, 8), rng.uniform(1, 3, 6))
    grid = open_grid(5, 4)
    a, b = (int(x) for x in grid.face_vertices[:2])
    return [pytest.param(torus, id="torus-nonuniform"),
            pytest.param(replace(grid, intervals={(min(a, b), max(a, b)): 2.5}, creases={}), id="grid-one-strip")]


def _same_topology(derived: Topology, built: Topology) -> None:
    for name in ARRAYS:
        a, b = getattr(derived, name), getattr(built, name)
        assert np.array_equal(a, b), name
    assert derived.n_strips == built.n_strips
    ptr_a, idx_a = derived.vertex_outgoing
    ptr_b, idx_b = built.vertex_outgoing
    assert np.array_equal(ptr_a, ptr_b)
    owner = np.repeat(np.arange(ptr_a.size - 1), np.diff(ptr_a))
    assert np.array_equal(idx_a[np.lexsort((idx_a, owner))], idx_b)  # the same half-edges per vertex
    assert np.array_equal(built.origin[idx_b], owner)


@pytest.mark.parametrize("mesh", SHAPES + _nonuniform())
def test_derived_child_topology_equals_the_built_one(mesh):
    rules = "opensubdiv" if np.ptp(Topology(mesh).strip_interval) == 0 else "seed"
    for _ in range(3 if mesh.n_faces < 300 else 2):
        _, child = subdivision_operator(mesh, rules=rules)
        built = Topology(_fresh(child))
        _same_topology(topology_of(child), built)  # derived from the parent's derived tables
        derived = child_topology(Topology(_fresh(mesh)), child)  # from a parent built afresh
        assert derived is not None
        _same_topology(derived, built)
        mesh = child


def _fresh(mesh: ControlMesh) -> ControlMesh:
    """The same mesh as a new object: its Topology is built afresh (the cache is by identity)."""
    return replace(mesh)


@pytest.mark.parametrize("rules, crease_method", [("opensubdiv", "uniform"), ("opensubdiv", "chaikin"), ("seed", "uniform")])
@pytest.mark.parametrize("mesh", SHAPES)
def test_rows_in_csr_order_equal_the_triplet_rows(mesh, rules, crease_method):
    mesh = subdivide(mesh, 1, rules=rules, crease_method=crease_method)  # all quads
    for _ in range(2 if mesh.n_faces < 2000 else 1):
        ctx = _Context(mesh, crease_method)
        fast = _uniform_quads(ctx, rules == "seed", canonical=True)
        assert fast is not None
        slow = _triplet_operator(_Context(_fresh(mesh), crease_method), rules, "standard")
        assert fast.shape == slow.shape and fast.has_canonical_format
        assert np.array_equal(fast.indptr, slow.indptr) and np.array_equal(fast.indices, slow.indices)
        assert np.abs(fast.data - slow.data).max() <= 1e-15
        loose = _uniform_quads(ctx, rules == "seed", canonical=False)
        assert np.abs(loose @ mesh.vertices - slow @ mesh.vertices).max() <= 1e-13
        mesh = _child_mesh(ctx, fast @ mesh.vertices)


def _reference_steps(mesh: ControlMesh, steps: int, rules: str, crease_method: str) -> ControlMesh:
    """Steps on freshly built topologies with the triplet rows (the general path)."""
    for _ in range(steps):
        ctx = _Context(_fresh(mesh), crease_method)
        s = _triplet_operator(ctx, rules, "standard")
        mesh = _child_mesh(ctx, s @ mesh.vertices)
    return mesh


def _check_child_intervals(parent: ControlMesh, child: ControlMesh) -> None:
    """Every child edge carries half the interval of its parent edge (the one it halves, or
    the parallel next(h) for the edge F(face h) - E(edge h)), one tag per child strip."""
    t, c = Topology(_fresh(parent)), Topology(_fresh(child))
    nf, ne = t.n_faces, t.n_edges
    want = np.empty(c.n_edges)
    key = c.edges[:, 0] * c.n_vertices + c.edges[:, 1]
    halves = np.concatenate([nf + np.arange(ne)] * 2) * c.n_vertices + nf + ne + t.edges.T.ravel()
    want[np.searchsorted(key, halves)] = np.concatenate([t.edge_interval] * 2) / 2
    inner = t.face * c.n_vertices + nf + t.edge_of
    want[np.searchsorted(key, inner)] = t.halfedge_interval[t.next] / 2
    assert np.array_equal(c.edge_interval, want)
    assert len(child.intervals) == c.n_strips


@pytest.mark.parametrize("rules, crease_method", [("opensubdiv", "uniform"), ("opensubdiv", "chaikin"), ("seed", "uniform")])
@pytest.mark.parametrize("mesh", SHAPES)
def test_subdivide_equals_the_general_path(mesh, rules, crease_method):
    steps = 3 if mesh.n_faces < 300 else 2
    fast = subdivide(mesh, steps, rules=rules, crease_method=crease_method)
    slow = _reference_steps(mesh, steps, rules, crease_method)
    assert np.abs(fast.vertices - slow.vertices).max() <= 1e-12 * max(1.0, np.abs(slow.vertices).max())
    assert np.array_equal(fast.face_vertices, slow.face_vertices)
    assert fast.creases == slow.creases and fast.corners == slow.corners and fast.holes == slow.holes
    assert fast.intervals == slow.intervals
    parent = subdivide(mesh, steps - 1, rules=rules, crease_method=crease_method)
    _check_child_intervals(parent, fast)


@pytest.mark.parametrize("mesh", _nonuniform())
def test_nonuniform_subdivide_keeps_the_intervals(mesh):
    parent = mesh
    for _ in range(3):
        child = subdivide(parent, 1)
        _check_child_intervals(parent, child)
        parent = child


def _face_lines(mesh: ControlMesh) -> str:
    """The f lines as Python's '%d' writes them."""
    sizes = mesh.face_sizes
    return "".join("f" + "".join(f" {int(v) + 1}" for v in mesh.face_vertices[a:a + k]) + "\n"
                   for a, k in zip(mesh.face_offsets[:-1].tolist(), sizes.tolist()))


def test_face_lines_are_those_of_percent_d():
    rng = np.random.default_rng(7)
    for trial in range(60):
        sizes = rng.integers(3, 8, int(rng.integers(1, 40))) if trial % 2 else np.full(int(rng.integers(1, 40)), 4)
        n = int(10 ** rng.uniform(0, 10.5))  # ids past int32 too
        fv = rng.integers(0, n, int(sizes.sum()))
        fv[0] = n - 1
        mesh = ControlMesh(np.zeros((1, 3)), fv, np.concatenate([[0], np.cumsum(sizes)]))
        text = format_obj(mesh)
        lines = text.splitlines(keepends=True)
        assert "".join(line for line in lines if line.startswith("f")) == _face_lines(mesh)


@pytest.mark.parametrize("mesh", _nonuniform())
def test_retagged_topology_equals_the_built_one(mesh):
    """``Topology.retagged``: a mesh's connectivity tables reused for the same faces with other
    tags (the adaptive path's windows) equal those built afresh, and the tag tables are the
    new tags' own, computed (and checked) when first asked for."""
    from patching.errors import TagError

    base = Topology(replace(mesh, intervals={}, creases={}, corners={}))
    assert np.all(base.strip_interval == 1.0) and not base.edge_sharpness.any()  # the bare mesh's, cached
    creased = replace(mesh, creases={tuple(int(x) for x in base.edges[3]): 2.0})
    _same_topology(base.retagged(creased), Topology(_fresh(creased)))
    missing = next((0, v) for v in range(1, mesh.n_vertices) if Topology(mesh).edge_id(0, v) < 0)
    with pytest.raises(TagError, match=f"edge {missing[0]}-{missing[1]}"):
        base.retagged(replace(mesh, creases={missing: 1.0})).edge_sharpness
    with pytest.raises(ValueError, match="other faces"):
        base.retagged(replace(mesh, face_vertices=np.roll(mesh.face_vertices, 1)))
