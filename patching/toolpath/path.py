"""3-axis ball-end tool paths on the patched surface ([FSLYJ] sec. 4.3).

Pipeline: faces that face up (some sample with unit normal n_z >= 0.1) -> regular pieces
(``segmentation``) -> in each piece a connected Fermat spiral (``spiral``) whose pass spacing
keeps the scallop <= H -> contact points S, ball centres C = S + R n -> drop-cutting against the
whole surface (no gouge) -> points thinned so that the chord error stays <= T -> a check of
every centre and segment (clearance) and of every up-facing sample (scallop).

Pass spacing from the normal curvature: two passes of a ball of radius R a distance w apart
on a surface of normal curvature kappa across the passes (kappa > 0 where the surface bends
away from the tool) leave a cusp of height h ~ w^2 / 8 (1/R + kappa) (the two balls' offset
circles meet at the cusp; exact on a plane: h = R - sqrt(R^2 - w^2/4)).  We use the largest
such kappa in any direction (the path direction is not known where the density is set),
1/R + kappa clipped below at 1/(2R) (concave spots tighter than the ball leave material the
ball cannot reach anyway), and a factor 0.9 on w for the w^4 terms:
w = 0.9 sqrt(8 H / (1/R + kappa)).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..errors import NupatchError, UnsupportedError
from ..mesh import ControlMesh
from ..surface import BezierSurface
from ..topology import Topology
from ..bernstein import common_nets
from .geometry import SurfaceIndex, evaluate_points, unit_normals
from .segmentation import Piece, segment
from .spiral import fermat_spiral

__all__ = ["UP", "ToolPath", "check_parameters", "clearance", "densify", "side_normals", "simplify", "tool_path", "up_faces"]

#: smallest n_z of the surface that the tool machines from +Z.
UP = 0.1
CELL_SAMPLES = 8  # density samples per face side


@dataclass(frozen=True)
class ToolPath:
    """A tool path, piece after piece.

    piece: (N,) int64 piece of each point (pieces are machined in increasing order, each one
    continuous); centres: (N, 3) ball centres; tips: (N, 3) programmed tool tips (centre - R z);
    contacts: (N, 3) surface points the passes follow (before lifting); normals: (N, 3) unit
    surface normals there; parameters: (N, 2) (u, v) of the contacts in their piece's
    rectangle [0, nu] x [0, nv].  pieces: the segmentation, piece_order[k] the index into pieces of
    machined piece k.  report: figures from the check (``tool_path``)."""

    piece: np.ndarray
    centres: np.ndarray
    tips: np.ndarray
    contacts: np.ndarray
    normals: np.ndarray
    parameters: np.ndarray
    radius: float
    scallop: float
    tolerance: float
    pieces: list[Piece] = field(repr=False)
    piece_order: np.ndarray = field(repr=False)
    report: dict = field(default_factory=dict)


def check_parameters(radius: float, scallop: float, tolerance: float | None) -> float:
    """Validate R, H, T (T defaults to H / 4); returns T."""
    for name, value in (("tool radius R", radius), ("scallop height H", scallop)):
        if not np.isfinite(value) or value <= 0:
            raise NupatchError(f"the {name} must be finite and > 0, not {value:g}", "--tool/--scallop")
    if scallop >= radius:
        raise NupatchError(f"the scallop height H = {scallop:g} must be smaller than the tool radius R = {radius:g}", "--scallop")
    if tolerance is None:
        tolerance = scallop / 4
    if not np.isfinite(tolerance) or tolerance <= 0:
        raise NupatchError(f"the chord tolerance T must be finite and > 0, not {tolerance:g}", "--tolerance")
    return float(tolerance)


class _PieceMap:
    """The patches of a piece as one map of [0, nu] x [0, nv] (nets turned to the grid)."""

    def __init__(self, piece: Piece, nets_of_face: dict[int, np.ndarray]):
        self.nu, self.nv = piece.shape
        d = next(iter(nets_of_face.values())).shape[0] - 1
        self.nets = np.zeros((self.nu, self.nv, d + 1, d + 1, 3))
        for i in range(self.nu):
            for j in range(self.nv):
                self.nets[i, j] = turn_net(nets_of_face[int(piece.faces[i, j])], int(piece.rotation[i, j]))

    def evaluate(self, uv: np.ndarray, order: int = 1):
        """Points and derivatives at (N, 2) piece parameters (a cell's own patch on its sides
        where u or v is an integer: the lower cell, except at the far end)."""
        u = np.clip(uv[:, 0], 0.0, self.nu)
        v = np.clip(uv[:, 1], 0.0, self.nv)
        i = np.minimum(np.floor(u).astype(int), self.nu - 1)
        j = np.minimum(np.floor(v).astype(int), self.nv - 1)
        return self.evaluate_cells(i, j, u - i, v - j, order)

    def evaluate_cells(self, i, j, s, t, order: int = 1):
        return evaluate_points(self.nets[i, j], s, t, order=order)


def turn_net(net: np.ndarray, r: int) -> np.ndarray:
    """The net of a face whose local side r is the piece's side 0 (-v), in piece coordinates:
    (s, t) = (1 - t', s') for r = 1, i.e. net'[a, b] = net[d - b, a] (``np.rot90`` by -r)."""
    return np.rot90(net, -r, axes=(0, 1))


