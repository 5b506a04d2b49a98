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
from functools import lru_cache

import numpy as np

from patching.surface import BezierSurface

__all__ = ["Block", "MAX_SIDE", "MAX_PATCHES", "Spline", "block_neighbours", "find_blocks", "block_poles", "block_boundary", "edge_chains",
           "knot_multiplicities", "bezier_matrix", "reduce_curve", "reduce_block"]

#: Blocks have at most this many patches a side, and at most MAX_PATCHES patches (the Bézier
#: form of a block, (3 w + 1) (3 h + 1) poles, is what the knot removal starts from).  Along a
#: semi-sharp crease a ring of level-6 leaves is 64 patches a control-mesh edge, and its knots
#: there are removed: one face a ring, not one every two edges.
MAX_SIDE = 4096
MAX_PATCHES = 128 * 128


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

    From a seed patch the block grows along its s direction, across side 1 and then across
    side 3, while the next patch is bicubic and free, then row by row across side 2 and then
    across side 0 while every patch of the new row is bicubic, free and the rows stay a grid
    (the patch right of each one is the next one of the row).  Neighbours whose (s, t) frame is turned are turned to match (``np.rot90`` of the
    net, spans swapped).  No side on a block's boundary faces a patch of the same block (a
    full ring of a torus, or a helix of patches on a twisted one), so that no packed face
    meets itself along a seam; a block whose knot intervals do not form one grid is dropped.

    spans: (p, 2) float64, the knot intervals of each patch along its s and t."""
    p = surface.n_patches
    free = _cubic_rows(surface)
    nb = block_neighbours(surface)
    # As flat lists of Python ints: the growth below looks sides up ~3.5 times a patch, and a
    # numpy scalar lookup costs several times a list's.
    nb_row, nb_side = nb[:, :, 0].ravel().tolist(), nb[:, :, 1].ravel().tolist()

    def across(row: int, turn: int, side: int):
        """(row, turn) of the patch across block side ``side`` of (row, turn), placed in the
        block's frame, or None."""
        at = 4 * row + (side + turn) % 4
        r = nb_row[at]
        if r < 0:
            return None
        return r, (nb_side[at] - (side + 2)) % 4  # its side plays the opposite block side

    def faces_block(cells, sides, block: set, extra=()) -> bool:
        """True when a patch across one of ``sides`` of one of ``cells`` is in ``block`` (or
        is one of ``extra``)."""
        return any((x := across(r, t, k)) is not None and (x[0] in block or x[0] in extra) for r, t in cells for k in sides)

    blocks = []
    for seed in range(p):
        if not free[seed]:
            continue
        row0 = [(seed, 0)]
        taken = {seed}
        # Along s both ways: across side 1 from the row's end, then across side 3 from its start
        # (patches come in no order along a ring: grown one way only, a ring of fine leaves
        # broke into pieces one coarse face long).  The new patch's sides other than the one
        # towards the row stay on the block's boundary (or become inner sides towards patches
        # not yet taken): none may face the row itself (a ring closes there).
        for side, outer in ((1, (0, 1, 2)), (3, (0, 2, 3))):
            while len(row0) < MAX_SIDE:
                nxt = across(*row0[-1 if side == 1 else 0], side)
                if nxt is None or not free[nxt[0]] or nxt[0] in taken:
                    break
                if faces_block([nxt], outer, taken, (nxt[0],)):
                    break
                row0.insert(len(row0) if side == 1 else 0, nxt)
                taken.add(nxt[0])
        grid = [row0]
        # Rows across side 2 above the last one, then across side 0 below the first.
        for side in (2, 0):
            while len(grid) < MAX_SIDE and len(grid) * len(row0) < MAX_PATCHES:
                edge_row = grid[-1] if side == 2 else grid[0]
                nxt_row = [across(r, t, side) for r, t in edge_row]
                if any(a is None or not free[a[0]] or a[0] in taken for a in nxt_row):
                    break
                ids = [a[0] for a in nxt_row]
                if len(set(ids)) != len(ids):
                    break
                # A grid: right of each new patch is the next new one.
                if any(across(*nxt_row[i], 1) != nxt_row[i + 1] for i in range(len(nxt_row) - 1)):
                    break
                # The new row's outer sides: ``side`` of every patch, 3 of the first and 1 of the last.
                new = set(ids)
                if (faces_block(nxt_row, (side,), taken, new) or faces_block(nxt_row[:1], (3,), taken, new)
                        or faces_block(nxt_row[-1:], (1,), taken, new)):
                    break
                grid.insert(len(grid) if side == 2 else 0, nxt_row)
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


