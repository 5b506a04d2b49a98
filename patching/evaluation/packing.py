"""Which patches make one multi-span B-spline face: rectangular blocks of bicubic patches, as
arrays (patch rows, quarter turns, knot intervals, the Bézier-form poles and knots).
``export.pack`` turns each block into an OpenCASCADE face; nothing here imports OCC.

A regular region of the surface is one bicubic B-spline on its knot grid (docs/knots.md, 3):
after global refinement the whole regular part of the mesh, after feature-adaptive
refinement (``patching.operator.adaptive``) every region of same-level leaves, whose
patches are the de Casteljau pieces of the level's regular B-spline.  So a grid of
bicubic patches, joined side to side through whole edges, is one B-spline with triple
interior knots at the cumulative knot intervals (the Bézier form: exactly the patches), and
its interior knots can be removed where the joins are C2 in that parametrisation.

Neighbours are read from the pieces of ``PatchTopology`` (``SidePieces``): two sides are
joined when each is one whole piece of the same edge, used by exactly those two sides of
different patches.  A side that is split (a coarse side meeting finer patches at a
T-junction), or is a piece of a split side, or lies on the boundary, ends the block there,
so patches of different levels never share a block and every block side is a run of whole
patch sides, each tiled by its own pieces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from patching.surface import BezierSurface

__all__ = ["Block", "MAX_SIDE", "block_neighbours", "find_blocks", "block_poles", "block_boundary", "edge_chains"]

#: Blocks have at most this many patches a side (keeps each face's pole grid moderate).
MAX_SIDE = 128


@dataclass(frozen=True)
class Block:
    """A w x h grid of patch rows: rows[i, j] is the patch at column i (along u), row j (along
    v); turns[i, j] how many quarter turns its net is rotated (side k of the block = the
    patch's original side (k + turns) mod 4); du (w,), dv (h,) the knot intervals."""

    rows: np.ndarray
    turns: np.ndarray
    du: np.ndarray
    dv: np.ndarray

    @property
    def knots(self) -> tuple[np.ndarray, np.ndarray]:
        """(w + 1,), (h + 1,) breakpoints: 0 and the cumulative knot intervals."""
        return np.concatenate([[0.0], np.cumsum(self.du)]), np.concatenate([[0.0], np.cumsum(self.dv)])


def block_neighbours(surface: BezierSurface) -> np.ndarray:
    """(p, 4, 2) int64: (row, side) across each side, or (-1, -1) where the side is not one
    whole edge shared with one whole side of another patch (boundary, T-junction, an edge
    with other than two sides, both sides one patch's)."""
    topo = surface.topology
    pieces = topo.pieces
    p = np.shape(topo.corner_vertex)[0]
    out = np.full((4 * p, 2), -1, dtype=np.int64)
    single = np.diff(pieces.indptr) == 1
    first = pieces.indptr[:-1]
    lone = single & pieces.whole[first]  # sides that are one whole piece
    n_edges = int(topo.n_edges)
    uses = np.bincount(pieces.edge, minlength=n_edges)
    whole_uses = np.bincount(pieces.edge[first[lone]], minlength=n_edges)
    sides = np.flatnonzero(lone)
    edge = pieces.edge[first[sides]]
    ok = (uses[edge] == 2) & (whole_uses[edge] == 2)
    sides, edge = sides[ok], edge[ok]
    order = np.argsort(edge, kind="stable")
    sides, edge = sides[order], edge[order]
    a, b = sides[0::2], sides[1::2]
    pair = a // 4 != b // 4
    a, b = a[pair], b[pair]
    out[a] = np.stack([b // 4, b % 4], axis=1)
    out[b] = np.stack([a // 4, a % 4], axis=1)
    return out.reshape(-1, 4, 2)


def _cubic_rows(surface: BezierSurface) -> np.ndarray:
    cubic = np.zeros(surface.n_patches, dtype=bool)
    offset = 0
    for g in surface.groups:
        cubic[offset : offset + len(g.faces)] = g.degree == 3
        offset += len(g.faces)
    return cubic


def find_blocks(surface: BezierSurface, spans: np.ndarray) -> list[Block]:
    """Rectangular blocks of at least 2 bicubic patches, grown greedily from each free patch
    in row order.

    From a seed patch the block grows along its s direction across side 1 while the next
    patch is bicubic and free, then row by row across side 2 while every patch above is
    bicubic, free and the rows stay a grid (the patch right of each one is the next one
    above).  Neighbours whose (s, t) frame is turned are turned to match (``np.rot90`` of the
    net, spans swapped).  No side on a block's boundary faces a patch of the same block (a
    full ring of a torus, or a helix of patches on a twisted one), so that no packed face
    meets itself along a seam; a block whose knot intervals do not form one grid is dropped.

    spans: (p, 2) float64, the knot intervals of each patch along its s and t."""
    p = surface.n_patches
    free = _cubic_rows(surface)
    nb = block_neighbours(surface)

    def across(row: int, turn: int, side: int):
        """(row, turn) of the patch across block side ``side`` of (row, turn), placed in the
        block's frame, or None."""
        r, s = nb[row, (side + turn) % 4]
        if r < 0:
            return None
        return int(r), int((s - (side + 2)) % 4)  # its side s plays the opposite block side

    def faces_block(cells, sides, block: set) -> bool:
        """True when a patch across one of ``sides`` of one of ``cells`` is in ``block``."""
        return any((x := across(r, t, k)) is not None and x[0] in block for r, t in cells for k in sides)

    blocks = []
    for seed in range(p):
        if not free[seed]:
            continue
        row0 = [(seed, 0)]
        taken = {seed}
        while len(row0) < MAX_SIDE:
            nxt = across(*row0[-1], 1)
            if nxt is None or not free[nxt[0]] or nxt[0] in taken:
                break
            # Its sides 0, 1, 2 stay on the block's boundary (or become inner sides towards
            # patches not yet taken): none may face the row itself (a ring closes at side 1).
            if faces_block([nxt], (0, 1, 2), taken | {nxt[0]}):
                break
            row0.append(nxt)
            taken.add(nxt[0])
        grid = [row0]
        while len(grid) < MAX_SIDE:
            above = [across(r, t, 2) for r, t in grid[-1]]
            if any(a is None or not free[a[0]] or a[0] in taken for a in above):
                break
            ids = [a[0] for a in above]
            if len(set(ids)) != len(ids):
                break
            # A grid: right of each patch above is the next one above.
            if any(across(*above[i], 1) != above[i + 1] for i in range(len(above) - 1)):
                break
            # The new row's outer sides: 2 of every patch, 3 of the first and 1 of the last.
            block = taken | set(ids)
            if faces_block(above, (2,), block) or faces_block(above[:1], (3,), block) or faces_block(above[-1:], (1,), block):
                break
            grid.append(above)
            taken.update(ids)
        if len(taken) < 2:
            continue
        rows = np.array([[r for r, _ in line] for line in grid], dtype=np.int64).T  # (w, h)
        turns = np.array([[t for _, t in line] for line in grid], dtype=np.int64).T
        span = np.asarray(spans, dtype=np.float64)[rows]  # (w, h, 2) in each patch's own frame
        odd = turns % 2 == 1
        du = np.where(odd, span[..., 1], span[..., 0])
        dv = np.where(odd, span[..., 0], span[..., 1])
        if not (np.allclose(du, du[:, :1], rtol=1e-12) and np.allclose(dv, dv[:1, :], rtol=1e-12)):
            continue  # not one knot grid: leave the patches alone
        free[rows.ravel()] = False
        blocks.append(Block(rows, turns, du[:, 0].copy(), dv[0, :].copy()))
    return blocks


def block_poles(block: Block, nets) -> tuple[np.ndarray, np.ndarray]:
    """(turned nets (w, h, 4, 4, 3), poles (3 w + 1, 3 h + 1, 3)) of a block: each patch's
    net in the block's frame, and the poles of the Bézier-form B-spline (every interior knot
    of multiplicity 3, knots ``block.knots``) whose spans are exactly those nets.
    nets: indexable by patch row, (4, 4, 3) each."""
    w, h = block.rows.shape
    stack = np.stack([nets[r] for r in block.rows.ravel().tolist()])
    turns = block.turns.ravel() % 4
    turned = np.empty((w * h, 4, 4, 3))
    for t in np.unique(turns).tolist():  # one rotation per distinct turn, not per patch
        at = turns == t
        turned[at] = np.rot90(stack[at], -t, axes=(1, 2))
    turned = turned.reshape(w, h, 4, 4, 3)
    # Pole (a, b) of the Bezier-form B-spline: entry (a - 3i, b - 3j) of net (i, j), the last
    # net covering it (i = min(a // 3, w - 1)), as when the nets are written one after another.
    def spans(n):
        a = np.arange(3 * n + 1)
        i = np.minimum(a // 3, n - 1)
        return i, a - 3 * i
    (i, p), (j, q) = spans(w), spans(h)
    grid = turned[i[:, None], j[None, :], p[:, None], q[None, :]]
    return turned, grid


def block_boundary(block: Block, with_cell: bool = False):
    """(row, turn, block side k[, (i, j)]) of the block's boundary, counter-clockwise: the
    bottom row's sides 0 left to right, the right column's sides 1 upwards, the top row's
    sides 2 right to left, the left column's sides 3 downwards."""
    w, h = block.rows.shape
    cells = [(i, 0, 0) for i in range(w)] + [(w - 1, j, 1) for j in range(h)]
    cells += [(i, h - 1, 2) for i in range(w - 1, -1, -1)] + [(0, j, 3) for j in range(h - 1, -1, -1)]
    for i, j, k in cells:
        item = (int(block.rows[i, j]), int(block.turns[i, j]), k)
        yield item + ((i, j),) if with_cell else item


def edge_chains(wires, ends: dict, degree: dict, corners=frozenset()) -> list[list[tuple[int, bool]]]:
    """Runs of B-rep edges that can be one edge: consecutive edges between the same two
    faces (or one face and the open boundary) whose shared vertex no other edge uses, and
    whose curves have one degree.  Along a packed block's side every patch side is an edge,
    and at a T-junction every fine side: joined, a level transition between two faces is one
    multi-span edge (the STEP file then holds one curve and two pcurves, not one per side).

    wires: per face, its wire as a list of (edge id, reversed).  ends: {edge id: (start
    vertex, end vertex)} in the edge's own direction.  degree: {edge id: curve degree}.
    corners: vertices where some face's boundary turns (kept: a face's wire turns there, and
    OpenCASCADE's check rejects a face whose edge has a kink, BRepCheck_UnorientableShape).
    Returns every edge of the wires once, as chains [(edge id, backward), ...] in chain order
    (backward: the chain runs against the edge's own direction); a closed loop of such edges
    is cut in two, so that every chain runs between two kept vertices."""
    faces_of: dict[int, list[int]] = {}
    for f, wire in enumerate(wires):
        for eid, _ in wire:
            faces_of.setdefault(eid, []).append(f)
    pair = {}
    for eid, fs in faces_of.items():
        fs = sorted(fs) + [-1] * (2 - len(fs))
        pair[eid] = tuple(fs) if len(fs) == 2 and fs[0] != fs[1] else None  # None: a seam, never joined
    incident: dict[int, list[int]] = {}
    for eid in faces_of:
        for v in ends[eid]:
            incident.setdefault(v, []).append(eid)

    def joinable(v: int) -> bool:
        es = incident[v]
        return (v not in corners and len(es) == 2 and es[0] != es[1] and pair[es[0]] is not None and pair[es[0]] == pair[es[1]]
                and degree[es[0]] == degree[es[1]])

    keep = {v: not joinable(v) for v in incident}
    seen: set[int] = set()
    chains = []

    def walk(eid: int, v: int) -> list[tuple[int, bool]]:
        chain = []
        while True:
            v0, v1 = ends[eid]
            backward = v == v1 and v != v0
            chain.append((eid, backward))
            seen.add(eid)
            v = v0 if backward else v1
            if keep[v]:
                return chain
            a, b = incident[v]
            eid = b if a == eid else a
            if eid in seen:
                return chain

    for eid in faces_of:  # paths: from an edge end that is kept
        if eid in seen:
            continue
        v0, v1 = ends[eid]
        if keep[v0] or keep[v1]:
            chains.append(walk(eid, v0 if keep[v0] else v1))
    for eid in faces_of:  # what is left are closed loops: cut each in two
        if eid in seen:
            continue
        loop = walk(eid, ends[eid][0])
        half = max(1, len(loop) // 2)
        chains += [c for c in (loop[:half], loop[half:]) if c]
    return chains
