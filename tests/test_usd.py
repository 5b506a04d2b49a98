"""USD input (export/usd.py, docs/input.md): stages written here with usd-core's own API build the
same surface, with the same sharp edges, as the equivalent tagged OBJ."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Gf, Sdf, Usd, UsdGeom  # noqa: E402

import patching  # noqa: E402
from export.usd import read_usd  # noqa: E402

from .conftest import SHAPES  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SHAPE_DIR = Path(os.environ.get("NUPATCH_SHAPES", SHAPES))


def shape(name: str) -> Path:
    path = SHAPE_DIR / name
    if not path.is_file():
        pytest.skip(f"OpenSubdiv shape {name} not found")
    return path


def f32(x: float) -> float:
    return float(np.float32(min(x, 10.0)))


def float32_mesh(mesh: patching.ControlMesh) -> patching.ControlMesh:
    """The mesh with its points and sharpnesses rounded as USD stores them (point3f, float;
    sharpness 10 and above are all infinitely sharp)."""
    from dataclasses import replace

    return replace(
        mesh.with_positions(mesh.vertices.astype(np.float32).astype(np.float64)),
        creases={e: f32(s) for e, s in mesh.creases.items()},
        intervals={e: f32(d) for e, d in mesh.intervals.items()},
        corners={v: f32(s) for v, s in mesh.corners.items()},
    )


def write_stage(mesh: patching.ControlMesh, path: Path, *, prim="/root/part", chain_creases=False,
                per_crease=False, intervals=True, xform=None, left_handed=False) -> Path:
    """A stage with one Mesh prim holding ``mesh`` and its tags, written with pxr directly."""
    stage = Usd.Stage.CreateNew(str(path))
    parent = UsdGeom.Xform.Define(stage, prim.rsplit("/", 1)[0])
    if xform is not None:
        parent.AddTransformOp().Set(Gf.Matrix4d(*np.asarray(xform, dtype=float).ravel().tolist()))
    m = UsdGeom.Mesh.Define(stage, prim)
    m.CreatePointsAttr([Gf.Vec3f(*map(float, p)) for p in mesh.vertices])
    faces = [list(map(int, mesh.face(f))) for f in range(mesh.n_faces)]
    if left_handed:
        faces = [[f[0]] + f[1:][::-1] for f in faces]
        m.CreateOrientationAttr("leftHanded")
    m.CreateFaceVertexCountsAttr([len(f) for f in faces])
    m.CreateFaceVertexIndicesAttr([v for f in faces for v in f])
    m.CreateInterpolateBoundaryAttr({0: "none", 1: "edgeAndCorner", 2: "edgeOnly"}[mesh.interpolate_boundary])
    if mesh.creases:
        items = sorted(mesh.creases.items())
        if chain_creases:  # one crease run of 3 vertices where two tagged edges share a vertex
            idx, lengths, sharp = [], [], []
            for (a, b), s in items:
                idx += [a, b]
                lengths.append(2)
                sharp.append(s)
        else:
            idx = [v for (a, b), _ in items for v in (a, b)]
            lengths = [2] * len(items)
            sharp = [s for _, s in items]
        m.CreateCreaseIndicesAttr(idx)
        m.CreateCreaseLengthsAttr(lengths)
        m.CreateCreaseSharpnessesAttr([min(float(s), 10.0) for s in sharp])
    if mesh.corners:
        m.CreateCornerIndicesAttr(list(mesh.corners))
        m.CreateCornerSharpnessesAttr([min(float(s), 10.0) for s in mesh.corners.values()])
    if mesh.holes:
        m.CreateHoleIndicesAttr(sorted(mesh.holes))
    if intervals and mesh.intervals:
        topo = patching.Topology(mesh)
        values = []
        for f in faces:
            for i in range(len(f)):
                values.append(float(topo.edge_interval[topo.edge_id(f[i], f[(i + 1) % len(f)])]))
        kind = Sdf.ValueTypeNames.DoubleArray if intervals == "double" else Sdf.ValueTypeNames.FloatArray
        pv = UsdGeom.PrimvarsAPI(m.GetPrim()).CreatePrimvar("nupatch:intervals", kind, UsdGeom.Tokens.faceVarying)
        pv.Set(values)
    stage.GetRootLayer().Save()
    return path


def coefficients(surface) -> np.ndarray:
    return np.concatenate([g.coefficients.reshape(-1, 3) for g in surface.groups])


def assert_same_surface(a: patching.ControlMesh, b: patching.ControlMesh):
    ta, tb = patching.Topology(a), patching.Topology(b)
    np.testing.assert_array_equal(np.minimum(ta.edge_sharpness, 10), np.minimum(tb.edge_sharpness, 10))
    np.testing.assert_array_equal(ta.edge_interval, tb.edge_interval)
    sa, sb = patching.build(a), patching.build(b)
    np.testing.assert_allclose(coefficients(sa), coefficients(sb), rtol=0, atol=1e-12 * sa.size)


@pytest.mark.parametrize("name", ["catmark_cube_creases0.obj", "catmark_cube_corner2.obj", "catmark_hole_test1.obj", "catmark_edgeonly.obj"])
def test_opensubdiv_shapes_as_usd_build_like_their_obj(tmp_path, name):
    obj = patching.read_mesh(shape(name))
    usd = read_usd(write_stage(obj, tmp_path / "s.usda"))
    assert usd.n_faces == obj.n_faces and usd.interpolate_boundary == obj.interpolate_boundary
    assert set(usd.holes) == set(obj.holes) and dict(usd.corners) == {v: f32(s) for v, s in obj.corners.items()}
    assert_same_surface(usd, float32_mesh(obj))


def test_tagged_bracket_with_intervals_primvar_builds_like_the_obj(tmp_path):
    obj = patching.read_mesh(REPO / "models" / "l_bracket.obj")
    for suffix in (".usda", ".usdc"):
        usd = read_usd(write_stage(obj, tmp_path / f"b{suffix}"))
        assert_same_surface(usd, float32_mesh(obj))
    # a double-precision primvar keeps the intervals exactly
    usd = read_usd(write_stage(obj, tmp_path / "d.usda", intervals="double"))
    np.testing.assert_array_equal(patching.Topology(usd).edge_interval, patching.Topology(obj).edge_interval)


def test_world_transform_and_left_handed_orientation(tmp_path):
    obj = patching.read_mesh(shape("catmark_cube_creases0.obj"))
    # row-vector convention: p_world = p M, translation in the last row
    m = np.array([[0, 2, 0, 0], [-2, 0, 0, 0], [0, 0, 2, 0], [5, -1, 3, 1]], dtype=float)
    usd = read_usd(write_stage(obj, tmp_path / "t.usda", xform=m, left_handed=True))
    expected = float32_mesh(obj).vertices @ m[:3, :3] + m[3, :3]
    np.testing.assert_allclose(usd.vertices, expected, atol=1e-12)
    np.testing.assert_array_equal(usd.face_vertices, obj.face_vertices)  # leftHanded faces reversed back
    mirrored = read_usd(write_stage(obj, tmp_path / "m.usda", xform=np.diag([-1.0, 1, 1, 1])))
    # a mirroring transform reverses the faces so that the solid stays outward-oriented
    assert patching.build(mirrored).n_patches == patching.build(obj).n_patches
    np.testing.assert_array_equal(mirrored.face_vertices.reshape(-1, 4)[:, 0], obj.face_vertices.reshape(-1, 4)[:, 0])
    np.testing.assert_array_equal(mirrored.face_vertices.reshape(-1, 4)[:, 1], obj.face_vertices.reshape(-1, 4)[:, 3])


def test_two_mesh_prims_are_one_control_mesh(tmp_path):
    obj = patching.read_mesh(shape("catmark_cube_creases0.obj"))
    path = tmp_path / "two.usda"
    write_stage(obj, path)
    stage = Usd.Stage.Open(str(path))
    second = UsdGeom.Mesh.Define(stage, "/other/cube")
    second.CreatePointsAttr([Gf.Vec3f(*map(float, p + 10)) for p in obj.vertices])
    second.CreateFaceVertexCountsAttr(obj.face_sizes.tolist())
    second.CreateFaceVertexIndicesAttr(obj.face_vertices.tolist())
    second.CreateInterpolateBoundaryAttr({0: "none", 1: "edgeAndCorner", 2: "edgeOnly"}[obj.interpolate_boundary])
    stage.GetRootLayer().Save()
    mesh = read_usd(path)
    assert mesh.n_faces == 2 * obj.n_faces and mesh.n_vertices == 2 * obj.n_vertices
    assert len(mesh.creases) == len(obj.creases)  # the second cube carries none


BLENDER_LIKE = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Z"
)
def Xform "Cube"
{
    matrix4d xformOp:transform = ( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) )
    uniform token[] xformOpOrder = ["xformOp:transform"]
    def Mesh "Cube"
    {
        int[] cornerIndices = [0]
        float[] cornerSharpnesses = [10]
        int[] creaseIndices = [0, 1, 3, 2, 0]
        int[] creaseLengths = [5]
        float[] creaseSharpnesses = [10]
        int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
        int[] faceVertexIndices = [0, 4, 6, 2, 3, 2, 6, 7, 7, 6, 4, 5, 5, 1, 3, 7, 1, 0, 2, 3, 5, 4, 0, 1]
        token interpolateBoundary = "edgeAndCorner"
        point3f[] points = [(1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1), (-1, 1, 1), (-1, 1, -1), (-1, -1, 1), (-1, -1, -1)]
        uniform token subdivisionScheme = "catmullClark"
    }
}
"""

