"""The per-edge G0/G1 table of export.continuity: a nudged face is found and named,
a correct model measures round-off, sharp edges are reported apart."""

from __future__ import annotations

import json

import numpy as np
import pytest

import patching
from export.brep import to_shape
from export.continuity import check_continuity
from export.step import write_step
from patching.mesh.primitives import torus_grid
from tests.helpers import cube_surface as cube

# A correct model: neighbours evaluate the same boundary polynomial and C1/G1 cross
# derivatives, measured 2e-16 of the diagonal and 8e-13 deg on this torus; bounds ~50x.
ROUND_OFF_GAP = 1e-14
ROUND_OFF_DEG = 1e-10
M, N = 8, 6


def ring() -> patching.BezierSurface:
    return patching.build(torus_grid(M, N, [1, 2, 4, 1, 0.5, 1, 3, 1], [1, 2, 1, 1, 3, 1], name="ring"))


def row_of(surface, face: int) -> int:
    return next(row for row, _, f, _ in surface.patches() if f == face)


def side_neighbours(face: int) -> dict[int, int]:
    """Mesh faces across the four sides of face (a, b) = divmod(face, N) of the torus grid:
    side 0 runs along a (v0 -> v1), side 1 along b at a + 1, and so on."""
    a, b = divmod(face, N)
    at = lambda i, j: (i % M) * N + j % N  # noqa: E731
    return {0: at(a, b - 1), 1: at(a + 1, b), 2: at(a, b + 1), 3: at(a - 1, b)}


def test_correct_model_reports_round_off_and_every_edge_g1():
    report = check_continuity(ring(), all_edges=True)
    assert report.valid and report.g1
    assert report.n_g1_edges == report.n_shared_edges == 2 * M * N
    assert (report.n_g0_edges, report.n_open_edges, report.n_sharp_edges) == (0, 0, 0)
    assert report.max_gap_relative < ROUND_OFF_GAP
    assert report.max_normal_jump_deg < ROUND_OFF_DEG
    assert report.max_smooth_normal_jump_deg == report.max_normal_jump_deg
    assert len(report.edges) == report.n_shared_edges
    assert {d.kind for d in report.edges} == {"G1"}


def test_nudged_face_interior_row_breaks_g1_on_its_edge_and_names_it():
    surface = ring()
    face = 20
    net = surface.groups[0].coefficients[row_of(surface, face)]
    # The row next to side 0 (t = 0), inner points only: side 0 loses tangent continuity,
    # and sides 1 and 3, whose cross-boundary rows hold net[1, 1] and net[2, 1] (cubic).
    net[1:-1, 1] += [0.0, 0.0, 0.05]
    report = check_continuity(surface)
    assert report.valid and not report.g1
    assert report.n_open_edges == 0 and report.n_g0_edges == 3
    assert report.max_gap_relative < ROUND_OFF_GAP
    worst = report.worst_edges[0]
    assert worst.kind == "G0" and worst.angle_deg > 1.0
    assert sorted(worst.faces) == sorted((face, side_neighbours(face)[0]))  # mesh face ids
    broken = {tuple(sorted(d.faces)) for d in report.worst_edges if d.kind == "G0"}
    assert broken == {tuple(sorted((face, side_neighbours(face)[k]))) for k in (0, 1, 3)}
    # The position is on that edge, at its worst sample (the middle of side 0, w = 1/2).
    middle = np.einsum("i,ic->c", [1 / 8, 3 / 8, 3 / 8, 1 / 8], net[:, 0])
    assert np.linalg.norm(np.array(worst.position) - middle) < 1e-12


def test_moved_face_opens_gaps_on_its_four_edges():
    surface = ring()
    face = 13
    surface.groups[0].coefficients[row_of(surface, face)] += [1e-3, 0.0, 0.0]
    report = check_continuity(surface)
    assert not report.valid and report.n_open_edges == 4
    open_edges = {tuple(sorted(d.faces)) for d in report.worst_edges if d.kind == "open"}
    assert open_edges == {tuple(sorted((face, other))) for other in side_neighbours(face).values()}
    assert report.max_smooth_gap == pytest.approx(1e-3, rel=1e-9)


def test_sharp_edges_are_reported_apart():
    report = check_continuity(to_shape(cube((3, 5, 3, 5, 5, 3))), worst=3)
    assert report.n_sharp_edges == 12 and report.n_g1_edges == 0
    assert report.worst_edges == () and len(report.sharp_edges) == 3
    assert all(d.kind == "sharp" and d.min_angle_deg == pytest.approx(90.0) for d in report.sharp_edges)
    assert report.max_normal_jump_deg == pytest.approx(90.0) and report.max_smooth_normal_jump_deg == 0.0
    assert report.g1  # no smooth edge is broken: the creases are meant
    assert check_continuity(to_shape(cube()), sharp_angle_deg=91.0).n_g0_edges == 12


def test_check_cli_prints_the_table_and_require_g1_fails_a_broken_file(tmp_path, run_cli, cli_main):
    """The table and the JSON through ``export.cli.main`` in this interpreter (``cli_main``);
    the failing --require-g1 in a fresh one, its exit status 1 being the process's."""
    surface = ring()
    good = write_step(to_shape(surface), tmp_path / "good.step", "good")
    face = 20
    surface.groups[0].coefficients[row_of(surface, face)][1:-1, 1] += [0.0, 0.0, 0.05]
    bad = write_step(to_shape(surface), tmp_path / "bad.step", "bad")
    result = cli_main("check", good, "--require-g1")
    assert result.returncode == 0, result.stderr
    assert "96 G1" in result.stdout and "0 G0 only" in result.stdout
    result = run_cli("check", bad, "--require-g1", "--worst", "1")
    assert result.returncode == 1
    # Faces of a STEP file are its face order, here the patch rows (= mesh faces of a torus).
    pair = sorted((face, side_neighbours(face)[0]))
    rows = [l.split() for l in result.stdout.splitlines() if l.startswith("  ")]
    assert [r[2] for r in rows] == ["G0", "G1"], result.stdout  # worst by jump, then by gap
    assert rows[0][1].replace(",", " ").split() == [str(f) for f in pair], result.stdout
    data = json.loads(cli_main("check", bad, "--json", "--all").stdout)
    assert data["n_g0_edges"] == 3 and len(data["edges"]) == 96
    result = cli_main("check", good, "--samples", "1")
    assert result.returncode == 2 and result.stderr.startswith("nupatch: error: ")


def test_cli_defaults_are_the_modules():
    from export import continuity
    from export.cli import CHECK_DEFAULTS

    assert CHECK_DEFAULTS == {
        "worst": continuity.N_WORST,
        "sharp_angle_deg": continuity.SHARP_ANGLE_DEG,
        "g1_tolerance_deg": continuity.G1_TOLERANCE_DEG,
    }
