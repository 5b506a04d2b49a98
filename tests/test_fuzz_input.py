"""Bad input never crashes: random OBJ text and random small meshes either build or raise the
NupatchError family (the CLI turns that into one line and exit 2); any other exception is a bug."""

import math
import warnings

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import patching
from patching.errors import NupatchError
from patching.obj import parse_obj

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
