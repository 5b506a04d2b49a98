"""export.render_subdivided and `nupatch render MESH --normals ...`: the triangles and normals
handed to the renderer, a PNG through the CLI, bad input refused in one line without a file."""

from __future__ import annotations

import numpy as np
import pytest

import patching
from export.render_subdivided import subdivided_sampled
from patching.shading import shading_operator
from tests.test_loop import BASES

Image = pytest.importorskip("PIL.Image")

CUBE_OBJ = """v -1 -1 -1\nv 1 -1 -1\nv -1 1 -1\nv 1 1 -1\nv -1 -1 1\nv 1 -1 1\nv -1 1 1\nv 1 1 1
f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\nt crease 2/1/0 4 5 10\nt crease 2/1/0 5 7 10
"""


@pytest.fixture
def cube(tmp_path_factory):
    path = tmp_path_factory.mktemp("mesh") / "cube.obj"
    path.write_text(CUBE_OBJ)
    return path


def _creased_tet():
    v, f = BASES["tet"]
    return patching.from_arrays(v, f, creases={(0, 1): 10.0})


@pytest.mark.parametrize("normals", ["flat", "limit", "shading"])
def test_sampled_triangles_carry_the_chosen_normals(normals):
    mesh = _creased_tet()
    s = subdivided_sampled(mesh, 2, "loop", normals)
    op = shading_operator(mesh, 2, "loop", "limit" if normals == "flat" else normals)
    out = op.evaluate(mesh.vertices)
    assert s.triangles.shape == out.faces.shape
    assert np.allclose(s.points[s.triangles], out.points[out.faces])  # same triangles, split vertices
    got = s.normals[s.triangles]
    if normals == "flat":
        p = out.points[out.faces]
        fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        fn /= np.linalg.norm(fn, axis=1)[:, None]
        assert np.abs(got - fn[:, None, :]).max() < 1e-12
    else:
        assert np.array_equal(got, out.normals[out.corner_normal])
    # the sharp edge splits its vertices: more drawn vertices than refined ones
    assert s.points.shape[0] > out.points.shape[0]


def test_cli_draws_a_subdivided_mesh(tmp_path, run_cli, cube):
    out = tmp_path / "c.png"
    result = run_cli("render", cube, "-n", "2", "--normals", "shading", "--zebra", "--size", "160x120", "-o", out, "-q")
    assert result.returncode == 0, result.stderr
    with Image.open(out) as image:
        assert image.size == (160, 120)
        px = np.asarray(image.convert("L"), dtype=float)
    assert px.std() > 10  # stripes, not a blank picture


@pytest.mark.parametrize("args, fragment", [
    (("-n", "0", "--normals", "limit"), "-n must be a number of steps >= 1"),
    (("--normals", "limit", "--curvature"), "--curvature is not drawn"),
    (("--normals", "limit", "-o", "{tmp}/x.jpg"), "must end in .png"),
])
def test_cli_bad_subdivided_render(tmp_path, run_cli, cube, args, fragment):
    out = [] if "-o" in args else ["-o", tmp_path / "x.png"]
    result = run_cli("render", cube, *(a.format(tmp=tmp_path) for a in args), *out)
    assert result.returncode == 2 and fragment in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and result.stderr.startswith("nupatch: error: ")
    assert list(tmp_path.iterdir()) == []
