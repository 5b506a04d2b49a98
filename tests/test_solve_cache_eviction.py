"""The on-disk cache of solved configurations stays under its size cap: least recently used
entries (mtime: last write, or last read) go first, down to EVICT_TO of the cap; temporaries
of writes in progress are never touched; builds and evictions running at once leave only
whole entries."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import time

import numpy as np

import patching
from export import solve_cache as disk
from export.atomic import temporary_name
from patching.util import solve_cache
from tests.conftest import REPO
from tests.helpers import clear_package_caches, whole_cache_entries

L_BRACKET = REPO / "models" / "l_bracket.obj"


def _key(i: int) -> str:
    return hashlib.sha256(f"entry {i}".encode()).hexdigest()


def _fill(store: disk.DiskStore, count: int, size: int = 1000) -> list[str]:
    """count entries of about 8 * size bytes, entry i last used at t = 1e9 + 100 i."""
    keys = []
    for i in range(count):
        key = _key(i)
        store.put(key, solve_cache.encode(key, [np.full(size, float(i))]))
        os.utime(store.path(key), (1e9 + 100 * i, 1e9 + 100 * i))
        keys.append(key)
    return keys


def _total(store: disk.DiskStore) -> int:
    return sum(size for _, size, _ in store.entries())


def test_eviction_removes_the_least_recently_used(tmp_path):
    store = disk.DiskStore(tmp_path, max_bytes=10**9)
    keys = _fill(store, 20)
    size = os.path.getsize(store.path(keys[0]))
    assert store.evict() == 0 and _total(store) == 20 * size  # under the cap: nothing goes
    cap = 10 * size
    removed = store.evict(cap)
    left = [k for k in keys if store.path(k).exists()]
    assert removed == 20 - len(left)
    assert _total(store) <= disk.EVICT_TO * cap < _total(store) + size  # down to the mark, no further
    assert left == keys[-len(left):]  # the newest stay
    for k in left:
        (a,) = solve_cache.decode(k, store.get(k), 1)
        assert a[0] == keys.index(k)


def test_a_read_makes_an_entry_recent(tmp_path):
    store = disk.DiskStore(tmp_path, max_bytes=10**9)
    keys = _fill(store, 10)
    size = os.path.getsize(store.path(keys[0]))
    store.refresh_after = 0.0
    assert store.get(keys[0]) is not None  # the oldest, read now
    store.evict(5 * size)
    assert store.path(keys[0]).exists()
    assert not store.path(keys[1]).exists()


def test_reads_within_the_refresh_interval_leave_mtime_alone(tmp_path):
    store = disk.DiskStore(tmp_path)
    (key,) = _fill(store, 1)
    os.utime(store.path(key), None)
    before = os.stat(store.path(key)).st_mtime_ns
    store.refresh_after = 3600.0
    store.get(key)
    assert os.stat(store.path(key)).st_mtime_ns == before


def test_temporaries_and_foreign_files_are_not_entries(tmp_path):
    store = disk.DiskStore(tmp_path)
    keys = _fill(store, 3)
    bucket = store.path(keys[0]).parent
    temporary = bucket / temporary_name(str(store.path(keys[0])))
    temporary.write_bytes(b"half an entry being written")
    other = bucket / "README"
    other.write_text("not ours")
    store.evict(0)
    assert not any(store.path(k).exists() for k in keys)
    assert temporary.exists() and other.exists()


def test_cap_from_the_environment(monkeypatch):
    monkeypatch.setenv(disk.MAX_MB_ENV, "1.5")
    assert disk.cache_max_bytes() == 1_500_000
    for bad in ("lots", "nan"):
        monkeypatch.setenv(disk.MAX_MB_ENV, bad)
        assert disk.cache_max_bytes() == int(disk.DEFAULT_MAX_MB * 1e6)
    monkeypatch.delenv(disk.MAX_MB_ENV)
    assert disk.cache_max_bytes() == int(disk.DEFAULT_MAX_MB * 1e6)


def test_a_build_that_writes_evicts_to_the_cap(tmp_path, monkeypatch):
    mesh = patching.read_mesh(L_BRACKET)
    reference = patching.build_operator(mesh).matrix
    monkeypatch.setenv(disk.MAX_MB_ENV, "0.005")
    clear_package_caches()
    with disk.using_disk_cache(root=tmp_path) as store:
        assert store is not None and store.max_bytes == 5_000
        built = patching.build_operator(mesh).matrix
    clear_package_caches()
    assert store.written > 5_000  # the build wrote more than the cap...
    assert 0 < _total(store) <= disk.EVICT_TO * 5_000  # ...and left at most the mark
    assert (built != reference).nnz == 0


def test_concurrent_writers_readers_and_evictors(tmp_path):
    """Three processes writing overlapping entries, reading them back and evicting to a small
    cap, all at once: none fails, every entry read is whole, and what is left is whole."""
    code = (
        "import hashlib, sys, numpy as np\n"
        "from export.solve_cache import DiskStore\n"
        "from patching.util.solve_cache import encode, decode\n"
        "s = DiskStore(sys.argv[1], max_bytes=60_000)\n"
        "s.refresh_after = 0.0\n"
        "for i in range(150):\n"
        "    j = (i * int(sys.argv[2])) % 40\n"
        "    k = hashlib.sha256(f'entry {j}'.encode()).hexdigest()\n"
        "    s.put(k, encode(k, [np.full(1000, float(j))]))\n"
        "    data = s.get(hashlib.sha256(f'entry {(j + 3) % 40}'.encode()).hexdigest())\n"
        "    if data is not None:\n"
        "        k2 = hashlib.sha256(f'entry {(j + 3) % 40}'.encode()).hexdigest()\n"
        "        (a,) = decode(k2, data, 1)\n"
        "        assert (a == (j + 3) % 40).all()\n"
        "    if i % 10 == 0:\n"
        "        s.evict()\n"
    )
    env = dict(os.environ, PYTHONPATH=str(REPO))
    procs = [subprocess.Popen([sys.executable, "-c", code, str(tmp_path), str(step)], env=env) for step in (1, 3, 7)]
    assert all(p.wait(timeout=120) == 0 for p in procs)
    store = disk.DiskStore(tmp_path, max_bytes=60_000)
    store.evict()
    assert _total(store) <= 60_000
    left = store.entries()
    assert left
    for _, _, path in left:
        key = os.path.basename(path)
        (a,) = solve_cache.decode(key, store.get(key), 1)
        j = [i for i in range(40) if _key(i) == key][0]
        assert (a == j).all()


def test_a_background_store_writes_every_entry_by_close(tmp_path):
    store = disk.DiskStore(tmp_path, background=True)
    keys = [_key(i) for i in range(40)]
    for i, key in enumerate(keys):
        store.put(key, solve_cache.encode(key, [np.full(100, float(i))]))
    store.close()
    assert sorted(whole_cache_entries(tmp_path)) == sorted(keys)
    assert store.written == sum(len(solve_cache.encode(k, [np.full(100, float(i))])) for i, k in enumerate(keys))


def test_an_abandoned_background_store_drops_the_entries_not_begun(tmp_path):
    import threading

    store = disk.DiskStore(tmp_path, background=True)
    gate, started = threading.Event(), threading.Event()
    write = store._write

    def held(key, data):  # the writer thread stops inside its first entry until the gate opens
        started.set()
        assert gate.wait(30)
        write(key, data)

    store._write = held
    keys = [_key(i) for i in range(10)]
    for key in keys:
        store.put(key, solve_cache.encode(key, [np.ones(10)]))
    assert started.wait(30)
    closer = threading.Thread(target=store.close, kwargs={"abandon": True})
    closer.start()
    deadline = time.monotonic() + 30
    while store._pending.qsize() != 1 and time.monotonic() < deadline:  # drained to the stop mark
        time.sleep(0.001)
    gate.set()
    closer.join(30)
    assert not closer.is_alive()
    assert whole_cache_entries(tmp_path) == [keys[0]]  # the one in progress ends whole, the rest dropped


def test_using_disk_cache_waits_for_its_writes_and_drops_them_when_interrupted(tmp_path):
    with disk.using_disk_cache(root=tmp_path / "a") as store:
        for i in range(30):
            store.put(_key(i), solve_cache.encode(_key(i), [np.full(50, float(i))]))
    assert len(whole_cache_entries(tmp_path / "a")) == 30  # all on disk when the block has ended
    try:
        with disk.using_disk_cache(root=tmp_path / "b") as store:
            for i in range(30):
                store.put(_key(i), solve_cache.encode(_key(i), [np.full(50, float(i))]))
            raise KeyboardInterrupt
    except KeyboardInterrupt:
        pass
    else:  # pragma: no cover
        raise AssertionError("the interrupt was swallowed")
    assert len(whole_cache_entries(tmp_path / "b")) <= 30  # whole entries only, however many were begun
