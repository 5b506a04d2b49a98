"""export.pack: regular blocks as multi-span B-spline faces, the same surface."""

from __future__ import annotations

import numpy as np
import pytest
from OCP.BRep import BRep_Tool
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_FACE
from OCP.TopExp import TopExp
from export.ocp_compat import TopoDS
from export.ocp_compat import TopTools_IndexedMapOfShape

import patching
from export.continuity import check_continuity
from export.pack import patch_spans, to_packed_shape
from export.step import read_step
from patching.evaluation.sampling import evaluate_nets
from patching.mesh.primitives import open_grid, torus_grid
from tests.helpers import net_volume
from tests.helpers import ell_mesh

# The packed face against the patches: the same polynomials, one re-expressed by knot
# removal; measured 2e-16 to 4.4e-16 of the size, so 1e-14 (25x; the issue asks 1e-12).
EXACT = 1e-14


def turned_torus() -> patching.ControlMesh:
    """A non-uniform torus whose faces start at random corners: patch frames turn."""
    base = torus_grid(9, 7, [1, 2, 3, 1, 1, 2, 3, 1, 5], [1, 2, 1, 3, 1, 1, 2], name="turned")
    rng = np.random.default_rng(3)
    faces = [list(np.roll(base.face(f), rng.integers(4))) for f in range(base.n_faces)]
    return patching.from_arrays(base.vertices, faces, intervals=dict(base.intervals), name="turned")


def split_torus() -> patching.ControlMesh:
    """An 8 x 6 torus with one quad split into two triangles (build subdivides it once)."""
    base = torus_grid(8, 6, name="split")
    a, b, c, d = (int(x) for x in base.face(0))
    faces = [[a, b, c], [a, c, d]] + [list(base.face(f)) for f in range(1, base.n_faces)]
    return patching.from_arrays(base.vertices, faces, name="split")


MESHES = {
    "non-quad faces": split_torus,
    "torus with a zero strip": lambda: patching.read_mesh("models/torus_nonuniform.obj"),
    "turned faces": turned_torus,
    "EP model": ell_mesh,
    "clamped open grid": lambda: open_grid(9, 7, [0, 1, 2, 1, 1, 3, 1, 0], [0, 1, 1, 2, 1, 0], name="grid"),
}


def faces_of(shape):
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    return [TopoDS.Face_s(faces.FindKey(i)) for i in range(1, faces.Extent() + 1)]


def join_multiplicities(block, nets, direction: int, size: float) -> list[int]:
    """Per inner join of the block along u (direction 0) or v (1): 3 - k for the highest order
    k <= 3 to which the patches on both sides agree, from OpenCASCADE's D3 of each patch as a
    Bézier face, in the block's parameters (derivative k divided by the span length to the
    k), at t = 0, 1/3, 2/3, 1 along every join (each jump is a cubic in t: those four values
    are all of it); 0 where they agree to order 3 (one cubic: no knot).
    A jump counts below 1e-9 of the size times the shorter span to the k (round-off is 1e-15,
    a real jump 1e-4 or more on these meshes)."""
    from OCP.gp import gp_Pnt, gp_Vec

    from export.brep import bezier_surface

    w, h = block.rows.shape
    spans = (block.du, block.dv)[direction]
    faces = {}  # (i, j) -> the patch as a Bézier face in the block's frame
    out = []
    for i in range(len(spans) - 1):
        order = 3
        for j in range((h, w)[direction]):
            cells = ((i, j), (i + 1, j)) if direction == 0 else ((j, i), (j, i + 1))
            derivs = []
            for side, (a, b) in enumerate(cells):
                if (a, b) not in faces:
                    net = np.rot90(nets[int(block.rows[a, b])], -int(block.turns[a, b]), axes=(0, 1))
                    faces[a, b] = bezier_surface(np.ascontiguousarray(net))
                face = faces[a, b]
                length = spans[i + side]
                rows = []
                for t in (0.0, 1 / 3, 2 / 3, 1.0):
                    p, vs = gp_Pnt(), [gp_Vec() for _ in range(9)]
                    at = (1.0 - side, t) if direction == 0 else (t, 1.0 - side)
                    face.D3(*at, p, *vs)
                    # D1U D1V D2U D2V D2UV D3U D3V D3UUV D3UVV
                    along = (vs[0], vs[2], vs[5]) if direction == 0 else (vs[1], vs[3], vs[6])
                    rows.append([np.array(p.Coord())] + [np.array(v.Coord()) / length ** (n + 1) for n, v in enumerate(along)])
                derivs.append(np.array(rows))  # (4, 4, 3)
            r = min(spans[i], spans[i + 1])
            jumps = np.linalg.norm(derivs[0] - derivs[1], axis=-1).max(axis=0) * r ** np.arange(4)
            agree = np.flatnonzero(jumps > 1e-9 * size)
            order = min(order, int(agree[0]) - 1 if agree.size else 3)
        out.append(3 - order)
    return out


