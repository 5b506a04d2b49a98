"""export.continuity: gaps and normal jumps measured on B-reps with known continuity."""

from __future__ import annotations

import json

import numpy as np
import pytest
from OCP.BRep import BRep_Builder
from OCP.TopoDS import TopoDS_Compound

from export.brep import to_shape
from export.continuity import ContinuityReport, check_continuity
from export.step import write_step

try:
    from tests.helpers import cube_surface as cube, edges_of, seam_tube, single_patch, torus_surface as torus
except ImportError:  # tests/ on sys.path rather than a package
    from tests.helpers import cube_surface as cube, edges_of, seam_tube, single_patch, torus_surface as torus

# Normals of C1 neighbours agree to round-off: unit normals from derivatives of size ~10
# computed to ~1e-15 relative give angles of a few 1e-15 rad (measured 4e-15 rad = 2.5e-13
# deg); 1e-11 deg is ~40x that.
ROUND_OFF_DEG = 1e-11
# Both faces evaluate the same boundary polynomial: a few ulps of coordinates of size ~4.
ROUND_OFF_GAP = 1e-14


def neighbour(surf, row: int, side: int) -> tuple[int, int]:
    """The patch rows on both sides of ``row``'s side ``side``."""
    topo = surf.topology
    rows = np.nonzero(topo.side_edge == topo.side_edge[row, side])[0]
    assert len(rows) == 2
    return tuple(sorted(int(r) for r in rows))


def test_cube_has_90_degree_edges_and_no_gaps():
    report = check_continuity(to_shape(cube((3, 5, 3, 5, 5, 3))))
    assert report.valid
    assert (report.n_solids, report.n_shells, report.n_faces) == (1, 1, 6)
    assert (report.n_edges, report.n_shared_edges, report.n_free_edges) == (12, 12, 0)
    assert report.max_gap_relative < ROUND_OFF_GAP
    assert report.max_normal_jump_deg == pytest.approx(90.0, abs=ROUND_OFF_DEG)
    assert report.diagonal == pytest.approx(np.sqrt(3.0), abs=1e-6)  # box grown by the tolerance


@pytest.mark.parametrize("degrees", [None, [3, 5] * 24, [5] * 48], ids=["bicubic", "mixed", "biquintic"])
def test_smooth_closed_torus_measures_round_off(degrees):
    report = check_continuity(to_shape(torus(degrees=degrees)))
    assert report.valid and report.n_solids == 1 and report.n_free_edges == 0
    assert report.n_shared_edges == 96
    assert report.max_gap_relative < ROUND_OFF_GAP
    assert report.max_normal_jump_deg < ROUND_OFF_DEG  # ~0, not 180: orientation is respected


def test_reversed_solid_still_measures_round_off():
    report = check_continuity(to_shape(torus()).Reversed())
    assert report.max_normal_jump_deg < ROUND_OFF_DEG


def test_step_file_measures_round_off(tmp_path):
    path = write_step(to_shape(torus(degrees=[3, 5] * 24)), tmp_path / "t.step", "t")
    report = check_continuity(path)
    assert report.valid and report.n_solids == 1 and report.n_free_edges == 0
    # OCC writes reals with 13 significant digits (StepData_StepWriter's FloatWriter(12)), and
    # a quintic face's poles round differently from its cubic neighbour's: measured 5e-14 of
    # the diagonal and 2.2e-10 deg; the bounds are 20x and 40x that.
    assert report.max_gap_relative < 1e-12
    assert report.max_normal_jump_deg < 1e-8


@pytest.mark.parametrize("degree", [3, 5])
def test_moved_interior_row_gives_a_normal_jump_on_its_edge(degree):
    surf = torus(degrees=[degree] * 48)
    row = 20
    net = surf.groups[0].coefficients[row]
    # Row 1 (next to side 3, s = 0) away from the sides' own cross-boundary rows where the
    # degree allows: only side 3 loses tangent continuity for degree 5.
    # For degree 3 the moved points net[1, 1] and net[1, 2] are also next to sides 0 and 2.
    inner, broken_sides = (slice(1, -1), {0, 2, 3}) if degree == 3 else (slice(2, -2), {3})
    net[1, inner] += [0.1, 0.15, 0.2]  # generic: not tangent to the torus at any side
    report = check_continuity(to_shape(surf))
    assert report.valid and report.max_gap_relative < ROUND_OFF_GAP
    jumps = {tuple(sorted(d.faces)): d.angle_deg for d in report.worst_edges}
    assert jumps[neighbour(surf, row, 3)] > 1.0
    broken = {neighbour(surf, row, k) for k in broken_sides}
    assert {faces for faces, angle in jumps.items() if angle > ROUND_OFF_DEG} == broken
    assert max(jumps.values()) == report.max_normal_jump_deg


def test_moved_boundary_row_gives_a_gap():
    surf = torus()
    row, delta = 13, 1e-3
    surf.groups[0].coefficients[row][1:-1, 0] += [0.0, 0.0, delta]  # side 0's interior points
    report = check_continuity(to_shape(surf, check=False))
    assert not report.valid
    # Largest at w = 1/2, a sample: (B_1 + B_2)(1/2) delta = 0.75 delta, up to round-off.
    assert report.max_gap == pytest.approx(0.75 * delta, abs=1e-14)
    by_gap = max(report.worst_edges, key=lambda d: d.gap)
    assert tuple(sorted(by_gap.faces)) == neighbour(surf, row, 0)


def test_seam_of_a_smooth_tube_is_compared_across_itself():
    report = check_continuity(to_shape(seam_tube()))
    assert report.valid
    assert (report.n_faces, report.n_edges, report.n_shared_edges, report.n_free_edges) == (1, 3, 1, 2)
    # The loop is C1 with equal end derivatives: both sides of the seam agree to round-off.
    assert report.max_gap_relative < ROUND_OFF_GAP
    assert report.max_normal_jump_deg < ROUND_OFF_DEG


def test_edges_without_same_parameter_are_projected():
    shape = to_shape(torus(degrees=[3, 5] * 24))
    builder = BRep_Builder()
    for edge in edges_of(shape):
        builder.SameParameter(edge, False)  # the pcurves may no longer be trusted: project
    report = check_continuity(shape)
    # ShapeAnalysis_Surface.ValueOfUV converges to round-off on these surfaces (measured
    # 2e-16 and 4e-13 deg).
    assert report.max_gap_relative < ROUND_OFF_GAP
    assert report.max_normal_jump_deg < ROUND_OFF_DEG


def test_separate_faces_have_free_edges():
    builder = BRep_Builder()
    both = TopoDS_Compound()
    builder.MakeCompound(both)
    builder.Add(both, to_shape(single_patch()))
    builder.Add(both, to_shape(single_patch()))  # same place, built again: nothing shared
    report = check_continuity(both)
    assert (report.n_faces, report.n_shared_edges, report.n_free_edges) == (2, 0, 8)
    assert report.worst_edges == () and report.max_gap == 0.0


def test_report_formats():
    report = check_continuity(to_shape(single_patch()), samples_per_edge=3)
    assert isinstance(report, ContinuityReport)
    data = json.loads(report.to_json())
    assert data == report.as_dict() | {"worst_edges": []}
    assert data["n_free_edges"] == 4 and data["samples_per_edge"] == 3
    text = report.summary()
    assert "max normal jump" in text and len(text.splitlines()) < 25
    with pytest.raises(ValueError):
        check_continuity(to_shape(single_patch()), samples_per_edge=1)
