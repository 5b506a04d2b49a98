"""Per-mesh-edge continuity of a patched quad mesh, with numpy (tests only).

``edge_jumps`` evaluates both patches along every interior mesh edge at the same points and
returns the position gap and the normal angle there, so tests can hold smooth edges to G1 and
sharp edges to their crease curve separately (the B-rep report of export.continuity can only
tell them apart by a threshold on the angle)."""

from __future__ import annotations

import numpy as np

import patching
from patching.evaluation.sampling import evaluate_nets
from patching.topology.features import features
from patching.topology.tables import Topology

SIDE_PARAMETERS = {
    0: lambda u: (u, 0 * u),
    1: lambda u: (1 + 0 * u, u),
    2: lambda u: (1 - u, 1 + 0 * u),
    3: lambda u: (0 * u, 1 - u),
}


def side_samples(net: np.ndarray, side: int, u: np.ndarray):
    """Points and unit normals of a patch along side ``side`` at parameters u (corner side to side+1)."""
    p, n = _batch_side_samples(net[None], side, u)
    return p[0], n[0]


def _batch_side_samples(nets: np.ndarray, side: int, u: np.ndarray):
    s, t = SIDE_PARAMETERS[side](u)
    p, ds, dt = evaluate_nets(nets, s, t, derivatives=True)
    n = np.cross(ds, dt)
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    return p, n / np.where(length > 0, length, 1.0)


def _side_table(mesh: patching.ControlMesh, surface, half_edges: np.ndarray, u: np.ndarray):
    """Points and normals (len(half_edges), m, 3) of the patch sides along half-edges, batched
    by degree and side."""
    base = mesh.face_offsets[:-1]
    points = np.zeros((half_edges.size, u.size, 3))
    normals = np.zeros_like(points)
    topo_face = np.searchsorted(mesh.face_offsets, half_edges, side="right") - 1
    side = half_edges - base[topo_face]
    for g in surface.groups:
        slot = np.full(mesh.n_faces, -1)
        slot[g.faces] = np.arange(len(g.faces))
        for k in range(4):
            pick = np.flatnonzero((slot[topo_face] >= 0) & (side == k))
            if pick.size:
                points[pick], normals[pick] = _batch_side_samples(g.coefficients[slot[topo_face[pick]]], k, u)
    return points, normals


def edge_jumps(mesh: patching.ControlMesh, surface, samples: int = 7):
    """(edges, gaps, angles_deg, sharp): for every interior edge of an all-quad mesh whose two
    faces have patches, the largest gap and normal angle over samples along it (the end points
    excluded, where a flat crease corner has no normal) and whether the edge is sharp."""
    topo = Topology(mesh)
    feats = features(topo)
    patched = np.zeros(mesh.n_faces, dtype=bool)
    for g in surface.groups:
        patched[g.faces] = True
    h = np.flatnonzero(topo.twin > np.arange(topo.twin.size))
    t = topo.twin[h]
    keep = patched[topo.face[h]] & patched[topo.face[t]]
    h, t = h[keep], t[keep]
    w = np.linspace(0.02, 0.98, samples)
    p1, n1 = _side_table(mesh, surface, h, w)
    p2, n2 = _side_table(mesh, surface, t, 1 - w)
    gaps = np.abs(p1 - p2).max(axis=(1, 2))
    angles = np.degrees(np.arctan2(np.linalg.norm(np.cross(n1, n2), axis=-1), (n1 * n2).sum(-1))).max(axis=1)
    edges = topo.edge_of[h]
    return edges, gaps, angles, feats.sharp[edges]


def _patches(surface):
    for g in surface.groups:
        for face, net in zip(g.faces, g.coefficients):
            yield g.degree, face, None, net


def crease_chains(topo: Topology, sharp: np.ndarray, corner: np.ndarray) -> list[tuple[list[int], bool]]:
    """Chains of sharp edges as vertex lists, and whether each closes on itself.  A chain runs
    on through crease vertices (exactly two sharp edges, no corner) and ends at corners or at
    darts (a small local walk, written independently of patching.topology.features)."""
    ends = topo.edges[sharp]
    count = np.bincount(ends.ravel(), minlength=topo.n_vertices)
    incident: dict[int, list[int]] = {}
    for e, (a, b) in zip(np.flatnonzero(sharp).tolist(), ends.tolist()):
        incident.setdefault(a, []).append(e)
        incident.setdefault(b, []).append(e)
    passes = lambda v: count[v] == 2 and not corner[v]  # noqa: E731
    seen: set[int] = set()
    chains = []
    starts = [v for v in incident if not passes(v)] + list(incident)
    for v0 in starts:
        for e0 in incident[v0]:
            if e0 in seen:
                continue
            chain, v, e = [v0], v0, e0
            while True:
                seen.add(e)
                a, b = (int(x) for x in topo.edges[e])
                v = b if a == v else a
                if v == v0 and passes(v0):
                    chains.append((chain, True))
                    break
                chain.append(v)
                if not passes(v):
                    chains.append((chain, False))
                    break
                e = next(x for x in incident[v] if x != e)
    return chains


