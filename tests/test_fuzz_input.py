"""Bad input never crashes: random OBJ text and random small meshes either build or raise the
NupatchError family (the CLI turns that into one line and exit 2); any other exception is a bug."""

import math
import warnings

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import patching
from patching.errors import NupatchError
from patching.mesh.obj import parse_obj

TOKENS = ["v", "f", "t", "vt", "vn", "#", "interval", "crease", "corner", "hole", "interpolateboundary",
          "2/1/0", "1/1/0", "1/0/0", "0", "1", "2", "3", "-1", "4", "1.5", "nan", "inf", "-2", "1/2/3", "x", "10"]


@st.composite
def obj_text(draw):
    lines = []
    # a plausible start: some vertices and quads, then noise
    nv = draw(st.integers(0, 8))
    for _ in range(nv):
        lines.append("v " + " ".join(str(draw(st.floats(-5, 5, allow_nan=False))) for _ in range(3)))
    for _ in range(draw(st.integers(0, 8))):
        lines.append(" ".join(draw(st.lists(st.sampled_from(TOKENS), min_size=1, max_size=7))))
    for _ in range(draw(st.integers(0, 6))):
        size = draw(st.integers(1, 5))
        lines.append("f " + " ".join(str(draw(st.integers(-nv - 1, nv + 1))) for _ in range(size)))
    return "\n".join(draw(st.permutations(lines)))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(obj_text())
def test_random_obj_text_reads_or_raises_the_error_family(text):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            mesh = parse_obj(text, source="fuzz.obj")
        except NupatchError as exc:
            assert str(exc) and "\n" not in str(exc)
            return
        try:
            op = patching.build_operator(mesh)
        except NupatchError as exc:
            assert str(exc) and "\n" not in str(exc)
            return
    assert np.allclose(op.row_sums, 1.0, atol=1e-9)
    assert np.isfinite(op.matrix.data).all()


@st.composite
def small_meshes(draw):
    n = draw(st.integers(3, 9))
    vertices = draw(st.lists(st.tuples(*[st.floats(-3, 3, allow_nan=False)] * 3), min_size=n, max_size=n))
    faces = draw(st.lists(st.lists(st.integers(0, n - 1), min_size=3, max_size=5, unique=True), min_size=1, max_size=10))
    intervals = draw(st.dictionaries(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), st.sampled_from([0.0, 0.5, 1.0, 2.0, 7.0]), max_size=4))
    return vertices, faces, intervals


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_meshes())
def test_random_small_meshes_build_or_raise_the_error_family(data):
    vertices, faces, intervals = data
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            mesh = patching.from_arrays(np.array(vertices), faces, intervals=intervals, name="fuzz")
            op = patching.build_operator(mesh)
        except NupatchError as exc:
            assert str(exc) and "\n" not in str(exc)
            return
    assert np.allclose(op.row_sums, 1.0, atol=1e-9)
    assert all(math.isfinite(x) for x in op.matrix.data)


def _bases():
    from patching.mesh.primitives import polycube, torus_grid
    from tests.helpers import quad_mesh_with_eps

    pyramid = patching.from_arrays(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1.0]]),
        [[0, 3, 2, 1], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]],
        name="pyramid",
    )
    return [quad_mesh_with_eps("cube"), polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0)], 1), quad_mesh_with_eps("bipyramid-5"), torus_grid(5, 4), pyramid]


BASES = None


@st.composite
def mutated_meshes(draw):
    global BASES
    if BASES is None:
        BASES = _bases()
    base = BASES[draw(st.integers(0, len(BASES) - 1))]
    faces = [list(base.face(f)) for f in range(base.n_faces)]
    vertices = base.vertices.copy()
    topo = patching.Topology(base)
    intervals = {}
    for _ in range(draw(st.integers(0, 4))):
        e = draw(st.integers(0, topo.n_edges - 1))
        a, b = (int(x) for x in topo.edges[e])
        intervals[(a, b)] = draw(st.sampled_from([0.0, 1e-6, 0.3, 1.0, 4.0, 1e6]))
    kind = draw(st.sampled_from(["none", "jitter", "collapse", "drop", "scale"]))
    if kind == "jitter":
        vertices = vertices + np.random.default_rng(draw(st.integers(0, 99))).normal(scale=draw(st.sampled_from([1e-9, 0.1, 10.0])), size=vertices.shape)
    elif kind == "collapse":
        i, j = draw(st.integers(0, len(vertices) - 1)), draw(st.integers(0, len(vertices) - 1))
        vertices[i] = vertices[j]
    elif kind == "drop" and len(faces) > 1:
        faces.pop(draw(st.integers(0, len(faces) - 1)))
    elif kind == "scale":
        vertices = vertices * draw(st.sampled_from([1e-12, 1e12]))
    return vertices, faces, intervals


