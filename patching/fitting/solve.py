"""Control points by sparse least squares through M ([FSLYJ] sec. 4.1).

The surface point at foot point (p, s, t) is S = sum_ij B_i(s) B_j(t) c_{p,ij}, and the
coefficients are c = M P, so S_k = a_k^T P with a_k = M^T b_k, b_k the tensor Bernstein row of
the point: the fit is linear in the control points P (n, 3).  With data points x_k, weights
w_k and foot points held fixed, one step minimises

    sum_k w_k (S_k - x_k)^T Q_k (S_k - x_k)  +  lambda |L (P - P_prev)|^2

with Q_k = I (point distance, PDM) or a symmetric positive semi-definite 3 x 3 matrix per point
(the tangent distance TDM, Q = n n^T + alpha I, or the squared-distance model SDM with its
curvature terms, ``fit.distance_models``).  L is the umbrella Laplacian of the control mesh: a
fairing of the step rather than of the shape, so that the system is well posed (L^T L adds a
positive term on every direction that the data leave free) while the fixed point is the
unbiased least-squares solution, which is what lets a sampled nupatch surface be recovered
exactly.

Assembly (``LeastSquares``).  A patch's coefficients depend on a few control points only (its
support, at most some 30 on the meshes measured), so per patch p the local design matrix is
A_p = B_p M_p, B_p the Bernstein rows of the patch's points (k_p x (d+1)^2) and M_p the dense
rows of M of the patch restricted to its support ((d+1)^2 x s_p); the normal matrix is the sum
of the local products A_p^T diag(w Q_ab) A_p scattered into one sparse matrix whose pattern,
the union of the supports' squares and of L^T L, depends on the topology only.  So the
scatter map and the fill-reducing order are computed once per fit, and each step costs a few
batched dense products and one ``bincount``.  The points of a patch are padded to a power of
two (patches of similar point counts batched together, so padding wastes at most half).

Solving.  PDM: the n x n system with three right-hand sides by sparse LU (SuperLU in the
precomputed minimum-degree order with diagonal pivots: an LDL^T in effect; scipy has no sparse
Cholesky).  TDM and SDM couple the coordinates: the 3n x 3n system, unknowns interleaved per
control point (3 v + c).  Up to ``DIRECT_UNKNOWNS`` unknowns it is factored in the n x n order
expanded (exact steps, which the recovery of a sampled surface needs); larger systems by
conjugate gradients for the step P - P_prev (the 3n factor costs some 25 n x n ones, ~6 s a
step on the benchmark), to ``CG_TOLERANCE`` of the residual at the previous points or
``CG_ITERATIONS`` steps.  Preconditioners (``LeastSquares.preconditioner``): "frame" (the
default, ``_frame_preconditioner``) splits each control point's displacement into the normal
of its diagonal 3 x 3 block and the tangent plane and factors one n x n matrix for each part
(exact when every point has the same Q, tested), since the normal and tangential stiffness
differ by up to 1 / alpha and the tangential one is mostly the fairing's bi-Laplacian; "scaled"
(``_scaled_preconditioner``) is one n x n factor of the point-distance matrix scaled per
control point by the diagonal blocks.  At alpha <= 1e-5 neither reaches 1e-4 in 200 steps
(the frame one 2e-3 to 4e-3 of the residual, the scaled one 3e-3 to 2e-2); the cap is 100
because the error per alternation does not follow the step's precision (with exact steps,
the 3n factor, the first SDM steps lowered E by the same fractions, 0.363, 0.412, 0.445, 0.395).
CG starts from the best multiple of the previous alternation's step (``guess``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, cg, splu

from ..bernstein import bernstein
from .projection import FootPoints, PatchLayout

__all__ = ["umbrella_laplacian", "LeastSquares", "principal_curvatures", "distance_model"]

#: Coupled (TDM, SDM) systems of at most this many unknowns are solved by their 3n factor.
DIRECT_UNKNOWNS = 3000
#: Larger ones by conjugate gradients for the step: tolerance relative to the residual at the
#: previous points, most iterations (``LeastSquares.solve``).  An inexact step is safe: the
#: alternation keeps a step only if the error falls.
CG_TOLERANCE, CG_ITERATIONS = 1e-4, 100


def umbrella_laplacian(n_vertices: int, edges: np.ndarray) -> sp.csr_matrix:
    """(n, n) L = I - D^-1 A over the control mesh's edges (e, 2)."""
    a, b = edges[:, 0], edges[:, 1]
    adj = sp.coo_matrix((np.ones(2 * a.size), (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(n_vertices,) * 2).tocsr()
    adj.data[:] = 1.0
    deg = np.asarray(adj.sum(axis=1)).ravel()
    return (sp.identity(n_vertices, format="csr") - sp.diags(1.0 / np.maximum(deg, 1.0)) @ adj).tocsr()


def _factor(matrix: sp.spmatrix):
    """SuperLU of an SPD matrix already in its fill-reducing order: natural column order,
    diagonal pivots, symmetric mode."""
    return splu(sp.csc_matrix(matrix), permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})


class LeastSquares:
    """The least-squares steps of one fit (module docstring): built once from M, the patch
    layout and L (topology only), then ``solve`` per alternation."""

    def __init__(self, matrix: sp.csr_matrix, layout: PatchLayout, laplacian: sp.csr_matrix):
        self.layout = layout
        self.n = n = matrix.shape[1]
        matrix = matrix.tocsr()
        self.groups = {}
        keys = []
        for d in layout.degrees:
            q = (d + 1) ** 2
            patches = np.flatnonzero(layout.degree == d)
            # the nonzeros of the patches' (d+1)^2 rows of M, as (patch, row, column, value)
            rows = (layout.row[patches][:, None] + np.arange(q)[None, :]).ravel()
            lengths = matrix.indptr[rows + 1] - matrix.indptr[rows]
            entry = np.repeat(matrix.indptr[rows], lengths) + np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths)
            owner = np.repeat(np.arange(rows.size), lengths)
            gp, local_row, col = owner // q, owner % q, matrix.indices[entry]
            key = np.unique(gp * n + col)  # each patch's support, sorted
            kp = key // n
            count = np.bincount(kp, minlength=patches.size)
            s = max(1, int(count.max()))
            start = np.cumsum(count) - count
            support = np.zeros((patches.size, s), dtype=np.int64)
            slot = np.arange(key.size) - start[kp]
            support[kp, slot] = key % n
            # padding: repeat the first support column (its M_p column stays zero)
            pad = np.arange(s)[None, :] >= count[:, None]
            support[pad] = np.broadcast_to(support[:, :1], support.shape)[pad]
            local = np.zeros((patches.size, q, s))
            local[gp, local_row, np.searchsorted(key, gp * n + col) - start[gp]] = matrix.data[entry]
            self.groups[d] = (patches, support, local)
            keys.append((support[:, :, None] * n + support[:, None, :]).ravel())
        self.ltl = (laplacian.T @ laplacian).tocoo()
        keys.append(self.ltl.row.astype(np.int64) * n + self.ltl.col)
        unique, inverse = np.unique(np.concatenate(keys), return_inverse=True)
        rows, cols = unique // n, unique % n
        self.pattern = sp.csr_matrix((np.zeros(unique.size), cols, np.searchsorted(rows, np.arange(n + 1))), shape=(n, n))
        self.nnz = unique.size
        # scatter maps: each group's (P, s, s) local entries and L^T L's entries -> data index
        self.maps, start = {}, 0
        for d in layout.degrees:
            size = keys[len(self.maps)].size
            self.maps[d] = inverse[start : start + size]
            start += size
        self.ltl_map = inverse[start:]
        self.ltl_trace = float(self.ltl.diagonal().mean())
        self.diag = np.searchsorted(unique, np.arange(n, dtype=np.int64) * (n + 1))  # (v, v) entries
        self.preconditioner = "frame"  # or "scaled" (module docstring)
        # the same pattern with 3 x 3 blocks, unknowns interleaved (3 v + c): entry k of row i
        # (in-row offset o, row length r) -> 9 indptr[i] + 3 a r + 3 o + b for block (a, b)
        indptr = self.pattern.indptr
        rowlen = np.diff(indptr)
        row_of = self.row_of = np.repeat(np.arange(n), rowlen)
        offset = np.arange(self.nnz) - indptr[row_of]
        ab = np.arange(3)
        self.map3 = (9 * indptr[row_of][:, None, None] + 3 * ab[None, :, None] * rowlen[row_of][:, None, None]
                     + 3 * offset[:, None, None] + ab[None, None, :])  # (nnz, 3, 3)
        indptr3 = np.empty(3 * n + 1, dtype=np.int64)
        indptr3[0] = 0
        indptr3[1:] = 9 * indptr[np.repeat(np.arange(n), 3)] + 3 * rowlen.repeat(3) * np.tile(ab + 1, n)
        indices3 = np.empty(9 * self.nnz, dtype=np.int64)
        indices3[self.map3.ravel()] = (3 * self.pattern.indices[:, None, None] + ab[None, None, :] + 0 * ab[None, :, None]).ravel()
        self.indptr3, self.indices3 = indptr3, indices3
        self.order = None  # the n x n fill-reducing order, from the first system
        self.factors = 0
        self.cg_iterations = 0
        self.cg_log: list[tuple[int, float]] = []  # (iterations, relative residual) per CG solve
        self.cg_tolerance = CG_TOLERANCE
        self.warm = True

    # -- assembly -------------------------------------------------------------------------

    def _local(self, feet: FootPoints):
        """Per degree and point-count class: (group patch ids (P,), point ids (P, L), -1
        padded, design matrices A (P, L, s))."""
        out = []
        for d, (patches, support, local) in self.groups.items():
            sel = np.flatnonzero(self.layout.degree[feet.patch] == d)
            if sel.size == 0:
                continue
            gpatch = np.searchsorted(patches, feet.patch[sel])
            order = np.argsort(gpatch, kind="stable")
            sel, gpatch = sel[order], gpatch[order]
            uniq, first, count = np.unique(gpatch, return_index=True, return_counts=True)
            width = 1 << np.ceil(np.log2(count)).astype(np.int64)
            for w in np.unique(width):
                cls = np.flatnonzero(width == w)
                ids = np.full((cls.size, int(w)), -1, dtype=np.int64)
                pos = np.arange(int(w))[None, :]
                inside = pos < count[cls][:, None]
                ids[inside] = sel[(first[cls][:, None] + pos)[inside]]
                bs = bernstein(d, feet.s[np.maximum(ids, 0)].ravel())
                bt = bernstein(d, feet.t[np.maximum(ids, 0)].ravel())
                rows = (bs[:, :, None] * bt[:, None, :]).reshape(cls.size, int(w), -1)
                rows[~inside] = 0.0
                out.append((d, uniq[cls], ids, np.matmul(rows, local[uniq[cls]])))
        return out

    def _ordered(self, pdm: sp.csr_matrix) -> None:
        if self.order is None:
            # SuperLU factors Pr A Pc with Pc[i, perm_c[i]] = 1: the new order is perm_c's inverse
            perm = splu(sp.csc_matrix(pdm), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                        options={"SymmetricMode": True}).perm_c
            self.order = np.argsort(perm)

    def solve(self, feet: FootPoints, data: np.ndarray, weights: np.ndarray, previous: np.ndarray,
              fairing: float, quadratic: np.ndarray | None = None, guess: np.ndarray | None = None) -> np.ndarray:
        """New control points (n, 3).  ``quadratic``: None for PDM, else (m, 3, 3) symmetric
        Q_k (module docstring).  ``guess``: (n, 3), a direction for the step (the previous
        alternation's): CG starts from its best multiple (module docstring)."""
        n = self.n
        parts = self._local(feet)
        data1 = np.zeros(self.nnz)
        rhs = np.zeros((n, 3))
        wx = weights[:, None] * (data if quadratic is None else np.einsum("kab,kb->ka", quadratic, data))
        for d, gp, ids, a in parts:
            w = np.where(ids >= 0, weights[np.maximum(ids, 0)], 0.0)
            block = np.matmul(a.transpose(0, 2, 1), a * w[:, :, None])
            data1 += np.bincount(self.maps[d].reshape(-1, *block.shape[1:])[gp].ravel(), weights=block.ravel(), minlength=self.nnz)
            r = np.matmul(a.transpose(0, 2, 1), np.where((ids >= 0)[:, :, None], wx[np.maximum(ids, 0)], 0.0))
            sup = 3 * self.groups[d][1][gp][:, :, None] + np.arange(3)[None, None, :]
            rhs += np.bincount(sup.ravel(), weights=r.ravel(), minlength=3 * n).reshape(n, 3)
        pdm = sp.csr_matrix((data1, self.pattern.indices, self.pattern.indptr), shape=(n, n))
        self._ordered(pdm)
        ltl = np.bincount(self.ltl_map, weights=self.ltl.data, minlength=self.nnz)
        lam = fairing * pdm.diagonal().mean() / max(self.ltl_trace, 1e-300)
        fair_rhs = lam * (self.ltl.tocsr() @ previous)
        if quadratic is None:
            system = sp.csr_matrix((data1 + lam * ltl, self.pattern.indices, self.pattern.indptr), shape=(n, n))
            o = self.order
            lu = _factor(system[o][:, o])
            out = np.empty((n, 3))
            out[o] = previous[o] + lu.solve(rhs[o] + fair_rhs[o] - system[o] @ previous)
            return out
        # 3n system: blocks (a, b) = sum_k w_k Q_k,ab a_k a_k^T, the six distinct ones
        # assembled on the n x n pattern, then placed in the interleaved 3n pattern
        pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
        blocks6 = np.zeros((6, self.nnz))
        for d, gp, ids, a in parts:
            safe = np.maximum(ids, 0)
            wq = np.stack([quadratic[safe, i, j] for i, j in pairs], axis=-1) * np.where(ids >= 0, weights[safe], 0.0)[:, :, None]
            s = a.shape[2]
            weighted = (a[:, :, None, :] * wq[:, :, :, None]).reshape(a.shape[0], a.shape[1], 6 * s)
            block = np.matmul(a.transpose(0, 2, 1), weighted).reshape(a.shape[0], s, 6, s)
            idx = self.maps[d].reshape(-1, s, s)[gp][:, :, None, :] + self.nnz * np.arange(6)[None, None, :, None]
            blocks6 += np.bincount(idx.ravel(), weights=block.ravel(), minlength=6 * self.nnz).reshape(6, self.nnz)
        data3 = np.zeros(9 * self.nnz)
        for k, (i, j) in enumerate(pairs):
            data3[self.map3[:, i, j]] = blocks6[k] + (lam * ltl if i == j else 0.0)
            data3[self.map3[:, j, i]] = blocks6[k] + (lam * ltl if i == j else 0.0)
        system = sp.csr_matrix((data3, self.indices3, self.indptr3), shape=(3 * n, 3 * n))
        # Conjugate gradients for the step from the previous points (the residual, not the
        # right-hand side, sets the relative tolerance, so the step keeps its precision as the
        # fit converges), preconditioned by n x n factors in the fixed order (module docstring)
        # instead of the 3n factor.
        x_prev = previous.ravel()
        residual = (rhs + fair_rhs).ravel() - system @ x_prev
        if 3 * n <= DIRECT_UNKNOWNS:  # small: the exact step by the 3n factor
            o3 = (3 * self.order[:, None] + np.arange(3)[None, :]).ravel()
            step = np.empty(3 * n)
            step[o3] = _factor(system[o3][:, o3]).solve(residual[o3])
            self.factors += 1
            return (x_prev + step).reshape(n, 3)
        o = self.order
        if self.preconditioner == "frame":
            precondition = self._frame_preconditioner(data3)
        else:
            precondition = self._scaled_preconditioner(data1 + lam * ltl, data3)
        steps = [0]

        def count(_):
            steps[0] += 1

        pre = LinearOperator(system.shape, matvec=precondition)
        start = None
        if guess is not None and self.warm:
            # the multiple c d of the direction d that minimises the quadratic (Galerkin on d):
            # never worse than the zero start in the system's norm
            d = np.asarray(guess, dtype=np.float64).ravel()
            curvature = float(d @ (system @ d))
            if curvature > 0.0:
                start = (float(d @ residual) / curvature) * d
        x, _ = cg(system, residual, x0=start, rtol=self.cg_tolerance, maxiter=CG_ITERATIONS, M=pre, callback=count)
        self.cg_iterations += steps[0]
        self.cg_log.append((steps[0], float(np.linalg.norm(system @ x - residual) / max(np.linalg.norm(residual), 1e-300))))
        return (x_prev + x).reshape(n, 3)

    def _scaled_preconditioner(self, base: np.ndarray, data3: np.ndarray):
        """B^1/2 (K (x) I3) B^1/2 with K the point-distance matrix plus the fairing (``base``,
        on the n x n pattern) and B_v the 3n system's diagonal 3 x 3 block at control point v
        over K_vv: it matches the diagonal blocks exactly (the normal stiffness and the small
        tangential one, alpha plus SDM's curvature terms) and K's coupling between control
        points.  Returns r -> z."""
        n, o = self.n, self.order
        blocks = data3[self.map3[self.diag]]  # (n, 3, 3)
        value, vector = np.linalg.eigh(blocks / base[self.diag][:, None, None])
        scale = np.einsum("nij,nj,nkj->nik", vector, 1.0 / np.sqrt(np.maximum(value, 1e-300)), vector)
        lu = _factor(sp.csr_matrix((base, self.pattern.indices, self.pattern.indptr), shape=(n, n))[o][:, o])
        self.factors += 1

        def precondition(r):
            r = np.einsum("nij,nj->ni", scale, np.asarray(r).reshape(n, 3))
            z = np.empty((n, 3))
            z[o] = lu.solve(np.ascontiguousarray(r[o]))
            return np.einsum("nij,nj->ni", scale, z).ravel()

        return precondition

    def _frame_preconditioner(self, data3: np.ndarray):
        """Normal and tangential parts apart: n_v the unit eigenvector of the largest eigenvalue
        of the 3n system's diagonal block at control point v (near the surface normal), P_v =
        I - n_v n_v^T, and two n x n matrices from the blocks A_uv: N_uv = n_u^T A_uv n_v and
        T_uv = trace(P_u A_uv P_v) / 2.  The preconditioner z = n (N^-1 (n . r)) + P ((T^-1
        (x) I3) (P r)) is SPD (a sum of two semi-definite parts that together span every
        direction) and does not depend on how the tangent plane is parametrised.  Normal and
        tangential stiffness differ by up to 1 / alpha, and the tangential one is the data's
        small share plus the fairing's bi-Laplacian, whose spectrum the point-distance matrix
        the ``scaled`` preconditioner uses does not follow.  Returns r -> z."""
        n, o = self.n, self.order
        blocks = data3[self.map3]  # (nnz, 3, 3)
        normal = np.linalg.eigh(blocks[self.diag])[1][:, :, 2]  # (n, 3)
        rows, cols = self.row_of, self.pattern.indices
        nu, nv = normal[rows], normal[cols]
        an = np.einsum("kij,kj->ki", blocks, nv)  # A_uv n_v
        n_data = np.einsum("ki,ki->k", nu, an)
        # trace(P_u A P_v) = tr A - n_u.A n_u... expanded: tr A - n_v.A n_v... (P = I - n n^T)
        ua = np.einsum("ki,kij->kj", nu, blocks)  # n_u^T A_uv
        t_data = 0.5 * (np.einsum("kii->k", blocks) - np.einsum("kj,kj->k", ua, nu) - np.einsum("ki,ki->k", an, nv)
                        + np.einsum("ki,ki->k", nu, nv) * n_data)
        shape = (n, n)
        lu_n = _factor(sp.csr_matrix((n_data, self.pattern.indices, self.pattern.indptr), shape=shape)[o][:, o])
        lu_t = _factor(sp.csr_matrix((t_data, self.pattern.indices, self.pattern.indptr), shape=shape)[o][:, o])
        self.factors += 2

        def precondition(r):
            r = np.asarray(r).reshape(n, 3)
            along = np.einsum("ni,ni->n", normal, r)
            tangential = r - along[:, None] * normal
            zn, zt = np.empty(n), np.empty((n, 3))
            zn[o] = lu_n.solve(np.ascontiguousarray(along[o]))
            zt[o] = lu_t.solve(np.ascontiguousarray(tangential[o]))
            zt -= np.einsum("ni,ni->n", normal, zt)[:, None] * normal
            return (zn[:, None] * normal + zt).ravel()

        return precondition