BLENDER_LIKE_OBJ = """v 1 1 1
v 1 1 -1
v 1 -1 1
v 1 -1 -1
v -1 1 1
v -1 1 -1
v -1 -1 1
v -1 -1 -1
f 1 5 7 3
f 4 3 7 8
f 8 7 5 6
f 6 2 4 8
f 2 1 3 4
f 6 5 1 2
t crease 2/1/0 0 1 10
t crease 2/1/0 1 3 10
t crease 2/1/0 3 2 10
t crease 2/1/0 2 0 10
t corner 1/1/0 0 10
"""


def test_a_crease_loop_written_as_one_run_like_blender_writes_it(tmp_path, capsys):
    import export
    from export.cli import main

    path = tmp_path / "cube.usda"
    path.write_text(BLENDER_LIKE)
    obj_path = tmp_path / "cube.obj"
    obj_path.write_text(BLENDER_LIKE_OBJ)
    usd, obj = read_usd(path), patching.read_mesh(obj_path)
    assert len(usd.creases) == 4 and usd.corners == {0: 10.0}
    assert_same_surface(usd, obj)
    # the B-reps have the same sharp edges: four, at the same places
    sharp = []
    for mesh in (usd, obj):
        report = export.check_continuity(patching.build(mesh))
        assert report.valid and report.n_sharp_edges == 4
        sharp.append(sorted(tuple(np.round(e.position, 9)) for e in report.sharp_edges))
    assert sharp[0] == sharp[1]
    assert main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["sharp_edges"] == 4 and info["corner_tags"] == 1 and info["holes"] == 0