# --- Knot removal ----------------------------------------------------------------------------
#
# A run of n Bézier spans of degree p, span i on [x_i, x_{i+1}], is a spline with every interior
# knot of multiplicity p.  Where two spans join C^k (k < p) the knot is needed only p - k
# times; where they are one polynomial (C^p: the jump of the p-th derivative is zero too) it is
# not needed at all.  Jumps are measured in pole units: the j-th derivative of a degree-p
# Bézier span of length d at its end is p!/(p-j)! Delta^j b_{p-j} / d^j, so a jump J_j there
# moves the poles of the shorter span (length r) by about |J_j| r^j (p-j)!/p!; a knot keeps the
# multiplicity p - k for the largest k whose jumps 0..k all are within the tolerance.  The
# B-spline on the kept knots is then the least-squares fit to the Bézier coefficients, through
# the exact linear map from its poles to them (``bezier_matrix``: knot insertion up to
# multiplicity p), and it is accepted only if that map gives back every span's coefficients
# to the exactness bound: by the convex hull property of the Bernstein basis the spline then
# differs from the spans by no more than that anywhere.  This is knot removal (Tiller's
# algorithm, Piegl and Tiller, The NURBS Book, sec. 5.4) decided for all knots at once from the
# spans themselves and made exact by the check, in place of one OpenCASCADE call per knot.


@dataclass(frozen=True)
class Spline:
    """A clamped B-spline of degree p (curve or tensor-product surface): distinct knots and
    their multiplicities per direction (ends p + 1), poles (N, c) or (Nu, Nv, c)."""

    knots: tuple[np.ndarray, ...]
    mults: tuple[np.ndarray, ...]
    poles: np.ndarray
    degree: int = 3


def knot_multiplicities(along: np.ndarray, d: np.ndarray, tol: float) -> np.ndarray:
    """(n - 1,) int64: the multiplicity each interior breakpoint of n Bézier spans needs (text
    above): 0 where the spans on both sides are one polynomial, p - k where they join C^k.

    along: (n, p + 1, m, c) the spans' coefficients along the direction (m rows across it, c
    coordinates); d: (n,) their parameter lengths, all > 0; tol: in model units."""
    n, p1 = along.shape[:2]
    p = p1 - 1
    if n < 2:
        return np.zeros(0, dtype=np.int64)
    d = np.asarray(d, dtype=np.float64)
    da, db = d[:-1], d[1:]
    r = np.minimum(da, db)
    ok = np.ones(n - 1, dtype=bool)
    cont = np.full(n - 1, -1, dtype=np.int64)
    for j, end, start in _join_differences(along):
        jump = end * ((r / da) ** j)[:, None, None] - start * ((r / db) ** j)[:, None, None]
        ok &= np.sqrt(np.einsum("kmc,kmc->km", jump, jump)).max(axis=1) <= tol
        cont[ok] = j
    return p - cont.clip(0, p)  # not even C0 (a bad join): p, and the check refuses it


def _join_differences(along: np.ndarray):
    """For j = 0..p, at each interior breakpoint of the spans along (n, p + 1, m, c): j,
    Delta^j b_{p-j} of the left span and Delta^j b_0 of the right one, each (n - 1, m, c)."""
    for j in range(along.shape[1]):
        yield j, np.diff(along[:-1], n=j, axis=1)[:, -1], np.diff(along[1:], n=j, axis=1)[:, 0]


#: A removed breakpoint whose derivative jump exceeds the roundoff bound (``_join_scores``) and
#: this many times the median of the other removed breakpoints of its span run is put back
#: first when the run's fit is off.  Measured on random cubic B-splines refined by
#: OpenCASCADE: true knots that the local test missed (beside a span 1e-4 of its neighbours)
#: scored 7.9x to 36x that median, breakpoints inside one polynomial at most 2.3x.  At most
#: ``STANDOUT_ROUNDS`` rounds put such knots back: then bisection alone, which halves the runs.
STANDS_OUT = 4.0
STANDOUT_ROUNDS = 16


