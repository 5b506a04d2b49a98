"""Reading OBJ polylines with corner and control-vector tags."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from patching.curves.polyline import parse_polyline
from patching.errors import InputFileError, MeshError, NupatchError, TagError


def test_closed_polyline_tags_and_order():
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1\nl 1 2\nl 2 3 4 1\nt corner 1/1/0 2 2.5\nt corner 1/1/0 3 12\n" \
           "t controlvector 1/4/0 1 0.5 0 0 1.5\n"
    p = parse_polyline(text)
    assert p.closed and len(p.points) == 4
    assert np.allclose(p.points[3], [0, 1, 0])  # a two-coordinate vertex gets z = 0
    assert p.corners == {2: 2.5, 3: math.inf}  # s >= 10 is infinitely sharp
    vec, s = p.vectors[1]
    assert np.allclose(vec, [0.5, 0, 0]) and s == 1.5


def test_polyline_order_differs_from_vertex_order():
    p = parse_polyline("v 0 0 0\nv 1 0 0\nv 2 0 0\nl 3 1 2\nt corner 1/1/0 0 inf\n")
    assert not p.closed
    assert np.allclose(p.points[:, 0], [2, 0, 1])
    assert p.corners == {1: math.inf}  # vertex 0 is the second point of the polyline


def test_unknown_tag_warns():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        parse_polyline("v 0 0 0\nv 1 0 0\nl 1 2\nt crease 2/1/0 0 1 2\n")
    assert any("unknown tag 'crease'" in str(w.message) for w in caught)


@pytest.mark.parametrize(
    "text, error, needle",
    [
        ("v 0 0 0\nl 1\n", MeshError, "at least 2"),
        ("v 0 0 0\nv 1 0 0\n", MeshError, "no polyline"),
        ("v 0 0 0\nv 1 0 0\nl 1 3\n", MeshError, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 2 0 0\nl 1 2\nl 3 1\n", MeshError, "does not continue"),
        ("v 0 0 0\nv 1 0 0\nl 1 2\nt corner 1/1/0 1 nan\n", TagError, "NaN"),
        ("v 0 0 0\nv 1 0 0\nl 1 2\nt corner 1/1/0 1 -2\n", TagError, "negative"),
        ("v 0 0 0\nv 1 0 0\nv 5 5 5\nl 1 2\nt corner 1/1/0 2 1\n", TagError, "not on the polyline"),
        ("v 0 0 0\nv 1 0 0\nl 1 2\nt controlvector 1/3/0 7 1 0 0\n", TagError, "vertex 7"),
        ("v 0 0 0\nv 1 0 0\nl 1 2\nt controlvector 1/3/0 0 1 nan 0\n", TagError, "non-finite"),
        ("v 0 0 x\nv 1 0 0\nl 1 2\n", InputFileError, "coordinate"),
    ],
)
def test_bad_files_name_the_line(text, error, needle):
    with pytest.raises(error) as info:
        parse_polyline(text, source="c.obj")
    assert needle in str(info.value)
    assert "c.obj" in str(info.value)
    assert isinstance(info.value, NupatchError)
