"""export.formats: every format writes atomically and reads back; normals come from the patches."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepTools import BRepTools
from OCP.GeomLProp import GeomLProp_SLProps
from OCP.IFSelect import IFSelect_RetDone
from OCP.IGESControl import IGESControl_Reader
from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
from OCP.TopExp import TopExp
from OCP.TopoDS import TopoDS_Shape
from export.ocp_compat import TopoDS
from export.ocp_compat import TopTools_IndexedMapOfShape

import export.formats as formats
import patching
from export.tolerances import MIN_TESSELLATION
from export.brep import to_shape
from export.formats import FORMATS, format_of, tessellate, write
from export.step import read_step
from patching.errors import OutputError
from patching.mesh.primitives import open_grid, torus_grid
from tests.helpers import exact_box

TESSELLATED = ("stl", "glb", "obj")
EXACT = ("step", "iges", "brep")


@pytest.fixture(scope="module")
def ring():
    surface = patching.build(torus_grid(8, 6, [1, 2, 4, 1, 0.5, 1, 3, 1], [1, 2, 1, 1, 3, 1], name="ring"))
    return surface, to_shape(surface)


def faces_of(shape) -> list:
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    return [TopoDS.Face_s(faces.FindKey(i)) for i in range(1, faces.Extent() + 1)]


def read_glb(path):
    """(json, {attribute: array}, indices) of a binary glTF written as one buffer."""
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<III", data)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    json_len, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A
    gltf = json.loads(data[20 : 20 + json_len])
    bin_len, bin_type = struct.unpack_from("<II", data, 20 + json_len)
    assert bin_type == 0x004E4942
    blob = data[28 + json_len : 28 + json_len + bin_len]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}
    dtype = {5126: "<f4", 5125: "<u4"}

    def accessor(i):
        a = gltf["accessors"][i]
        view = gltf["bufferViews"][a["bufferView"]]
        array = np.frombuffer(blob, dtype[a["componentType"]], a["count"] * width[a["type"]], view["byteOffset"])
        return array.reshape(a["count"], width[a["type"]]) if width[a["type"]] > 1 else array

    primitive = gltf["meshes"][0]["primitives"][0]
    attributes = {k: accessor(v) for k, v in primitive["attributes"].items()}
    return gltf, attributes, accessor(primitive["indices"]).reshape(-1, 3)


def read_back(fmt: str, path):
    """(shape or None, (v, 3) points or None, triangle count or None) of a written file."""
    if fmt == "step":
        return read_step(path), None, None
    if fmt == "brep":
        shape = TopoDS_Shape()
        assert BRepTools.Read_s(shape, str(path), BRep_Builder())
        return shape, None, None
    if fmt == "iges":
        reader = IGESControl_Reader()
        assert reader.ReadFile(str(path)) == IFSelect_RetDone
        reader.TransferRoots()
        return reader.OneShape(), None, None
    if fmt == "glb":
        gltf, attributes, triangles = read_glb(path)
        assert gltf["nodes"][0]["scale"] == [0.001] * 3  # millimetres under a metre scene
        return None, attributes["POSITION"].astype(float), len(triangles)
    import trimesh

    mesh = trimesh.load(path, process=False, force="mesh")
    return None, np.asarray(mesh.vertices), len(mesh.faces)


def test_format_follows_the_suffix_unless_given():
    assert format_of("a.STP") == "step" and format_of("a.igs") == "iges" and format_of("a.glb") == "glb"
    assert format_of("a.step", "stl") == "stl"
    with pytest.raises(OutputError, match="suffix '.ply'"):
        format_of("a.ply")
    with pytest.raises(OutputError, match="'ply' is not supported"):
        format_of("a.step", "ply")
    assert set(FORMATS) == {"step", "iges", "brep", "stl", "glb", "obj", "3dm"}


@pytest.mark.parametrize("fmt", [f for f in FORMATS if f != "3dm"])  # 3dm: read back by tests/test_rhino.py
def test_every_format_reads_back_with_the_steps_faces_and_box(tmp_path, ring, fmt):
    surface, shape = ring
    path = write(surface, tmp_path / f"ring.{fmt}", shape=shape, tolerance=0.01)
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"ring.{fmt}"]  # no temporary left
    reference = exact_box(shape)
    back, points, n_triangles = read_back(fmt, path)
    if fmt in EXACT:
        assert BRepCheck_Analyzer(back).IsValid()
        assert len(faces_of(back)) == surface.n_patches
        # Same surfaces: the box agrees to the 13 significant digits STEP and IGES print.
        np.testing.assert_allclose(exact_box(back), reference, rtol=0, atol=1e-9 * surface.size)
    else:
        t = tessellate(surface, shape, 0.01)
        assert n_triangles == len(t.triangles) > surface.n_patches
        # glTF and OBJ keep our vertices (one per face and node); STL has three per triangle.
        assert len(points) == (3 * len(t.triangles) if fmt == "stl" else len(t.points))
        box = np.array([points.min(axis=0), points.max(axis=0)])
        # Nodes lie on the surface, so the box can only shrink, by at most the deflection;
        # 1e-5 covers the float32 of STL and glTF (7 digits of coordinates ~4).
        assert np.all(box[0] >= reference[0] - 1e-5) and np.all(box[1] <= reference[1] + 1e-5)
        np.testing.assert_allclose(box, reference, atol=0.01 + 1e-5)


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_format_write_is_atomic(tmp_path, ring, monkeypatch, fmt):
    surface, shape = ring
    path = tmp_path / f"ring.{fmt}"
    path.write_bytes(b"old")
    real = formats.WRITERS[fmt]

    def failing(job, tmp):
        real(job, tmp)  # the whole file, then a failure
        raise RuntimeError("disk on fire")

    monkeypatch.setitem(formats.WRITERS, fmt, failing)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write(surface, path, shape=shape)
    assert path.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    monkeypatch.setitem(formats.WRITERS, fmt, real)
    write(surface, path, shape=shape)
    assert path.stat().st_size > 3


@pytest.fixture(scope="module")
def ell():
    """An EP model: bicubic and bi-quintic patches (two groups, rows offset)."""
    from tests.helpers import ell_mesh

    surface = patching.build(ell_mesh())
    assert [g.degree for g in surface.groups] == [3, 5]
    return surface, to_shape(surface)


@pytest.mark.parametrize("model", ["ring", "ell"])
def test_gltf_normals_are_the_patch_normals(tmp_path, request, model):
    """At every stored vertex, OCC's own surface normal (GeomLProp) at the stored (s, t) of the
    stored patch agrees with the file's normal: float32 storage leaves ~1e-7 rad, the bound 1e-6."""
    surface, shape = request.getfixturevalue(model)
    path = write(surface, tmp_path / "model.glb", shape=shape, tolerance=0.01 * surface.size / 10)
    _, attributes, _ = read_glb(path)
    faces = faces_of(shape)
    rng = np.random.default_rng(5)
    picked = rng.choice(len(attributes["NORMAL"]), 300, replace=False)
    worst = 0.0
    for k in picked:
        face = faces[int(attributes["_PATCH"][k])]
        s, t = (float(x) for x in attributes["TEXCOORD_0"][k])
        props = GeomLProp_SLProps(BRep_Tool.Surface_s(face), s, t, 1, 1e-12)
        n = np.array(props.Normal().Coord()) * (-1 if face.Orientation() == TopAbs_REVERSED else 1)
        p = np.array(props.Value().Coord())
        assert np.linalg.norm(p - attributes["POSITION"][k]) < 1e-5  # float32 positions
        stored = attributes["NORMAL"][k].astype(float)
        worst = max(worst, np.arctan2(np.linalg.norm(np.cross(n, stored)), n @ stored))
    assert worst < 1e-6, worst