def test_info_reports_holes_and_corners_for_obj_and_usd(tmp_path, capsys):
    from export.cli import main

    obj_path = shape("catmark_hole_test1.obj")
    obj = patching.read_mesh(obj_path)
    usd_path = write_stage(obj, tmp_path / "h.usda")
    infos = []
    for src in (obj_path, usd_path):
        assert main(["info", str(src), "--json"]) == 0
        infos.append(json.loads(capsys.readouterr().out))
    assert infos[0]["holes"] == infos[1]["holes"] == len(obj.holes) > 0
    assert infos[0]["corner_tags"] == infos[1]["corner_tags"] == len(obj.corners)


def _one_line_error(result, *needles):
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1 and lines[0].startswith("nupatch: error: "), result.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


def _main(capsys, *args):
    """``nupatch ARGS`` in this process (export.cli.main), as a CompletedProcess-like result."""
    from types import SimpleNamespace

    from export.cli import main

    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return SimpleNamespace(returncode=code, stdout=captured.out, stderr=captured.err)


def _mesh_stage(path: Path, points, counts, indices, scheme=None):
    stage = Usd.Stage.CreateNew(str(path))
    m = UsdGeom.Mesh.Define(stage, "/world/bad")
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in points])
    m.CreateFaceVertexCountsAttr(counts)
    m.CreateFaceVertexIndicesAttr(indices)
    if scheme:
        m.CreateSubdivisionSchemeAttr(scheme)
    stage.GetRootLayer().Save()
    return path


