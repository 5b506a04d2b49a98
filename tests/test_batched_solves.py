"""The local problems of a build solved in batches (one stacked solve per valence and kind)
give the operator of the one-problem-at-a-time path to 1e-12, and each batched solver equals
its one-problem solver problem by problem."""

from __future__ import annotations


import numpy as np
import pytest

import patching
from patching.extraordinary import auxiliary_points, g1_patches
from patching.rules import eigen_polyhedron
from patching.util import solve_cache
from patching.util.memo import set_batching
from tests.conftest import SHAPES
from tests.helpers import boundary_ep, clear_package_caches, meridian_crease, quad_mesh_with_eps, with_random_intervals

TOL = 1e-12


def _both(mesh, monotone: bool = False, **options):
    """M built with batching and without it, each from empty in-process caches.

    The monotone-spoke step (``g1_patches.MONOTONE_SPOKES``) is off unless asked for: it runs
    after the red operators, the same code on both paths, and its active-set QP amplifies the
    red operators' round-off differences (~3e-16) to a few 1e-12 (measured on bipyramid-5 at
    ratio 20: 2.8e-16 without it, 4.3e-12 with it); ``test_batched_operator_with_monotone_spokes``
    bounds that separately."""
    out = []
    saved = g1_patches.MONOTONE_SPOKES
    g1_patches.MONOTONE_SPOKES = monotone
    try:
        for on in (True, False):
            clear_package_caches()
            previous = set_batching(on)
            try:
                out.append(patching.build_operator(mesh, **options).matrix.tocsr())
            finally:
                set_batching(previous)
    finally:
        g1_patches.MONOTONE_SPOKES = saved
    clear_package_caches()
    return out


def _assert_close(a, b):
    assert a.shape == b.shape
    assert abs(a - b).max() <= TOL * max(1.0, abs(b).max())


MESHES = {
    "bipyramid-3": lambda: with_random_intervals(quad_mesh_with_eps("bipyramid-3"), 5.0, seed=1),
    "bipyramid-5": lambda: with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 20.0, seed=2),
    "bipyramid-7": lambda: with_random_intervals(quad_mesh_with_eps("bipyramid-7"), 3.0, seed=3),
    "cube": lambda: with_random_intervals(quad_mesh_with_eps("cube"), 5.0, seed=4),
    "meridian-crease": lambda: meridian_crease(6, 0, 2, 4.0, seed=5),
    "boundary-gap": lambda: boundary_ep(1),
}


@pytest.mark.parametrize("name", sorted(MESHES))
def test_batched_operator_equals_the_one_by_one_operator(name):
    a, b = _both(MESHES[name]())
    _assert_close(a, b)


def test_batched_operator_with_monotone_spokes():
    """With the monotone-spoke step on (the default), the two paths differ only by what that
    step's QP makes of the red operators' round-off: far below any geometric tolerance, and the
    same bound on every mesh of ``MESHES``."""
    for name, make in MESHES.items():
        a, b = _both(make(), monotone=True)
        assert abs(a - b).max() <= 1e-10 * max(1.0, abs(b).max()), name


@pytest.mark.parametrize(
    "options",
    [{"anchors": "extraction"}, {"eigen_angles": "modified"}, {"method": "t-spline"}, {"g1_solve": "joint"}, {"angles": "uniform"}],
    ids=lambda o: "-".join(f"{k}={v}" for k, v in o.items()),
)
def test_batched_operator_equals_under_options(options):
    a, b = _both(with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 6.0, seed=8), **options)
    _assert_close(a, b)


@pytest.mark.parametrize("shape", ["catmark_cube_creases1", "catmark_dart_edgeonly", "catmark_hole_test1", "catmark_cube_corner2", "catmark_torus_creases1", "catmark_tent_creases1"])
def test_batched_operator_equals_on_tagged_shapes(shape):
    path = SHAPES / f"{shape}.obj"
    if not path.exists():
        pytest.skip(f"{path} absent")
    a, b = _both(with_random_intervals(patching.read_mesh(path), 4.0, seed=9))
    _assert_close(a, b)