def test_normals_differ_from_facet_normals_and_point_outwards(ring):
    surface, shape = ring
    t = tessellate(surface, shape, 0.05)
    corners = t.points[t.triangles]
    facet = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    facet /= np.linalg.norm(facet, axis=1, keepdims=True)
    vertex = t.normals[t.triangles[:, 0]]
    cosine = np.einsum("ij,ij->i", facet, vertex)
    assert cosine.min() > 0.5, "triangles wound against the patch normals"
    assert cosine.min() < 1 - 1e-6, "vertex normals equal facet normals: not from the patches"
    # Outward on a torus around the z axis: the normal points away from the tube's centre line.
    radial = t.points.copy()
    radial[:, 2] = 0
    centre = 3.0 * radial / np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", t.points - centre, t.normals) > 0)


def test_open_surface_and_bad_tolerance(tmp_path):
    surface = patching.build(open_grid(5, 4, [0, 1, 1, 0], [0, 1, 0], name="sheet"))
    path = write(surface, tmp_path / "sheet.obj")
    assert path.read_text().count("\nf ") > 0
    with pytest.raises(patching.NupatchError, match="tolerance"):
        write(surface, tmp_path / "bad.stl", tolerance=-1.0)
    assert not (tmp_path / "bad.stl").exists()


def test_a_tiny_mesh_tessellates_and_a_tolerance_below_occs_precision_is_refused(tmp_path):
    """Found by fuzzing: a grid of size 7e-6 builds a valid shell, but its default deflection
    (1e-3 x size) is below OpenCASCADE's precision (1e-7) and BRepMesh_IncrementalMesh threw
    Standard_NumericError (an internal error, exit 1); so did --tolerance 1e-300."""
    grid = open_grid(5, 4, [0, 1, 1, 0], [0, 1, 0], name="speck")
    surface = patching.build(grid.with_positions(grid.vertices * 1e-6))
    for fmt in TESSELLATED:
        assert write(surface, tmp_path / f"speck.{fmt}").stat().st_size > 0
    assert tessellate(surface).tolerance == MIN_TESSELLATION
    for tolerance in (1e-300, 0.5 * MIN_TESSELLATION):
        with pytest.raises(patching.NupatchError, match="at least 1e-07") as info:
            write(surface, tmp_path / "bad.stl", tolerance=tolerance)
        assert "\n" not in str(info.value)
    assert not (tmp_path / "bad.stl").exists()