@settings(max_examples=120, deadline=None, suppress_health_check=list(HealthCheck))
@given(mutated_meshes())
def test_mutated_meshes_export_or_raise_the_error_family(data):
    from export import to_shape

    vertices, faces, intervals = data
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            mesh = patching.from_arrays(vertices, faces, intervals=intervals, name="fuzz")
            surface = patching.build(mesh)
            shape = to_shape(surface)
        except NupatchError as exc:
            assert str(exc) and "\n" not in str(exc)
            return
    assert not shape.IsNull()


def test_a_mesh_where_no_face_gives_a_patch_is_refused_in_one_line():
    """Found by fuzzing: an open grid under interpolateboundary 0, a mesh whose faces are all
    holes, or a quad of zero span gave an empty surface, and the B-rep an internal error
    (BrepError: the surface has no patches, exit 1)."""
    import pytest

    from patching.mesh.primitives import open_grid
    from tests.helpers import quad_mesh_with_eps

    grid = open_grid(4, 3)
    cube = quad_mesh_with_eps("cube")
    quad = ([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]])
    cases = {
        "interpolateboundary 0": patching.from_arrays(grid.vertices, grid.quads(), interpolate_boundary=0),
        "holes": patching.from_arrays(cube.vertices, cube.quads(), holes=range(cube.n_faces)),
        "zero knot intervals": patching.from_arrays(*quad, intervals={(0, 1): 0.0}),
    }
    for cause, mesh in cases.items():
        with pytest.raises(patching.MeshError, match="no face gives a patch") as info:
            patching.build(mesh)
        assert cause in str(info.value) and "\n" not in str(info.value)


def test_a_small_mesh_far_from_the_origin_is_refused_in_one_line_not_a_brep_bug():
    """Found by fuzzing: the cube moved to 1e9 (size 1.7) has coordinates whose round-off
    (2.2e-7) exceeds the B-rep tolerance (1.7e-7); OpenCASCADE rejected every face and the CLI
    reported an internal error (BrepError, exit 1), packed or not.  Moved to 1e7 it builds."""
    import pytest

    from export import to_shape
    from export.pack import patch_spans, to_packed_shape
    from tests.helpers import quad_mesh_with_eps

    cube = quad_mesh_with_eps("cube")
    near = cube.with_positions(cube.vertices + 1e7)
    assert not to_shape(patching.build(near)).IsNull()
    far = cube.with_positions(cube.vertices + 1e9)
    surface = patching.build(far)
    for make in (lambda: to_shape(surface), lambda: to_packed_shape(surface, patch_spans(surface, far))):
        with pytest.raises(patching.MeshError, match="too far from the origin") as info:
            make()
        assert "\n" not in str(info.value)


def test_huge_coordinates_are_refused_in_one_line_naming_the_vertex(tmp_path):
    """Found by fuzzing: the cube scaled by 1e40 wrote an STL of infinities (32-bit floats) with
    exit 0; by 1e80 OpenCASCADE's meshing hung (STL, glTF, OBJ); by 1e120 it was refused as
    'encloses no volume' (the volume overflows).  Up to MAX_COORDINATE it still exports."""
    import pytest

    from export.formats import write
    from patching.mesh.control_mesh import MAX_COORDINATE
    from tests.helpers import quad_mesh_with_eps

    cube = quad_mesh_with_eps("cube")
    faces = cube.quads()
    for scale in (1e40, -1e80, 1e150):
        with pytest.raises(patching.MeshError, match="of vertex 1 is beyond") as info:
            patching.from_arrays(cube.vertices * scale, faces)
        assert "\n" not in str(info.value)
    with pytest.raises(patching.MeshError, match="cube.obj:3"):
        parse_obj("v 0 0 0\nv 0 0 0\nv 1e300 0 0\nf 1 2 3\n", source="cube.obj")
    points = cube.vertices / np.abs(cube.vertices).max() * MAX_COORDINATE
    write(patching.build(patching.from_arrays(points, faces)), tmp_path / "big.stl")
    data = np.fromfile(tmp_path / "big.stl", dtype=np.uint8)[84:].tobytes()
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
    assert np.isfinite(np.frombuffer(data, dtype=record)["corners"]).all()