def face_multiplicities(bspline, block, direction: int) -> list[int]:
    """The packed face's multiplicity at each inner join of the block along u or v (0: no
    knot there); every knot of the face is at a join."""
    knots = block.knots[direction]
    n = bspline.NbUKnots() if direction == 0 else bspline.NbVKnots()
    knot = bspline.UKnot if direction == 0 else bspline.VKnot
    mult = bspline.UMultiplicity if direction == 0 else bspline.VMultiplicity
    at = {float(knot(i)): int(mult(i)) for i in range(1, n + 1)}
    assert all(any(x == y for y in knots.tolist()) for x in at), "a knot off the joins"
    return [at.get(float(x), 0) for x in knots[1:-1].tolist()]


@pytest.mark.parametrize("name", sorted(MESHES))
def test_packed_faces_are_the_patches(name):
    mesh = MESHES[name]()
    surface = patching.build(mesh)
    shape, report = to_packed_shape(surface, patch_spans(surface, mesh))
    assert report.packed_faces >= 1 and report.faces < surface.n_patches
    assert report.faces == report.patches - report.packed_patches + report.packed_faces
    faces = faces_of(shape)
    assert len(faces) == report.faces
    nets = [net for _, _, _, net in surface.patches()]
    s = np.linspace(0.0, 1.0, 7)
    ss, tt = (a.ravel() for a in np.meshgrid(s, s, indexing="ij"))
    worst = 0.0
    for k, (block, u, v) in enumerate(report.blocks):
        bspline = BRep_Tool.Surface_s(faces[k])
        # The fewest knots: at each join of the block exactly the multiplicity its continuity
        # needs (OpenCASCADE's derivatives of the Bézier patches), none where one polynomial
        # goes on; with wrong knot intervals the joins would not be C2 and 3 w + 1 poles stay.
        for direction in (0, 1):
            expected = join_multiplicities(block, nets, direction, surface.size)
            assert face_multiplicities(bspline, block, direction) == expected, (k, direction)
        for (i, j), row in np.ndenumerate(block.rows):
            # The patch in the block's frame: turned as the block says, at its span of knots.
            net = np.rot90(nets[row], -int(block.turns[i, j]), axes=(0, 1))
            expected = evaluate_nets(net[None], ss, tt)[0]
            got = np.array([bspline.Value(u[i] + a * block.du[i], v[j] + b * block.dv[j]).Coord() for a, b in zip(ss, tt)])
            worst = max(worst, np.abs(got - expected).max())
    assert worst <= EXACT * surface.size, worst
    report_c = check_continuity(shape)
    assert report_c.valid and report_c.n_free_edges == (0 if surface.topology.is_closed else report_c.n_free_edges)
    assert report_c.g1 and report_c.max_gap_relative < 1e-14


@pytest.mark.parametrize("name", ["torus with a zero strip", "EP model"])
def test_packed_solid_has_the_patches_volume(name):
    """BRepGProp's default rule is coarse on multi-span faces (0.8% off on the torus), so
    its adaptive form is used, to 1e-12; the patch volume is the exact Gauss sum."""
    mesh = MESHES[name]()
    surface = patching.build(mesh)
    shape, _ = to_packed_shape(surface, patch_spans(surface, mesh))
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props, 1e-12, False)
    assert props.Mass() == pytest.approx(net_volume(surface), rel=1e-12)


def test_full_rings_are_not_closed_on_themselves():
    """A 12 x 8 all-regular torus: no block may wrap around (its face would need a seam)."""
    mesh = torus_grid(12, 8, name="ring")
    surface = patching.build(mesh)
    _, report = to_packed_shape(surface, patch_spans(surface, mesh))
    assert all(b.rows.shape[0] < 12 and b.rows.shape[1] < 8 for b, _, _ in report.blocks)
    # 11 x 7, 11 x 1 and 1 x 7 blocks and the one patch left in the corner.
    assert (report.packed_faces, report.packed_patches, report.faces) == (3, 95, 4)


