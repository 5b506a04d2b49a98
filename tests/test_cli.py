"""The command line: every bad input gives exit 2, one stderr line naming the place, no file."""

import os
from pathlib import Path

import pytest
from tests.helpers import assert_refused as _assert_refused

GOOD_QUADS = """v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0 0
v 2 1 0
f 1 2 3 4
f 2 5 6 3
"""


def torus_obj(m: int = 4, n: int = 4, extra: str = "") -> str:
    """A closed m x n torus grid as OBJ text (vertex (a, b) on line a n + b + 1)."""
    import math

    def point(a: int, b: int) -> str:
        u, w = 2 * math.pi * a / m, 2 * math.pi * b / n
        return f"{(3 + math.cos(w)) * math.cos(u):.12g} {(3 + math.cos(w)) * math.sin(u):.12g} {math.sin(w):.12g}"

    lines = [f"v {point(a, b)}" for a in range(m) for b in range(n)]
    idx = lambda a, b: (a % m) * n + (b % n) + 1  # noqa: E731
    lines += [f"f {idx(a, b)} {idx(a + 1, b)} {idx(a + 1, b + 1)} {idx(a, b + 1)}" for a in range(m) for b in range(n)]
    return "\n".join(lines) + "\n" + extra


BAD_INPUTS = {
    # name: (file content, text the message must contain, place it must name)
    "empty mesh": ("# nothing\n", "empty mesh", "bad.obj"),
    "vertices only": ("v 0 0 0\nv 1 0 0\n", "empty mesh", "bad.obj"),
    "unparsable number": ("v 0 0 zero\n", "cannot read coordinate 'zero'", "bad.obj:1"),
    "face index out of range": (GOOD_QUADS + "f 1 2 9\n", "out of range", "bad.obj:9"),
    "face index 0": (GOOD_QUADS + "f 0 1 2\n", "face index 0", "bad.obj:9"),
    "face with two vertices": (GOOD_QUADS + "f 1 2\n", "at least 3", "bad.obj:9"),
    "repeated vertex": (GOOD_QUADS + "f 1 2 2 4\n", "repeats vertex", "bad.obj:9"),
    "edge shared by three faces": (GOOD_QUADS + "v 1 0 1\nv 1 1 1\nf 2 7 8 3\n", "shared by 3 faces", "bad.obj:"),
    "inconsistent orientation": ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 3 6 5\n", "opposite orientations", "bad.obj:8"),
    "nan coordinate": ("v nan 0 0\n" + GOOD_QUADS, "non-finite coordinate", "bad.obj:1"),
    "infinite coordinate": ("v 0 inf 0\n" + GOOD_QUADS, "non-finite coordinate", "bad.obj:1"),
    "negative interval": (torus_obj(extra="t interval 2/1/0 0 1 -1\n"), "must be finite and >= 0", "bad.obj:33"),
    "nan interval": (torus_obj(extra="t interval 2/1/0 0 1 nan\n"), "must be finite and >= 0", "bad.obj:33"),
    "infinite interval": (torus_obj(extra="t interval 2/1/0 0 1 inf\n"), "must be finite and >= 0", "bad.obj:33"),
    "negative sharpness": (torus_obj(extra="t crease 2/1/0 0 1 -2\n"), "must be finite and >= 0", "bad.obj:33"),
    "nan sharpness": (torus_obj(extra="t crease 2/1/0 0 1 nan\n"), "must be finite and >= 0", "bad.obj:33"),
    "interval on a missing edge": (torus_obj(extra="t interval 2/1/0 0 5 2\n"), "does not exist", "bad.obj:33"),
    "crease on a missing edge": (torus_obj(extra="t crease 2/1/0 0 5 2\n"), "does not exist", "bad.obj:33"),
    "two intervals on one strip": (
        torus_obj(extra="t interval 2/1/0 0 4 2\nt interval 2/1/0 1 5 3\n"),
        "edge 0-4 has 2, edge 1-5 has 3",
        "bad.obj:33 and bad.obj:34",
    ),
    "not an obj (binary)": (b"\x89PNG\r\n\x1a\n\0\0\0", "binary", "bad.obj"),
    "a step file handed to build": ("ISO-10303-21;\nHEADER;\n", "STEP file", "bad.obj"),
    "text that is not obj": ("hello world\n", "not an OBJ statement", "bad.obj:1"),
    "tag with missing arguments": (torus_obj(extra="t interval 2/1/0 0\n"), "declares", "bad.obj:33"),
    "tag with more arguments than declared": (torus_obj(extra="t crease 2/1/0 0 1 3 4\n"), "declares 2/1/0 arguments, has 4", "bad.obj:33"),
    "one edge, two crease values": (
        torus_obj(extra="t crease 2/1/0 0 1 3\nt crease 2/1/0 1 0 5\n"), "edge 1-0 has two crease values, 3.0 and 5.0", "bad.obj:33 and bad.obj:34"
    ),
    "one vertex, two corner values": (
        torus_obj(extra="t corner 1/1/0 4 3\nt corner 1/1/0 4 10\n"), "vertex 4 has two corner values", "bad.obj:33 and bad.obj:34"
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_is_refused_in_one_line_and_writes_nothing(tmp_path, run_cli, case):
    content, what, where = BAD_INPUTS[case]
    mesh = tmp_path / "bad.obj"
    mesh.write_bytes(content if isinstance(content, bytes) else content.encode())
    out = tmp_path / "out.step"
    out.write_text("precious")
    result = run_cli("build", mesh, "-o", out)
    _assert_refused(result, what, where)
    assert out.read_text() == "precious", "an existing output must be untouched"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.obj", "out.step"], "no stray files"


def test_default_output_is_not_created_on_failure(tmp_path, run_cli):
    mesh = tmp_path / "bad.obj"
    mesh.write_text("v 0 0 zero\n")
    _assert_refused(run_cli("build", mesh), "bad.obj:1")
    assert not (tmp_path / "bad.step").exists()


def test_missing_file(tmp_path, run_cli):
    _assert_refused(run_cli("build", tmp_path / "nope.obj"), "no such file", "nope.obj")


def test_unreadable_file(tmp_path, run_cli):
    # Root reads any file whatever its mode, so a directory stands for an unreadable path.
    folder = tmp_path / "folder.obj"
    folder.mkdir()
    _assert_refused(run_cli("build", folder, "-o", tmp_path / "x.step"), "directory", "folder.obj")


def test_output_directory_missing(tmp_path, run_cli):
    mesh = tmp_path / "t.obj"
    mesh.write_text(torus_obj())
    result = run_cli("build", mesh, "-o", tmp_path / "no" / "such" / "dir" / "t.step")
    _assert_refused(result, "does not exist", "no/such/dir")


def test_output_directory_not_writable(tmp_path, run_cli):
    target = Path("/sys")
    if not target.is_dir():
        pytest.skip("needs a directory nobody can write into (/sys)")
    mesh = tmp_path / "t.obj"
    mesh.write_text(torus_obj())
    _assert_refused(run_cli("build", mesh, "-o", target / "t.step"), "not writable", "/sys")


def test_check_refuses_an_obj(tmp_path, run_cli):
    mesh = tmp_path / "t.obj"
    mesh.write_text(torus_obj())
    _assert_refused(run_cli("check", mesh), "not a STEP file", "t.obj")


def test_unsupported_features_are_refused_not_built_wrong(tmp_path, run_cli):
    mesh = tmp_path / "t.obj"
    cube = "".join(f"v {x} {y} {z}\n" for x in (0, 1) for y in (0, 1) for z in (0, 1))
    cube += "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n"
    mesh.write_text(cube + "t interval 2/1/0 0 1 0\n")  # a zero interval on an EP's spoke
    out = tmp_path / "t.step"
    _assert_refused(run_cli("build", mesh, "-o", out), "not supported yet", "t.obj:15")
    assert not out.exists()


def test_isolated_vertex_and_unknown_tag_warn_and_go_on(tmp_path, run_cli):
    mesh = tmp_path / "t.obj"
    mesh.write_text(torus_obj(extra="v 9 9 9\nt facevaryinginterpolateboundary 1/0/0 1\n"))
    out = tmp_path / "t.step"
    result = run_cli("build", mesh, "-o", out, "-q")
    assert result.returncode == 0, result.stderr
    warnings = [l for l in result.stderr.splitlines() if l.startswith("nupatch: warning:")]
    assert any("isolated" in w for w in warnings) and any("facevaryinginterpolateboundary" in w for w in warnings)
    assert out.exists()


def test_build_info_check_and_version(tmp_path, run_cli, cli_main):
    """What build, check and info compute, in this interpreter (``cli_main``); --version in a
    fresh one, so the ``python -m export.cli`` entry point itself is run here too."""
    mesh = tmp_path / "ring.obj"
    mesh.write_text(torus_obj(6, 5, extra="t interval 2/1/0 0 5 3\n"))
    result = cli_main("build", mesh)
    assert result.returncode == 0, result.stderr
    step = tmp_path / "ring.step"
    text = step.read_text()
    assert "ring" in text and "MILLI" in text
    check = cli_main("check", step, "--json")
    assert check.returncode == 0, check.stderr
    import json

    report = json.loads(check.stdout)
    assert report["valid"] and report["n_solids"] == 1 and report["n_free_edges"] == 0
    # round-off level, read back from the STEP (13 significant digits)
    assert report["max_gap_relative"] <= 1e-9 and report["max_normal_jump_deg"] <= 1e-6
    info = cli_main("info", mesh)
    assert info.returncode == 0 and "30 vertices, 30 faces" in info.stdout
    assert run_cli("--version").stdout.startswith("nupatch ")
    for command in ("build", "info", "check"):
        assert cli_main(command, "--help").returncode == 0


def test_building_twice_gives_the_same_step_but_the_timestamp(tmp_path, run_cli, cli_main):
    """One build in this interpreter, one in a fresh one: still two interpreters (different
    hash seeds), so an order that depends on set or dict hashing would still show."""
    mesh = tmp_path / "ring.obj"
    mesh.write_text(torus_obj(5, 4))
    a, b = tmp_path / "a.step", tmp_path / "b.step"
    assert cli_main("build", mesh, "-o", a, "-q").returncode == 0
    assert run_cli("build", mesh, "-o", b, "-q").returncode == 0
    strip = lambda p: [l for l in p.read_text().splitlines() if not l.startswith("FILE_NAME")]  # noqa: E731
    assert strip(a) == strip(b)
    assert a.read_text() != "" and len(strip(a)) > 50


# --- formats, options -------------------------------------------------------------


@pytest.mark.parametrize("args, expected", [
    ((), "ring.step"),
    (("--format", "glb"), "ring.glb"),
    (("-o", "{tmp}/out.stl"), "out.stl"),
    (("-o", "{tmp}/out.step", "--format", "obj"), "out.step"),
])
def test_format_follows_the_suffix_unless_given(tmp_path, run_cli, args, expected):
    mesh = tmp_path / "ring.obj"
    mesh.write_text(torus_obj(5, 4))
    result = run_cli("build", mesh, *(a.format(tmp=tmp_path) for a in args), "-q")
    assert result.returncode == 0, result.stderr
    out = tmp_path / expected
    head = out.read_bytes()[:64]
    fmt = args[args.index("--format") + 1] if "--format" in args else Path(expected).suffix[1:]
    signature = {"step": b"ISO-10303-21", "glb": b"glTF", "stl": b"nupatch ring", "obj": b"# nupatch ring"}[fmt]
    assert head.startswith(signature), head


@pytest.mark.parametrize("args, fragment, where", [
    (("-o", "{tmp}/out.ply"), "suffix '.ply'", "out.ply"),
    (("--format", "ply"), "invalid choice: 'ply'", "command line"),
    (("-o", "{tmp}/out.stl", "--tolerance", "0"), "tolerance must be finite and at least 1e-07", "--tolerance"),
    (("-o", "{tmp}/out.stl", "--tolerance", "nan"), "tolerance must be finite and at least 1e-07", "--tolerance"),
    (("-o", "{tmp}/out.stl", "--tolerance", "1e-300"), "tolerance must be finite and at least 1e-07", "--tolerance"),
    (("--angles", "random"), "invalid choice: 'random'", "command line"),
])
def test_bad_output_options_are_refused_in_one_line(tmp_path, run_cli, args, fragment, where):
    mesh = tmp_path / "ring.obj"
    mesh.write_text(torus_obj(5, 4))
    result = run_cli("build", mesh, *(a.format(tmp=tmp_path) for a in args))
    _assert_refused(result, fragment, where)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ring.obj"]


def test_angles_and_anchors_change_the_output(tmp_path, cli_main):
    from export import write_obj
    from tests.helpers import ell_mesh

    mesh = tmp_path / "ell.obj"
    write_obj(ell_mesh(), mesh)
    outputs = {}
    choices = (("--angles", "uniform"), ("--anchors", "extraction"), ("--anchors", "faired"))
    for options in ((), ("--angles", "optimized", "--anchors", "eigen-polyhedron")) + choices:
        out = tmp_path / f"ell{len(outputs)}.brep"  # BREP: no time stamp, so equal builds give equal files
        result = cli_main("build", mesh, "-o", out, "-q", *options)
        assert result.returncode == 0, result.stderr
        outputs[options] = out.read_bytes()
    defaults, explicit, *others = outputs.values()
    assert defaults == explicit
    assert len({defaults, *others}) == 1 + len(choices)  # every rule the README names is taken


# --- several meshes in parallel, progress ------------------------------------------


def test_many_meshes_in_parallel_each_failure_on_its_own_line(tmp_path, run_cli):
    good = [tmp_path / f"ring{k}.obj" for k in range(3)]
    for k, path in enumerate(good):
        path.write_text(torus_obj(4 + k, 4))
    bad = [tmp_path / "bad1.obj", tmp_path / "bad2.obj"]
    bad[0].write_text("v 0 0 zero\n")
    bad[1].write_text(torus_obj(extra="t interval 2/1/0 0 1 -1\n"))
    out = tmp_path / "out"
    out.mkdir()
    result = run_cli("build", good[0], bad[0], good[1], bad[1], good[2], "-j", "2", "-o", out, "--format", "stl", "-q")
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    errors = [l for l in lines if l.startswith("nupatch: error: ")]
    assert len(errors) == 2 and len(lines) == 2, result.stderr  # -q: the failures only
    assert any("bad1.obj:1" in l for l in errors) and any("bad2.obj:33" in l for l in errors)
    assert sorted(p.name for p in out.iterdir()) == ["ring0.stl", "ring1.stl", "ring2.stl"]


def test_many_meshes_need_an_output_directory_and_distinct_names(tmp_path, cli_main):
    a, b = tmp_path / "a.obj", tmp_path / "sub" / "a.obj"
    b.parent.mkdir()
    for path in (a, b):
        path.write_text(torus_obj())
    _assert_refused(cli_main("build", a, b, "-o", tmp_path / "nowhere"), "existing directory", "nowhere")
    _assert_refused(cli_main("build", a, b, "-o", tmp_path), "would both be written", "command line")
    _assert_refused(cli_main("build", a, "-j", "0"), "-j must be at least 1", "command line")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.obj", "sub"]
    result = cli_main("build", a, b, "-q")  # beside each mesh
    assert result.returncode == 0 and result.stderr == "", result.stderr
    assert (tmp_path / "a.step").exists() and (tmp_path / "sub" / "a.step").exists()


@pytest.mark.slow
def test_progress_on_stderr_for_long_builds_and_q_silences_it(tmp_path):
    import os
    import subprocess

    from tests.conftest import NUPATCH, REPO

    mesh = tmp_path / "big.obj"
    mesh.write_text(torus_obj(60, 60))  # 3600 faces: ~4 s here, well over the bar's 1 s delay
    env = dict(os.environ, PYTHONPATH=str(REPO), NUPATCH_PROGRESS="1")
    run = lambda *extra: subprocess.run([*NUPATCH, "build", str(mesh), *extra], capture_output=True, text=True, env=env, timeout=600)  # noqa: E731
    loud = run()
    assert loud.returncode == 0, loud.stderr
    import re

    # The bar shows whichever stage is running once a second has passed (B-rep or writing).
    assert re.search(r"nupatch: big\.obj: (reading|patches|B-rep|writing step) .* [0-3]/4 stages", loud.stderr), loud.stderr
    last = loud.stderr.replace("\r", "\n").strip().splitlines()[-1]
    assert last.startswith("nupatch: 3600 patches from 3600 faces, wrote "), last
    quiet = run("-q")
    assert quiet.returncode == 0 and quiet.stderr == ""


def test_subdivide_writes_a_mesh_that_reads_back_with_its_tags(tmp_path, run_cli):
    import numpy as np

    import patching
    from patching.subdivision.catmark import subdivide

    mesh_path = tmp_path / "ring.obj"
    mesh_path.write_text(torus_obj(5, 4, extra="t interval 2/1/0 0 4 3\nt crease 2/1/0 0 1 2.5\n"))
    out = tmp_path / "fine.obj"
    result = run_cli("subdivide", mesh_path, "-n", "2", "-o", out, "-q")
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""  # quiet, and the rules record is a known tag
    fine = patching.read_mesh(out)
    expected = subdivide(patching.read_mesh(mesh_path), 2)
    assert fine.n_faces == 16 * 20
    np.testing.assert_allclose(fine.vertices, expected.vertices, atol=1e-15)
    assert sorted(fine.intervals.values()) == sorted(expected.intervals.values())
    assert max(fine.intervals.values()) == 0.75  # 3 halved twice
    assert sorted(fine.creases.values()) == sorted(expected.creases.values())
    assert "t nupatch_rules 0/0/1 seed" in out.read_text()


def test_subdivide_chaikin_creasing(tmp_path, run_cli):
    """--crease-method chaikin (OpenSubdiv's CREASE_CHAIKIN, opensubdiv rules) is the API's;
    with the seed rules it is refused in one line and nothing is written."""
    import numpy as np

    import patching
    from patching.subdivision.catmark import subdivide

    mesh_path = tmp_path / "ring.obj"
    mesh_path.write_text(torus_obj(5, 4, extra="t crease 2/1/0 0 1 2.5\nt crease 2/1/0 1 2 0.5\n"))
    out = tmp_path / "fine.obj"
    result = run_cli("subdivide", mesh_path, "-n", "3", "--rules", "opensubdiv", "--crease-method", "chaikin", "-o", out, "-q")
    assert result.returncode == 0, result.stderr
    fine = patching.read_mesh(out)
    chaikin = subdivide(patching.read_mesh(mesh_path), 3, rules="opensubdiv", crease_method="chaikin")
    uniform = subdivide(patching.read_mesh(mesh_path), 3, rules="opensubdiv")  # differs from step 3 on
    np.testing.assert_allclose(fine.vertices, chaikin.vertices, atol=1e-15)
    assert np.abs(fine.vertices - uniform.vertices).max() > 1e-6
    assert "crease method chaikin" in out.read_text()
    refused = tmp_path / "no.obj"
    _assert_refused(run_cli("subdivide", mesh_path, "--crease-method", "chaikin", "-o", refused), "chaikin")
    assert not refused.exists()


def test_subdivide_refuses_opensubdiv_rules_on_non_uniform_knots(tmp_path, run_cli):
    mesh_path = tmp_path / "ring.obj"
    mesh_path.write_text(torus_obj(5, 4, extra="t interval 2/1/0 0 4 3\n"))
    out = tmp_path / "fine.obj"
    out.write_text("precious")
    result = run_cli("subdivide", mesh_path, "-n", "1", "--rules", "opensubdiv", "-o", out)
    _assert_refused(result, "uniform knot intervals", "interval")
    assert out.read_text() == "precious"


def test_degenerate_geometry_is_refused_in_one_line(tmp_path, run_cli):
    """A cube whose control points collapse to a point: a valid mesh, but no surface."""
    mesh = tmp_path / "point.obj"
    faces = ["f 1 2 4 3", "f 5 7 8 6", "f 1 5 6 2", "f 3 4 8 7", "f 1 3 7 5", "f 2 6 8 4"]
    mesh.write_text("\n".join(["v 0 0 0"] * 8 + faces) + "\n")
    out = tmp_path / "out.step"
    _assert_refused(run_cli("build", mesh, "-o", out), "side 0 of the patch on face 0 has no length")
    assert not out.exists()


def test_flat_closed_mesh_is_written_as_a_shell_with_a_warning(tmp_path, run_cli):
    """A cube whose control points collapse to a plane: a closed surface of no volume is
    written as a shell (one warning line naming it), not refused."""
    mesh = tmp_path / "flat.obj"
    faces = ["f 1 2 4 3", "f 5 7 8 6", "f 1 5 6 2", "f 3 4 8 7", "f 1 3 7 5", "f 2 6 8 4"]
    mesh.write_text("\n".join([f"v {x} {y} 0" for x in (0, 1) for y in (0, 1)] * 2 + faces) + "\n")
    out = tmp_path / "out.step"
    result = run_cli("build", mesh, "-o", out, "-q")
    assert result.returncode == 0, result.stderr
    warning = [line for line in result.stderr.splitlines() if "encloses no volume" in line]
    assert len(warning) == 1 and warning[0].startswith("nupatch: warning: ") and "a shell" in warning[0]
    from export.continuity import check_continuity

    report = check_continuity(out)
    assert report.valid and report.n_solids == 0 and report.n_shells == 1


@pytest.mark.slow
def test_a_reader_that_goes_away_stops_the_output_quietly(tmp_path, cli_main):
    """`nupatch check big.step --all | head -1`: no 'internal error' when the pipe closes."""
    import subprocess

    from tests.conftest import NUPATCH, REPO

    mesh = tmp_path / "big.obj"
    mesh.write_text(torus_obj(40, 40))
    assert cli_main("build", mesh, "-q").returncode == 0  # only the input; the pipe is a real process
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([*NUPATCH, "check", str(tmp_path / "big.step"), "--all"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=REPO, env=env)
    assert proc.stdout.readline().startswith(b"valid")
    proc.stdout.close()  # the reader goes away with most of the table unread
    stderr = proc.stderr.read().decode()
    proc.wait(timeout=600)
    assert "internal error" not in stderr and "Traceback" not in stderr
    assert proc.returncode in (0, 141)


def test_info_reports_what_the_sharp_features_become(run_cli):
    """`nupatch info --json` on the shipped machined bracket: its corners, darts and the
    vertices whose sectors take the EP path (patching.topology.features)."""
    import json

    from tests.conftest import REPO

    result = run_cli("info", REPO / "models" / "machined_bracket.obj", "--json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert info["sharp_edges"] == 56
    assert info["sharp_features"] == {"corners": 10, "darts": 10, "sector_vertices": 15}


def test_pack_takes_semi_sharp_meshes_and_adaptive_ones(tmp_path, cli_main):
    """--pack reads the knot spans of the faces the patches cover: after the global steps of a
    semi-sharp mesh those of the refined mesh (patching.operator.patched_mesh); where even
    the global setting refines adaptively (7 steps), the spans the adaptive path gives its
    patches, and the split sides (T-junctions) stay shared edges of the packed faces."""
    mesh = tmp_path / "ring.obj"
    mesh.write_text(torus_obj(6, 5, extra="t crease 2/1/0 0 1 2\n"))
    out = tmp_path / "ring.step"
    result = cli_main("build", mesh, "-o", out, "--pack", "-q")
    assert result.returncode == 0, result.stderr
    assert out.exists()
    deep = tmp_path / "deep.obj"
    deep.write_text(torus_obj(6, 5, extra="t crease 2/1/0 0 1 7\n"))  # 7 steps: adaptive
    packed, plain = tmp_path / "deep.step", tmp_path / "deep_plain.step"
    assert cli_main("build", deep, "-o", packed, "--pack", "-q").returncode == 0
    assert cli_main("build", deep, "-o", plain, "--no-pack", "-q").returncode == 0
    faces = [p.read_text().count("ADVANCED_FACE(") for p in (packed, plain)]
    assert faces[0] < faces[1] / 4


def test_pack_keeps_the_global_steps_that_build_leaves_for_the_adaptive_path(tmp_path, run_cli):
    """Sharpness 3 on a 6 x 5 torus: three global steps would make 30 x 4^3 = 1,920 faces, so
    build refines adaptively (fewer patches, split sides); --pack, which merges the patches of
    one mesh, still takes the global steps and packs them, as before (exit 0, not refused)."""
    from export.pipeline import BuildJob, run_build

    mesh = tmp_path / "ring.obj"
    mesh.write_text(torus_obj(6, 5, extra="t crease 2/1/0 0 1 3\n"))
    plain = run_build(BuildJob(str(mesh), str(tmp_path / "plain.step"), "step", pack=False))
    packed = tmp_path / "packed.step"
    result = run_cli("build", mesh, "-o", packed, "--pack", "-q")
    assert result.returncode == 0, result.stderr
    assert packed.exists() and packed.stat().st_size < (tmp_path / "plain.step").stat().st_size
    assert plain[1] < 30 * 4**3 // 4  # adaptive: 258 patches


def test_a_bar_shown_only_by_its_ticker_is_cleared_at_the_end(monkeypatch, capsys):
    """All updates before the delay, the bar shown by the ticker alone: closing it must still
    clear the line, so that the next line starts at its beginning."""
    import argparse
    import time

    from export import cli

    monkeypatch.setenv("NUPATCH_PROGRESS", "1")
    monkeypatch.setattr(cli._Bar, "DELAY", 0.2)
    with cli._Bar(argparse.Namespace(quiet=False), 4, "stages", "x: reading") as bar:
        bar.update()
        time.sleep(1.3)  # the ticker (every 0.5 s) shows it at least once
    err = capsys.readouterr().err
    assert "1/4 stages" in err, err
    # what stays on the line after the last carriage return is blank
    assert err.split("\r")[-1].strip() == "", repr(err)
