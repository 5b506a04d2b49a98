"""Fault injection: damaged STEP files, signals to real processes, hostile output targets, full
disks, geometry that is not what it says, resource limits, API misuse, and an OBJ grammar fuzzer.

Every bad case through the CLI: exit 2 (or 128 + signal), one line on stderr, nothing on stdout
that is not ours, no output file and no temporary file left.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import resource
import signal
import stat
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import patching
from patching.errors import KnotError, MeshError, NupatchError, TagError
from patching.mesh.obj import parse_obj

from .conftest import NUPATCH, REPO

ENV = dict(os.environ, PYTHONPATH=str(REPO))
ANSI = re.compile(r"\x1b\[")


# ---------------------------------------------------------------- meshes of our own

def cube_obj() -> str:
    """A unit cube, 8 vertices and 6 quads (outward)."""
    v = [(x, y, z) for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    return "".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join("f " + " ".join(map(str, f)) + "\n" for f in faces)


def torus_obj(n: int, m: int) -> str:
    """A regular n x m torus (valence 4 everywhere, bicubic patches only)."""
    lines = []
    for i in range(n):
        for j in range(m):
            u, w = 2 * math.pi * i / n, 2 * math.pi * j / m
            lines.append(f"v {(3 + math.cos(w)) * math.cos(u):.9f} {(3 + math.cos(w)) * math.sin(u):.9f} {math.sin(w):.9f}")
    for i in range(n):
        for j in range(m):
            a, b = i * m + j + 1, ((i + 1) % n) * m + j + 1
            c, d = ((i + 1) % n) * m + (j + 1) % m + 1, i * m + (j + 1) % m + 1
            lines.append(f"f {a} {b} {c} {d}")
    return "\n".join(lines) + "\n"


def run(*args, cwd=None, timeout=300, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([*NUPATCH, *map(str, args)], capture_output=True, text=True, cwd=cwd or REPO, env=ENV, timeout=timeout, **kw)


def one_error_line(proc: subprocess.CompletedProcess, code: int = 2) -> str:
    lines = proc.stderr.splitlines()
    assert proc.returncode == code, (proc.returncode, proc.stderr)
    assert len(lines) == 1 and lines[0].startswith("nupatch: "), proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    return lines[0]


def leftovers(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.name.startswith(".nupatch") or p.suffix in (".tmp", ".probe"))


@pytest.fixture(scope="module")
def cube_step(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("cube")
    (d / "cube.obj").write_text(cube_obj())
    proc = run("build", d / "cube.obj", "-o", d / "cube.step", "-q")
    assert proc.returncode == 0, proc.stderr
    return d / "cube.step"


# ---------------------------------------------------------------- 1. damaged STEP files

def _damaged(text: str, kind: str) -> str:
    first_point = re.search(r"CARTESIAN_POINT\('',\(([^,]+),", text)
    if kind == "truncated":
        return text[: len(text) // 2]
    if kind == "truncated at an entity, closed":  # the syntax is whole, references dangle
        body = text[: text.index("DATA;")]
        entities = text[text.index("DATA;") :].split(";\n")
        return body + ";\n".join(entities[: len(entities) // 2]) + ";\nENDSEC;\nEND-ISO-10303-21;\n"
    if kind == "missing reference":
        ref = re.search(r"B_SPLINE_SURFACE_WITH_KNOTS\('',\d,\d,\(\s*\(#(\d+)", text)
        return text[: ref.start(1)] + "999999" + text[ref.end(1) :]
    if kind == "dropped entity":
        return re.sub(r"\n#(\d+) = CARTESIAN_POINT[^;]*;", "", text, count=1)
    value = {"NAN": "NAN", "infinite": "1.E999", "huge": "1.E200"}[kind]
    return text[: first_point.start(1)] + value + text[first_point.end(1) :]


DAMAGE = ["truncated", "truncated at an entity, closed", "missing reference", "dropped entity", "NAN", "infinite", "huge"]


@pytest.mark.parametrize("kind", DAMAGE)
def test_check_refuses_a_damaged_step_file_in_one_line_and_prints_nothing_on_stdout(cube_step, tmp_path, kind):
    bad = tmp_path / "bad.step"
    bad.write_text(_damaged(cube_step.read_text(), kind))
    proc = run("check", bad, "--json", "--require-g1", timeout=120)
    line = one_error_line(proc)
    assert "damaged STEP file" in line or "not a readable" in line, line
    assert proc.stdout == "" and not ANSI.search(proc.stderr)


@pytest.mark.parametrize("kind", ["NAN", "infinite", "missing reference"])
def test_render_refuses_a_damaged_step_file_without_hanging(cube_step, tmp_path, kind):
    bad = tmp_path / "bad.step"
    bad.write_text(_damaged(cube_step.read_text(), kind))
    proc = run("render", bad, "-o", tmp_path / "x.png", timeout=120)
    one_error_line(proc)
    assert not (tmp_path / "x.png").exists() and leftovers(tmp_path) == []


def test_the_undamaged_file_still_checks_and_its_json_is_pure(cube_step):
    import json

    proc = run("check", cube_step, "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["valid"] is True and not ANSI.search(proc.stdout)


def test_real_scan_ignores_strings_and_names_the_line():
    from export.step_check import check_step_reals

    check_step_reals(b"#1 = PRODUCT('1.E999','x',(#2));\n#3 = CARTESIAN_POINT('',(1.E2,0.,0.));\n", "f")
    with pytest.raises(patching.InputFileError, match=r"f:2"):
        check_step_reals(b"#1 = X('it''s');\n#3 = CARTESIAN_POINT('',(-1.5E31,0.,0.));\n", "f")


# ---------------------------------------------------------------- 2. signals and processes

SLOW_WRITER = """
import ctypes, os, signal, sys, export.formats as f
from export.cli import main
real = f.WRITERS["step"]
def slow(job, tmp):
    real(job, tmp)
    print("WRITING", file=sys.stderr, flush=True)
    if os.environ.get("BLOCK") == "1":  # the signal reaches another thread, as during OCC's work
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM, signal.SIGHUP})
    ctypes.CDLL(None).sleep(30)   # a long native call, as OpenCASCADE's write of a big model