def principal_curvatures(su: np.ndarray, sv: np.ndarray, suu: np.ndarray, suv: np.ndarray, svv: np.ndarray):
    """Unit normal n = S_s x S_t / |.|, principal curvatures (m, 2) and unit principal
    directions (m, 2, 3) from the first and second derivatives.  Curvature kappa > 0 where the
    surface bends towards n (the centre of curvature at S + n / kappa).  In the orthonormal
    tangent frame (t1 = S_s / |S_s|, t2 = n x t1) with J the 2 x 2 coordinates of (S_s, S_t),
    the shape operator is J^-T II J^-1, II = [[S_ss.n, S_st.n], [S_st.n, S_tt.n]]: symmetric,
    so ``eigh`` gives the principal pairs."""
    n = np.cross(su, sv)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    t1 = su / np.maximum(np.linalg.norm(su, axis=1, keepdims=True), 1e-300)
    t2 = np.cross(n, t1)
    jac = np.zeros((su.shape[0], 2, 2))
    jac[:, 0, 0] = np.einsum("ij,ij->i", su, t1)
    jac[:, 0, 1] = np.einsum("ij,ij->i", sv, t1)
    jac[:, 1, 1] = np.einsum("ij,ij->i", sv, t2)
    second = np.empty((su.shape[0], 2, 2))
    second[:, 0, 0] = np.einsum("ij,ij->i", suu, n)
    second[:, 0, 1] = second[:, 1, 0] = np.einsum("ij,ij->i", suv, n)
    second[:, 1, 1] = np.einsum("ij,ij->i", svv, n)
    det = jac[:, 0, 0] * jac[:, 1, 1]
    det = np.where(np.abs(det) > 1e-300, det, 1e-300)
    inv = np.zeros_like(jac)  # J is upper triangular
    inv[:, 0, 0] = jac[:, 1, 1] / det
    inv[:, 0, 1] = -jac[:, 0, 1] / det
    inv[:, 1, 1] = jac[:, 0, 0] / det
    shape = np.matmul(inv.transpose(0, 2, 1), np.matmul(second, inv))
    shape = 0.5 * (shape + shape.transpose(0, 2, 1))
    kappa, vec = np.linalg.eigh(shape)
    directions = vec[:, 0, :, None] * t1[:, None, :] + vec[:, 1, :, None] * t2[:, None, :]
    return n, kappa, directions