def _spacing(radius: float, scallop: float, su, sv, suu, suv, svv) -> np.ndarray:
    """Allowed pass spacing w (module docstring) at points with these derivatives."""
    n = unit_normals(su, sv)
    e, f, g = (np.einsum("nc,nc->n", a, b) for a, b in ((su, su), (su, sv), (sv, sv)))
    l, m, k = (np.einsum("nc,nc->n", a, n) for a in (suu, suv, svv))
    det = np.maximum(e * g - f * f, 1e-300)
    mean = (e * k - 2 * f * m + g * l) / (2 * det)
    gauss = (l * k - m * m) / det
    root = np.sqrt(np.maximum(mean * mean - gauss, 0.0))
    bend_away = -(mean - root)  # -(smallest principal curvature): > 0 on a dome seen from outside
    effective = np.maximum(1.0 / radius + bend_away, 0.5 / radius)
    return 0.9 * np.sqrt(8.0 * scallop / effective)


def _densities(pm: _PieceMap, radius: float, scallop: float):
    """Passes per unit u (max over v) and per unit v (max over u) on the piece's sample grid."""
    # Each cell sampled on its own closed grid: the parameter speed jumps across patch
    # sides (non-uniform knots), so both one-sided values enter the pass count.
    local = np.linspace(0.0, 1.0, CELL_SAMPLES + 1)
    ui = np.repeat(np.arange(pm.nu), local.size)
    vj = np.repeat(np.arange(pm.nv), local.size)
    us = np.tile(local, pm.nu)
    vs = np.tile(local, pm.nv)
    I, J = np.meshgrid(np.arange(ui.size), np.arange(vj.size), indexing="ij")
    _, su, sv, suu, suv, svv = pm.evaluate_cells(ui[I.ravel()], vj[J.ravel()], us[I.ravel()], vs[J.ravel()], order=2)
    w = _spacing(radius, scallop, su, sv, suu, suv, svv)
    gu = (np.linalg.norm(su, axis=1) / w).reshape(I.shape)
    gv = (np.linalg.norm(sv, axis=1) / w).reshape(I.shape)
    return ui + us, gu.max(axis=1), vj + vs, gv.max(axis=0), float(w.min())


def _resample(pm: _PieceMap, uv: np.ndarray, step: float, radius: float) -> np.ndarray:
    """Insert parameter points so that consecutive ball centres S + R n (and surface points)
    are about <= step apart: around a convex rim of radius rho the centres move (rho + R) / rho
    times as fast as the contacts, so spacing the contacts alone leaves long chords there."""
    p, su, sv = pm.evaluate(uv)
    c = p + radius * unit_normals(su, sv)
    seg = np.maximum(np.linalg.norm(np.diff(p, axis=0), axis=1), np.linalg.norm(np.diff(c, axis=0), axis=1))
    extra = np.maximum(np.ceil(seg / step).astype(int), 1)
    frac = np.concatenate([np.arange(k) / k for k in extra])
    start = np.repeat(np.arange(len(seg)), extra)
    out = uv[start] + frac[:, None] * (uv[start + 1] - uv[start])
    return np.concatenate([out, uv[-1:]])