f.WRITERS["step"] = slow
sys.exit(main(sys.argv[1:]))
"""


def _default_sigint():
    """A shell's background job inherits SIGINT ignored, and Python then keeps it ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("signame,block", [("SIGTERM", "0"), ("SIGHUP", "0"), ("SIGINT", "0"), ("SIGTERM", "1"), ("SIGHUP", "1")])
def test_a_signal_during_a_long_native_write_leaves_no_temp_file_and_the_old_output(tmp_path, signame, block):
    """block=1: the main thread does not see the signal while in native code (the watchdog's case)."""
    (tmp_path / "m.obj").write_text(cube_obj())
    out = tmp_path / "m.step"
    out.write_text("old")
    p = subprocess.Popen([sys.executable, "-c", SLOW_WRITER, "build", "m.obj", "-o", "m.step", "-q"],
                         cwd=tmp_path, env=dict(ENV, BLOCK=block), stderr=subprocess.PIPE, text=True,
                         preexec_fn=_default_sigint)
    assert p.stderr.readline().strip() == "WRITING"
    assert leftovers(tmp_path)  # the temporary file exists while writing
    signum = getattr(signal, signame)
    p.send_signal(signum)
    err = p.communicate(timeout=20)[1]
    assert p.returncode == 128 + signum, (p.returncode, err)
    assert len(err.splitlines()) == 1 and err.startswith("nupatch: "), err
    assert leftovers(tmp_path) == [] and out.read_text() == "old"


def test_an_interrupt_during_the_output_probe_leaves_no_probe(tmp_path, monkeypatch):
    """A signal that unwinds (Terminated, KeyboardInterrupt) right after the probe file of the
    output check was created still removes it (the SIGHUP run of the real write below once
    left a ``.probe`` file when the signal came during the check)."""
    from export import atomic

    real_close = os.close

    def interrupted(fd):
        real_close(fd)
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic.os, "close", interrupted)
    with pytest.raises(KeyboardInterrupt):
        atomic.check_output_path(tmp_path / "out.step")
    monkeypatch.undo()
    assert leftovers(tmp_path) == []