SQUARE = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]


def test_bad_usd_input_is_one_line_naming_the_prim(tmp_path, run_cli, capsys):
    out = tmp_path / "out.step"
    empty = tmp_path / "empty.usda"
    stage = Usd.Stage.CreateNew(str(empty))
    UsdGeom.Xform.Define(stage, "/world")
    stage.GetRootLayer().Save()
    _one_line_error(_main(capsys, "build", empty, "-o", out), "no UsdGeom.Mesh prim", "empty.usda")
    # an edge shared by three faces
    pts = SQUARE + [(1, 0, 1), (1, 1, 1), (1, 0, -1), (1, 1, -1)]
    nonman = _mesh_stage(tmp_path / "nonman.usda", pts, [4, 4, 4], [0, 1, 2, 3, 1, 4, 5, 2, 2, 7, 6, 1])
    _one_line_error(_main(capsys, "build", nonman, "-o", out), "non-manifold", "/world/bad")
    nan = _mesh_stage(tmp_path / "nan.usda", [(0, 0, 0), (1, float("nan"), 0), (1, 1, 0), (0, 1, 0)], [4], [0, 1, 2, 3])
    _one_line_error(_main(capsys, "build", nan, "-o", out), "not finite", "/world/bad")
    loop = _mesh_stage(tmp_path / "loop.usda", SQUARE, [3, 3], [0, 1, 2, 0, 2, 3], scheme="loop")
    _one_line_error(_main(capsys, "info", loop), "subdivisionScheme 'loop'", "/world/bad")
    garbage = tmp_path / "garbage.usda"
    garbage.write_text("#usda 1.0\ndef Mesh \"x\" { this is not usd\n")
    _one_line_error(_main(capsys, "build", garbage, "-o", out), "not a USD stage", "garbage.usda")
    # the two face-vertices of edge 1-2 give it different intervals
    clash = _mesh_stage(tmp_path / "clash.usda", SQUARE + [(2, 0, 0), (2, 1, 0)], [4, 4], [0, 1, 2, 3, 1, 4, 5, 2])
    stage = Usd.Stage.Open(str(clash))
    UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/world/bad")).CreatePrimvar(
        "nupatch:intervals", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.faceVarying).Set([1, 2, 1, 2, 3, 2, 3, 2.5])
    stage.GetRootLayer().Save()
    _one_line_error(_main(capsys, "build", clash, "-o", out), "edge 1-2 has two knot intervals, 2 and 2.5", "/world/bad")
    # and once through a fresh `nupatch` process
    _one_line_error(run_cli("build", loop, "-o", out), "subdivisionScheme 'loop'", "/world/bad")
    assert not out.exists() and not list(tmp_path.glob("*.step*"))


def test_usda_on_standard_input(tmp_path):
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=str(REPO))
    result = subprocess.run([sys.executable, "-m", "export", "info", "-", "--json"], input=BLENDER_LIKE, capture_output=True,
                            text=True, env=env, timeout=300)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["sharp_edges"] == 4


BLENDER_CUBE = REPO / "tests" / "data" / "blender" / "creased_cube.usda"