def distance_model(method: str, surface_points: np.ndarray, derivatives: tuple, data: np.ndarray,
                   alpha: float, point_distance: np.ndarray | None = None) -> np.ndarray:
    """(m, 3, 3) Q_k of the squared-distance model at each foot point:

    TDM: Q = n n^T + alpha I (the tangent distance; alpha a Levenberg-Marquardt-like share of
    the point distance that bounds the tangential motion).
    SDM ([PLH02], [FSLYJ]'s [31]; the curvature-based form and safeguard of [WPL06]):
    the second-order approximation of the squared distance to the surface near the foot point,
    Q = n n^T + sum_i c_i e_i e_i^T + alpha I with the principal directions e_i, curvatures
    kappa_i and the signed distance d = (x - S).n: c_i = d kappa_i / (d kappa_i - 1), i.e.
    d / (d - rho_i) with rho_i = 1 / kappa_i the signed radius, where d kappa_i < 0 (the point
    on the side away from the centre of curvature); c_i = 0 otherwise (the safeguard for points
    between the surface and the centre or beyond it, where the model is not convex: the tangent
    distance there).  Reconstructed from the squared distance (r - R)^2 to a circle of radius R:
    at distance r from the centre half its Hessian has the tangential part (r - R) / r, and
    r = R - d gives d / (d - R); checked in the tests against central differences of the exact
    squared distance to a sphere, outside (equal) and inside (the safeguard).
    Rows of ``point_distance`` (points held to the open boundary) keep Q = I."""
    su, sv = derivatives[0], derivatives[1]
    if method == "tdm":
        n = np.cross(su, sv)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        q = n[:, :, None] * n[:, None, :]
    elif method == "sdm":
        n, kappa, e = principal_curvatures(*derivatives)
        d = np.einsum("ij,ij->i", data - surface_points, n)
        dk = d[:, None] * kappa
        c = np.where(dk < 0.0, dk / (dk - 1.0), 0.0)
        q = n[:, :, None] * n[:, None, :] + np.einsum("mi,mia,mib->mab", c, e, e)
    else:
        raise ValueError(f"method must be 'tdm' or 'sdm', not {method!r}")
    q = q + alpha * np.eye(3)[None]
    if point_distance is not None:
        q[np.asarray(point_distance, dtype=bool)] = np.eye(3)
    return q