@pytest.mark.slow
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_sigterm_during_a_real_step_write(tmp_path, signame):
    (tmp_path / "t.obj").write_text(torus_obj(24, 24))
    out = tmp_path / "t.step"
    out.write_text("old")
    p = subprocess.Popen([*NUPATCH, "build", "t.obj", "-o", "t.step", "-q"], cwd=tmp_path, env=ENV, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    # the write's temporary file (not the output check's probe, which lives a few microseconds)
    while not [n for n in leftovers(tmp_path) if n.endswith(".tmp")] and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert p.poll() is None, "the write ended before the signal: use a larger torus"
    p.send_signal(getattr(signal, signame))
    err = p.communicate(timeout=60)[1]
    assert p.returncode == 128 + getattr(signal, signame), err
    assert err.strip() == f"nupatch: terminated by {signame}"
    assert leftovers(tmp_path) == [] and out.read_text() == "old"


def test_a_temp_file_left_by_sigkill_is_recognised_and_removed_by_the_next_run(tmp_path):
    from export.atomic import is_temporary_name

    (tmp_path / "m.obj").write_text(cube_obj())
    p = subprocess.Popen([sys.executable, "-c", SLOW_WRITER, "build", "m.obj", "-o", "m.step", "-q"],
                         cwd=tmp_path, env=ENV, stderr=subprocess.PIPE, text=True)
    assert p.stderr.readline().strip() == "WRITING"
    p.kill()
    p.wait()
    left = leftovers(tmp_path)
    assert len(left) == 1 and is_temporary_name(left[0])
    other = tmp_path / ("." + "x" * 20 + ".tmp")  # not ours: never touched
    other.write_text("keep")
    proc = run("build", "m.obj", "-o", "m.step", "-q", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert leftovers(tmp_path) == [other.name] and (tmp_path / "m.step").stat().st_size > 1000


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True).stdout
    return [int(x) for x in out.split()]


def _running(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGTERM])
def test_workers_of_build_j2_die_with_their_parent_and_write_nothing(tmp_path, how):
    injected = SLOW_WRITER.replace("real(job, tmp)\n", "real(job, tmp)\n    open(tmp.parent / ('started-' + tmp.name), 'w').close()\n")
    for name in ("a", "b"):
        (tmp_path / f"{name}.obj").write_text(cube_obj())
    (tmp_path / "out").mkdir()
    p = subprocess.Popen([sys.executable, "-c", injected, "build", "-j", "2", "a.obj", "b.obj", "-o", "out", "-q"],
                         cwd=tmp_path, env=ENV, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while len(list((tmp_path / "out").glob("started-*"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    workers = _children(p.pid)
    assert len(workers) == 2
    os.kill(p.pid, how)
    p.wait(timeout=30)
    deadline = time.monotonic() + 15
    while any(_running(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_running(w) for w in workers)
    written = sorted(x.name for x in (tmp_path / "out").iterdir() if not x.name.startswith("started-"))
    assert written == [] or how == signal.SIGKILL and all(x.startswith(".nupatch-") for x in written), written


# ---------------------------------------------------------------- 3. output targets

@pytest.fixture(scope="module")
def cube_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("out")
    (d / "cube.obj").write_text(cube_obj())
    return d


def test_a_fifo_is_refused_and_stays_a_fifo(cube_dir):
    fifo = cube_dir / "pipe.stl"
    os.mkfifo(fifo)
    try:
        line = one_error_line(run("build", cube_dir / "cube.obj", "-o", fifo, timeout=120))
        assert "FIFO" in line and stat.S_ISFIFO(os.stat(fifo).st_mode)
    finally:
        fifo.unlink()


def test_a_character_device_is_refused_and_left_alone(cube_dir):
    link = cube_dir / "null.step"
    link.symlink_to("/dev/null")
    targets = [link]
    if os.geteuid() == 0:
        node = cube_dir / "node.step"
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, 3))
        targets.append(node)
    try:
        for target in targets:
            line = one_error_line(run("build", cube_dir / "cube.obj", "-o", target, timeout=120))
            assert "character device" in line
            assert stat.S_ISCHR(os.stat(target).st_mode)
        assert link.is_symlink() and leftovers(cube_dir) == []
    finally:
        for target in targets:
            target.unlink()


def test_a_long_legal_name_is_written(cube_dir):
    out = cube_dir / ("n" * 251 + ".stl")  # 255 bytes: NAME_MAX
    proc = run("build", cube_dir / "cube.obj", "-o", out, "-q")
    assert proc.returncode == 0, proc.stderr
    assert out.stat().st_size > 84 and leftovers(cube_dir) == []
    out.unlink()


def test_a_replaced_file_keeps_its_mode(cube_dir):
    out = cube_dir / "private.brep"
    out.write_text("old")
    os.chmod(out, 0o600)
    assert run("build", cube_dir / "cube.obj", "-o", out, "-q").returncode == 0
    assert stat.S_IMODE(out.stat().st_mode) == 0o600 and out.read_text() != "old"


@pytest.mark.parametrize("fmt", ["stl", "step"])
def test_dash_writes_to_stdout_and_no_file_named_dash(cube_dir, fmt):
    proc = subprocess.run([*NUPATCH, "build", "cube.obj", "-o", "-", "--format", fmt, "-q"], cwd=cube_dir, env=ENV, capture_output=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert not (cube_dir / "-").exists()
    ref = cube_dir / f"ref.{fmt}"
    assert run("build", cube_dir / "cube.obj", "-o", ref, "-q").returncode == 0
    if fmt == "stl":
        assert proc.stdout == ref.read_bytes()
    else:
        assert proc.stdout.startswith(b"ISO-10303-21") and len(proc.stdout) > 0.9 * ref.stat().st_size


@contextlib.contextmanager
def full_disk(tmp_path: Path):
    """A directory on a 64 KiB tmpfs (root and mount allowed); else None (callers fall back)."""
    mnt = tmp_path / "tiny"
    mnt.mkdir()
    ok = os.geteuid() == 0 and subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mnt)], capture_output=True).returncode == 0
    try:
        yield mnt if ok else None
    finally:
        if ok:
            subprocess.run(["umount", str(mnt)], check=False)


def _fsize_limit():
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # inherited: write() then fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (32 * 1024, 32 * 1024))


FORMATS = ["step", "iges", "brep", "stl", "glb", "obj"]


@pytest.mark.slow
def test_a_full_disk_is_one_line_exit_2_in_every_format(tmp_path):
    """ENOSPC from a 64 KiB tmpfs where mounting works; otherwise EFBIG from RLIMIT_FSIZE."""
    mesh = tmp_path / "t.obj"
    mesh.write_text(torus_obj(8, 8))  # every format's file is larger than 64 KiB
    with full_disk(tmp_path) as mnt:
        for fmt in FORMATS:
            if mnt is not None:
                proc = run("build", mesh, "-o", mnt / f"t.{fmt}", "--tolerance", "1e-3", timeout=300)
                where = mnt
            else:
                where = tmp_path / "lim"
                where.mkdir(exist_ok=True)
                proc = run("build", mesh, "-o", where / f"t.{fmt}", "--tolerance", "1e-3", preexec_fn=_fsize_limit, timeout=300)
            line = one_error_line(proc)
            assert "no space left" in line or "file too large" in line, (fmt, line)
            assert list(where.iterdir()) == [], (fmt, list(where.iterdir()))


# ---------------------------------------------------------------- 4. geometry that is not what it says

def _cube_mesh(extra: str = "") -> patching.ControlMesh:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return parse_obj(cube_obj() + extra, source="cube.obj", name="cube")


def test_a_far_stray_vertex_changes_neither_size_nor_tessellation():
    from export.formats import tessellate

    plain, stray = patching.build(_cube_mesh()), patching.build(_cube_mesh("v 1e6 0 0\n"))
    assert stray.size == plain.size
    assert len(tessellate(stray).triangles) == len(tessellate(plain).triangles)


def test_all_points_on_a_line_are_refused_a_closed_plane_is_a_shell():
    """A net on a line has no area: refused.  A closed net on a plane encloses no volume: the
    B-rep makes it a shell with a warning (each component judged on its own scale)."""
    from export.brep import to_shape
    from OCP.TopAbs import TopAbs_SHELL

    line = np.array([[t, 2 * t, 0.5 * t] for t in np.linspace(0, 1, 8)])
    plane = np.array([[x, y, 0.0] for x in (0.0, 1.0) for y in (0.0, 1.0) for _ in (0, 1)])
    plane[1::2, 0] += 0.25
    cube = _cube_mesh()
    with pytest.raises(MeshError, match="line"):
        patching.build(cube.with_positions(line))
    with pytest.warns(patching.NupatchWarning):
        shape = to_shape(patching.build(cube.with_positions(plane)))
    assert shape.ShapeType() == TopAbs_SHELL


@pytest.mark.parametrize("sep", ["\u2028", "\u2029", "\x85", "\x0c", "\x1c", "\r", "\x0b"])
def test_unicode_line_breaks_inside_a_comment_start_no_statement(sep):
    mesh = _cube_mesh(f"# note{sep}v 9 9 9\n")
    assert mesh.n_vertices == 8


def test_crlf_continuation_and_maplib_usemap_are_valid_obj():
    text = cube_obj().replace("\n", "\r\n").replace("f 1 2 4 3", "f 1 2 \\\r\n 4 3")
    mesh = parse_obj("maplib a.map\nusemap m\n" + text, source="c.obj")
    assert mesh.n_faces == 6 and list(mesh.face(0)) == [0, 1, 3, 2]


# ---------------------------------------------------------------- 5. resource limits

def test_a_tolerance_that_would_need_gigabytes_is_refused_up_front(cube_dir):
    start = time.monotonic()
    line = one_error_line(run("build", cube_dir / "cube.obj", "-o", cube_dir / "b.stl", "--tolerance", "1e-6", timeout=120))
    assert "--tolerance" in line and "budget" in line and time.monotonic() - start < 60
    assert not (cube_dir / "b.stl").exists()


def test_render_and_build_refuse_a_tolerance_in_the_same_line(cube_dir):
    a = one_error_line(run("render", cube_dir / "cube.obj", "-o", cube_dir / "x.png", "--tolerance", "1e-9", timeout=120))
    b = one_error_line(run("build", cube_dir / "cube.obj", "-o", cube_dir / "x.stl", "--tolerance", "1e-9", timeout=120))
    assert a == b and "--tolerance" in a


def test_the_triangle_estimate_follows_opencascade_within_a_factor_of_three():
    from export.budget import estimate_triangles
    from export.formats import tessellate

    for mesh in (_cube_mesh(), parse_obj(torus_obj(10, 10))):
        surface = patching.build(mesh)
        for rel in (1e-2, 1e-3):
            occ = len(tessellate(surface, tolerance=rel * surface.size).triangles)
            ratio = estimate_triangles(surface, rel * surface.size) / occ
            assert 1 / 3 < ratio < 3, (mesh.n_faces, rel, ratio)


def test_render_of_a_step_file_checks_the_budget_too(cube_step, tmp_path):
    from export.budget import estimate_shape_triangles, estimate_triangles
    from export.step import read_step

    line = one_error_line(run("render", cube_step, "-o", tmp_path / "x.png", "--tolerance", "1e-6", timeout=120))
    assert "budget" in line and not (tmp_path / "x.png").exists()
    # the shape's estimate is the surface's: one Bezier span per face, the same nets
    surface = patching.build(_cube_mesh())
    assert estimate_shape_triangles(read_step(cube_step), 1e-3) == estimate_triangles(surface, 1e-3)


def test_info_on_an_endless_device_is_refused_from_its_first_bytes():
    line = one_error_line(run("info", "/dev/zero", timeout=60))
    assert "binary" in line


def test_many_patches_from_a_small_mesh_warn_naming_the_tags():
    from types import SimpleNamespace

    from export.budget import MANY_PATCHES, warn_many_patches

    mesh = patching.from_arrays(*_cube_arrays(), creases={(0, 1): 9.5, (2, 3): 3.0})
    with pytest.warns(patching.NupatchWarning, match=r"crease 0-1 s=9.5"):
        warn_many_patches(mesh, SimpleNamespace(n_patches=MANY_PATCHES + 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_many_patches(mesh, SimpleNamespace(n_patches=MANY_PATCHES))


# ---------------------------------------------------------------- 6. the Python API

def _cube_arrays():
    m = _cube_mesh()
    return m.vertices.copy(), m.quads().copy()


V, F = _cube_arrays()
MISUSE = [
    ("faces", dict(faces=F.ravel().tolist()), MeshError),
    ("faces", dict(faces=F.reshape(2, 3, 4)), MeshError),
    ("faces", dict(faces=F.astype(float) + 0.5), MeshError),
    ("faces", dict(faces="1 2 3 4"), MeshError),
    ("faces", dict(faces=[["a", "b", "c"]]), MeshError),
    ("vertices", dict(vertices=V[:, :2]), MeshError),
    ("vertices", dict(vertices="xyz"), MeshError),
    ("vertices", dict(vertices=[["a", 0, 0]] * 8), MeshError),
    ("intervals", dict(intervals={"0-1": 1.0}), KnotError),
    ("intervals", dict(intervals={(0, 1, 2): 1.0}), KnotError),
    ("intervals", dict(intervals={(0, 1): "one"}), KnotError),
    ("intervals", dict(intervals=[(0, 1)]), KnotError),
    ("creases", dict(creases={(0, 1.5): 2.0}), TagError),
    ("corners", dict(corners=[0, 1]), TagError),
    ("corners", dict(corners={0: None}), TagError),
    ("holes", dict(holes=3), TagError),
    ("name", dict(name=None), MeshError),
    ("interpolate_boundary", dict(interpolate_boundary="1"), TagError),
]


@pytest.mark.parametrize("argument,change,error", MISUSE)
def test_from_arrays_misuse_raises_our_error_naming_the_argument(argument, change, error):
    kwargs = dict(vertices=V, faces=F) | change
    with pytest.raises(error) as info:
        patching.from_arrays(**kwargs)
    assert argument in str(info.value)


def test_whole_float_indices_are_taken():
    assert patching.from_arrays(V, F.astype(float)).n_faces == 6


@pytest.mark.parametrize("points,argument", [(V[:, :2], "points"), (np.hstack([V, V[:, :1]]), "points"),
                                             (np.where(np.arange(8)[:, None] == 3, np.nan, V), "points"),
                                             (V[:5], "points"), ("abc", "points")])
def test_evaluate_checks_its_points(points, argument):
    op = patching.build_operator(patching.from_arrays(V, F))
    with pytest.raises(MeshError, match=argument):
        op.evaluate(points)


@pytest.mark.parametrize("call", [
    lambda m: patching.build(m, angles="bogus"),
    lambda m: patching.build(m, anchors=3),  # (None means the default: BuildOptions.of)
    lambda m: patching.build_operator(m, g1_solve=1),
    lambda m: patching.build_operator(m, refinement="never"),
    lambda m: patching.build("cube.obj"),
    lambda m: patching.build_operator(m, topology=42),
])
def test_build_arguments_are_checked(call):
    with pytest.raises(NupatchError):
        call(patching.from_arrays(V, F))


@pytest.mark.parametrize("arg,kw", [(42, {}), (None, {}), ([1, 2], {}), ("x.step", {"samples_per_edge": 1.5})])
def test_check_continuity_misuse(arg, kw):
    import export

    with pytest.raises(NupatchError):
        export.check_continuity(arg, **kw)


# ---------------------------------------------------------------- 7. smaller

def test_interval_values_equal_up_to_round_off_are_one_value_and_a_conflict_shows_its_digits():
    text = cube_obj() + "t interval 2/1/0 0 1 0.3\nt interval 2/1/0 1 0 0.30000000000000004\n"
    assert parse_obj(text).intervals[(0, 1)] == 0.3
    with pytest.raises(KnotError, match=r"0\.3 and 0\.3000001"):
        parse_obj(cube_obj() + "t interval 2/1/0 0 1 0.3\nt interval 2/1/0 1 0 0.3000001\n")


def test_the_obj_writer_takes_a_non_ascii_name(tmp_path):
    from export.formats import write

    mesh = patching.from_arrays(V, F, name="Würfel")
    out = write(patching.build(mesh), tmp_path / "Würfel.obj")
    assert "o Würfel" in out.read_text(encoding="utf-8")


def test_source_date_epoch_fixes_step_and_iges_time_and_iges_has_no_login_name(cube_dir):
    import getpass

    env = dict(ENV, SOURCE_DATE_EPOCH="1700000000")
    for fmt in ("step", "iges"):
        out = cube_dir / f"dated.{fmt}"
        proc = subprocess.run([*NUPATCH, "build", "cube.obj", "-o", out.name, "-q"], cwd=cube_dir, env=env, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        head = out.read_text()[:2000]
        assert ("2023-11-14T22:13:20" if fmt == "step" else "20231114.221320") in head
        if fmt == "iges":
            assert f"{len(getpass.getuser())}H{getpass.getuser()}," not in head


# ---------------------------------------------------------------- the OBJ grammar fuzzer

NUMBER = st.one_of(st.integers(-3, 12).map(str), st.floats(-4, 4, allow_nan=False).map(repr),
                   st.sampled_from(["nan", "inf", "-inf", "1e400", "1e-320", "0x1", "1,5", "", "--1"]))
JUNK = st.sampled_from(["\u2028", "\x85", "\x0c", "\r", "\t", " \\", "#", "é", "\x00", "\ufeff"])


@st.composite
def obj_statement(draw, nv: int) -> str:
    kind = draw(st.sampled_from(["v", "v", "f", "f", "t", "comment", "blank", "ignored", "junk"]))
    if kind == "v":
        return "v " + " ".join(draw(st.lists(NUMBER, min_size=2, max_size=4)))
    if kind == "f":
        idx = st.integers(-nv - 1, nv + 1).map(str) | st.sampled_from(["1/1", "2//2", "x", "1.5"])
        return "f " + " ".join(draw(st.lists(idx, min_size=2, max_size=5)))
    if kind == "t":
        name = draw(st.sampled_from(["interval", "crease", "corner", "hole", "interpolateboundary", "bogus"]))
        ints = draw(st.lists(st.integers(-1, nv), max_size=4))
        floats = draw(st.lists(NUMBER, max_size=2))
        counts = draw(st.sampled_from([f"{len(ints)}/{len(floats)}/0", "2/1/0", "x/y"]))
        return " ".join(["t", name, counts, *map(str, ints), *floats])
    if kind == "comment":
        return "# " + draw(st.text(max_size=10))
    if kind == "ignored":
        return draw(st.sampled_from(["vt 0 0", "g part", "usemtl m", "maplib x", "s off", "o obj"]))
    if kind == "junk":
        return draw(JUNK) + draw(st.sampled_from(["v 1 2 3", "f 1 2 3", "", "x"]))
    return ""


@st.composite
def obj_files(draw) -> str:
    base = draw(st.sampled_from(["", cube_obj()]))
    nv = 8 if base else draw(st.integers(0, 6))
    lines = draw(st.lists(obj_statement(nv), max_size=8))
    ending = draw(st.sampled_from(["\n", "\r\n"]))
    return base.replace("\n", ending) + ending.join(lines)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(obj_files())
def test_no_obj_from_the_grammar_gives_a_traceback_a_bad_exit_or_a_file_on_failure(tmp_path, capsys, text):
    from export.cli import main

    d = Path(tempfile.mkdtemp(dir=tmp_path))
    mesh = d / "fuzz.obj"
    mesh.write_bytes(text.encode("utf-8", "surrogatepass"))
    out = d / "fuzz.brep"
    code = main(["build", str(mesh), "-o", str(out), "-q"])
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if not line.startswith("nupatch: warning:")]
    assert "Traceback" not in err and "internal error" not in err, err
    assert code in (0, 2), (code, err)
    if code == 2:
        assert len(errors) == 1 and errors[0].startswith("nupatch: error: "), err
        assert not out.exists()
    else:
        assert out.stat().st_size > 0
    assert leftovers(d) == []


def _ep_dense_obj(path: Path) -> None:
    """An icosphere's triangles split into quads (EPs of valence 5 and 6 next to each other)
    with strip intervals drawn from {1, 2, 5}: many distinct local configurations to cache."""
    import trimesh

    from export import write_obj
    from patching.subdivision.catmark import subdivide

    base = trimesh.creation.icosphere(subdivisions=2)
    quad = subdivide(patching.from_arrays(base.vertices, base.faces), 1, rules="opensubdiv")
    topo = patching.Topology(quad)
    rng = np.random.default_rng(0)
    values = rng.choice([1.0, 2.0, 5.0], topo.n_strips)
    first = np.unique(topo.edge_strip, return_index=True)[1]
    intervals = {tuple(int(x) for x in topo.edges[e]): float(values[topo.edge_strip[e]]) for e in first}
    write_obj(patching.from_arrays(quad.vertices, quad.quads(), intervals=intervals), path)


def test_sigterm_while_the_cache_is_written_leaves_only_whole_entries(tmp_path):
    """A real SIGTERM as soon as the first entry of an empty cache is on disk (the writer
    thread has more to write): exit 143, one line, and the cache holds whole entries only; a
    later build over that cache is the same surface and fills in the rest."""
    from tests.helpers import whole_cache_entries

    _ep_dense_obj(tmp_path / "m.obj")
    cache = tmp_path / "cache"
    env = dict(ENV, NUPATCH_CACHE_DIR=str(cache))
    p = subprocess.Popen([*NUPATCH, "build", "m.obj", "-o", "m.step", "-q"], cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not list(cache.glob("solves/*/*")) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.002)
    assert p.poll() is None, "the build ended before its first cache entry: a larger mesh is needed"
    p.send_signal(signal.SIGTERM)
    err = p.communicate(timeout=60)[1]
    assert p.returncode == 143, err
    assert err.strip() == "nupatch: terminated by SIGTERM"
    partial = whole_cache_entries(cache)
    assert not (tmp_path / "m.step").exists()
    again = subprocess.run([*NUPATCH, "build", "m.obj", "-o", "m.step", "-q"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    full = whole_cache_entries(cache)
    assert set(partial) < set(full)  # the interrupted run left some, the next wrote the others
    plain = subprocess.run([*NUPATCH, "build", "m.obj", "-o", "plain.step", "-q", "--no-cache"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert plain.returncode == 0, plain.stderr
    data = lambda path: path.read_text().split("DATA;", 1)[1]  # noqa: E731 - the header holds the time stamp
    assert data(tmp_path / "m.step") == data(tmp_path / "plain.step")


def test_sigterm_while_the_operator_is_written_leaves_no_partial_entry(tmp_path):
    """A real SIGTERM while the operator cache's writer has its temporary file open: exit 143,
    one line, no output, no temporary file and no partial entry left (an entry there is whole);
    the next build gives the same surface as --no-cache and leaves a whole entry."""
    import trimesh

    from export import write_obj
    from export.atomic import is_temporary_name
    from export.operator_cache import OperatorCache
    from patching.operator.archive import operator_key
    from patching.subdivision.catmark import subdivide

    base = trimesh.creation.icosphere(subdivisions=3)  # 3,840 quads after one step: M of ~45 MB
    write_obj(subdivide(patching.from_arrays(base.vertices, base.faces), 1, rules="opensubdiv"), tmp_path / "m.obj")
    cache = tmp_path / "cache"
    env = dict(ENV, NUPATCH_CACHE_DIR=str(cache))
    p = subprocess.Popen([*NUPATCH, "build", "m.obj", "-o", "m.step", "-q"], cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True)
    writing = lambda: [f for f in (cache / "operators").glob("*") if is_temporary_name(f.name)] if (cache / "operators").is_dir() else []  # noqa: E731
    deadline = time.monotonic() + 240
    while not writing() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    assert p.poll() is None, "the build ended before its operator was being written: a larger mesh is needed"
    p.send_signal(signal.SIGTERM)
    err = p.communicate(timeout=60)[1]
    assert p.returncode == 143, err
    assert err.strip() == "nupatch: terminated by SIGTERM"
    assert not (tmp_path / "m.step").exists()
    assert [f.name for f in (cache / "operators").iterdir() if not f.name.endswith(".npop")] == []
    store = OperatorCache(cache)
    key = operator_key(patching.read_mesh(tmp_path / "m.obj"), patching.BuildOptions())
    assert all(store.load(Path(path).stem, "m") is not None for _, _, path in store.entries())  # whole, or none
    again = subprocess.run([*NUPATCH, "build", "m.obj", "-o", "m.step", "-q"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert store.load(key, "m") is not None
    plain = subprocess.run([*NUPATCH, "build", "m.obj", "-o", "plain.step", "-q", "--no-cache"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert plain.returncode == 0, plain.stderr
    data = lambda path: path.read_text().split("DATA;", 1)[1]  # noqa: E731 - the header holds the time stamp
    assert data(tmp_path / "m.step") == data(tmp_path / "plain.step")
