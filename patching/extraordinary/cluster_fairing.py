"""Joint G1 solve for clusters of extraordinary points joined by spokes (ours).

[FSLYJ] (section 3.4) sets the G1 unknowns EP by EP and spoke by spoke: red (spoke points,
face points, P^i[2,0]) nearest to the extraction under G_0, G_1 at one EP; black (P30) from the
fifth difference; green (A[k,1], B[1,k], k = 2, 3) nearest to the extraction under G_2, G_3.
Where two EPs share a spoke whose interval is short against its neighbours' while its
geometric length is not, this order folds the surface (measured, ``benchmarks/folds.py``):
G_0 at both ends fixes the spoke's legs short, the spoke curve then covers its length between
r_2 and r_3, and G_2, G_3 fix a weighted average of the cross rows A[k,1], B[1,k] that runs
backwards by more than half the edge whatever the green step chooses.  The red solves at the
two ends cannot see each other, so no per-EP rule removes it.

Here every cluster (a connected component, two EPs or more, of the graph of EP-EP spokes with
G1 conditions or a dart's free sharp spoke: ``ep_clusters``) takes all the coefficients those
steps would set, at every EP of the cluster, as the unknowns u of one problem:

    min_u  sum_f E(net_f)  +  mu |u - u_hat|^2      subject to  G_0..G_5 of every spoke,

    E(net) = integral over [0,1]^2 of |S_ss|^2 + 2 |S_st|^2 + |S_tt|^2   (thin plate),

f over the patches around the cluster's EPs (a hole has none), u_hat the unknowns' values
before this step (the degree-elevated extraction), mu = ``MU`` times the mean diagonal of the
energy's Hessian in u.  P00 (the anchors' vertex point, hence the limit point) and all other
coefficients are held.  Spokes to a regular vertex take G_0..G_3 and the fifth difference (the
black rule), spokes between two EPs G_0..G_5 written in the frame of the lower-numbered end
(both frames give the same conditions).  Sector EPs ([FSLYJ] sec. 4.2) as in the seed's
steps: a sharp spoke has no G1 condition and keeps the crease B-spline (its spoke points
held), a dart's one sharp spoke is free but for the fifth difference, and a boundary fan's
missing patch has no unknowns.  The energy is quadratic and the constraints linear in the
coefficients, so u = K s over the held rows s: a row mixing built from intervals and
connecting functions only (M never reads positions).  K's rows sum to 1 (constants satisfy the
constraints with zero energy and zero pull), so affine invariance holds.

The energy is the isotropic thin plate in patch parameters.  Measured against the
interval-weighted energy of ``anchor_fairing`` (x = delta s, y = eps t) on catmark_lefthanded:
the same fold counts within noise (34 against 37 folded patches over eight draws of ratio 20,
none over 21 draws of ratio 5 for both), so the simpler form is used.  mu: 0.1 (0.03 gave the
same folds, 0.2 and 0.5 more; 0.01 left folds at ratio 5).

Cost: one dense solve per cluster (QR of the constraints, null space, energy), and every
unknown row depends on every held row of the cluster, so M's rows there are as long as the
cluster's stencil.  Clusters above ``MAX_CLUSTER_EPS`` EPs or ``MAX_CLUSTER_FACES`` faces keep
the seed's per-EP steps.  On meshes refined once or more no two EPs are adjacent, and nothing
changes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from patching.util.graph import connected_components

from patching.extraordinary.anchor_fairing import thin_plate_matrices
from patching.extraordinary.g1_constraints import fifth_difference, spoke_equations
from patching.extraordinary.g1_patches import cache_key

if TYPE_CHECKING:
    from patching.extraordinary.g1_patches import EPGroup, G1Assembly, RowMixer
    from patching.topology.tables import Topology

__all__ = ["ep_clusters", "ClusterFairing", "MU", "MAX_CLUSTER_EPS", "MAX_CLUSTER_FACES"]

#: Weight of the pull towards the extraction, relative to the mean diagonal of the energy.
MU = 0.1
#: Largest cluster solved jointly, in EPs and in faces around them; larger ones keep the seed's
#: per-EP steps (module docstring).  Every unknown row (about 8 a face) depends on every held
#: row (36 a face), so a cluster of f faces puts about 300 f^2 weights into the step: 1.2M at
#: 64 faces.
MAX_CLUSTER_EPS = 16
MAX_CLUSTER_FACES = 64


def ep_clusters(groups: "list[EPGroup]", topo: "Topology", max_eps: int | None = None) -> list[np.ndarray]:
    """Clusters as (m, 2) arrays of (group index, row index), m >= 2: components of the graph
    of EP-EP spokes whose inner coefficients the solve sets from both ends: spokes with G1
    constraints, and a dart's sharp spoke (free but for the fifth difference) to another EP.
    Crease and boundary spokes (pinned) join nothing.  A component of more than ``max_eps``
    EPs (default ``MAX_CLUSTER_EPS``) or ``MAX_CLUSTER_FACES`` faces around them is left out:
    its EPs take the per-EP steps.

    Why darts join: the solve at each end of a dart spoke takes P10..P30 of its own frame as
    unknowns, so two clusters at its two ends would both set the middle rows (a row set twice
    sums its rules: row sums 2 on the cube with four parallel darts), and each would hold the
    other's end of the quartic condition at its value before the step."""
    max_eps = MAX_CLUSTER_EPS if max_eps is None else max_eps
    n_vertices = topo.n_vertices
    where = np.full((n_vertices, 2), -1, dtype=np.int64)
    for k, g in enumerate(groups):
        where[g.vertices, 0] = k
        where[g.vertices, 1] = np.arange(len(g.vertices))
    a, b = [], []
    for g in groups:
        far = np.where(g.unconstrained[None, :], -1, g.far)
        dart = g.unconstrained & ~g.pinned
        ends = topo.dest[g.h[:, dart]]
        far[:, dart] = np.where(where[ends, 0] >= 0, ends, -1)
        e, i = np.nonzero(far >= 0)
        a.append(g.vertices[e])
        b.append(far[e, i])
    a = np.concatenate(a) if a else np.zeros(0, np.int64)
    b = np.concatenate(b) if b else np.zeros(0, np.int64)
    graph = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(n_vertices, n_vertices))
    _, label = connected_components(graph, directed=False)
    is_ep = where[:, 0] >= 0
    labels, counts = np.unique(label[is_ep], return_counts=True)
    out = []
    for lab, count in zip(labels.tolist(), counts.tolist()):
        if count < 2 or count > max_eps:
            continue
        vs = np.flatnonzero(is_ep & (label == lab))
        members = where[vs]
        faces = np.concatenate([groups[k].faces[e] for k, e in members.tolist()])
        if np.unique(faces[faces >= 0]).size > MAX_CLUSTER_FACES:
            continue
        out.append(members)
    return out