def test_cli_pack_writes_fewer_faces_with_the_same_box(tmp_path, cli_main):
    from tests.conftest import REPO

    mesh = REPO / "models" / "torus_nonuniform.obj"
    plain, packed = tmp_path / "plain.step", tmp_path / "packed.step"
    assert cli_main("build", mesh, "-o", plain, "-q").returncode == 0
    result = cli_main("build", mesh, "-o", packed, "-q", "--pack")
    assert result.returncode == 0, result.stderr
    a, b = read_step(plain), read_step(packed)
    assert (len(faces_of(a)), len(faces_of(b))) == (88, 4)
    from tests.helpers import exact_box

    np.testing.assert_allclose(exact_box(b), exact_box(a), atol=1e-9)
    assert packed.stat().st_size < plain.stat().st_size / 3


def test_inside_out_mesh_gives_a_positive_solid():
    base = torus_grid(6, 5, [1, 2, 3, 3, 2, 1], None, name="inside_out")
    faces = [list(base.face(f))[::-1] for f in range(base.n_faces)]
    mesh = patching.from_arrays(base.vertices, faces, intervals=dict(base.intervals), name="inside_out")
    surface = patching.build(mesh)
    assert net_volume(surface) < 0
    shape, _ = to_packed_shape(surface, patch_spans(surface, mesh))
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props, 1e-12, False)
    assert props.Mass() == pytest.approx(-net_volume(surface), rel=1e-12)


def test_pack_refuses_degenerate_geometry_as_build_does(tmp_path, run_cli):
    """A cube collapsed to a point is refused by ``build`` (test_cli); with --pack it was
    written (exit 0): to_packed_shape skipped to_shape's input checks."""
    from tests.helpers import assert_refused as _assert_refused

    mesh = tmp_path / "point.obj"
    faces = ["f 1 2 4 3", "f 5 7 8 6", "f 1 5 6 2", "f 3 4 8 7", "f 1 3 7 5", "f 2 6 8 4"]
    mesh.write_text("\n".join(["v 0 0 0"] * 8 + faces) + "\n")
    out = tmp_path / "out.step"
    _assert_refused(run_cli("build", mesh, "-o", out, "--pack"), "side 0 of the patch on face 0 has no length")
    assert not out.exists()


def test_pack_writes_a_flat_closed_mesh_as_a_shell_as_build_does(tmp_path, run_cli):
    """A cube collapsed to a plane: with --pack too a shell and one warning line."""
    mesh = tmp_path / "flat.obj"
    faces = ["f 1 2 4 3", "f 5 7 8 6", "f 1 5 6 2", "f 3 4 8 7", "f 1 3 7 5", "f 2 6 8 4"]
    mesh.write_text("\n".join([f"v {x} {y} 0" for x in (0, 1) for y in (0, 1)] * 2 + faces) + "\n")
    out = tmp_path / "out.step"
    result = run_cli("build", mesh, "-o", out, "--pack", "-q")
    assert result.returncode == 0, result.stderr
    assert sum("encloses no volume" in line for line in result.stderr.splitlines()) == 1
    from export.continuity import check_continuity

    report = check_continuity(out)
    assert report.valid and report.n_solids == 0 and report.n_shells == 1


def twisted_torus(m: int = 8, n: int = 6) -> patching.ControlMesh:
    """A regular m x n torus grid glued with a shift: going once around in u climbs one row
    in v, so the rows of patches along u form one helix through all m n faces."""
    def vid(i, k):
        return (i % m) * n + (k + i // m) % n

    i, k = (a.ravel() for a in np.meshgrid(np.arange(m), np.arange(n), indexing="ij"))
    a, b = 2 * np.pi * i / m, 2 * np.pi * (k + i / m) / n
    vertices = np.stack([(3 + np.cos(b)) * np.cos(a), (3 + np.cos(b)) * np.sin(a), np.sin(b)], -1)
    faces = [[vid(x, y), vid(x + 1, y), vid(x + 1, y + 1), vid(x, y + 1)] for x, y in zip(i.tolist(), k.tolist())]
    return patching.from_arrays(vertices, faces, name="twisted")


def test_no_packed_face_meets_itself():
    """On the twisted torus a block grown along u winds around the helix: before, a 47 x 1
    block's sides 0 and 2 met each other along 46 edges, each then a seam of that one
    non-periodic face (valid to BRepCheck, but not the seamless faces the module promises).
    No boundary side of a block may face a patch of the same block."""
    from tests.helpers import edges_of

    mesh = twisted_torus()
    surface = patching.build(mesh)
    shape, report = to_packed_shape(surface, patch_spans(surface, mesh))
    assert report.packed_faces >= 1
    edges = edges_of(shape)
    faces = faces_of(shape)
    assert not any(BRep_Tool.IsClosed_s(e, f) for f in faces for e in edges)
    report_c = check_continuity(shape)
    assert report_c.valid and report_c.n_solids == 1 and report_c.g1