def simplify(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices of a Douglas-Peucker subset: every point lies within ``tolerance`` of the
    segment between the kept points around it (the chord error)."""
    keep = np.zeros(len(points), dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, len(points) - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        dist = segment_distances(points[a + 1 : b], points[a], points[b])
        k = int(np.argmax(dist))
        if dist[k] > tolerance:
            keep[a + 1 + k] = True
            stack += [(a, a + 1 + k), (a + 1 + k, b)]
    return np.flatnonzero(keep)


def segment_distances(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances of points x (N, 3) to the segment(s) a-b (broadcast)."""
    ab = b - a
    t = np.clip(np.sum((x - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-300), 0.0, 1.0)
    return np.linalg.norm(x - (a + t[..., None] * ab), axis=-1)


def densify(points: np.ndarray, step: float) -> np.ndarray:
    """Points on the polyline at most ``step`` apart (vertices kept)."""
    if len(points) < 2:
        return points
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    extra = np.maximum(np.ceil(seg / step).astype(int), 1)
    frac = np.concatenate([np.arange(k) / k for k in extra])
    start = np.repeat(np.arange(len(seg)), extra)
    out = points[start] + frac[:, None] * (points[start + 1] - points[start])
    return np.concatenate([out, points[-1:]])


def up_faces(faces: np.ndarray, nets: np.ndarray, samples: int = 9) -> np.ndarray:
    """(p,) bool, patches with a sample whose unit normal has n_z >= UP."""
    u = np.linspace(0.0, 1.0, samples)
    s, t = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    k = len(nets)
    _, su, sv = evaluate_points(np.repeat(nets, s.size, axis=0), np.tile(s, k), np.tile(t, k))
    nz = unit_normals(su, sv)[:, 2].reshape(k, -1)
    return nz.max(axis=1) >= UP


def side_normals(mesh: ControlMesh, faces: np.ndarray, nets: np.ndarray) -> np.ndarray:
    """(n_faces, 4, 3) unit normal at the middle of each patch side (zero without a patch)."""
    mid = np.array([[0.5, 0.0], [1.0, 0.5], [0.5, 1.0], [0.0, 0.5]])
    k = len(nets)
    _, su, sv = evaluate_points(np.repeat(nets, 4, axis=0), np.tile(mid[:, 0], k), np.tile(mid[:, 1], k))
    out = np.zeros((mesh.n_faces, 4, 3))
    out[faces] = unit_normals(su, sv).reshape(k, 4, 3)
    return out


def tool_path(
    surface: BezierSurface,
    mesh: ControlMesh,
    radius: float,
    scallop: float,
    tolerance: float | None = None,
    topology: Topology | None = None,
) -> ToolPath:
    """The 3-axis tool path of a ball-end mill of radius R over the up-facing surface, scallop
    <= H, chord error <= T (default H / 4), no gouge (module docstring; [FSLYJ] sec. 4.3).

    report keys: pieces, points, path_length (along the ball centres, inside pieces),
    max_scallop (largest distance of a reachable up-facing sample to the densified path of
    centres minus R), unreachable (fraction of up-facing samples no ball of radius R touches
    without gouging), max_chord_error (largest distance of the dense spiral of lifted centres
    to the programmed polyline, an upper bound), min_clearance (certified smallest distance of
    the centre path to the surface, >= R - T), lifted (fraction of dense centres raised by
    more than T / 10)."""
    tolerance = check_parameters(radius, scallop, tolerance)
    topo = topology if topology is not None else Topology(mesh)
    faces, nets, _ = common_nets(surface)
    if not np.all(np.isfinite(nets)):
        bad = int(faces[np.flatnonzero(~np.all(np.isfinite(nets.reshape(len(nets), -1)), axis=1))[0]])
        raise NupatchError("the surface has non-finite coefficients", f"face {bad}")
    up = up_faces(faces, nets)
    quads = mesh.face_sizes[faces] == 4
    if not np.any(up & quads):
        raise UnsupportedError(f"nothing faces up: no patch has a unit normal with n_z >= {UP}", "the whole surface")
    nets_of_face = {int(f): n for f, n in zip(faces, nets)}
    pieces = segment(mesh, faces[up & quads], side_normals(mesh, faces, nets), topo)

    # Samples: spacing from the ball and the pass spacing on a plane (w ~ sqrt(8 R H)).
    flat_w = np.sqrt(8.0 * radius * scallop)
    index = SurfaceIndex(nets, spacing=max(radius / 8.0, surface.size / 1500.0))
    step = np.sqrt(2.0 * radius * tolerance)  # dense spiral sampling: sagitta of a step <= R T kappa / 4

    chunks, maps = [], []
    for k, piece in enumerate(pieces):
        pm = _PieceMap(piece, nets_of_face)
        ug, du, vg, dv, _ = _densities(pm, radius, scallop)
        uv = fermat_spiral(ug, du, vg, dv)
        uv = _resample(pm, uv, step, radius)
        p, su, sv = pm.evaluate(uv)
        n = unit_normals(su, sv)
        chunks.append([k, uv, p, n, p + radius * n])
        maps.append(pm)
    # One drop-cutter call for the centres of all pieces.
    c0 = np.concatenate([ch[4] for ch in chunks])
    lifted = np.split(index.drop(c0, radius, rounds=40), np.cumsum([len(ch[4]) for ch in chunks])[:-1])
    chunks = [[*ch, up] for ch, up in zip(chunks, lifted)]
    _refine_dense(chunks, maps, index, radius, tolerance, step)

    # Machine pieces in a greedy nearest order; each may run backwards.
    order, flip = [], []
    left = set(range(len(chunks)))
    at = np.array([-np.inf, -np.inf])
    while left:
        best = None
        for k in left:
            c = chunks[k][5]
            for rev, start in ((False, c[0]), (True, c[-1])):
                dist = np.linalg.norm(start[:2] - at) if np.all(np.isfinite(at)) else (0.0 if not rev else 1.0)
                if best is None or dist < best[0]:
                    best = (dist, k, rev)
        _, k, rev = best
        order.append(k)
        flip.append(rev)
        left.remove(k)
        at = (chunks[k][5][0] if rev else chunks[k][5][-1])[:2]

    polys, contacts, normals, params, piece_ids, dense = [], [], [], [], [], []
    lifted_count, dense_count = 0, 0
    check_step = np.sqrt(2.0 * radius * tolerance)
    for slot, (k, rev) in enumerate(zip(order, flip)):
        _, uv, p, n, c0, c = chunks[k]
        if rev:
            p, n, c0, c, uv = p[::-1], n[::-1], c0[::-1], c[::-1], uv[::-1]
        lifted_count += int(np.sum(c[:, 2] > c0[:, 2] + 0.1 * tolerance))
        dense_count += len(c)
        keep = simplify(c, 0.5 * tolerance)
        polys.append(c[keep])
        contacts.append(p[keep])
        normals.append(n[keep])
        params.append(uv[keep])
        piece_ids.append(np.full(len(keep), slot, dtype=np.int64))
        dense.append(c)
    centres, contacts, normals, params = (np.concatenate(x) for x in (polys, contacts, normals, params))
    piece = np.concatenate(piece_ids)
    # Gouge check of every segment of every piece at once; lifted midpoints where it fails.
    for _ in range(12):
        within = piece[:-1] == piece[1:]
        clear = clearance(index, centres, check_step, within)
        bad = np.flatnonzero(within & (clear < radius - tolerance))
        if bad.size == 0:
            break
        mid = index.drop(0.5 * (centres[bad] + centres[bad + 1]), radius, rounds=40)
        centres = np.insert(centres, bad + 1, mid, axis=0)
        contacts = np.insert(contacts, bad + 1, 0.5 * (contacts[bad] + contacts[bad + 1]), axis=0)
        normals = np.insert(normals, bad + 1, normals[bad], axis=0)
        params = np.insert(params, bad + 1, 0.5 * (params[bad] + params[bad + 1]), axis=0)
        piece = np.insert(piece, bad + 1, piece[bad])
    min_clear = float(clear[within].min()) if within.any() else np.inf
    # chord error: the dense spiral of lifted centres against the programmed polyline
    # (nearest point of the polyline sampled at T / 5: an upper bound, by at most T / 10)
    max_chord = 0.0
    for slot, c in enumerate(dense):
        d, _ = cKDTree(densify(centres[piece == slot], 0.2 * tolerance)).query(c)
        max_chord = max(max_chord, float(d.max()))

    report = {
        "pieces": len(pieces),
        "points": len(centres),
        "path_length": float(sum(np.linalg.norm(np.diff(x, axis=0), axis=1).sum() for x in np.split(centres, np.flatnonzero(np.diff(piece)) + 1))),
        "max_chord_error": max_chord,
        "min_clearance": min_clear,
        "lifted": lifted_count / max(dense_count, 1),
    }
    fine = SurfaceIndex(nets, spacing=flat_w / 4.0)
    report["max_scallop"], report["unreachable"] = _scallop_check(
        fine, up_samples_mask(fine), centres, piece, radius, min(step, flat_w / 8.0), tolerance
    )
    return ToolPath(
        piece=piece,
        centres=centres,
        tips=centres - np.array([0.0, 0.0, radius]),
        contacts=contacts,
        normals=normals,
        parameters=params,
        radius=float(radius),
        scallop=float(scallop),
        tolerance=tolerance,
        pieces=[pieces[k] for k in order],
        piece_order=np.array(order, dtype=np.int64),
        report=report,
    )


def _refine_dense(chunks: list, maps: list, index: SurfaceIndex, radius: float, tolerance: float, step: float, rounds: int = 6) -> None:
    """Where a segment of the dense lifted spiral next to a lifted centre comes closer than
    R - T / 2 to the surface (the drop-cutter's lift peaks between two samples), insert the
    lifted centre of the contact midway in parameters, until none does or ``rounds`` passed
    (in place; chunks: [k, uv, p, n, c0, c]).  The chord error is measured against this
    dense path, so it should not dip into the surface where the programmed path may not."""
    for _ in range(rounds):
        lengths = [len(ch[5]) for ch in chunks]
        pid = np.repeat(np.arange(len(chunks)), lengths)
        within = pid[:-1] == pid[1:]
        # only near lifted centres: elsewhere the ball rides its own contact, chord sagitta
        # <= R T kappa / 4 (the certified check of the programmed path follows anyway)
        rise = np.concatenate([ch[5][:, 2] - ch[4][:, 2] for ch in chunks]) > 0.1 * tolerance
        near = np.convolve(rise.astype(float), np.ones(3), mode="same") > 0
        within &= near[:-1] | near[1:]
        clear = clearance(index, np.concatenate([ch[5] for ch in chunks]), step, within)
        bad = np.flatnonzero(within & (clear < radius - 0.5 * tolerance))
        if bad.size == 0:
            return
        first = np.r_[0, np.cumsum(lengths)[:-1]]
        local = [bad[pid[bad] == k] - first[k] for k in range(len(chunks))]
        new = []
        for ch, pm, b in zip(chunks, maps, local):
            uv = 0.5 * (ch[1][b] + ch[1][b + 1])
            p, su, sv = pm.evaluate(uv)
            n = unit_normals(su, sv)
            new.append((uv, p, n, p + radius * n))
        up = np.split(index.drop(np.concatenate([x[3] for x in new]), radius, rounds=40), np.cumsum([len(b) for b in local])[:-1])
        for ch, b, (uv, p, n, c0), c in zip(chunks, local, new, up):
            for slot, value in zip((1, 2, 3, 4, 5), (uv, p, n, c0, c)):
                ch[slot] = np.insert(ch[slot], b + 1, value, axis=0)


def clearance(index: SurfaceIndex, poly: np.ndarray, step: float, within: np.ndarray | None = None) -> np.ndarray:
    """Certified smallest distance to the surface along each segment of a polyline of ball
    centres, (n-1,); segments where ``within`` is False (between pieces) are skipped (inf).

    Along a segment x(t) (t arc length), d(t)^2 - t^2 = min_q (|x(t) - q|^2 - t^2) is a minimum
    of functions linear in t, hence concave; so between two points a distance L apart with
    distances d_a, d_b, d^2 >= (1 - l) d_a^2 + l d_b^2 - l (1 - l) L^2 for l in [0, 1].  The
    segment is sampled at spacing <= step, the distances measured (``SurfaceIndex.closest``,
    all segments in one call), and the bound minimised over l per interval."""
    within = np.ones(len(poly) - 1, dtype=bool) if within is None else within
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    parts = np.where(within, np.maximum(np.ceil(seg / step).astype(int), 1), 0)
    start = np.repeat(np.arange(len(seg)), parts)
    frac = np.concatenate([np.arange(k) / k for k in parts if k]) if parts.any() else np.zeros(0)
    x = poly[start] + frac[:, None] * (poly[start + 1] - poly[start])
    # The next sample is the next row of x, except after the last sample of a piece's last
    # segment (the end point of a piece is not the start of a sampled segment).
    nxt = np.r_[start[1:], -1]
    alone = np.flatnonzero((nxt != start) & (nxt != start + 1))
    d = index.closest(np.concatenate([x, poly[start[alone] + 1]]))[0]
    d_x = d[: len(x)]
    d_b = np.r_[d_x[1:], 0.0]
    d_b[alone] = d[len(x) :]
    a, b = d_x**2, d_b**2
    ll = np.repeat(np.where(parts > 0, seg / np.maximum(parts, 1), 0.0), parts) ** 2
    lam = np.clip((a - b + ll) / np.maximum(2 * ll, 1e-300), 0.0, 1.0)
    low = np.sqrt(np.maximum((1 - lam) * a + lam * b - lam * (1 - lam) * ll, 0.0))
    per = np.full(len(seg), np.inf)
    np.minimum.at(per, start, low)
    return per


def up_samples_mask(index: SurfaceIndex) -> np.ndarray:
    """(m,) bool, the index's samples whose unit normal has n_z >= UP."""
    _, rows, st = index.samples
    _, su, sv = evaluate_points(index.nets[rows], st[:, 0], st[:, 1])
    return unit_normals(su, sv)[:, 2] >= UP


def _scallop_check(
    index: SurfaceIndex, mask: np.ndarray, centres: np.ndarray, piece: np.ndarray, radius: float, step: float, tolerance: float
) -> tuple[float, float]:
    """(largest distance of a reachable up-facing sample to the densified centre path minus R,
    fraction of up-facing samples the ball cannot reach).

    A sample p with unit normal n is reachable when the one ball of radius R touching the
    surface there from outside, centred at p + R n, stays >= R - T from every sample (in a
    concave corner tighter than the ball it does not, and no path can machine p)."""
    pts, rows, st = index.samples
    _, su, sv = evaluate_points(index.nets[rows[mask]], st[mask, 0], st[mask, 1])
    p = pts[mask]
    touch, _ = index.tree.query(p + radius * unit_normals(su, sv))
    reach = touch >= radius - tolerance
    parts = np.split(centres, np.flatnonzero(np.diff(piece)) + 1)
    dense = np.concatenate([densify(x, step) for x in parts])
    d, _ = cKDTree(dense).query(p[reach])
    worst = float(max(d.max() - radius, 0.0)) if d.size else 0.0
    return worst, float(1.0 - reach.mean()) if reach.size else 0.0