#: What was drawn in Blender (tests/data/blender/make_creased_cube.py): the cube [-1, 1]^3 moved
#: to x = 10, in the order of the positions Blender chose, written here as the tagged OBJ a user
#: would type: crease 1.0 on the top face's edges (sharpness 10 c^2 = 10), 0.5 on the vertical
#: edge 0-1 (2.5), vertex crease 1.0 on vertex 0, Blender's boundary rule edgeOnly (2).
BLENDER_CUBE_OBJ = """v 9 -1 -1
v 9 -1 1
v 9 1 -1
v 9 1 1
v 11 -1 -1
v 11 -1 1
v 11 1 -1
v 11 1 1
f 1 2 4 3
f 3 4 8 7
f 7 8 6 5
f 5 6 2 1
f 3 7 5 1
f 8 4 2 6
t crease 2/1/0 0 1 2.5
t crease 2/1/0 1 3 10
t crease 2/1/0 3 7 10
t crease 2/1/0 7 5 10
t crease 2/1/0 5 1 10
t corner 1/1/0 0 10
t interpolateboundary 1/0/0 2
"""


def check_blender_cube(path: Path, tmp_path: Path) -> None:
    """The cube Blender exported builds as the tagged OBJ of what was drawn: the same tags on the
    same edges (in world coordinates), the same surface, and in the B-rep exactly the four top
    edges sharp (the 2.5 edge is semi-sharp, so smooth in the limit), the tagged corner on it."""
    import export

    usd = read_usd(path)
    obj_path = tmp_path / "cube.obj"
    obj_path.write_text(BLENDER_CUBE_OBJ)
    obj = patching.read_mesh(obj_path)
    np.testing.assert_array_equal(usd.vertices, obj.vertices)  # the world transform x + 10
    assert usd.creases == obj.creases and usd.corners == obj.corners
    assert usd.interpolate_boundary == 2
    assert_same_surface(usd, obj)
    surface = patching.build(usd)
    report = export.check_continuity(surface)
    # the semi-sharp edge refines the faces around it, so the top loop's four crease curves come
    # in several B-rep edges each (the report lists the worst few): at z = 1, as many as and the
    # same as the OBJ's
    report_obj = export.check_continuity(patching.build(obj))
    assert report.valid and report.n_free_edges == 0 and report.n_sharp_edges >= 4
    assert report.n_sharp_edges == report_obj.n_sharp_edges
    sharp = np.array([e.position for e in report.sharp_edges])
    np.testing.assert_allclose(sharp[:, 2], 1.0, atol=1e-9)
    assert sorted(map(tuple, np.round(sharp, 9))) == sorted(tuple(np.round(e.position, 9)) for e in report_obj.sharp_edges)
    # the vertex crease makes vertex 0 a corner the surface interpolates (a patch corner there)
    corners = np.array([net[i, j] for _, _, _, net in surface.patches() for i in (0, -1) for j in (0, -1)])
    assert np.min(np.linalg.norm(corners - [9, -1, -1], axis=1)) < 1e-12 * surface.size


def test_blender_exported_creased_cube(tmp_path):
    """A file Blender 5.0.1 wrote (committed with the script that wrote it)."""
    check_blender_cube(BLENDER_CUBE, tmp_path)


def test_blender_exports_the_creased_cube_the_same_way_today(tmp_path):
    """Where ``bpy`` imports (it needs numpy < 2, so not in the test environment), a fresh export
    by the installed Blender builds the same way."""
    pytest.importorskip("bpy")
    import runpy

    script = runpy.run_path(str(BLENDER_CUBE.with_name("make_creased_cube.py")))
    fresh = tmp_path / "fresh.usda"
    script["creased_cube"](str(fresh))
    check_blender_cube(fresh, tmp_path)


