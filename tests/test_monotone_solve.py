"""The monotone spoke step's solve (``g1_patches._monotone_red``: the QP of every ring of a group
in its dual form, in lockstep) against the step as first shipped (``tests.helpers``'s
``monotone_red_primal``: an explicit basis of the changes and the primal active set, ring by
ring), ring by ring against the batch bit for bit, and through the solve caches: a cached step
is the fresh one to the bit, a damaged entry is solved again, and the step is not skipped;
and the dense blocks of the functions each ring reaches (``_ring_blocks``)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import patching
from patching.extraordinary import g1_patches
from patching.subdivision import subdivide
from patching.util import solve_cache
from patching.extraordinary.g1_patches import cache_key
from tests.helpers import clear_package_caches, monotone_red_primal, prism, quad_mesh_with_eps, with_random_intervals


def _meshes():
    return {
        "prism-cap": with_random_intervals(subdivide(prism(6), 1), 20.0, seed=657701828),
        "bipyramid-5": with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 20.0, seed=2),
    }


@pytest.fixture(scope="module")
def solves():
    """Per mesh: the arguments and results of every ``_monotone_red`` call of a build."""
    out = {}
    original = g1_patches._monotone_red
    for name, mesh in _meshes().items():
        calls = []

        def spy(*args):
            result = original(*args)
            calls.append((args, result))
            return result

        clear_package_caches()
        g1_patches._monotone_red = spy
        try:
            patching.build_operator(mesh)
        finally:
            g1_patches._monotone_red = original
            clear_package_caches()
        out[name] = calls
    return out


@pytest.mark.parametrize("name", ["prism-cap", "bipyramid-5"])
def test_dual_solve_is_the_primal_qp(solves, name):
    """Every ring: the same rings changed, and the same change D as the explicit-basis QP up to
    what its conditioning makes of round-off (the ridge leaves directions of D that change no
    function nearly free, so D itself agrees to ~1e-8 of its size; the functions' change D x,
    which is what reaches M, to ~1e-11)."""
    calls = solves[name]
    assert calls, "no ring broke a bound: the test would not test the step"
    rings = changed = 0
    for (n, configs, inverse, pinned, skip, q_weight, k, x, lo, hi, watch), (ok, d) in calls:
        y = g1_patches._stage2_unknowns(n, pinned, -1)
        for e in range(k.shape[0]):
            key = tuple(cache_key(r) for r in configs[inverse[e]])
            i_idx, c_idx = np.nonzero(watch[e])
            bounds = [(int(c), int(i), float(lo[e, i, c]), float(hi[e, i, c])) for i, c in zip(i_idx, c_idx)]
            primal = monotone_red_primal(n, key, pinned, skip, q_weight, k[e], x[e], bounds)
            rings += 1
            assert (primal is not None) == bool(ok[e])
            if primal is None:
                continue
            changed += 1
            d_primal = primal[y] - k[e][y]
            scale = max(1.0, np.abs(d_primal).max())
            assert np.abs(d[e] - d_primal).max() <= 1e-7 * scale
            assert np.abs((d[e] - d_primal) @ x[e]).max() <= 1e-10 * max(1.0, np.abs(d_primal @ x[e]).max())
    assert changed and rings


@pytest.mark.parametrize("name", ["prism-cap", "bipyramid-5"])
def test_a_ring_alone_is_the_ring_in_its_batch(solves, name):
    """A ring's numbers do not depend on the other rings solved with it (so the one-by-one path
    and the batched one share cache entries to the bit)."""
    for (n, configs, inverse, pinned, skip, q_weight, k, x, lo, hi, watch), (ok, d) in solves[name]:
        width = int(watch.any(axis=1).sum(axis=1).max())
        for e in range(k.shape[0]):
            one = slice(e, e + 1)
            ok1, d1 = g1_patches._monotone_red(n, configs[inverse[one]], np.zeros(1, dtype=np.int64), pinned, skip, q_weight,
                                               k[one], x[one], lo[one], hi[one], watch[one], width)
            assert ok1[0] == ok[e] and np.array_equal(d1[0], d[e])


def _build(mesh, store=None, monotone=True, batched=True):
    from patching.util.memo import set_batching

    clear_package_caches()
    previous = solve_cache.set_store(store)
    saved, g1_patches.MONOTONE_SPOKES = g1_patches.MONOTONE_SPOKES, monotone
    was = set_batching(batched)
    try:
        return patching.build_operator(mesh).matrix.tocsr()
    finally:
        set_batching(was)
        g1_patches.MONOTONE_SPOKES = saved
        solve_cache.set_store(previous)
        clear_package_caches()


def _monotone_keys(store):
    """The store's entries that decode as the monotone step's (flags, changes)."""
    out = []
    for key, data in store.entries.items():
        arrays = solve_cache.decode(key, data, 2)
        if arrays is not None and arrays[0].ndim == 1 and arrays[1].ndim == 3 and np.isin(arrays[0], (0.0, 1.0)).all():
            out.append(key)
    return out


def test_the_step_runs_and_a_cached_step_is_the_fresh_one(monkeypatch):
    """On the prism cap (a ring breaks a bound) the operator with the step differs from the plain
    one; a build with the store filled reads the step's entries (the solve is never called) and
    gives the filling build's M to the bit, without the store too; batched and ring by ring
    fill and read the same entries."""
    mesh = _meshes()["prism-cap"]
    plain = _build(mesh, monotone=False)
    fresh = _build(mesh)
    assert abs(fresh - plain).max() > 1e-4
    by_mode = {True: fresh, False: _build(mesh, batched=False)}  # (the red solves round differently)
    for fill, read in ((True, True), (False, True), (True, False)):
        store = solve_cache.MemoryStore()
        first = _build(mesh, store, batched=fill)
        assert (first != by_mode[fill]).nnz == 0
        assert _monotone_keys(store)
        entries = dict(store.entries)

        def refuse(*args):
            raise AssertionError("the monotone step was solved although its entry is in the store")

        with monkeypatch.context() as m:
            m.setattr(g1_patches, "_monotone_red", refuse)
            second = _build(mesh, store, batched=read)
        assert (second != first).nnz == 0 and store.entries == entries


@pytest.mark.parametrize("damage", ["changes", "flags", "shape"])
def test_a_damaged_monotone_entry_is_solved_again(damage):
    """Well-formed entries for the right key (the payload digest matches) whose values no solve
    gives: changes moved off the G_1 space and the bounds, flags that are not 0 / 1, changes
    for other rings: each is refused by ``_monotone_valid``, solved again and rewritten."""
    mesh = _meshes()["prism-cap"]
    store = solve_cache.MemoryStore()
    fresh = _build(mesh, store)
    good = dict(store.entries)
    keys = _monotone_keys(store)
    assert keys
    for key in keys:
        flags, changes = solve_cache.decode(key, good[key], 2)
        if damage == "changes":
            changes = changes + 1e-3 * np.sign(np.arange(changes.size).reshape(changes.shape) % 3 - 1)
        elif damage == "flags":
            flags = np.where(flags == 1.0, 0.5, flags)
        else:
            changes = changes[:-1] if changes.shape[0] else np.zeros((1,) + changes.shape[1:])
        store.entries[key] = solve_cache.encode(key, [flags, changes])
    again = _build(mesh, store)
    assert (again != fresh).nnz == 0
    assert store.entries == good


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 7), st.integers(1, 5), st.integers(1, 40), st.integers(0, 2**31 - 1), st.integers(1, 4))
def test_ring_blocks_are_the_rows_over_the_columns_each_ring_reaches(rings, per, width, seed, table):
    """``_ring_blocks`` (a table numbers each ring's columns, a few rings at a time) against
    the dense rows: every ring's columns once, its block equal to its rows there, zero padding;
    duplicate entries summed, as the sparse matrix means them."""
    rng = np.random.default_rng(seed)
    dense = np.where(rng.random((rings * per, width)) < 0.3, rng.standard_normal((rings * per, width)), 0.0)
    coo = sp.coo_matrix(dense)
    half = coo.nnz // 2  # split some entries in two: the same matrix with duplicates
    rows = np.concatenate([coo.row, coo.row[:half]])
    cols = np.concatenate([coo.col, coo.col[:half]])
    data = np.concatenate([coo.data - np.r_[coo.data[:half] / 2, np.zeros(coo.nnz - half)], coo.data[:half] / 2])
    ref = sp.csr_matrix((data, (rows, cols)), shape=dense.shape)
    saved, g1_patches.RING_TABLE = g1_patches.RING_TABLE, table
    try:
        x, columns = g1_patches._ring_blocks(ref, rings, per)
    finally:
        g1_patches.RING_TABLE = saved
    for e in range(rings):
        block = dense[e * per : (e + 1) * per]
        reached = np.flatnonzero(np.abs(sp.csr_matrix(block)).sum(axis=0).A1 > 0)
        mine = columns[e][columns[e] >= 0]
        assert sorted(mine.tolist()) == sorted(set(mine.tolist())) and set(mine.tolist()) >= set(reached.tolist())
        np.testing.assert_allclose(x[e][:, : mine.size], block[:, mine], rtol=1e-15, atol=0)
        assert not x[e][:, mine.size :].any()