def _join_scores(along: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(n - 1,): each interior breakpoint's largest derivative jump over a bound of its
    roundoff.  The j-th derivatives at the join are p!/(p-j)! Delta^j b / d^j from either
    side, and coefficients good to eps B (B their largest magnitude) give Delta^j b good to
    2^j eps B, so a jump of one polynomial is at most about 2^j eps B (d_a^-j + d_b^-j) (the
    common factor p!/(p-j)! dropped).  Inside one polynomial the score stays below 1 (measured
    0.1 to 0.25); a true knot whose jumps were too small for ``knot_multiplicities`` at the
    scale of a tiny neighbouring span still stands out from them (1.6 to 3 in the cases that
    the property test found)."""
    da, db = d[:-1], d[1:]
    bound = np.finfo(np.float64).eps * max(float(np.abs(along).max()), np.finfo(np.float64).tiny)
    score = np.zeros(along.shape[0] - 1)
    for j, end, start in _join_differences(along):
        step = end / (da**j)[:, None, None] - start / (db**j)[:, None, None]
        jump = np.sqrt(np.einsum("kmc,kmc->km", step, step)).max(axis=1)
        score = np.maximum(score, jump / (2.0**j * bound * (da**-j + db**-j)))
    return score


def _stands_out(score: np.ndarray, lo: int, hi: int) -> int | None:
    """In the run of spans lo..hi-1 (its breakpoints removed) whose fit is off, the removed
    breakpoint (an index into the multiplicities) whose jump stands out above roundoff and
    above the others (``STANDS_OUT``): a true knot that the local test missed.  None when none
    does: jumps below the tolerance that add up, which bisection mends."""
    inside = score[lo : hi - 1]
    best = int(np.argmax(inside))
    others = np.delete(inside, best)
    if inside[best] >= 1.0 and (not others.size or inside[best] >= STANDS_OUT * np.median(others)):
        return lo + best
    return None


@lru_cache(maxsize=None)
def _bezier_from_values(p: int) -> np.ndarray:
    """(p + 1, p + 1): a degree-p polynomial's Bézier coefficients on [0, 1] from its values at
    0, 1/p, ..., 1 (the inverse of the Bernstein collocation; its first and last rows exact)."""
    from patching.bernstein import bernstein

    out = np.linalg.inv(bernstein(p, np.linspace(0.0, 1.0, p + 1)))
    out[[0, -1]] = 0.0
    out[0, 0] = out[-1, -1] = 1.0
    out.setflags(write=False)
    return out


def flat_knots(x: np.ndarray, mults: np.ndarray, p: int) -> np.ndarray:
    """The knot vector on breakpoints x (n + 1,) with interior multiplicities mults (n - 1,)
    and clamped ends (multiplicity p + 1)."""
    m = np.concatenate([[p + 1], np.asarray(mults, dtype=np.int64), [p + 1]])
    return np.repeat(np.asarray(x, dtype=np.float64), m)


def bezier_matrix(x: np.ndarray, mults: np.ndarray, p: int):
    """(p n + 1, N) scipy CSR: the Bézier coefficients of the n spans of the clamped degree-p
    B-spline with breakpoints x (increasing) and interior multiplicities mults, from its N
    poles; span i's are rows p i .. p i + p.  Span i's coefficients are ``_bezier_from_values``
    of the spline's values at x_i + (x_{i+1} - x_i) k / p (scipy's B-spline basis)."""
    from scipy.interpolate import BSpline
    from scipy.sparse import csr_matrix, identity, kron

    x = np.asarray(x, dtype=np.float64)
    n = len(x) - 1
    k = np.arange(p + 1) / p
    nodes = np.clip((x[:-1, None] + (x[1:] - x[:-1])[:, None] * k[None, :]).ravel(), x[0], x[-1])
    values = BSpline.design_matrix(nodes, flat_knots(x, mults, p), p).tocsr()  # (n (p + 1), N)
    per_span = kron(identity(n, format="csr"), csr_matrix(_bezier_from_values(p)), format="csr") @ values
    rows = np.append((np.arange(n)[:, None] * (p + 1) + np.arange(p)[None, :]).ravel(), n * (p + 1) - 1)
    return per_span.tocsr()[rows]


class _FitMap:
    """The map from a B-spline's poles to its spans' Bézier coefficients (``bezier_matrix``),
    dense when small, and its least squares: argmin_z |a z - y| column by column through the
    normal equations (a has full column rank and rows that each touch p + 1 consecutive
    columns: banded Cholesky), with one step of iterative refinement."""

    def __init__(self, x: np.ndarray, mults: np.ndarray, p: int):
        from scipy.linalg import cholesky_banded

        a = bezier_matrix(x, mults, p)
        g = (a.T @ a).tocoo()
        n = a.shape[1]
        bw = int(np.abs(g.row - g.col).max()) if g.nnz else 0
        ab = np.zeros((bw + 1, n))
        upper = g.col >= g.row
        ab[bw - (g.col - g.row)[upper], g.col[upper]] = g.data[upper]  # ab[bw - k, j] = g[j - k, j]
        self.factor = (cholesky_banded(ab), False)
        self.a = a.toarray() if a.shape[0] * a.shape[1] <= 1 << 18 else a
        self.at = self.a.T if isinstance(self.a, np.ndarray) else a.T.tocsr()

    def solve(self, y: np.ndarray) -> np.ndarray:
        from scipy.linalg import cho_solve_banded

        z = cho_solve_banded(self.factor, self.at @ y)
        return z + cho_solve_banded(self.factor, self.at @ (y - self.a @ z))


@lru_cache(maxsize=256)
def _cached_fit_map(x: bytes, mults: bytes, p: int) -> _FitMap:
    return _FitMap(np.frombuffer(x), np.frombuffer(mults, dtype=np.int64), p)


def _fit_map(x: np.ndarray, mults: np.ndarray, p: int) -> _FitMap:
    """``_FitMap`` of breakpoints x, the same for x and any a x + b (a > 0), so that the many
    small blocks of one pattern (two patches across a band, ...) share one: those of up to 64
    spans are kept (256 of them, at most ~50 MB), longer ones made each time."""
    x = np.asarray(x, dtype=np.float64)
    mults = np.asarray(mults, dtype=np.int64)
    if len(x) > 65:
        return _FitMap(x, mults, p)
    return _cached_fit_map(((x - x[0]) / (x[-1] - x[0])).tobytes(), mults.tobytes(), p)


def kept_knots(along: np.ndarray, x: np.ndarray, tol: float, exact: float) -> np.ndarray | None:
    """(n - 1,) multiplicities of the interior breakpoints x (n + 1,) of n Bézier spans along
    (n, p + 1, m, c) such that the least-squares B-spline on them gives back every span to
    ``exact``: ``knot_multiplicities`` (necessary, not sufficient: jumps below the tolerance
    at each of 500 fine knots add up, on a ring of level-9 leaves near extraordinary points,
    to 1e-9 of the size over the merged span; a true knot beside a span 1e-4 of its
    neighbours can look removable at that span's scale), then, while a merged span is off,
    removed knots put back at multiplicity 1 (those whose jumps stand out, ``_stands_out``,
    alone, else the middle one of each run that is off, bisecting), and a span that is off
    alone between kept knots raising them by one.  None if a span is still off
    with its knots at multiplicity p (the Bézier form, which the caller takes then)."""
    n, p1, m, c = along.shape
    p = p1 - 1
    x = np.asarray(x, dtype=np.float64)
    mults = knot_multiplicities(along, np.diff(x), tol)
    target = np.concatenate([along[:, :-1].reshape(n * p, m * c), along[-1:, -1].reshape(1, m * c)])
    rows = np.arange(n)[:, None] * p + np.arange(p1)
    score = None  # _join_scores, once a fit is off
    for round_ in range(64):
        if not np.any(mults == 0):
            return mults
        fit = _fit_map(x, mults, p)
        back = (fit.a @ fit.solve(target))[rows].reshape(n, p1, m, c)
        bad = np.sqrt(((back - along) ** 2).sum(axis=-1)).max(axis=(1, 2)) > exact  # (n,)
        if not bad.any():
            return mults
        kept = np.concatenate([[0], np.flatnonzero(mults > 0) + 1, [n]])  # segment ends (breakpoints)
        runs = [(int(kept[s]), int(kept[s + 1])) for s in np.unique(np.searchsorted(kept, np.flatnonzero(bad), side="right") - 1)]
        # Knots the local test missed first, alone: the error of a run that lacks one spreads
        # through the least-squares fit into its neighbours, which would otherwise be split too.
        missed = []
        if round_ < STANDOUT_ROUNDS and any(hi - lo >= 2 for lo, hi in runs):
            score = _join_scores(along, np.diff(x)) if score is None else score
            missed = [k for k in (_stands_out(score, lo, hi) for lo, hi in runs if hi - lo >= 2) if k is not None]
        if missed:
            mults[missed] = 1
            continue
        changed = False
        for lo, hi in runs:
            if hi - lo >= 2:
                mults[(lo + hi) // 2 - 1] = 1  # bisecting
                changed = True
                continue
            # One span, no knot removed in it: off through the fit of its neighbours (least
            # squares spreads), or its end knots were lowered too far (a C2 jump below the
            # tolerance), which raising them mends.
            ends = [k - 1 for k in (lo, hi) if 0 < k < n and mults[k - 1] < p]
            mults[ends] += 1
            changed |= bool(ends)
        if not changed:
            return None
    return None


def reduce_curve(rows: np.ndarray, x: np.ndarray, tol: float, exact: float) -> Spline:
    """The fewest-knot B-spline equal to the Bézier rows (n, p + 1, c), row i on [x_i,
    x_{i+1}]: knots removed where the joins allow (text above), the poles fitted and checked
    to ``exact`` (model units); failing that the knots kept at multiplicity >= 1, failing that
    the Bézier form itself (every interior knot p times: the rows, the joins as row i + 1 has
    them)."""
    rows = np.asarray(rows, dtype=np.float64)
    n, p1, c = rows.shape
    p = p1 - 1
    x = np.asarray(x, dtype=np.float64)
    target = np.concatenate([rows[:, :-1].reshape(-1, c), rows[-1:, -1]])
    m = kept_knots(rows[:, :, None, :], x, tol, exact)
    for mults in [] if m is None else [m, np.maximum(m, 1)]:
        fit = _fit_map(x, mults, p)
        poles = fit.solve(target)
        spans = (fit.a @ poles)[np.arange(n)[:, None] * p + np.arange(p1)]
        if np.sqrt(((spans - rows) ** 2).sum(axis=-1)).max() <= exact:
            return _spline((x,), (mults,), poles, p)
        if np.all(m >= 1):
            break
    return _spline((x,), (np.full(n - 1, p),), target, p)


def _spline(xs, ms, poles, p) -> Spline:
    full = tuple(np.concatenate([[p + 1], np.asarray(m, dtype=np.int64), [p + 1]]) for m in ms)
    keep = tuple(f > 0 for f in full)
    return Spline(tuple(np.asarray(x)[k] for x, k in zip(xs, keep)), tuple(f[k] for f, k in zip(full, keep)), poles, p)


def reduce_block(block: Block, nets, tol: float, exact: float) -> Spline | None:
    """The packed B-spline of a block with the fewest knots (text above), poles (Nu, Nv, 3), or
    None if not even its Bézier form gives back every patch to ``exact`` (model units).
    A knot along u is removed (or lowered) only as far as every row of poles across the block
    allows, likewise along v; the fit is the tensor product of the two least-squares maps."""
    turned, grid = block_poles(block, nets)
    w, h = block.rows.shape
    if np.any(block.du <= 0) or np.any(block.dv <= 0):
        return None
    u, v = block.knots
    along_u = turned.transpose(0, 2, 1, 3, 4).reshape(w, 4, 4 * h, 3)
    along_v = turned.transpose(1, 3, 0, 2, 4).reshape(h, 4, 4 * w, 3)
    # each direction to a quarter of the bound, so that the tensor product of the two fits
    # passes the check on the whole block as a rule
    mu, mv = kept_knots(along_u, u, tol, exact / 4), kept_knots(along_v, v, tol, exact / 4)
    mu = np.full(w - 1, 1, dtype=np.int64) if mu is None else mu  # then the C2 form, or the Bézier form
    mv = np.full(h - 1, 1, dtype=np.int64) if mv is None else mv
    ru, rv = np.arange(w)[:, None] * 3 + np.arange(4), np.arange(h)[:, None] * 3 + np.arange(4)

    def fits(mu_, mv_):
        fu, fv = _fit_map(u, mu_, 3), _fit_map(v, mv_, 3)
        au, av = fu.a, fv.a
        nu, nv = au.shape[1], av.shape[1]
        ru_, rv_ = grid.shape[:2]
        # along u: (nu, rv * 3), then along v
        cu = fu.solve(grid.reshape(ru_, rv_ * 3)).reshape(nu, rv_, 3)
        poles = fv.solve(cu.transpose(1, 0, 2).reshape(rv_, nu * 3)).reshape(nv, nu, 3).transpose(1, 0, 2)
        back = (av @ (au @ poles.reshape(nu, nv * 3)).reshape(ru_, nv, 3).transpose(1, 0, 2).reshape(nv, ru_ * 3))
        back = back.reshape(rv_, ru_, 3).transpose(1, 0, 2)
        spans = back[ru[:, None, :, None], rv[None, :, None, :]]  # (w, h, 4, 4, 3)
        err = np.sqrt(((spans - turned) ** 2).sum(axis=-1)).max()
        return poles if err <= exact else None

    tried = set()
    for mu_, mv_ in ((mu, mv), (np.maximum(mu, 1), np.maximum(mv, 1))):
        key = (mu_.tobytes(), mv_.tobytes())
        if key in tried:
            continue
        tried.add(key)
        poles = fits(mu_, mv_)
        if poles is not None:
            return _spline((u, v), (mu_, mv_), poles, 3)
    err = np.sqrt(((grid[ru[:, None, :, None], rv[None, :, None, :]] - turned) ** 2).sum(axis=-1)).max()
    if err <= exact:
        return _spline((u, v), (np.full(w - 1, 3), np.full(h - 1, 3)), grid, 3)
    return None
