"""Installing beside a CAD stack: metadata, the OCP check (export/ocp_compat.py), the wheel's
contents, python -m export, stdin/stdout, check on IGES and BREP, short reprs."""

from __future__ import annotations

import importlib.metadata as md
import os
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

import patching
from export import ocp_compat

REPO = Path(__file__).resolve().parent.parent
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
ENV = dict(os.environ, PYTHONPATH=str(REPO))


def run(args, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, env=ENV, timeout=600, **kwargs)


def test_core_dependencies_name_no_ocp_flavour_and_the_extras_exist():
    deps = PYPROJECT["project"]["dependencies"]
    names = [re.split(r"[<>=!~ \[;]", d, maxsplit=1)[0].lower() for d in deps]
    assert set(names) == {"numpy", "scipy", "tqdm", "threadpoolctl", "cadquery-ocp-proxy"}
    proxy = next(d for d in deps if d.startswith("cadquery-ocp-proxy"))
    assert ">=7.9" in proxy and "<8.1" in proxy  # a range over both supported versions
    extras = PYPROJECT["project"]["optional-dependencies"]
    assert {"ocp", "cadquery", "build123d", "usd", "rhino", "test"} <= set(extras)
    assert any("trimesh" in d for d in extras["test"])


def test_trimesh_is_imported_only_behind_its_extras():
    """patching never imports trimesh; export only inside the two functions that need it
    (fit's triangle reader, subdivide's glb writer), each with a one-line error naming its
    extra when it is missing."""
    users = set()
    for package in ("patching", "export"):
        for path in (REPO / package).rglob("*.py"):
            text = path.read_text()
            if "import trimesh" in text:
                users.add(path.relative_to(REPO).as_posix())
                assert "\nimport trimesh" not in text, path  # never at module level
    assert users == {"export/triangles.py", "export/subdivided.py"}
    extras = PYPROJECT["project"]["optional-dependencies"]
    assert any("trimesh" in d for d in extras["fit"]) and any("trimesh" in d for d in extras["mesh"])


def test_moved_ocp_names_are_imported_through_ocp_compat_only():
    moved = re.compile(r"from OCP\.(TColgp|TColStd|collections) import|from OCP\.TopTools import .*Indexed|from OCP\.TopoDS import .*\bTopoDS\b(?!_)")
    for path in sorted((REPO / "export").rglob("*.py")) + sorted((REPO / "tests").rglob("*.py")):
        if path.name in ("ocp_compat.py", "test_install.py"):
            continue
        for line in path.read_text().splitlines():
            assert not moved.search(line), f"{path.name}: {line.strip()}"


def test_supported_ocp_is_reported_ok():
    status = ocp_compat.ocp_status()
    assert status.ok, status.problem
    assert ocp_compat._major_minor(status.module_version) in ocp_compat.SUPPORTED


def _fake_versions(monkeypatch, versions: dict[str, str]):
    real = md.version

    def version(name):
        if name in ocp_compat.WHEELS or name in ("cadquery", "build123d"):
            if name in versions:
                return versions[name]
            raise md.PackageNotFoundError(name)
        return real(name)

    monkeypatch.setattr(ocp_compat.md, "version", version)


def test_two_wheels_are_a_mix_with_one_repair_command(monkeypatch):
    _fake_versions(monkeypatch, {"cadquery-ocp": "7.9.3.1.1", "cadquery-ocp-novtk": "8.0.1.1.0", "cadquery": "2.8.0"})
    problem = ocp_compat.ocp_status().problem
    assert problem and "\n" not in problem
    assert "cadquery-ocp 7.9.3.1.1 and cadquery-ocp-novtk 8.0.1.1.0" in problem
    # cadquery needs the VTK wheel: drop the other one, reinstall the one kept
    assert "pip uninstall -y cadquery-ocp-novtk && pip install --force-reinstall --no-deps cadquery-ocp==7.9.3.1.1" in problem
    _fake_versions(monkeypatch, {"cadquery-ocp": "8.0.1.1.0", "cadquery-ocp-novtk": "8.0.1.1.0", "build123d": "0.13.0"})
    assert "pip uninstall -y cadquery-ocp &&" in ocp_compat.ocp_status().problem


