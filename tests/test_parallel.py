"""Row-block parallel products (``patching.util.parallel``) are the plain products, bit for bit."""

import numpy as np
import pytest
import scipy.sparse as sp

from patching.util import parallel


def random_csr(rows: int, cols: int, per_row: int, seed: int, empty_rows: int = 0) -> sp.csr_matrix:
    rng = np.random.default_rng(seed)
    r = np.repeat(np.arange(rows), per_row)
    c = rng.integers(0, cols, r.size)
    a = sp.csr_matrix((rng.normal(size=r.size), (r, c)), shape=(rows, cols))
    if empty_rows:
        keep = np.ones(rows)
        keep[rng.choice(rows, empty_rows, replace=False)] = 0.0
        a = (sp.diags(keep) @ a).tocsr()
        a.eliminate_zeros()
    return a


@pytest.fixture
def split_everything(monkeypatch):
    monkeypatch.setattr(parallel, "MIN_SPLIT_NNZ", 0)
    monkeypatch.setattr(parallel, "_workers", lambda: 3)
    monkeypatch.setattr(parallel, "_POOL", None)


@pytest.mark.parametrize("seed", range(4))
def test_sparse_times_sparse_is_the_plain_product(split_everything, seed):
    a = random_csr(500, 300, 7, seed, empty_rows=40)
    b = random_csr(300, 200, 5, seed + 10)
    plain, split = (a @ b).tocsr(), parallel.product(a, b)
    assert split.shape == plain.shape
    for name in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(split, name), getattr(plain, name))


@pytest.mark.parametrize("seed", range(4))
def test_sparse_times_points_is_the_plain_product(split_everything, seed):
    a = random_csr(700, 400, 9, seed, empty_rows=seed * 30)
    points = np.random.default_rng(seed).normal(size=(400, 3))
    np.testing.assert_array_equal(parallel.product(a, points), a @ points)


def test_blocks_cover_the_rows_once_with_balanced_work():
    a = random_csr(1000, 50, 4, 0)
    ranges = parallel.row_blocks(a, 4)
    assert ranges[0][0] == 0 and ranges[-1][1] == a.shape[0]
    assert all(r1 == r0 for (_, r1), (r0, _) in zip(ranges[:-1], ranges[1:]))
    work = [a.indptr[r1] - a.indptr[r0] for r0, r1 in ranges]
    assert max(work) - min(work) <= 2 * 4


@pytest.mark.parametrize("r0, r1", [(0, 100), (100, 900), (450, 1000), (0, 1000), (300, 300)])
def test_row_blocks_are_views_of_the_rows(r0, r1):
    """A block is rows r0..r1-1 of A with A's own data and indices (a copy of a block under half
    of A, which scipy's constructor makes, was ~50 MB of fresh pages in the operator's product)."""
    a = random_csr(1000, 60, 5, 1, empty_rows=50)
    block = parallel._block(a, r0, r1)
    assert (block - a[r0:r1]).count_nonzero() == 0 and block.shape == (r1 - r0, 60)
    np.testing.assert_array_equal(block.indptr, a[r0:r1].indptr)
    if r1 > r0:
        assert np.shares_memory(block.data, a.data) and np.shares_memory(block.indices, a.indices)
    block.check_format(full_check=True)


def blas_threads() -> int:
    from threadpoolctl import threadpool_info

    return max((i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"), default=1)


def test_builds_run_their_small_dense_solves_on_one_blas_thread(monkeypatch):
    """``blas.one_blas_thread`` around build_operator and subdivision_operator: inside, BLAS
    has one thread (the local solves run there); after, the caller's limit is back."""
    from threadpoolctl import threadpool_limits

    import patching
    from patching.extraordinary import g1_patches
    from patching.subdivision import catmark as subdivision
    from tests.helpers import quad_mesh_with_eps

    seen = []
    angles = g1_patches.angle_configurations
    monkeypatch.setattr(g1_patches, "angle_configurations", lambda *a, **k: seen.append(blas_threads()) or angles(*a, **k))
    with threadpool_limits(limits=2, user_api="blas"):
        before = blas_threads()
        patching.build_operator(quad_mesh_with_eps("bipyramid-5"))
        subdivision.subdivision_operator(quad_mesh_with_eps("cube"))
        assert blas_threads() == before
    assert seen and set(seen) == {1}


def signs_csr(rows: int, cols: int, per_row: int, seed: int) -> sp.csr_matrix:
    """Entries +-1: products of these cancel exactly in many places (scipy's kernel drops
    those sums, so row blocks leave gaps in a result written in one piece)."""
    a = random_csr(rows, cols, per_row, seed)
    a.data = np.sign(a.data)
    return a


@pytest.mark.parametrize("seed", range(3))
def test_chains_with_exact_cancellations_are_the_plain_products(split_everything, seed):
    a, b, c = signs_csr(600, 300, 6, seed), signs_csr(300, 250, 4, seed + 1), signs_csr(250, 90, 3, seed + 2)
    one = (a @ b).tocsr()
    assert one.nnz < (a.astype(bool) @ b.astype(bool)).nnz  # the kernel did drop exact zeros
    for factors, prune in (((b,), False), ((b, c), False), ((b, c), True)):
        plain = a
        for f in factors:
            plain = (plain @ f).tocsr()
        if prune:
            plain.eliminate_zeros()
        split = parallel.product(a, *factors, prune=prune)
        assert split.shape == plain.shape and split.format == "csr"
        for name in ("indptr", "indices", "data"):
            np.testing.assert_array_equal(getattr(split, name), getattr(plain, name))


def test_the_stacking_fallback_is_the_plain_product(split_everything, monkeypatch):
    """Where scipy's kernels cannot write one result (``_product_into_one`` gives None), the
    blocks' products are stacked: the same arrays."""
    monkeypatch.setattr(parallel, "_product_into_one", lambda blocks, b: None)
    a, b, c = signs_csr(400, 200, 5, 7), signs_csr(200, 150, 4, 8), signs_csr(150, 60, 3, 9)
    plain = ((a @ b).tocsr() @ c).tocsr()
    plain.eliminate_zeros()
    split = parallel.product(a, b, c, prune=True)
    for name in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(split, name), getattr(plain, name))