def test_two_components_tessellate_with_outward_normals(tmp_path):
    """Found by fuzzing: a mesh of two frames (bicubic and bi-quintic patches, so the patch rows
    of the two components interleave) built a valid compound of two solids, but its faces come
    component by component and STL, glTF and OBJ stopped with an internal error (RuntimeError:
    tessellation nodes are 19.3 off the patches); check_continuity named other mesh faces than
    the ones meeting at an edge."""
    from patching.mesh.primitives import polycube

    frame = polycube([(x, y, 0) for x in range(3) for y in range(3) if (x, y) != (1, 1)], 1)
    faces = frame.quads()
    pair = patching.from_arrays(np.vstack([frame.vertices, frame.vertices + 10.0]), np.vstack([faces, faces + frame.n_vertices]))
    surface = patching.build(pair)
    assert len({g.degree for g in surface.groups}) == 2
    t = tessellate(surface)
    assert sorted(set(t.patch.tolist())) == list(range(surface.n_patches))
    corners = t.points[t.triangles]
    facet = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert (np.einsum("ij,ij->i", facet, t.normals[t.triangles].mean(axis=1)) > 0).all()
    for fmt in TESSELLATED:
        assert write(surface, tmp_path / f"pair.{fmt}").stat().st_size > 0
    # check_continuity names mesh faces: both faces of every shared edge share a mesh edge
    from export import check_continuity

    edges = {frozenset(map(int, e)) for f in range(pair.n_faces) for e in zip(pair.face(f), np.roll(pair.face(f), -1))}
    sides = [{frozenset(map(int, e)) for e in zip(pair.face(f), np.roll(pair.face(f), -1))} for f in range(pair.n_faces)]
    report = check_continuity(surface, all_edges=True)
    assert report.edges and all(sides[a] & sides[b] & edges for a, b in (d.faces for d in report.edges))
