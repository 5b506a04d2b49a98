"""Whole operators kept between builds (``patching.operator.archive``, ``export.operator_cache``):
M does not read positions, so its key leaves them out and moved control points reuse it; an
entry comes back bit for bit, as maps of its file; damaged entries are misses; the cap holds;
an abandoned write leaves nothing; ``nupatch build`` reads the entry and ``--no-cache`` does not."""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import patching
from export import operator_cache
from export.operator_cache import OperatorCache, operator_for
from patching.operator.archive import operator_arrays, operator_key
from patching.options import BuildOptions
from tests.conftest import REPO
from tests.helpers import adaptive_grid, cube_level2, ep_disc, quad_mesh_with_eps, with_random_intervals

L_BRACKET = REPO / "models" / "l_bracket.obj"


def _meshes() -> dict[str, patching.ControlMesh]:
    v, f, _ = adaptive_grid(8, 7)
    return {
        "eps_random_intervals": with_random_intervals(quad_mesh_with_eps("bipyramid-5"), 4.0, seed=3),
        "adaptive_semi_sharp": cube_level2(2.5, np.random.default_rng(1)),  # split sides, spans
        "open_disc": ep_disc(5, rings=3),
        "grid_corner_hole": patching.from_arrays(v, f, creases={(20, 21): 10.0, (21, 22): 10.0}, corners={0: 10.0},
                                                 holes=[30], name="grid"),
        "l_bracket": patching.read_mesh(L_BRACKET),
    }


MESHES = _meshes()


def _moved(mesh: patching.ControlMesh, seed: int) -> patching.ControlMesh:
    rng = np.random.default_rng(seed)
    return dataclasses.replace(mesh, vertices=mesh.vertices + rng.normal(0.0, 0.05, mesh.vertices.shape))


def assert_same_operator(a: patching.SurfaceOperator, b: patching.SurfaceOperator) -> None:
    """Every array of the two operators equal, bit for bit, and the same scalars."""
    arrays_a, scalars_a = operator_arrays(a)
    arrays_b, scalars_b = operator_arrays(b)
    assert scalars_a == scalars_b
    assert arrays_a.keys() == arrays_b.keys()
    for name, x in arrays_a.items():
        y = arrays_b[name]
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), name  # bits, NaN-safe


@pytest.mark.parametrize("name", sorted(MESHES))
def test_an_entry_comes_back_bit_for_bit_as_maps_of_its_file(tmp_path, name):
    mesh = MESHES[name]
    op = patching.build_operator(mesh)
    cache = OperatorCache(tmp_path, background=False)
    key = operator_key(mesh, BuildOptions())
    cache.save(key, op)
    back = cache.load(key, "renamed")
    assert back is not None and back.name == "renamed"
    assert_same_operator(op, back)
    m = back.matrix
    for a in (m.data, m.indices, m.indptr):
        assert not a.flags.owndata  # views of the map, not copies
    # the same surface from the loaded M, and M stays usable like the built one
    p = mesh.vertices
    assert np.array_equal(back.coefficients(p), op.coefficients(p))
    assert np.array_equal(back.used_points, op.used_points)
    assert [g.degree for g in back.groups] == [g.degree for g in op.groups]
    if name == "adaptive_semi_sharp":
        assert back.topology.has_split_sides and all(g.spans is not None for g in back.groups)


@pytest.mark.skipif(not os.path.exists("/proc/self/maps"), reason="reads the process's maps (Linux)")
def test_the_file_is_unmapped_once_m_is_dropped(tmp_path):
    """The surface keeps the groups and the patch topology, not M: those arrays are copied out
    of the map, so dropping the operator unmaps the entry (else the whole file stays resident
    through the B-rep and the STEP writer)."""
    import gc

    mesh, cache, key = _saved(tmp_path, "adaptive_semi_sharp")
    path = str(cache.path(key))
    mapped = lambda: path in open("/proc/self/maps").read()  # noqa: E731
    op = cache.load(key, mesh.name)
    assert mapped()
    surface = op.evaluate(mesh.vertices)
    del op
    gc.collect()
    assert not mapped()
    assert surface.n_patches > 0 and surface.topology.has_split_sides