def test_a_polygonal_mesh_prim_builds_with_a_warning_naming_it(tmp_path, run_cli):
    """``subdivisionScheme = "none"`` says the mesh is flat polygons: it still builds (as a
    Catmull-Clark control mesh, the only thing nupatch makes of a quad mesh), but the user is told."""
    text = BLENDER_LIKE.replace('uniform token subdivisionScheme = "catmullClark"', 'uniform token subdivisionScheme = "none"')
    assert text != BLENDER_LIKE
    path = tmp_path / "flat.usda"
    path.write_text(text)
    with pytest.warns(patching.NupatchWarning, match=r"subdivisionScheme 'none'.*prim /Cube/Cube"):
        mesh = read_usd(path)
    assert mesh.n_faces == 6 and len(mesh.creases) == 4
    result = run_cli("build", path, "-o", tmp_path / "flat.step")
    assert result.returncode == 0 and (tmp_path / "flat.step").is_file()
    assert "subdivisionScheme 'none'" in result.stderr and "/Cube/Cube" in result.stderr


def _pyramid(rule: str | None = None):
    """A square pyramid (four triangles on a quad), its points exact in float32."""
    pts = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (1, 1, 1.5)]
    faces = [[0, 3, 2, 1], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]
    return patching.from_arrays(pts, faces, triangle_subdivision=rule or "catmark", name="pyramid")


def test_triangle_subdivision_rule_is_read_and_written(tmp_path):
    from export.usd import write_usd
    from patching.subdivision import subdivide

    plain = _pyramid()
    for rule, expected in ((None, "catmark"), ("catmullClark", "catmark"), ("smooth", "smooth")):
        path = tmp_path / f"pyramid_{rule}.usda"
        write_stage(plain, path, intervals=False)
        stage = Usd.Stage.Open(str(path))
        if rule is not None:
            UsdGeom.Mesh(stage.GetPrimAtPath("/root/part")).CreateTriangleSubdivisionRuleAttr(rule)
        stage.GetRootLayer().Save()
        mesh = read_usd(path)
        assert mesh.triangle_subdivision == expected
        # the rule reaches the refinement: equal to the same mesh given the rule in Python
        ref = subdivide(_pyramid(expected), 2, rules="opensubdiv")
        np.testing.assert_array_equal(subdivide(mesh, 2, rules="opensubdiv").vertices, ref.vertices)
    assert not np.array_equal(subdivide(_pyramid("smooth"), 1, rules="opensubdiv").vertices,
                              subdivide(plain, 1, rules="opensubdiv").vertices)
    # and write_usd writes it back (only when smooth, as the OBJ writer)
    back = read_usd(write_usd(_pyramid("smooth"), tmp_path / "back.usda"))
    assert back.triangle_subdivision == "smooth"
    assert "triangleSubdivisionRule" not in (write_usd(plain, tmp_path / "plain.usda")).read_text()


def test_prims_with_different_triangle_rules_are_refused(tmp_path, capsys):
    path = tmp_path / "two.usda"
    write_stage(_pyramid(), path, intervals=False)
    stage = Usd.Stage.Open(str(path))
    second = UsdGeom.Mesh.Define(stage, "/other/pyramid")
    plain = _pyramid()
    second.CreatePointsAttr([Gf.Vec3f(*map(float, p + 10)) for p in plain.vertices])
    second.CreateFaceVertexCountsAttr(plain.face_sizes.tolist())
    second.CreateFaceVertexIndicesAttr(plain.face_vertices.tolist())
    second.CreateTriangleSubdivisionRuleAttr("smooth")
    stage.GetRootLayer().Save()
    _one_line_error(_main(capsys, "info", path), "different triangleSubdivisionRule", "/other/pyramid")
    bad = tmp_path / "bad.usda"
    write_stage(plain, bad, intervals=False)
    stage = Usd.Stage.Open(str(bad))
    UsdGeom.Mesh(stage.GetPrimAtPath("/root/part")).CreateTriangleSubdivisionRuleAttr("loopy")
    stage.GetRootLayer().Save()
    _one_line_error(_main(capsys, "info", bad), "triangleSubdivisionRule 'loopy'", "/root/part")