class ClusterFairing:
    """The joint step for the clusters of a ``G1Assembly`` (module docstring)."""

    def __init__(self, g1: "G1Assembly", clusters: list[np.ndarray], has_patch: np.ndarray) -> None:
        """has_patch: (faces,) bool, the faces that give a patch (holes do not): only those
        count in the energy; a hole's rows are still read and set like any other."""
        self.g1 = g1
        self.clusters = clusters
        self.has_patch = has_patch
        # rows[k][e, i, j, m]: row of local (j, m) of patch i of EP e of group k
        self._rows = {}
        for k in {int(k) for c in clusters for k in c[:, 0]}:
            g = g1.groups[k]
            self._rows[k] = np.stack(
                [np.stack([np.stack([g1.rows(g, i, j, m) for m in range(6)], -1) for j in range(6)], -2) for i in range(g.n)],
                axis=1,
            )

    def members(self) -> list[np.ndarray]:
        """(E,) bool per group: the EPs that belong to a cluster."""
        inside = [np.zeros(len(g.vertices), dtype=bool) for g in self.g1.groups]
        for c in self.clusters:
            for k, e in c.tolist():
                inside[k][e] = True
        return inside

    def joint(self, mixer: "RowMixer") -> None:
        """Set every cluster's unknown rows: new rows = K @ held rows.  No row may be set by
        two clusters (RowMixer would add the two rules: row sums 2, a wrong surface), which
        ``ep_clusters`` ensures by joining EPs along every spoke both ends set; checked here."""
        owned = np.zeros(mixer.n_rows, dtype=bool)
        for c in self.clusters:
            targets, sources, weights = self.solve(c)
            if owned[targets].any():
                raise AssertionError(f"cluster_fairing: row {int(targets[owned[targets]][0])} is set by two clusters")
            owned[targets] = True
            mixer.set(targets, sources, weights)

    def solve(self, cluster: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(targets (T,), sources (S,), weights (T, S)) of one cluster."""
        g1 = self.g1
        unknown_rows, merges, faces, equations = [], [], [], []
        for k, e in cluster.tolist():
            g = g1.groups[k]
            r = self._rows[k][e]  # (n, 6, 6); patch g.gap (a boundary fan's missing one) unused
            before = np.roll(r, 1, axis=0)  # before[i] = patch i - 1
            present = np.arange(g.n) != g.gap
            pinned, free = g.pinned, ~g.unconstrained
            keys = g1.spoke_keys(k)[e]
            v = int(g.vertices[e])
            for i in range(g.n):
                a_side, b_side = present[i], present[i - 1]
                if a_side and b_side:  # spoke i's coefficients are rows of both patches beside it
                    merges.append(np.stack([r[i, :, 0], before[i, 0, :]], axis=1))
                if a_side:
                    faces.append(g.faces[e, i])
                    unknown_rows.append(r[i, 1:2, 1])  # the face point
                spoke = r[i, :, 0] if a_side else before[i, 0, :]
                if not pinned[i]:  # spoke points, P20, P30 (a crease keeps its B-spline)
                    unknown_rows.append(spoke[1:4])
                if not free[i]:
                    continue  # no G1 across a sharp spoke
                # A[2,1], A[3,1] and B[1,2], B[1,3] beside a smooth spoke (both patches exist)
                unknown_rows += [r[i, 2:4, 1], before[i, 1, 2:4]]
                far = int(g.far[e, i])
                if 0 <= far < v:
                    continue  # set once, from the lower-numbered end
                slots = np.concatenate([r[i, :, 0], r[i, :, 1], before[i, 1, :]])
                eq = spoke_equations(*cache_key(keys[i]))
                if far < 0:
                    fifth = np.concatenate([fifth_difference, np.zeros(12)])
                    eq = np.vstack([eq[:4], fifth])
                equations.append((slots, eq))
            for i in np.flatnonzero(~free & ~pinned & (g.far[e] < 0)):  # a dart's spoke: P30 by eq. 8's last row
                spoke = r[i, :, 0] if present[i] else before[i, 0, :]
                equations.append((spoke, fifth_difference[None, :]))
        faces = np.unique(np.asarray(faces, dtype=np.int64))
        face_rows = g1.face_row[faces][:, None] + np.arange(36)[None, :]
        unknown_rows = np.concatenate(unknown_rows)
        merges = np.concatenate(merges) if merges else np.zeros((0, 2), dtype=np.int64)
        slot_rows = np.concatenate([s for s, _ in equations] + [np.zeros(0, dtype=np.int64)])
        rows = np.unique(np.concatenate([face_rows.ravel(), unknown_rows, merges.ravel(), slot_rows]))

        def loc(r: np.ndarray) -> np.ndarray:  # row -> local index (rows is sorted and holds r)
            return np.searchsorted(rows, r)

        m = merges.shape[0]
        link = sp.coo_matrix((np.ones(m), (loc(merges[:, 0]), loc(merges[:, 1]))), shape=(rows.size, rows.size))
        _, comp = connected_components(link, directed=False)
        # columns: one per unknown component, then one per held row
        is_unknown = np.zeros(comp.max() + 1, dtype=bool)
        is_unknown[comp[loc(unknown_rows)]] = True
        unknown_comps = np.flatnonzero(is_unknown)
        nu = unknown_comps.size
        comp_column = np.full(comp.max() + 1, -1, dtype=np.int64)
        comp_column[unknown_comps] = np.arange(nu)
        held = np.flatnonzero(~is_unknown[comp])  # local rows that are sources
        column = comp_column[comp]
        column[held] = nu + np.arange(held.size)
        # an unknown's own value before the step: the first row of its component, as a source
        first_of_comp = np.unique(comp, return_index=True)[1]
        pull_rows = first_of_comp[unknown_comps]
        sources = np.concatenate([rows[held], rows[pull_rows]])
        ns = sources.size
        size = nu + ns
        pull_column = nu + held.size + np.arange(nu)
        # the thin-plate energy of every patch of the cluster (hole faces have no surface)
        iss, ist, itt = thin_plate_matrices(5)
        q = iss + 2.0 * ist + itt
        h = np.zeros((nu, size))  # the energy's rows of the unknowns: [H_uu | H_us]
        for cols in column[loc(face_rows[self.has_patch[faces]])]:
            mine = cols < nu
            h[np.ix_(cols[mine], cols)] += q[mine]
        c = np.zeros((sum(eq.shape[0] for _, eq in equations), size))
        at = 0
        for slots, eq in equations:
            np.add.at(c, (slice(at, at + eq.shape[0]), column[loc(slots)]), eq)
            at += eq.shape[0]
        return self._minimise(h, c, nu, pull_column, rows, column, sources)

    @staticmethod
    def _minimise(h, c, nu, pull_column, rows, column, sources):
        """u = K s minimising u^T H_uu u + 2 u^T H_us s + mu |u - s_pull|^2 under C_u u + C_s s = 0.

        Each equation is first scaled to unit norm: G_0..G_5 scale with the intervals squared
        (alpha = d_i d_{i-1}), the fifth difference does not, and the rank test below is
        relative, so intervals of 1e5 made it drop the fifth differences as dependent rows and
        intervals of 1e-6 the G_k (normal jumps of 10 and 100 degrees).  Pivoted QR of C_u^T
        (G_0 is rank deficient: the tangent plane): C_u^T[:, piv] = Q R, r its rank;
        u = Q_1 y + Z w with Z = Q[:, r:] the null space of C_u, y from the r independent
        equations (R_1^T y = -C_s[piv] s, triangular; the dependent ones hold since the per-EP
        steps show the system solvable for every s), and w minimising the energy on Z
        (positive definite there: mu > 0)."""
        import scipy.linalg as sla  # here: only clusters of EPs joined by spokes need it

        huu, hus = h[:, :nu], h[:, nu:]
        scale = float(np.mean(np.diag(huu)))
        mu = MU * scale if scale > 0.0 else 1.0  # every face a hole: nearest to the extraction
        ns = h.shape[1] - nu
        pull = np.zeros((nu, ns))
        pull[np.arange(nu), pull_column - nu] = 1.0
        norm = np.linalg.norm(c, axis=1, keepdims=True)
        c = c / np.where(norm > 0.0, norm, 1.0)
        cu, cs = c[:, :nu], c[:, nu:]
        q, r, piv = sla.qr(cu.T, pivoting=True)
        diag = np.abs(np.diag(r))
        rank = int(np.count_nonzero(diag > 1e-11 * diag.max()))
        y = sla.solve_triangular(r[:rank, :rank].T, -cs[piv[:rank]], lower=True)
        u0 = q[:, :rank] @ y
        z = q[:, rank:]
        a = huu + mu * np.eye(nu)
        w = np.linalg.solve(z.T @ a @ z, z.T @ (mu * pull - hus - a @ u0))
        k = u0 + z @ w
        k[np.abs(k) < 1e-15] = 0.0
        k[np.arange(nu), pull_column - nu] += 1.0 - k.sum(axis=1)  # rows sum to 1 exactly
        # every row of a solved component takes the component's solution
        members = np.flatnonzero(column < nu)
        targets = rows[members]
        return targets, sources, k[column[members]]