@pytest.mark.parametrize("name", ["eps_random_intervals", "adaptive_semi_sharp", "grid_corner_hole"])
@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_the_operator_does_not_read_positions(name, seed):
    """The cache's premise: moving the control points gives the same M, bit for bit."""
    mesh = MESHES[name]
    moved = _moved(mesh, seed)
    assert operator_key(moved, BuildOptions()) == operator_key(mesh, BuildOptions())
    assert_same_operator(patching.build_operator(mesh), patching.build_operator(moved))


def test_the_key_names_everything_but_positions():
    mesh = MESHES["grid_corner_hole"]
    key = operator_key(mesh, BuildOptions())
    assert operator_key(dataclasses.replace(mesh, name="other", locations={}), BuildOptions()) == key
    changed = {
        "interval": dataclasses.replace(mesh, intervals={(0, 1): 2.0}),
        "interval bits": dataclasses.replace(mesh, intervals={(0, 1): float(np.nextafter(1.0, 2.0))}),
        "crease": dataclasses.replace(mesh, creases={**mesh.creases, (21, 22): 3.0}),
        "corner": dataclasses.replace(mesh, corners={}),
        "hole": dataclasses.replace(mesh, holes=frozenset({31})),
        "boundary": dataclasses.replace(mesh, interpolate_boundary=2),
        "crease method": dataclasses.replace(mesh, crease_method="chaikin"),
        "faces": dataclasses.replace(mesh, face_vertices=np.roll(mesh.face_vertices.reshape(-1, 4), 1, axis=1).ravel()),
    }
    keys = {what: operator_key(m, BuildOptions()) for what, m in changed.items()}
    keys["angles"] = operator_key(mesh, BuildOptions(angles="uniform"))
    keys["anchors"] = operator_key(mesh, BuildOptions(anchors="extraction"))
    assert key not in keys.values() and len(set(keys.values())) == len(keys)
    assert operator_key(mesh, BuildOptions(anchors="limit-fit")) is None  # reads the control points


def test_the_key_follows_the_g1_settings(monkeypatch):
    from patching.extraordinary import g1_patches

    mesh = MESHES["eps_random_intervals"]
    key = operator_key(mesh, BuildOptions())
    monkeypatch.setattr(g1_patches, "MONOTONE_SPOKES", False)
    assert operator_key(mesh, BuildOptions()) != key


def _saved(tmp_path, name="eps_random_intervals"):
    mesh = MESHES[name]
    cache = OperatorCache(tmp_path, background=False)
    key = operator_key(mesh, BuildOptions())
    cache.save(key, patching.build_operator(mesh))
    return mesh, cache, key


