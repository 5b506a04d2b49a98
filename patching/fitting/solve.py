"""Control points by sparse least squares through M ([FSLYJ] sec. 4.1).

The surface point at foot point (p, s, t) is S = sum_ij B_i(s) B_j(t) c_{p,ij}, and the
coefficients are c = M P, so S = a^T P with a = M^T b, b the tensor Bernstein row of the
point: the fit is linear in the control points P (n, 3).  With data points x_k, weights w_k
and foot points held fixed, one step minimises

    point distance (PDM):    sum_k w_k |S_k - x_k|^2
    tangent distance (TDM):  sum_k w_k (S_k - x_k)^T Q_k (S_k - x_k),  Q_k = n_k n_k^T + alpha I

(n_k the unit surface normal at the foot point: the tangent-distance approximation of SDM,
[PLH02]; alpha keeps a little of the point distance so the tangential motion stays bounded;
the input's boundary vertices, held on the surface's boundary curves, keep Q_k = I)
plus lambda |L (P - P_prev)|^2, L the umbrella Laplacian of the control mesh: a fairing of
the step rather than of the shape, so that the system is well posed (L^T L adds a positive
term on every direction that the data leave free) while the fixed point is the unbiased least
squares solution, which is what lets a sampled nupatch surface be recovered exactly.

The normal matrix is assembled as M^T G M with G the block-diagonal Gram matrix of the
Bernstein rows per patch ((d+1)^2 blocks, summed over the points of each patch in chunks), so
no (points x control points) matrix is formed; it is solved by sparse LU with a symmetric order (``_spd_solve``), the large TDM
systems by conjugate gradients preconditioned with the n x n point-distance factor.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, cg, splu

from .projection import FootPoints, PatchLayout, evaluate

__all__ = ["umbrella_laplacian", "bernstein_rows", "gram_blocks", "solve_step"]

#: TDM systems (3 n unknowns) above this size are solved by preconditioned CG (``solve_step``).
DIRECT_UNKNOWNS = 3000
CG_TOLERANCE, CG_ITERATIONS = 1e-8, 300


def _spd_solve(matrix: sp.spmatrix, rhs: np.ndarray) -> np.ndarray:
    """Solve the symmetric positive definite system by sparse LU with a symmetric
    fill-reducing order (minimum degree on A + A^T) and diagonal pivots.  (Plain
    Jacobi-preconditioned CG was tried for large systems: with the small step fairing the
    system is ill-conditioned along the surface, and it took 4x longer than LU on the
    100k-triangle benchmark; ``solve_step`` preconditions the large TDM systems better.)"""
    lu = splu(sp.csc_matrix(matrix), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return lu.solve(np.asarray(rhs, dtype=np.float64))


def umbrella_laplacian(n_vertices: int, edges: np.ndarray) -> sp.csr_matrix:
    """(n, n) L = I - D^-1 A over the control mesh's edges (e, 2)."""
    a, b = edges[:, 0], edges[:, 1]
    adj = sp.coo_matrix((np.ones(2 * a.size), (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(n_vertices,) * 2).tocsr()
    adj.data[:] = 1.0
    deg = np.asarray(adj.sum(axis=1)).ravel()
    return (sp.identity(n_vertices, format="csr") - sp.diags(1.0 / np.maximum(deg, 1.0)) @ adj).tocsr()


def bernstein_rows(layout: PatchLayout, feet: FootPoints, d: int) -> tuple[np.ndarray, np.ndarray]:
    """(points of degree-d patches (k,), their tensor Bernstein rows (k, (d+1)^2))."""
    from ..bernstein import bernstein

    sel = np.flatnonzero(layout.degree[feet.patch] == d)
    bs, bt = bernstein(d, feet.s[sel]), bernstein(d, feet.t[sel])
    return sel, (bs[:, :, None] * bt[:, None, :]).reshape(sel.size, -1)


def gram_blocks(layout: PatchLayout, feet: FootPoints, weights: list[np.ndarray], n_rows: int) -> list[sp.csr_matrix]:
    """For each weight vector w (m,): the (rows, rows) block-diagonal G = B^T diag(w) B, one
    (d+1)^2 block per patch, as batched products of the patches' point rows (zero-padded to
    the largest point count of a patch)."""
    out = [sp.csr_matrix((n_rows, n_rows)) for _ in weights]
    for d in layout.degrees:
        sel, rows = bernstein_rows(layout, feet, d)
        if sel.size == 0:
            continue
        q = (d + 1) ** 2
        patches = feet.patch[sel]
        order = np.argsort(patches, kind="stable")
        sel, rows, patches = sel[order], rows[order], patches[order]
        uniq, first, count = np.unique(patches, return_index=True, return_counts=True)
        local = np.repeat(np.arange(uniq.size), count)
        pos = np.arange(sel.size) - np.repeat(first, count)
        idx = layout.row[uniq][:, None] + np.arange(q)[None, :]
        ii = np.repeat(idx, q, axis=1).ravel()
        jj = np.tile(idx, (1, q)).ravel()
        padded = np.zeros((uniq.size, int(count.max()), q))
        padded[local, pos] = rows
        for k, w in enumerate(weights):
            wpad = np.zeros(padded.shape[:2])
            wpad[local, pos] = w[sel]
            blocks = np.matmul(padded.transpose(0, 2, 1), padded * wpad[:, :, None])
            out[k] = out[k] + sp.csr_matrix((blocks.ravel(), (ii, jj)), shape=(n_rows, n_rows))
    return out


def _bt_times(layout: PatchLayout, feet: FootPoints, values: np.ndarray, n_rows: int) -> np.ndarray:
    """B^T values: (rows, c) for values (m, c)."""
    out = np.zeros((n_rows, values.shape[1]))
    for d in layout.degrees:
        sel, rows = bernstein_rows(layout, feet, d)
        if sel.size == 0:
            continue
        idx = layout.row[feet.patch[sel]][:, None] + np.arange((d + 1) ** 2)[None, :]
        for c in range(values.shape[1]):
            out[:, c] += np.bincount(idx.ravel(), weights=(rows * values[sel, c][:, None]).ravel(), minlength=n_rows)
    return out


def solve_step(
    matrix: sp.csr_matrix,
    layout: PatchLayout,
    feet: FootPoints,
    data: np.ndarray,
    weights: np.ndarray,
    previous: np.ndarray,
    laplacian: sp.csr_matrix,
    fairing: float,
    method: str = "pdm",
    alpha: float = 1e-7,
    point_distance: np.ndarray | None = None,
) -> np.ndarray:
    """New control points (n, 3) for fixed foot points (module docstring)."""
    n_rows, n = matrix.shape
    mt = matrix.T.tocsr()
    ltl = (laplacian.T @ laplacian).tocsr()
    if method == "pdm":
        (g,) = gram_blocks(layout, feet, [weights], n_rows)
        normal = (mt @ g @ matrix).tocsr()
        lam = fairing * normal.diagonal().mean() / max(ltl.diagonal().mean(), 1e-300)
        rhs = mt @ _bt_times(layout, feet, weights[:, None] * data, n_rows) + lam * (ltl @ previous)
        return _spd_solve(normal + lam * ltl, rhs).reshape(n, 3)
    if method != "tdm":
        raise ValueError(f"method must be 'pdm' or 'tdm', not {method!r}")
    coefficients = matrix @ previous
    _, su, sv = evaluate(layout, coefficients, feet.patch, feet.s, feet.t, order=1)
    nrm = np.cross(su, sv)
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    # Points held to the open boundary (``point_distance``: the input's boundary vertices,
    # their feet on the surface's boundary curves) keep the point distance, Q = I: their
    # residual runs along the surface, which the tangent distance would ignore.
    off = np.zeros(feet.patch.size, dtype=bool) if point_distance is None else np.asarray(point_distance, dtype=bool)
    iso = np.where(off, 1.0, alpha)
    pairs = [(a, b) for a in range(3) for b in range(a, 3)]
    ws = [weights * nrm[:, a] * nrm[:, b] for a, b in pairs] + [weights * iso]
    grams = gram_blocks(layout, feet, ws, n_rows)
    iso_block = mt @ grams[-1] @ matrix
    blocks = [[None] * 3 for _ in range(3)]
    for (a, b), g in zip(pairs, grams[:-1]):
        block = mt @ g @ matrix
        if a == b:
            block = block + iso_block
        blocks[a][b] = block
        blocks[b][a] = block if a == b else block
    normal = sp.bmat(blocks, format="csr")
    lam = fairing * normal.diagonal().mean() / max(ltl.diagonal().mean(), 1e-300)
    qx = weights[:, None] * (nrm * np.einsum("ij,ij->i", nrm, data)[:, None] + iso[:, None] * data)
    rhs = (mt @ _bt_times(layout, feet, qx, n_rows)).T.ravel()
    fair = sp.block_diag([ltl] * 3, format="csr")
    rhs = rhs + lam * (fair @ previous.T.ravel())
    system = normal + lam * fair
    if system.shape[0] <= DIRECT_UNKNOWNS:
        solution = _spd_solve(system, rhs)
    else:
        # Large: conjugate gradients from the previous points, preconditioned by the
        # coordinate-blind matrix K (x) I3, K the mean of the three diagonal blocks: one LU of
        # size n instead of 3n (whose fill made it 20x dearer).  T <= (1 + alpha) K-ish and
        # T >= alpha K-ish, so CG needs some sqrt(1/alpha) steps; stopped early it still lowers
        # the step's objective, and the alternation keeps a TDM step only if E falls.
        k = ((blocks[0][0] + blocks[1][1] + blocks[2][2]) / 3.0 + lam * ltl).tocsc()
        lu = splu(k, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        pre = LinearOperator(system.shape, matvec=lambda r: lu.solve(np.asarray(r).reshape(3, n).T).T.ravel())
        solution, _ = cg(system, rhs, x0=previous.T.ravel(), rtol=CG_TOLERANCE, maxiter=CG_ITERATIONS, M=pre)
    return np.asarray(solution).reshape(3, n).T.copy()
