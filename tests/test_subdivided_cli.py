"""``nupatch subdivide --scheme/--normals`` (export/subdivided.py) and OBJ ``fs``/``as``/``vn``."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import patching
from patching.mesh.obj import parse_obj
from patching.shading import shading_operator
from patching.subdivision import subdivide

from tests.conftest import SHAPES  # noqa: E402
TET = "v 1 1 1\nv -1 -1 1\nv -1 1 -1\nv 1 -1 -1\nf 1 2 3\nf 1 4 2\nf 1 3 4\nf 2 4 3\n"


def _one_line_error(res, out: Path, what: str):
    assert res.returncode == 2, res.stderr
    lines = [l for l in res.stderr.splitlines() if l.strip() and "warning" not in l]
    assert len(lines) == 1 and lines[0].startswith("nupatch: error:") and what in lines[0], res.stderr
    assert not out.exists()
    assert not list(out.parent.glob(f".{out.name}*")) and not list(out.parent.glob("*.tmp"))


def test_obj_with_shading_normals(tmp_path, run_cli):
    src = tmp_path / "tet.obj"
    src.write_text(TET + "t crease 2/1/0 0 1 10\nt crease 2/1/0 1 2 10\nt crease 2/1/0 2 0 10\n")
    out = tmp_path / "out.obj"
    res = run_cli("subdivide", src, "-n", "2", "--scheme", "loop", "--normals", "shading", "-o", out)
    assert res.returncode == 0, res.stderr
    text = out.read_text()
    vn = np.array([[float(x) for x in l.split()[1:]] for l in text.splitlines() if l.startswith("vn ")])
    faces = [l.split()[1:] for l in text.splitlines() if l.startswith("f ")]
    assert all("//" in t for f in faces for t in f)
    mesh = patching.read_mesh(src)
    op = shading_operator(mesh, 2, "loop")
    want = op.evaluate(mesh.vertices)
    assert vn.shape == want.normals.shape and np.abs(vn - want.normals).max() < 1e-15
    assert np.abs(np.linalg.norm(vn, axis=1) - 1).max() < 1e-15
    idx = np.array([[int(t.split("//")[1]) - 1 for t in f] for f in faces])
    assert np.array_equal(idx, want.corner_normal)
    # the vertices at the three sharp edges carry more than one normal
    vid = np.array([[int(t.split("//")[0]) - 1 for t in f] for f in faces])
    per_vertex = {}
    for v, n in zip(vid.ravel(), idx.ravel()):
        per_vertex.setdefault(v, set()).add(n)
    assert max(len(s) for s in per_vertex.values()) >= 2
    # reads back (vn ignored with one warning), same positions
    with pytest.warns(patching.NupatchWarning, match="vn normals ignored"):
        back = patching.read_mesh(out)
    assert np.abs(back.vertices - want.points).max() == 0


def test_glb_has_normals(tmp_path, run_cli):
    pygltflib = pytest.importorskip("pygltflib")
    out = tmp_path / "cube.glb"
    src = SHAPES / "catmark_cube_creases1.obj"
    if not src.exists():
        pytest.skip("OpenSubdiv shapes absent")
    res = run_cli("subdivide", src, "-n", "2", "--normals", "limit", "-o", out)
    assert res.returncode == 0, res.stderr
    g = pygltflib.GLTF2().load(str(out))
    prim = g.meshes[0].primitives[0]
    assert prim.attributes.NORMAL is not None
    acc = g.accessors[prim.attributes.NORMAL]
    blob = g.binary_blob()
    view = g.bufferViews[acc.bufferView]
    data = np.frombuffer(blob[view.byteOffset + (acc.byteOffset or 0):][: acc.count * 12], dtype=np.float32).reshape(-1, 3)
    assert np.abs(np.linalg.norm(data, axis=1) - 1).max() < 1e-6


def test_loop_without_normals_reads_back_with_tags(tmp_path, run_cli):
    src = tmp_path / "tet.obj"
    src.write_text(TET + "t crease 2/1/0 0 1 2.5\n")
    out = tmp_path / "out.obj"
    assert run_cli("subdivide", src, "-n", "1", "--scheme", "loop", "-o", out).returncode == 0
    back = patching.read_mesh(out)
    assert back.n_faces == 16 and sorted(back.creases.values()) == [1.5, 1.5]


@pytest.mark.parametrize("case", ["quad", "intervals", "no_steps", "suffix", "fs_count", "fs_after", "variant"])
def test_bad_input_one_line_no_file(tmp_path, run_cli, case):
    src = tmp_path / "m.obj"
    out = tmp_path / "o.obj"
    args = ["--scheme", "loop"]
    what = ""
    if case == "quad":
        src.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
        what = "face 0 has 4 vertices"
    elif case == "intervals":
        src.write_text(TET + "t interval 2/1/0 0 1 2\n")
        what = "uniform knots"
    elif case == "no_steps":
        src.write_text(TET)
        args += ["--normals", "shading", "-n", "0"]
        what = "at least one"
    elif case == "suffix":
        src.write_text(TET)
        out = tmp_path / "o.stl"
        what = ".obj or .glb"
    elif case == "fs_count":
        src.write_text(TET.replace("f 1 2 3\n", "fs 1 2\nf 1 2 3\n"))
        what = "has 2 values"
    elif case == "fs_after":
        src.write_text(TET + "fs 1 1 1\n")
        what = "after the last face"
    elif case == "variant":
        src.write_text(TET)
        args += ["--normals", "shading", "--shading-variant", "c"]
        res = run_cli("subdivide", src, "-o", out, *args)
        assert res.returncode == 2 and not out.exists()
        return
    res = run_cli("subdivide", src, "-o", out, *args)
    _one_line_error(res, out, what)


def test_fs_and_as_map_to_crease_tags():
    text = TET.replace("f 1 2 3\n", "fs 0 2 10\nf 1 2 3\n").replace("f 1 4 2\n", "as 2 1 0 0.5\nf 1 4 2\n")
    mesh = parse_obj(text)
    # face (0 1 2): edge 1-2 gets 2, edge 2-0 infinitely sharp; faces (0 3 1), (0 2 3):
    # edge 0-3 gets 1, edge 1-0 0.5 and edge 3-0 1, edge 2-0 max(10, 0.5)
    assert mesh.creases == {(1, 2): 2.0, (0, 2): 10.0, (0, 3): 1.0, (0, 1): 0.5}


def test_vn_ignored_with_one_warning():
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        parse_obj("vn 0 0 1\nvn 0 1 0\n" + TET)
    assert sum("vn normals ignored" in str(x.message) for x in w) == 1


PYRAMID = "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\nv 1 1 1.5\nf 4 3 2 1\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\n"


def test_subdivide_smooth_triangles_tag_and_flag(tmp_path, run_cli):
    """``t smoothtriangles 0/0/1 smooth`` and ``--triangles smooth`` give the points of
    ``subdivide(rules="opensubdiv")`` on the tagged mesh (the rule is tested against a
    reference in test_subdivision.py); ``--triangles catmark`` overrides the tag; rules seed
    refuse it in one line, writing nothing."""
    tagged, plain = tmp_path / "tagged.obj", tmp_path / "plain.obj"
    tagged.write_text(PYRAMID + "t smoothtriangles 0/0/1 smooth\n")
    plain.write_text(PYRAMID)
    want = subdivide(patching.read_mesh(tagged), 2, rules="opensubdiv").vertices
    base = subdivide(patching.read_mesh(plain), 2, rules="opensubdiv").vertices
    assert np.abs(want - base).max() > 1e-3

    def points(src, *flags):
        out = tmp_path / f"out{len(list(tmp_path.iterdir()))}.obj"
        res = run_cli("subdivide", src, "-n", "2", "--rules", "opensubdiv", *flags, "-o", out, "-q")
        assert res.returncode == 0, res.stderr
        return patching.read_mesh(out).vertices

    assert np.abs(points(tagged) - want).max() == 0
    assert np.abs(points(plain, "--triangles", "smooth") - want).max() == 0
    assert np.abs(points(tagged, "--triangles", "catmark") - base).max() == 0
    out = tmp_path / "seed.obj"
    _one_line_error(run_cli("subdivide", tagged, "-o", out), out, "TRI_SUB_SMOOTH")
    _one_line_error(run_cli("subdivide", tagged, "-o", out), out, "tagged.obj:11")
    step = tmp_path / "tagged.step"
    _one_line_error(run_cli("build", tagged, "-o", step), step, "tagged.obj:11")


GRID_CREASES = "t crease 2/1/0 11 12 1.2\nt crease 2/1/0 12 13 0.3\nt crease 2/1/0 12 17 2.5\n"


def _grid_obj() -> str:
    """An open 5 x 4 grid of quads (6 x 5 points, 0-based id 5 i + j) with crease sharpness
    that changes at vertex 12, where Chaikin's rule differs from uniform creasing."""
    pts = "".join(f"v {i} {j} {0.1 * ((i * 7 + j * 3) % 5)}\n" for i in range(6) for j in range(5))
    quads = "".join(f"f {5 * i + j + 1} {5 * (i + 1) + j + 1} {5 * (i + 1) + j + 2} {5 * i + j + 2}\n" for i in range(5) for j in range(4))
    return pts + quads + GRID_CREASES


