"""Each closed piece of a multi-part model is judged on its own scale (export.brep): tiny
closed boxes beside a big part are solids, a closed piece of no volume is a shell with one
warning, and the rest of the model is still written."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_SOLID
from OCP.TopExp import TopExp
from export.ocp_compat import TopTools_IndexedMapOfShape

import patching
from export.brep import to_shape
from export.continuity import check_continuity
from export.pack import patch_spans, to_packed_shape

#: The six quads of the unit cube with vertex (x, y, z) at index 4x + 2y + z, outward.
CUBE_FACES = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
CORNERS = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float) - 0.5


def boxes(parts, name="parts") -> patching.ControlMesh:
    """One closed 6-quad box per (centre, (sx, sy, sz)) of ``parts``; sz = 0 gives a flat
    closed piece (both lids in one plane)."""
    verts, faces = [], []
    for centre, scale in parts:
        base = 8 * len(verts)
        verts.append(CORNERS * np.asarray(scale, float) + np.asarray(centre, float))
        faces += [[base + i for i in f] for f in CUBE_FACES]
    return patching.from_arrays(np.vstack(verts), faces, name=name)


def solid_volumes(shape) -> list[float]:
    solids = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_SOLID, solids)
    out = []
    for i in range(1, solids.Extent() + 1):
        props = GProp_GProps()
        BRepGProp.VolumeProperties_s(solids.FindKey(i), props)
        out.append(props.Mass())
    return out


def limit_box_volume(edge: float) -> float:
    """Volume of the Catmull-Clark limit of a cube of this edge: the surface of one unit box
    measured alone (a model of one piece, which the old global check accepted), scaled."""
    shape = to_shape(patching.build(boxes([((0, 0, 0), (1, 1, 1))])))
    return solid_volumes(shape)[0] * edge**3


@pytest.mark.parametrize("build", ["to_shape", "pack"])
def test_tiny_closed_boxes_beside_a_big_part_are_solids(build):
    """A part of size 10 and boxes of 1/250 and 1/1000 of the model's size (about 25): each
    a solid of the right volume (was refused whole: 'encloses no volume')."""
    small = [0.1, 0.025]
    mesh = boxes([((0, 0, 0), (10, 6, 4)), ((20, 0, 0), (small[0],) * 3), ((0, 15, 3), (small[1],) * 3)])
    surface = patching.build(mesh)
    with warnings.catch_warnings():
        warnings.simplefilter("error", patching.NupatchWarning)
        shape = to_shape(surface) if build == "to_shape" else to_packed_shape(surface, patch_spans(surface, mesh))[0]
    report = check_continuity(shape)
    assert report.valid and report.n_solids == 3 and report.n_shells == 3
    volumes = sorted(solid_volumes(shape))
    for v, edge in zip(volumes[:2], sorted(small)):
        assert v == pytest.approx(limit_box_volume(edge), rel=1e-6)
    assert volumes[2] > 0


@pytest.mark.parametrize("build", ["to_shape", "pack"])
def test_a_flat_closed_piece_becomes_a_shell_with_one_warning(build):
    """Beside two boxes, a closed piece whose control points lie in a plane: it is written
    as a shell, named in one warning; the boxes stay solids."""
    mesh = boxes([((0, 0, 0), (10, 6, 4)), ((20, 0, 0), (2, 2, 0)), ((0, 15, 3), (0.05,) * 3)])
    surface = patching.build(mesh)
    with pytest.warns(patching.NupatchWarning, match="encloses no volume") as caught:
        shape = to_shape(surface) if build == "to_shape" else to_packed_shape(surface, patch_spans(surface, mesh))[0]
    messages = [str(w.message) for w in caught if issubclass(w.category, patching.NupatchWarning)]
    assert len(messages) == 1 and "mesh face 6" in messages[0] and "a shell" in messages[0]
    report = check_continuity(shape)
    assert report.valid and report.n_solids == 2 and report.n_shells == 3
    assert min(solid_volumes(shape)) > 0


def test_flat_piece_through_the_cli(tmp_path, run_cli):
    """`nupatch build` writes the model with one warning line naming the piece (the flat
    piece's lids also fold onto each other, which the fold warning reports); exit 0."""
    from export import write_obj

    mesh = boxes([((0, 0, 0), (10, 6, 4)), ((20, 0, 0), (2, 2, 0)), ((0, 15, 3), (0.05,) * 3)], name="parts")
    src = tmp_path / "parts.obj"
    write_obj(mesh, src)
    out = tmp_path / "parts.step"
    result = run_cli("build", src, "-o", out, "-q")
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert all(line.startswith("nupatch: warning: ") for line in lines)
    assert sum("encloses no volume" in line for line in lines) == 1
    report = check_continuity(out)
    assert report.valid and report.n_solids == 2 and report.n_shells == 3