@pytest.mark.parametrize("damage", ["flip a data byte", "flip a header byte", "truncate", "empty", "garbage"])
def test_a_damaged_entry_is_a_miss_and_the_next_build_rewrites_it(tmp_path, damage):
    mesh, cache, key = _saved(tmp_path)
    path = cache.path(key)
    data = bytearray(path.read_bytes())
    if damage == "flip a data byte":
        data[-5] ^= 0x10
    elif damage == "flip a header byte":
        data[len(operator_cache.MAGIC) + 20] ^= 0x01
    elif damage == "truncate":
        data = data[: len(data) // 2]
    elif damage == "empty":
        data = bytearray()
    else:
        data = bytearray(os.urandom(5000))
    path.write_bytes(bytes(data))
    assert cache.load(key, mesh.name) is None
    op = operator_for(mesh, BuildOptions(), cache)  # built afresh and written again
    back = cache.load(key, mesh.name)
    assert back is not None
    assert_same_operator(op, back)


def test_an_entry_under_another_key_is_a_miss(tmp_path):
    mesh, cache, key = _saved(tmp_path)
    other = "0" * 64
    cache.path(other).write_bytes(cache.path(key).read_bytes())
    assert cache.load(other, mesh.name) is None
    assert cache.load(key, mesh.name) is not None


def test_the_cap_keeps_the_most_recently_used(tmp_path):
    cache = OperatorCache(tmp_path, background=False)
    op = patching.build_operator(MESHES["open_disc"])
    keys = [f"{i:064x}" for i in range(4)]
    for i, key in enumerate(keys):
        cache.save(key, op)
        os.utime(cache.path(key), (1e9 + 100 * i, 1e9 + 100 * i))
    size = cache.path(keys[0]).stat().st_size
    assert cache.load(keys[0], "x") is not None  # a read refreshes the oldest entry's mtime
    assert cache.evict(max_bytes=3 * size) == 2  # down to EVICT_TO (0.8) of the cap: 2.4 entries
    assert sorted(p for _, _, p in cache.entries()) == sorted(str(cache.path(k)) for k in (keys[0], keys[3]))
    small = OperatorCache(tmp_path / "small", max_bytes=size // 2, background=False)
    small.save(keys[0], op)  # larger than the whole cap: not written
    assert not small.path(keys[0]).exists()


class _AbandonLater:
    """An abandon flag that is raised at its ``calls``-th look, noting what the entry's folder
    held then (the writer looks once per piece of the digest pass and once per chunk)."""

    def __init__(self, calls: int, folder) -> None:
        self.calls, self.folder, self.seen = calls, folder, None

    def is_set(self) -> bool:
        self.calls -= 1
        if self.calls == 0:
            self.seen = sorted(p.name for p in self.folder.iterdir())
        return self.calls <= 0

    def set(self) -> None:
        self.calls = 0


@pytest.mark.parametrize("when", ["before the first chunk", "in the middle of the file"])
def test_an_abandoned_write_leaves_no_file(tmp_path, monkeypatch, when):
    mesh = MESHES["eps_random_intervals"]
    op = patching.build_operator(mesh)
    monkeypatch.setattr(operator_cache, "CHUNK", 256)  # many chunks, so many looks at the flag
    cache = OperatorCache(tmp_path, background=True)
    digest_looks = 2 * len(operator_arrays(op)[0])  # at most: one a piece, an array and its padding
    cache._abandon = _AbandonLater(1 if when == "before the first chunk" else digest_looks + 20, cache.directory)
    key = operator_key(mesh, BuildOptions())
    cache.save(key, op)
    cache.close()  # waits for the writer, which stopped at the flag
    if when == "in the middle of the file":
        (tmp,) = cache._abandon.seen  # the temporary file was there, part written
        assert tmp.startswith(".nupatch-") and tmp.endswith(".tmp")
    assert not cache.path(key).exists()
    assert not cache.directory.exists() or list(cache.directory.iterdir()) == []  # no temporary file left


def test_nupatch_build_reads_the_entry_and_no_cache_does_not(tmp_path, cli_main, monkeypatch):
    monkeypatch.setenv("NUPATCH_CACHE_DIR", str(tmp_path / "cache"))
    mesh_path = tmp_path / "ring.obj"
    mesh = MESHES["eps_random_intervals"]
    from export import write_obj

    write_obj(mesh, mesh_path)
    first = tmp_path / "first.stl"
    assert cli_main("build", mesh_path, "-o", first, "-q").returncode == 0
    cache = OperatorCache(tmp_path / "cache")
    (entry,) = [p for _, _, p in cache.entries()]
    read = patching.read_mesh(mesh_path)
    key = operator_key(read, BuildOptions())
    assert entry == str(cache.path(key))
    # Replace the entry by a valid one of another operator (M scaled by 2): a build that reads
    # the entry writes that surface, twice the size; --no-cache writes the right one.
    op = cache.load(key, read.name)
    doubled = dataclasses.replace(op, matrix=op.matrix * 2.0)
    OperatorCache(tmp_path / "cache", background=False).save(key, doubled)
    from_cache, fresh = tmp_path / "from_cache.stl", tmp_path / "fresh.stl"
    assert cli_main("build", mesh_path, "-o", from_cache, "-q").returncode == 0
    assert cli_main("build", mesh_path, "-o", fresh, "-q", "--no-cache").returncode == 0
    import trimesh

    size = lambda p: float(np.ptp(trimesh.load(p).vertices, axis=0).max())  # noqa: E731
    # (tessellations of the two surfaces sample them at other points: the extents agree to 1e-4)
    assert size(from_cache) == pytest.approx(2.0 * size(fresh), rel=1e-3)
    assert first.read_bytes() == fresh.read_bytes()


def test_moved_control_points_build_from_the_entry(tmp_path, cli_main, monkeypatch):
    """The edit cycle: the same mesh with moved points reads the entry and gives the surface
    of its own points (the same file as a build without the cache)."""
    monkeypatch.setenv("NUPATCH_CACHE_DIR", str(tmp_path / "cache"))
    from export import write_obj

    mesh = MESHES["adaptive_semi_sharp"]
    write_obj(mesh, tmp_path / "a.obj")
    write_obj(_moved(mesh, 5), tmp_path / "b.obj")
    for name in ("a", "b"):
        assert cli_main("build", tmp_path / f"{name}.obj", "-o", tmp_path / f"{name}.stl", "-q").returncode == 0
    cache = OperatorCache(tmp_path / "cache")
    assert len(cache.entries()) == 1 and cache.load(operator_key(patching.read_mesh(tmp_path / "b.obj"), BuildOptions()), "b")
    assert cli_main("build", tmp_path / "b.obj", "-o", tmp_path / "b_fresh.stl", "-q", "--no-cache").returncode == 0
    assert (tmp_path / "b.stl").read_bytes() == (tmp_path / "b_fresh.stl").read_bytes()


def test_concurrent_builds_of_one_mesh_share_a_whole_entry(tmp_path, run_cli, monkeypatch):
    """Three ``nupatch build`` processes of the same mesh at once, over one empty cache, while
    a fourth process evicts everything in a loop: each writes the right file, and what the
    cache holds afterwards is whole (or nothing, if the evictor had the last word)."""
    import subprocess
    import sys

    from export import write_obj
    from tests.conftest import NUPATCH

    mesh = MESHES["adaptive_semi_sharp"]
    write_obj(mesh, tmp_path / "m.obj")
    monkeypatch.setenv("NUPATCH_CACHE_DIR", str(tmp_path / "cache"))  # for run_cli's builds too
    env = dict(os.environ, PYTHONPATH=str(REPO))
    evictor = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom export.operator_cache import OperatorCache\n"
         "c = OperatorCache(sys.argv[1])\nend = time.monotonic() + 20\n"
         "while time.monotonic() < end:\n    c.evict(max_bytes=0)\n    time.sleep(0.01)\n", str(tmp_path / "cache")],
        env=env)
    builds = [subprocess.Popen([*NUPATCH, "build", "m.obj", "-o", f"out{i}.stl", "-q"], cwd=tmp_path, env=env,
                               stderr=subprocess.PIPE, text=True) for i in range(3)]
    for p in builds:
        assert p.wait(timeout=300) == 0, p.stderr.read()
    evictor.kill()
    evictor.wait()
    fresh = tmp_path / "fresh.stl"
    assert run_cli("build", tmp_path / "m.obj", "-o", fresh, "-q", "--no-cache").returncode == 0
    for i in range(3):
        assert (tmp_path / f"out{i}.stl").read_bytes() == fresh.read_bytes()
    cache = OperatorCache(tmp_path / "cache")
    key = operator_key(patching.read_mesh(tmp_path / "m.obj"), BuildOptions())
    leftovers = [p.name for p in cache.directory.iterdir() if p.name != f"{key}.npop"]
    assert leftovers == []
    if cache.path(key).exists():
        assert_same_operator(cache.load(key, "m"), patching.build_operator(patching.read_mesh(tmp_path / "m.obj")))
    # and a build now (no evictor) leaves the whole entry
    assert run_cli("build", tmp_path / "m.obj", "-o", tmp_path / "again.stl", "-q").returncode == 0
    assert cache.load(key, "m") is not None