def test_subdivide_creasemethod_tag_and_flag(tmp_path, cli_main):
    """``t creasemethod 0/0/1 chaikin`` gives ``--crease-method chaikin``'s points; the flag
    overrides the tag both ways; the refined file keeps the tag (and only a chaikin one); rules
    seed and build refuse the tag in one line naming its line, writing nothing."""
    tagged, plain = tmp_path / "tagged.obj", tmp_path / "plain.obj"
    tagged.write_text(_grid_obj() + "t creasemethod 0/0/1 chaikin\n")
    plain.write_text(_grid_obj())
    line = len(tagged.read_text().splitlines())

    def run(src, *flags):
        out = tmp_path / f"out{len(list(tmp_path.iterdir()))}.obj"
        res = cli_main("subdivide", src, "-n", "3", "--rules", "opensubdiv", *flags, "-o", out, "-q")
        assert res.returncode == 0, res.stderr
        return out

    want = patching.read_mesh(run(plain, "--crease-method", "chaikin"))
    base = patching.read_mesh(run(plain))
    assert np.abs(want.vertices - base.vertices).max() > 1e-3
    got = run(tagged)
    assert np.abs(patching.read_mesh(got).vertices - want.vertices).max() == 0
    assert "t creasemethod 0/0/1 chaikin" in got.read_text() and "crease method chaikin" in got.read_text()
    assert patching.read_mesh(got).crease_method == "chaikin"
    over = run(tagged, "--crease-method", "uniform")
    assert np.abs(patching.read_mesh(over).vertices - base.vertices).max() == 0
    assert "creasemethod" not in over.read_text()
    # Loop and the shading path: the tag is read there too
    for scheme in ("catmark", "loop"):
        src = tagged if scheme == "catmark" else tmp_path / "tet_tagged.obj"
        if scheme == "loop":
            src.write_text(TET + "t crease 2/1/0 0 1 2.0\nt crease 2/1/0 1 2 0.5\nt creasemethod 0/0/1 chaikin\n")
            (tmp_path / "tet_plain.obj").write_text(TET + "t crease 2/1/0 0 1 2.0\nt crease 2/1/0 1 2 0.5\n")
        plain_src = plain if scheme == "catmark" else tmp_path / "tet_plain.obj"
        a = run(src, "--scheme", scheme, "--normals", "shading")
        b = run(plain_src, "--scheme", scheme, "--normals", "shading", "--crease-method", "chaikin")
        c = run(plain_src, "--scheme", scheme, "--normals", "shading")
        assert a.read_text().split("\n", 1)[1] == b.read_text().split("\n", 1)[1] != c.read_text().split("\n", 1)[1]
    out = tmp_path / "seed.obj"
    _one_line_error(cli_main("subdivide", tagged, "-o", out), out, f"tagged.obj:{line}")
    step = tmp_path / "tagged.step"
    _one_line_error(cli_main("build", tagged, "-o", step), step, f"tagged.obj:{line}")


def test_render_normals_reads_the_creasemethod_tag():
    """``render --normals`` draws ``subdivided_sampled``: the tag chooses its crease method, an
    explicit one wins (the CLI's ``--crease-method`` is set on the mesh, export.subdivided)."""
    from export.render_subdivided import subdivided_sampled
    from export.subdivided import with_mesh_options
    from types import SimpleNamespace

    tagged = parse_obj(_grid_obj() + "t creasemethod 0/0/1 chaikin\n", source="t.obj")
    plain = parse_obj(_grid_obj(), source="p.obj")
    a = subdivided_sampled(tagged, 3, "catmark", "shading")
    b = subdivided_sampled(plain, 3, "catmark", "shading", crease_method="chaikin")
    c = subdivided_sampled(with_mesh_options(tagged, SimpleNamespace(crease_method="uniform")), 3, "catmark", "shading")
    d = subdivided_sampled(plain, 3, "catmark", "shading")
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(c.points, d.points)
    assert np.abs(a.points - d.points).max() > 1e-3
    assert ("tag", "creasemethod") not in with_mesh_options(tagged, SimpleNamespace(crease_method="uniform")).locations
