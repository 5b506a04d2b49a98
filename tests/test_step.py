"""export.step: atomic, deterministic STEP writes that read back as the same solid."""

from __future__ import annotations

import os
import re
import stat

import pytest
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.IFSelect import IFSelect_RetFail
from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID

import export.step as step_module
from export.brep import to_shape
from export.step import StepError, read_step, write_step
from patching.errors import InputFileError, NupatchError, OutputError

try:
    from tests.helpers import count, cube_surface as cube, torus_surface as torus, volume
except ImportError:  # tests/ on sys.path rather than a package
    from tests.helpers import count, cube_surface as cube, torus_surface as torus, volume

FILE_NAME = re.compile(r"FILE_NAME\(.*?\);", re.DOTALL)


@pytest.fixture(scope="module")
def cube_shape():
    return to_shape(cube((3, 5, 3, 5, 5, 3)))


def test_write_then_read_gives_the_same_solid(tmp_path, cube_shape):
    path = write_step(cube_shape, tmp_path / "cube.step", "cube")
    assert path == tmp_path / "cube.step"
    shape = read_step(path)
    assert count(shape, TopAbs_SOLID) == 1 and count(shape, TopAbs_FACE) == 6
    assert BRepCheck_Analyzer(shape).IsValid()
    # OCC writes reals with 13 significant digits, which moves poles within their face's
    # plane (e.g. 1/3) and may open 1e-13 slits between a cubic face and a quintic one.
    assert volume(shape) == pytest.approx(1.0, abs=1e-12)


def test_product_name_and_millimetres_are_in_the_file(tmp_path, cube_shape):
    text = write_step(cube_shape, tmp_path / "out.step", "my part 'v2'").read_text()
    assert "PRODUCT('my part ''v2''','my part ''v2''','',(" in text
    assert re.search(r"LENGTH_UNIT\(\)\s*NAMED_UNIT\(\*\)\s*SI_UNIT\(\.MILLI\.,\.METRE\.\)", text)
    assert "FILE_NAME('out.step'," in text
    assert "AUTOMOTIVE_DESIGN" in text  # AP214


def test_writes_are_deterministic_but_for_the_time_stamp(tmp_path):
    shape = to_shape(torus(degrees=[3, 5] * 24))
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first = write_step(shape, tmp_path / "a" / "t.step", "torus").read_text()
    second = write_step(shape, tmp_path / "b" / "t.step", "torus").read_text()
    assert len(FILE_NAME.findall(first)) == 1
    assert FILE_NAME.sub("", first) == FILE_NAME.sub("", second)


def test_file_mode_follows_the_umask(tmp_path, cube_shape):
    mask = os.umask(0o022)
    try:
        path = write_step(cube_shape, tmp_path / "c.step", "c")
    finally:
        os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


def _assert_untouched(directory, path, old: bytes):
    assert path.read_bytes() == old
    assert sorted(p.name for p in directory.iterdir()) == [path.name]  # no temporary left


def test_invalid_shape_leaves_the_old_file(tmp_path):
    surf = torus()
    surf.groups[0].coefficients[7][1:-1, 0] += [0.0, 0.0, 1e-3]  # neighbours disagree
    broken = to_shape(surf, check=False)
    path = tmp_path / "t.step"
    path.write_bytes(b"old")
    with pytest.raises(StepError, match="invalid shape"):
        write_step(broken, path, "t")
    _assert_untouched(tmp_path, path, b"old")


def test_writer_failure_leaves_the_old_file(tmp_path, monkeypatch, cube_shape):
    class FailingWriter(step_module.STEPControl_Writer):
        def Write(self, name):  # a partial file, then a failure status
            super().Write(name)
            return IFSelect_RetFail

    monkeypatch.setattr(step_module, "STEPControl_Writer", FailingWriter)
    path = tmp_path / "c.step"
    path.write_bytes(b"old")
    with pytest.raises(StepError, match="Write returned"):
        write_step(cube_shape, path, "c")
    _assert_untouched(tmp_path, path, b"old")


def test_missing_directory_is_an_output_error(tmp_path, cube_shape):
    with pytest.raises(OutputError) as info:
        write_step(cube_shape, tmp_path / "nowhere" / "c.step", "c")
    assert isinstance(info.value, NupatchError) and "nowhere" in str(info.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_read_only_directory_is_an_output_error(tmp_path, cube_shape):
    path = tmp_path / "c.step"
    path.write_bytes(b"old")
    tmp_path.chmod(0o555)
    try:
        with pytest.raises(OutputError):
            write_step(cube_shape, path, "c")
    finally:
        tmp_path.chmod(0o755)
    _assert_untouched(tmp_path, path, b"old")


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc")
def test_directory_refusing_new_files_is_an_output_error(cube_shape):
    with pytest.raises(OutputError):  # /proc takes no new files, even from root
        write_step(cube_shape, "/proc/nupatch-test.step", "c")


def test_path_through_a_file_is_an_output_error(tmp_path, cube_shape):
    (tmp_path / "file").write_bytes(b"x")
    with pytest.raises(OutputError):
        write_step(cube_shape, tmp_path / "file" / "c.step", "c")


def test_path_that_is_a_directory_is_an_output_error(tmp_path, cube_shape):
    (tmp_path / "c.step").mkdir()
    with pytest.raises(OutputError, match="is a directory"):
        write_step(cube_shape, tmp_path / "c.step", "c")
    assert [p.name for p in tmp_path.iterdir()] == ["c.step"]


def test_reading_a_missing_or_bad_file_is_an_input_error(tmp_path):
    with pytest.raises(InputFileError):
        read_step(tmp_path / "missing.step")
    bad = tmp_path / "bad.step"
    bad.write_text("not a step file\n")
    with pytest.raises(InputFileError):
        read_step(bad)
