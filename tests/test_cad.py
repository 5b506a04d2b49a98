"""export.cad: build123d and cadquery objects that survive booleans and fillets."""

from __future__ import annotations

import math

import pytest

import export
import patching
from patching.mesh.primitives import open_grid, torus_grid
from tests.conftest import REPO
from tests.helpers import net_volume
from tests.helpers import ell_mesh

build123d = pytest.importorskip("build123d")
cadquery = pytest.importorskip("cadquery")

# Relative volume tolerances, each the measured error times ~10-100:
# BRepGProp on untrimmed Bézier faces against the exact Gauss sum (net_volume): ~1e-15;
EXACT = 1e-12
# on faces trimmed by a boolean, BRepGProp integrates adaptively and the boolean trims within
# its fuzzy tolerance: ~2e-8 measured on the non-uniform torus cut at x = 0;
TRIMMED = 1e-7
# a fillet surface is OCC's approximation of the rolling-ball sweep: ~4e-10 measured.
FILLET = 1e-8


@pytest.fixture(scope="module")
def mirror_torus():
    """A non-uniform torus symmetric about the plane y = 0 (vertex at angle u <-> -u, strip a
    <-> strip m-1-a), so cutting at y = 0 halves its volume exactly."""
    mesh = torus_grid(6, 4, [1, 2, 3, 3, 2, 1], [1, 2, 1, 0.5], name="mirror")
    return patching.build(mesh)


def test_closed_surface_is_a_valid_build123d_solid_with_the_right_volume(mirror_torus):
    solid = export.to_build123d(mirror_torus)
    assert isinstance(solid, build123d.Solid) and solid.is_valid
    assert solid.volume == pytest.approx(net_volume(mirror_torus), rel=EXACT)


def test_build123d_cut_with_a_half_space_box_halves_the_volume(mirror_torus):
    solid = export.to_build123d(mirror_torus)
    half = solid - build123d.Pos(0, 50, 0) * build123d.Box(100, 100, 100)
    assert half.is_valid
    assert half.volume == pytest.approx(solid.volume / 2, rel=TRIMMED)
    # Bnd_Box is enlarged by the shape tolerance (Precision::Confusion, 1e-7) on every side.
    assert half.bounding_box().max.Y == pytest.approx(0.0, abs=2e-7)


def test_build123d_union_with_a_disjoint_cylinder_adds_its_volume(mirror_torus):
    solid = export.to_build123d(mirror_torus)
    cylinder = build123d.Cylinder(1.0, 4.0)  # through the hole: the torus' inner radius is > 1.5
    union = solid + cylinder
    assert union.is_valid and len(union.solids()) == 2
    assert union.volume == pytest.approx(solid.volume + 4 * math.pi, rel=TRIMMED)


def test_fillet_on_a_plate_fused_to_the_surface(mirror_torus):
    """The README's script: a plate fused under the ring, its four vertical edges filleted;
    each fillet of radius r on a height h removes (1 - pi/4) r^2 h."""
    from build123d import Axis, Box, Pos, fillet

    solid = export.to_build123d(mirror_torus)
    part = solid + Pos(0, 0, -1.2) * Box(10, 10, 1)
    assert part.is_valid and len(part.solids()) == 1
    rounded = fillet(part.edges().filter_by(Axis.Z).group_by(Axis.X)[0], radius=1.0)  # the 2 at x = -5
    assert rounded.is_valid
    assert rounded.volume == pytest.approx(part.volume - 2 * (1 - math.pi / 4), rel=FILLET)


def test_cadquery_workplane_from_a_mesh_file_cut_with_a_box():
    path = REPO / "models" / "torus_nonuniform.obj"
    wp = export.to_cadquery(path)
    assert isinstance(wp, cadquery.Workplane)
    solid = wp.val()
    assert isinstance(solid, cadquery.Solid) and solid.isValid()
    volume = solid.Volume()
    assert volume == pytest.approx(net_volume(patching.build(patching.read_mesh(path))), rel=EXACT)
    box = cadquery.Workplane("XY").box(100, 100, 100).translate((50, 0, 0))
    outside = wp.cut(box).val()
    inside = wp.intersect(box).val()
    assert outside.isValid() and inside.isValid()
    assert 0 < outside.Volume() < volume and 0 < inside.Volume() < volume
    # The two halves make the whole: the boolean neither loses nor adds material.
    assert outside.Volume() + inside.Volume() == pytest.approx(volume, rel=TRIMMED)


def test_open_surface_is_a_shell_in_both_libraries():
    mesh = open_grid(6, 5, [0, 1, 2, 1, 0], [0, 1, 1, 0], name="sheet")
    shell = export.to_build123d(mesh)
    assert isinstance(shell, build123d.Shell) and shell.is_valid
    assert len(shell.faces()) == patching.build(mesh).n_patches
    wp = export.to_cadquery(mesh)
    assert isinstance(wp.val(), cadquery.Shell) and wp.val().isValid()


def test_angles_and_anchors_reach_the_build():
    mesh = ell_mesh()
    volumes = {
        (angles, anchors): export.to_build123d(mesh, angles=angles, anchors=anchors).volume
        for angles, anchors in (("optimized", "eigen-polyhedron"), ("uniform", "eigen-polyhedron"), ("optimized", "extraction"))
    }
    assert len({round(v, 9) for v in volumes.values()}) == 3, volumes


def test_build_options_reach_the_build():
    """g1_solve (and any other keyword of patching.build) passes through: every vertex of the
    cube is an EP, one cluster, where the joint and the seed's solves give different surfaces."""
    from tests.helpers import quad_mesh_with_eps, with_random_intervals

    mesh = with_random_intervals(quad_mesh_with_eps("cube"), 5.0, seed=0)
    joint = export.to_build123d(mesh).volume
    seed = export.to_cadquery(mesh, g1_solve="seed").val().Volume()
    assert seed == pytest.approx(export.to_build123d(mesh, g1_solve="seed").volume, rel=1e-12)
    assert abs(joint - seed) > 1e-9 * abs(joint)


def test_bad_sources_are_refused(tmp_path):
    with pytest.raises(TypeError, match="BezierSurface"):
        export.to_build123d(42)
    with pytest.raises(patching.InputFileError, match="no such file"):
        export.to_cadquery(tmp_path / "missing.obj")