def test_a_zero_strip_between_two_sharp_creases_is_refused_in_one_line():
    """Found by fuzzing: on a 5 x 4 torus, a zero strip (edge 0-3) between two infinitely sharp
    rings built patches on either side that end on two different crease curves while the B-rep
    joins them across the collapsed strip: BRepCheck_Analyzer rejected it (BrepError, exit 1),
    packed or not.  Two zero strips in a row between two rings likewise.  One ring beside the
    strip stays a valid solid."""
    import pytest

    from export import to_shape
    from patching.mesh.primitives import torus_grid

    base = torus_grid(5, 4)  # vertex (i, j) is 4 i + j
    def ring(j):
        return {tuple(sorted((4 * i + j, 4 * ((i + 1) % 5) + j))): 10.0 for i in range(5)}

    def torus(intervals, creases):
        return patching.from_arrays(base.vertices, base.quads(), intervals=intervals, creases=creases)

    for intervals, creases in [({(0, 3): 0.0}, {**ring(0), **ring(3)}), ({(0, 3): 0.0, (2, 3): 0.0}, {**ring(0), **ring(2)})]:
        with pytest.raises(patching.UnsupportedError, match="between the infinitely sharp creases") as info:
            patching.build(torus(intervals, creases))
        assert "\n" not in str(info.value) and "interval" in info.value.where
    for creases in (ring(0), ring(3)):
        assert not to_shape(patching.build(torus({(0, 3): 0.0}, creases))).IsNull()


def test_an_obj_file_with_a_byte_order_mark_reads(tmp_path):
    """Found by fuzzing: a UTF-8 byte-order mark before the first line (Windows editors write
    one) was refused as "not an OBJ statement: '\\ufeffv'" (exit 2) for a valid mesh."""
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"
    path = tmp_path / "bom.obj"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    mesh = patching.read_mesh(path)
    assert mesh.n_vertices == 4 and mesh.n_faces == 1
    assert np.array_equal(mesh.vertices, parse_obj(text).vertices)


def test_a_tiny_knot_interval_is_named_as_a_cause_of_a_degenerate_patch():
    """Found by fuzzing: an open grid with interval 1e-9 on one strip (1 elsewhere) was refused
    as 'side 1 of the patch on face 0 has no length (its control points coincide)', which
    they do not: the patches on the strip are thinner than the tolerance.  0 builds (a
    multiple knot, no patch on the strip)."""
    import pytest

    from export import to_shape
    from patching.mesh.primitives import open_grid

    grid = open_grid(4, 3)
    for value in (1e-9, 1e-11):
        mesh = patching.from_arrays(grid.vertices, grid.quads(), intervals={(6, 7): value})
        with pytest.raises(patching.MeshError, match="knot interval is tiny") as info:
            to_shape(patching.build(mesh))
        assert "\n" not in str(info.value)
    assert not to_shape(patching.build(patching.from_arrays(grid.vertices, grid.quads(), intervals={(6, 7): 0.0}))).IsNull()


def test_too_many_subdivision_steps_are_refused_before_any_work():
    """Found by fuzzing: `nupatch subdivide cube.obj -n 40` ran out of memory and was killed
    (exit 137, no error line).  Steps past MAX_SUBDIVIDE_FACES are refused in one line."""
    import pytest

    from patching.subdivision.catmark import MAX_SUBDIVIDE_FACES, subdivide
    from tests.helpers import quad_mesh_with_eps

    cube = quad_mesh_with_eps("cube")
    with pytest.raises(patching.UnsupportedError, match="take fewer steps") as info:
        subdivide(cube, 40)
    assert "\n" not in str(info.value)
    steps = 1  # the most steps within the limit
    while cube.n_faces * 4 ** (steps + 1) <= MAX_SUBDIVIDE_FACES:
        steps += 1
    with pytest.raises(patching.UnsupportedError, match="take fewer steps"):
        subdivide(cube, steps + 1)
    assert subdivide(cube, 2).n_faces == cube.n_faces * 16


def test_a_knot_interval_below_1e_12_of_the_largest_is_refused_naming_its_tag():
    """Found by fuzzing: the L polycube with interval 5e-324 on one strip (a hole and other
    tags beside) gave non-finite patch coefficients and an internal error (BrepError, exit 1);
    1e-300 on a grid was refused as a degenerate patch side.  Both name the interval now."""
    import pytest

    from patching.mesh.primitives import open_grid, polycube

    grid = open_grid(4, 3)
    ell = polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0)], 1)
    for base, edge in ((grid, (6, 7)), (ell, (3, 9))):
        for value in (1e-300, 5e-324, 1e-13):
            text = "\n".join(f"v {x!r} {y!r} {z!r}" for x, y, z in base.vertices.tolist())
            text += "\n" + "\n".join("f " + " ".join(str(v + 1) for v in base.face(f)) for f in range(base.n_faces))
            text += f"\nt interval 2/1/0 {edge[0]} {edge[1]} {value!r}\n"
            mesh = parse_obj(text, source="tiny.obj")
            with pytest.raises(patching.KnotError, match=f"edge {edge[0]}-{edge[1]} is below 1e-12") as info:
                patching.build(mesh)
            assert str(info.value).endswith(f"(tiny.obj:{len(base.vertices) + base.n_faces + 1})")