def crease_bezier_curves(mesh: patching.ControlMesh) -> dict[tuple[int, int], np.ndarray]:
    """{(a, b): (4, 3) Bezier points} of the crease curve over every sharp edge a-b (also keyed
    (b, a), reversed): the cubic B-spline of the crease polygon with its edges' intervals
    (docs/knots.md), closed chains periodic, open chains extended at both ends by the point
    reflection of the polygon and its intervals through the end vertex (the phantom
    2 P_0 - P_k), so the curve ends at the corner.  Uses tests/reference_bspline, not the
    product's extraction."""
    from tests.reference_bspline import cubic_span_extraction

    topo = Topology(mesh)
    feats = features(topo)
    out = {}
    for chain, closed in crease_chains(topo, feats.sharp, feats.corner):
        pts = mesh.vertices[chain]
        m = len(chain)
        legs = [topo.edge_interval[topo.edge_id(chain[i], chain[(i + 1) % m])] for i in range(m if closed else m - 1)]
        if closed:
            P = lambda i: pts[i % m]  # noqa: E731
            D = lambda i: legs[i % m]  # noqa: E731
        else:
            def P(i):  # point reflection through the end vertices, as often as needed
                if i < 0:
                    return 2 * pts[0] - P(-i)
                if i >= m:
                    return 2 * pts[-1] - P(2 * (m - 1) - i)
                return pts[i]

            def D(i):  # interval of leg P_i P_{i+1}, reflected likewise
                if i < 0:
                    return D(-i - 1)
                if i >= m - 1:
                    return D(2 * (m - 1) - i - 1)
                return legs[i]
        for i in range(len(legs)):
            w = cubic_span_extraction(np.array([[D(i - 2), D(i - 1), D(i), D(i + 1), D(i + 2)]]))[0]
            bez = w @ np.array([P(i - 1), P(i), P(i + 1), P(i + 2)])
            a, b = chain[i], chain[(i + 1) % m]
            out[(a, b)] = bez
            out[(b, a)] = bez[::-1]
    return out


def crease_deviation(mesh: patching.ControlMesh, surface, samples: int = 9) -> float:
    """Largest distance, over every patch side on a sharp edge (boundary included), between
    the side curve and the crease B-spline at equal parameters (the patch side is the span's
    Bezier curve, degree-elevated at EPs).  Edges at a dart are left out: the crease fades out
    there, so no B-spline of the polygon describes them."""
    from patching.bernstein import bernstein

    topo = Topology(mesh)
    curves = crease_bezier_curves(mesh)
    if not curves:
        return 0.0
    dart = features(topo).dart
    keys = list(zip(topo.origin.tolist(), topo.dest.tolist()))
    hs = np.array([h for h, (a, b) in enumerate(keys) if (a, b) in curves and not (dart[a] or dart[b])], dtype=np.int64)
    patched = np.zeros(mesh.n_faces, dtype=bool)
    for g in surface.groups:
        patched[g.faces] = True
    hs = hs[patched[topo.face[hs]]]
    if hs.size == 0:
        return 0.0
    u = np.linspace(0.0, 1.0, samples)
    points, _ = _side_table(mesh, surface, hs, u)
    ref = np.einsum("mj,kjc->kmc", bernstein(3, u), np.array([curves[keys[h]] for h in hs]))
    return float(np.abs(points - ref).max())


def brep_smooth_jump(mesh: patching.ControlMesh, surface) -> float:
    """Largest normal jump (degrees) that OpenCASCADE measures on the exported B-rep
    (export.check_continuity, docs/verification.md) over the edges between faces that share no sharp mesh
    edge: the G1 acceptance on the B-rep, with sharp edges told apart by the mesh's tags
    rather than by the size of the jump."""
    from export import check_continuity

    topo = Topology(mesh)
    sharp = features(topo).sharp
    pair_sharp: dict[tuple[int, int], bool] = {}
    h = np.flatnonzero(topo.twin >= 0)
    for f, g, s in zip(topo.face[h].tolist(), topo.face[topo.twin[h]].tolist(), sharp[topo.edge_of[h]].tolist()):
        key = (min(f, g), max(f, g))
        pair_sharp[key] = pair_sharp.get(key, False) or s
    report = check_continuity(surface, all_edges=True)
    jumps = [e.angle_deg for e in report.edges if not pair_sharp.get((min(e.faces), max(e.faces)), False)]
    return max(jumps, default=0.0)