def test_batched_eigen_analysis_equals_one_vertex_at_a_time():
    rng = np.random.default_rng(12)
    for n in (3, 5, 6, 8, 11):
        d = np.exp(rng.uniform(0.0, np.log(8.0), (9, n)))
        d[0] = 1.0  # uniform: real eigenvalues
        d[1] = d[2]  # a repeated configuration
        d[3] = 3.0 * d[4]  # the same configuration at another scale
        clear_package_caches()
        limit, projector = eigen_polyhedron.limit_and_projectors(d)
        values = [eigen_polyhedron.subdivision_eigenvalues(row) for row in d]
        clear_package_caches()
        previous = set_batching(False)
        try:
            for k, row in enumerate(d):
                np.testing.assert_allclose(limit[k], eigen_polyhedron.limit_point_weights(row), rtol=0, atol=TOL)
                np.testing.assert_allclose(projector[k], eigen_polyhedron.tangent_projector(row), rtol=0, atol=TOL)
                alone = eigen_polyhedron.subdivision_eigenvalues(row)
                assert alone.dtype == values[k].dtype == np.complex128  # as documented, on every machine
                np.testing.assert_allclose(values[k], alone, rtol=0, atol=TOL)
        finally:
            set_batching(previous)


@pytest.mark.parametrize("rule", auxiliary_points.RULES)
def test_batched_anchor_weights_equal_one_configuration_at_a_time(rule):
    rng = np.random.default_rng(13)
    for n in (3, 5, 6):
        d = rng.choice([1.0, 2.0, 5.0], (12, n))
        a = rng.uniform(1.0, 5.0, (12, n))
        clear_package_caches()
        batch = auxiliary_points.anchor_weights_batch(d, a, rule=rule)
        clear_package_caches()
        previous = set_batching(False)
        try:
            for k in range(d.shape[0]):
                np.testing.assert_allclose(batch[k], auxiliary_points.anchor_weights(d[k], a[k], rule=rule), rtol=0, atol=TOL)
        finally:
            set_batching(previous)


def test_batched_red_solves_equal_one_configuration_at_a_time():
    """Random spoke keys with regular (None) and EP far ends, with and without pinned spokes
    and a gap, against ``_red_solve`` key by key."""
    rng = np.random.default_rng(14)
    for n, pinned, gap in ((5, (), -1), (6, (True, False, False, True, False, False), -1), (5, (), 2), (3, (), -1)):
        keys = []
        for _ in range(10):
            key = []
            for _ in range(n):
                far = None if rng.random() < 0.5 else float(rng.uniform(-1.0, 1.0))
                key.append((float(rng.uniform(1, 25)), float(rng.uniform(1, 25)), float(rng.uniform(-2.0, 2.0)), far))
            keys.append(tuple(key))
        keys.append(keys[0])  # a repeated one
        batch = g1_patches._red_solve_batch(n, keys, pinned, gap, pinned, 1.0)
        for k, key in enumerate(keys):
            alone = g1_patches._red_solve(n, key, pinned, gap, pinned, 1.0)
            np.testing.assert_allclose(batch[k], alone, rtol=0, atol=TOL)


def test_batched_lookups_share_the_persistent_entries():
    """The batched path reads and writes the same store entries as the one-by-one path: a
    store filled by one serves the other without a miss, with the same operator."""
    mesh = with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 5.0, seed=15)

    class Counting(solve_cache.MemoryStore):
        misses = 0

        def get(self, key):
            data = super().get(key)
            self.misses += data is None
            return data

    for fill, read in ((False, True), (True, False)):
        store = Counting()
        previous = solve_cache.set_store(store)
        try:
            clear_package_caches()
            set_batching(fill)
            first = patching.build_operator(mesh).matrix.tocsr()
            entries = dict(store.entries)
            store.misses = 0
            clear_package_caches()
            set_batching(read)
            second = patching.build_operator(mesh).matrix.tocsr()
        finally:
            set_batching(True)
            solve_cache.set_store(previous)
            clear_package_caches()
        assert store.misses == 0 and store.entries == entries
        assert (first != second).nnz == 0  # entries are float64 bit for bit


def test_memo_is_bounded_and_shared_by_threads():
    """The memo keeps at most maxsize entries (first in, first out) and stays consistent when
    threads fill it at once."""
    from concurrent.futures import ThreadPoolExecutor

    from patching.util.memo import Memo

    calls = []
    square = Memo(lambda x: calls.append(x) or x * x, maxsize=50)
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(square, [i % 80 for i in range(2000)]))
    assert results == [(i % 80) ** 2 for i in range(2000)]
    assert square.cache_info().currsize <= 50
    square.prime((1000,), -1)
    assert square.known((1000,)) and square(1000) == -1
    square.cache_clear()
    assert square.cache_info().currsize == 0 and not square.known((1000,))