def test_unsupported_version_and_files_of_two_versions(monkeypatch):
    import OCP

    wheel = next(iter(ocp_compat._installed_wheels()), "cadquery-ocp")
    monkeypatch.setattr(OCP, "__version__", "7.7.2", raising=False)
    problem = ocp_compat.ocp_status().problem
    assert "OCP 7.7.2 is not supported" in problem and f"pip install '{wheel}>=7.9.3,<8.1'" in problem
    monkeypatch.setattr(OCP, "__version__", "8.0.1.1", raising=False)
    _fake_versions(monkeypatch, {wheel: "7.9.3.1.1"})
    problem = ocp_compat.ocp_status().problem
    assert "files of two installs are mixed" in problem and f"--no-deps {wheel}==7.9.3.1.1" in problem


def _without_ocp(code: str) -> str:
    """Python source that runs ``code`` as if no OpenCASCADE wheel were installed."""
    return (
        "import sys, importlib.metadata as md\n"
        "sys.modules['OCP'] = None\n"
        "real = md.version\n"
        "def version(name):\n"
        "    if name.startswith('cadquery-ocp') and name != 'cadquery-ocp-proxy':\n"
        "        raise md.PackageNotFoundError(name)\n"
        "    return real(name)\n"
        "md.version = version\n" + code
    )


@pytest.mark.parametrize("call", ["main(ARGS)", "main()"])  # in an interpreter; as the process (OCP imported frozen)
def test_without_opencascade_nupatch_exits_2_naming_the_extra(tmp_path, call):
    out = tmp_path / "a.step"
    args = ["build", str(REPO / "models" / "clamped_grid.obj"), "-o", str(out)]
    code = _without_ocp(f"from export.cli import main\nARGS = {args!r}\nsys.argv[1:] = ARGS\nsys.exit({call})\n")
    result = run(["-c", code], text=True)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'nupatch[ocp]'" in lines[0], result.stderr
    assert not out.exists()
    # the pure-numpy part still works without OpenCASCADE
    code = _without_ocp(f"import patching\nprint(patching.build(patching.read_mesh({str(REPO / 'models' / 'clamped_grid.obj')!r})).n_patches)\n")
    result = run(["-c", code], text=True)
    expected = patching.build(patching.read_mesh(REPO / "models" / "clamped_grid.obj")).n_patches
    assert result.returncode == 0 and result.stdout.strip() == str(expected), result.stderr


def test_missing_cad_library_names_its_extra(tmp_path):
    code = (
        "import sys; sys.modules['build123d'] = None\n"
        "import export\n"
        "try:\n"
        f"    export.to_build123d({str(REPO / 'models' / 'clamped_grid.obj')!r})\n"
        "except ImportError as exc:\n"
        "    print(exc)\n"
    )
    result = run(["-c", code], text=True)
    assert "pip install 'nupatch[build123d]'" in result.stdout, result.stderr


def test_license_and_py_typed():
    text = (REPO / "LICENSE").read_text()
    assert "Apache License" in text and "Version 2.0, January 2004" in text
    assert "TERMS AND CONDITIONS FOR USE, REPRODUCTION, AND DISTRIBUTION" in text
    assert (REPO / "patching" / "py.typed").is_file() and (REPO / "export" / "py.typed").is_file()
    assert PYPROJECT["project"]["license"] == "Apache-2.0"


