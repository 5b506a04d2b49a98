"""The speed work keeps every result identical: connected components in numpy against scipy's
csgraph, the persistent cache of solved configurations (hits give the same operator to the
bit, damaged or implausible entries are ignored and rewritten, --no-cache and NUPATCH_NO_CACHE
write nothing), and the imports a build does not need stay out of ``nupatch``'s start."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse.csgraph import connected_components as scipy_components

import patching
from export.solve_cache import DiskStore, using_disk_cache
from patching.util import solve_cache
from patching.util.graph import connected_components
from tests.helpers import clear_package_caches

REPO = Path(__file__).resolve().parent.parent
L_BRACKET = REPO / "models" / "l_bracket.obj"


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 40).flatmap(lambda n: st.tuples(st.just(n), st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=60))))
def test_components_match_scipy(case):
    n, edges = case
    a = np.array([e[0] for e in edges], dtype=np.int64)
    b = np.array([e[1] for e in edges], dtype=np.int64)
    graph = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    ref_count, ref_labels = scipy_components(graph, directed=False)
    assert count == ref_count
    np.testing.assert_array_equal(labels, ref_labels)


def test_components_long_chains_and_explicit_zeros():
    rng = np.random.default_rng(3)
    order = rng.permutation(5000)  # one path visiting the nodes in random order, and a zero weight
    graph = sp.coo_matrix((np.r_[np.zeros(1), np.ones(4998)], (order[:-1], order[1:])), shape=(5001, 5001))
    count, labels = connected_components(graph)
    ref = scipy_components(graph, directed=False)
    assert count == ref[0] == 2
    np.testing.assert_array_equal(labels, ref[1])


def _operator(mesh, store):
    _clear()  # the in-process caches would hide the persistent one
    previous = solve_cache.set_store(store)
    try:
        return patching.build_operator(mesh).matrix.tocsr()
    finally:
        solve_cache.set_store(previous)
        _clear()


def _clear():
    clear_package_caches()  # the in-process caches would hide the persistent one


@pytest.fixture(scope="module")
def bracket():
    mesh = patching.read_mesh(L_BRACKET)
    return mesh, _operator(mesh, None)


def _same(m1, m2):
    assert m1.shape == m2.shape
    assert (m1 != m2).nnz == 0  # bit for bit


class CountingStore(solve_cache.MemoryStore):
    def __init__(self) -> None:
        super().__init__()
        self.hits = self.misses = 0

    def get(self, key):
        data = super().get(key)
        self.hits += data is not None
        self.misses += data is None
        return data


def test_cache_hits_give_the_same_operator(bracket):
    mesh, reference = bracket
    store = CountingStore()
    _same(_operator(mesh, store), reference)  # fills the store
    assert store.entries and store.hits == 0 and store.misses == len(store.entries)
    first = dict(store.entries)
    store.misses = 0
    _same(_operator(mesh, store), reference)  # every solve from the store (a cached anchor
    assert store.hits and store.misses == 0 and store.entries == first  # needs no eigen-structure)


@pytest.mark.parametrize("damage", ["flip", "truncate", "empty", "other_key", "implausible"])
def test_damaged_entries_are_ignored(bracket, damage):
    mesh, reference = bracket
    store = solve_cache.MemoryStore()
    _operator(mesh, store)
    good = dict(store.entries)
    keys = sorted(good)
    for i, key in enumerate(keys):
        data = good[key]
        if damage == "flip":
            data = data[:-3] + bytes([data[-3] ^ 0x10]) + data[-2:]
        elif damage == "truncate":
            data = data[: len(data) // 2]
        elif damage == "empty":
            data = b""
        elif damage == "other_key":
            data = good[keys[(i + 1) % len(keys)]]  # a well-formed entry of another problem
        else:  # well-formed and for this key, but values no solve gives (angles > pi, weights
            # not summing to 1): each problem's validation refuses them
            count = next(c for c in range(1, 10) if solve_cache.decode(key, data, c) is not None)
            data = solve_cache.encode(key, [np.full_like(a, 4.0) for a in solve_cache.decode(key, data, count)])
        store.entries[key] = data
    _same(_operator(mesh, store), reference)
    if len(keys) > 1 or damage != "other_key":
        assert store.entries == good  # rewritten by the fresh solves


def test_entry_codec_round_trip():
    arrays = [np.array([0.1, np.pi / 3, 1e-300]), np.arange(6.0).reshape(2, 3)]
    data = solve_cache.encode("k", arrays)
    back = solve_cache.decode("k", data, 2)
    for a, b in zip(arrays, back):
        assert a.tobytes() == b.tobytes()
    assert solve_cache.decode("k", data, 3) is None
    assert solve_cache.decode("j", data, 2) is None
    assert solve_cache.decode("k", solve_cache.encode("k", [np.array([np.nan])]), 1) is None


def test_disk_store_atomic_and_unwritable(tmp_path, bracket):
    mesh, reference = bracket
    store = DiskStore(tmp_path / "cache")
    _same(_operator(mesh, store), reference)
    files = sorted(p for p in (tmp_path / "cache").rglob("*") if p.is_file())
    assert files and all(p.parent.name == p.name[:2] for p in files)  # no temporaries left
    _same(_operator(mesh, store), reference)
    blocked = tmp_path / "blocked"
    blocked.write_text("a file where the cache directory should be")
    _same(_operator(mesh, DiskStore(blocked)), reference)  # no cache, no error


def test_disk_store_concurrent_writers(tmp_path):
    """Processes writing the same entries at once: every entry left is whole."""
    code = (
        "import sys, numpy as np\n"
        "from export.solve_cache import DiskStore\n"
        "from patching.util.solve_cache import encode\n"
        "s = DiskStore(sys.argv[1])\n"
        "for i in range(200):\n"
        "    s.put(f'{i % 7:02d}key', encode(f'{i % 7:02d}key', [np.arange(20000.0) + i % 7]))\n"
    )
    env = dict(os.environ, PYTHONPATH=str(REPO))
    procs = [subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], env=env) for _ in range(3)]
    assert all(p.wait(timeout=120) == 0 for p in procs)
    store = DiskStore(tmp_path)
    for k in range(7):
        key = f"{k:02d}key"
        (arr,) = solve_cache.decode(key, store.get(key), 1)
        np.testing.assert_array_equal(arr, np.arange(20000.0) + k)
    assert sum(1 for p in tmp_path.rglob("*") if p.is_file()) == 7


def test_cli_cache_switches(tmp_path, run_cli, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("NUPATCH_CACHE_DIR", str(cache))
    entries = lambda: sorted(p.name for p in cache.rglob("*") if p.is_file()) if cache.exists() else []  # noqa: E731
    out = tmp_path / "a.step"
    assert run_cli("build", L_BRACKET, "-o", out, "-q", "--no-cache").returncode == 0
    assert entries() == []
    monkeypatch.setenv("NUPATCH_NO_CACHE", "1")
    assert run_cli("build", L_BRACKET, "-o", out, "-q").returncode == 0
    assert entries() == []
    monkeypatch.delenv("NUPATCH_NO_CACHE")
    assert run_cli("build", L_BRACKET, "-o", out, "-q").returncode == 0
    operators = [p.name for p in (cache / "operators").iterdir()]
    solves = sorted(p.name for p in (cache / "solves").rglob("*") if p.is_file())
    assert operators and solves and sorted(solves + operators) == entries()
    with using_disk_cache(root=cache) as store:
        assert store is not None and all(store.get(k) for k in solves)
    from export.operator_cache import OperatorCache

    assert all(OperatorCache(cache).load(name.removesuffix(".npop"), "l_bracket") for name in operators)


def test_build_start_imports_only_what_it_needs():
    """Parsing ``nupatch build``'s command line and importing the build path loads no
    scipy.optimize / interpolate / csgraph / linalg, no Loop or shading modules, and not
    multiprocessing (only ``-j``'s worker pool needs it)."""
    code = (
        "import sys, export.cli, export.pipeline, export.brep, export.step, export.formats, export.inputs, export.signals\n"
        "export.cli._parser()\n"
        "bad = [m for m in ('scipy.optimize', 'scipy.interpolate', 'scipy.sparse.csgraph', 'scipy.linalg',"
        " 'patching.loop', 'patching.shading', 'multiprocessing', 'concurrent.futures.process') if m in sys.modules]\n"
        "print(' '.join(bad))\n"
    )
    env = dict(os.environ, PYTHONPATH=str(REPO))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


#: A whole ``nupatch build`` process (``main()`` on its own command line, as the console script
#: runs it), then what it left: modules it should not have loaded, whether the collector is on,
#: how many objects were frozen and how many are still tracked.
_WHOLE_BUILD = (
    "import gc, sys, export.cli\n"
    "walked = []  # full collections that walked OpenCASCADE's objects (OCP loaded, nothing frozen)\n"
    "gc.callbacks.append(lambda phase, info: walked.append(1) if phase == 'start' and info['generation'] == 2"
    " and 'OCP' in sys.modules and not gc.get_freeze_count() else None)\n"
    "sys.argv = ['nupatch', 'build', *sys.argv[1:]]\n"
    "code = export.cli.main()\n"
    "bad = [m for m in ('tqdm', 'multiprocessing') if m in sys.modules]\n"
    "print(code, gc.isenabled(), len(walked), gc.get_freeze_count(), len(gc.get_objects()), *bad)\n"
)


def _strip_time_stamp(path: Path) -> str:
    text = path.read_text()
    return re.sub(r"FILE_NAME\(.*?\);", "", text, count=1, flags=re.DOTALL)


def test_whole_build_process_freezes_its_heap_and_writes_the_same_step(tmp_path, cli_main):
    """``nupatch build`` as its own process imports OpenCASCADE with the collector off and
    freezes the heap (``export.cli._import_frozen``): the STEP of l_bracket, first build and
    cached build, is the file a build in this interpreter writes (which freezes nothing),
    time stamp aside; -q loads no tqdm, a single build no multiprocessing."""
    env = dict(os.environ, PYTHONPATH=str(REPO), NUPATCH_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("NUPATCH_NO_CACHE", None)
    outs = []
    for name in ("first", "cached"):
        out = tmp_path / f"{name}.step"
        run = subprocess.run([sys.executable, "-c", _WHOLE_BUILD, str(L_BRACKET), "-o", str(out), "-q"],
                             env=env, capture_output=True, text=True, check=True, cwd=tmp_path)
        code, enabled, walked, frozen, tracked, *bad = run.stdout.split()
        assert (code, enabled, walked, bad) == ("0", "True", "0", [])
        assert int(frozen) > 50_000 and int(tracked) < 1_000  # OCP's objects frozen, the rest at the end
        outs.append(out)
    assert any((tmp_path / "cache").rglob("*"))  # the second build read what the first wrote
    import gc

    frozen_before = gc.get_freeze_count()
    here = tmp_path / "here.step"
    assert cli_main("build", L_BRACKET, "-o", here, "-q", "--no-cache").returncode == 0
    assert gc.get_freeze_count() == frozen_before and gc.isenabled()  # main(argv) leaves gc alone
    reference = _strip_time_stamp(here)
    assert len(reference) > 100_000
    for out in outs:
        assert _strip_time_stamp(out) == reference


#: ``nupatch build A B -j 2`` as its own process; at the pool's start (``build_files``, before
#: the workers fork) whether OCP is loaded and how many objects are frozen.
_POOL_BUILD = (
    "import gc, sys, export.cli, export.pipeline\n"
    "seen = []\n"
    "real = export.pipeline.build_files\n"
    "def files(*args, **kwargs):\n"
    "    seen.append(('OCP' in sys.modules, gc.get_freeze_count()))\n"
    "    return real(*args, **kwargs)\n"
    "export.pipeline.build_files = files\n"
    "sys.argv = ['nupatch', 'build', *sys.argv[1:]]\n"
    "print(export.cli.main(), *seen[0])\n"
)


def test_a_pool_build_imports_opencascade_frozen_before_forking(tmp_path, cli_main):
    """``build -j 2`` as its own process imports the build path frozen before the pool forks
    its workers (``export.cli._build_many``), so they inherit OCP's objects in the collector's
    permanent generation (without: ~0.15 s of CPU a worker, its collections walking them); the
    STEP files are those of a build in this interpreter, time stamp aside."""
    for name in ("a", "b"):
        (tmp_path / f"{name}.obj").write_text(L_BRACKET.read_text())
    (tmp_path / "out").mkdir()
    env = dict(os.environ, PYTHONPATH=str(REPO), NUPATCH_NO_CACHE="1")
    run = subprocess.run([sys.executable, "-c", _POOL_BUILD, "a.obj", "b.obj", "-j", "2", "-q", "-o", "out"],
                         env=env, capture_output=True, text=True, check=True, cwd=tmp_path)
    code, ocp_loaded, frozen = run.stdout.split()
    assert (code, ocp_loaded) == ("0", "True") and int(frozen) > 50_000
    for name in ("a", "b"):  # the product is named after the mesh: a reference for each
        here = tmp_path / f"here-{name}" / f"{name}.step"
        here.parent.mkdir()
        assert cli_main("build", tmp_path / f"{name}.obj", "-o", here, "-q", "--no-cache").returncode == 0
        assert _strip_time_stamp(tmp_path / "out" / f"{name}.step") == _strip_time_stamp(here)


def test_first_build_imports_no_scipy_optimize(tmp_path):
    """A whole ``nupatch build --no-cache`` of l_bracket (which optimises angle configurations:
    its intervals are not uniform) never imports scipy.optimize: the angle configurations of
    [FSLYJ] sec. 3.3 are solved by the package's own batched solver."""
    code = (
        "import sys, export.cli\n"
        "from patching.extraordinary import angle_configuration as ac\n"
        f"code = export.cli.main(['build', {str(L_BRACKET)!r}, '-o', {str(tmp_path / 'a.step')!r}, '-q', '--no-cache'])\n"
        "solved = [c for c in ac._cached._values.values() if c.iterations > 0]\n"
        "print(code, len(solved), 'scipy.optimize' in sys.modules)\n"
    )
    env = dict(os.environ, PYTHONPATH=str(REPO), NUPATCH_CACHE_DIR=str(tmp_path / "cache"))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=tmp_path)
    code, solved, imported = out.stdout.split()
    assert code == "0" and int(solved) > 0 and imported == "False"
    assert not (tmp_path / "cache").exists()


def _format_obj_line_by_line(mesh, comment=""):
    """The OBJ writer as it was, one line at a time: the reference of the vectorised one."""
    lines = [f"# {line}" for line in comment.splitlines()]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist()]
    for f in range(mesh.n_faces):
        lines.append("f " + " ".join(str(int(v) + 1) for v in mesh.face(f)))
    for (a, b), d in sorted(mesh.intervals.items()):
        lines.append(f"t interval 2/1/0 {a} {b} {d!r}")
    for (a, b), s in sorted(mesh.creases.items()):
        lines.append(f"t crease 2/1/0 {a} {b} {s!r}")
    for v, s in sorted(mesh.corners.items()):
        lines.append(f"t corner 1/1/0 {v} {s!r}")
    for f in sorted(mesh.holes):
        lines.append(f"t hole 1/0/0 {f}")
    lines.append(f"t interpolateboundary 1/0/0 {mesh.interpolate_boundary}")
    return "\n".join(lines) + "\n"


SHAPES = REPO.parent / "shared" / "opensubdiv-shapes"


@pytest.mark.parametrize("name", ["catmark_nonquads", "catmark_hole_test1", "catmark_cube_corner4", "catmark_pawn"])
def test_obj_writer_same_text(name):
    from patching.mesh.obj import format_obj, read_obj
    from patching.subdivision.catmark import subdivide

    path = SHAPES / f"{name}.obj"
    if not path.exists():
        pytest.skip("OpenSubdiv shapes absent")
    mesh = read_obj(path)
    assert format_obj(mesh, "two\nlines") == _format_obj_line_by_line(mesh, "two\nlines")
    refined = subdivide(mesh, 1)
    assert format_obj(refined) == _format_obj_line_by_line(refined)