@pytest.mark.slow
def test_the_wheel_ships_models_license_and_py_typed(tmp_path):
    result = run(["-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(REPO)], text=True)
    if result.returncode != 0:
        pytest.skip(f"cannot build a wheel here: {result.stderr.strip().splitlines()[-1:]}")
    (wheel,) = tmp_path.glob("nupatch-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {"patching/py.typed", "export/py.typed", "export/ocp_compat.py", "export/__main__.py"} <= names
    assert {f"export/models/{p.name}" for p in (REPO / "models").glob("*.obj")} <= names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    metadata = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert "Requires-Dist: cadquery-ocp-proxy<8.1,>=7.9.3" in metadata
    core = [line.split(":", 1)[1].strip() for line in metadata.splitlines()
            if line.startswith("Requires-Dist:") and "extra ==" not in line]
    assert sorted(re.split(r"[<>=!~ ]", d, maxsplit=1)[0] for d in core) == [
        "cadquery-ocp-proxy", "numpy", "scipy", "threadpoolctl", "tqdm"]


def test_python_m_export_and_models(tmp_path):
    result = run(["-m", "export", "--version"], text=True)
    assert result.returncode == 0 and result.stdout.strip() == f"nupatch {patching.__version__}"
    result = run(["-m", "export", "models"], text=True)
    assert result.returncode == 0
    assert result.stdout.split() == sorted(p.stem for p in (REPO / "models").glob("*.obj"))
    out = tmp_path / "g.brep"
    result = run(["-m", "export", "build", "--example", "clamped_grid", "-o", str(out), "-q"], text=True)
    assert result.returncode == 0 and out.stat().st_size > 0, result.stderr
    result = run(["-m", "export", "build", "--example", "no_such_model", "-o", str(tmp_path / "x.step")], text=True)
    assert result.returncode == 2 and "clamped_grid" in result.stderr and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_stdin_to_stdout_equals_the_file_build(tmp_path):
    src = REPO / "models" / "clamped_grid.obj"
    result = run(["-m", "export", "build", "-", "-o", "-", "--format", "obj", "-q"], input=src.read_bytes())
    assert result.returncode == 0, result.stderr
    from export.formats import write

    out = write(patching.build(patching.read_mesh(src)), tmp_path / "g.obj")
    strip = lambda b: [line for line in b.splitlines() if not line.startswith(b"# nupatch") and not line.startswith(b"o ")]  # noqa: E731
    assert strip(result.stdout) == strip(out.read_bytes())
    # STEP on stdout by default for stdin; a failing build prints nothing on stdout
    result = run(["-m", "export", "build", "-", "-q"], input=src.read_bytes())
    assert result.returncode == 0 and result.stdout.startswith(b"ISO-10303-21;")
    result = run(["-m", "export", "build", "-", "-q"], input=b"v 0 0 0\n")
    assert result.returncode == 2 and result.stdout == b"" and len(result.stderr.strip().splitlines()) == 1
    result = run(["-m", "export", "subdivide", "-", "-n", "1", "-o", "-", "-q"], input=src.read_bytes())
    assert result.returncode == 0 and patching.mesh.parse_obj(result.stdout.decode()).n_faces == 4 * 48


def test_check_reads_step_iges_and_brep(tmp_path, capsys):
    import json

    from export.cli import main
    from export.formats import write

    surface = patching.build(patching.read_mesh(REPO / "models" / "l_bracket.obj"))
    reports = {}
    for fmt in ("step", "iges", "brep"):
        out = write(surface, tmp_path / f"g.{fmt}")
        assert main(["check", str(out), "--json"]) == 0
        reports[fmt] = json.loads(capsys.readouterr().out)
    for fmt in ("iges", "brep"):
        assert reports[fmt]["valid"] and reports[fmt]["n_faces"] == reports["step"]["n_faces"] == surface.n_patches
        assert reports[fmt]["n_solids"] == reports["step"]["n_solids"] == 1
        assert reports[fmt]["n_free_edges"] == reports["step"]["n_free_edges"] == 0
    bad = tmp_path / "bad.igs"
    bad.write_text("hello\n")
    assert main(["check", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a STEP file, nor IGES or BREP" in err[0]


def test_reprs_are_short():
    mesh = patching.read_mesh(REPO / "models" / "l_bracket.obj")
    surface = patching.build(mesh)
    assert repr(mesh) == ("ControlMesh('l_bracket', 200 vertices, 198 faces, 144 interval tags, 0 creases, "
                          "0 corners, 0 holes, interpolate_boundary=1)")
    text = repr(surface)
    assert text.startswith("BezierSurface('l_bracket', 198 patches: ") and len(text) < 120
    assert all(len(repr(g)) < 60 for g in surface.groups)


def test_check_continuity_shows_its_options_with_the_modules_defaults(tmp_path):
    import inspect

    import export
    import export.continuity as continuity
    from export.formats import write

    public = inspect.signature(export.check_continuity).parameters
    inner = inspect.signature(continuity.check_continuity).parameters
    assert list(public) == list(inner)
    assert all(public[k].default == inner[k].default for k in inner)
    assert "samples_per_edge" in export.check_continuity.__doc__
    surface = patching.build(patching.read_mesh(REPO / "models" / "clamped_grid.obj"))
    path = write(surface, tmp_path / "g.brep")
    report = export.check_continuity(path, worst=2)
    assert report.valid and report.n_faces == surface.n_patches
