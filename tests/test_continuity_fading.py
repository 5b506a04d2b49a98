"""Creases that fade into darts in export.continuity: the shipped machined bracket passes
``check --require-g1`` (its ten crease edges ending at darts are "fading", not G0), and real
defects next to them still fail the gate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import patching
from export.brep import to_shape
from export.continuity import check_continuity
from export.step import write_step
from patching.mesh.primitives import torus_grid

BRACKET = Path(__file__).resolve().parent.parent / "models" / "machined_bracket.obj"


@pytest.fixture(scope="module")
def bracket() -> patching.BezierSurface:
    return patching.build(patching.read_mesh(BRACKET))


def _fresh(surface: patching.BezierSurface) -> patching.BezierSurface:
    """A copy whose nets can be nudged without touching the module's surface."""
    import copy

    return copy.deepcopy(surface)


def _net(surface, face: int) -> np.ndarray:
    return next(net for _, _, f, net in surface.patches() if f == face)


def _dart_count(mesh) -> int:
    from patching.topology.features import features
    from patching.topology.tables import Topology

    return int(features(Topology(mesh)).dart.sum())


def test_bracket_fading_creases_pass_the_gate(bracket):
    """Ten darts, each the end of one crease edge: ten fading edges, no G0 edge, g1 holds; the
    fading edges' jump is 0 at one end (the dart's common tangent plane) and the crease's
    (about 90 deg) at the other."""
    assert _dart_count(patching.read_mesh(BRACKET)) == 10
    report = check_continuity(bracket, all_edges=True, samples_per_edge=17)
    assert report.valid and report.g1
    assert report.n_fading_edges == 10 and report.n_g0_edges == 0 and report.n_open_edges == 0
    kinds = [d.kind for d in report.edges]
    assert kinds.count("fading") == 10 and kinds.count("sharp") == report.n_sharp_edges > 0
    fading = [d for d in report.edges if d.kind == "fading"]
    assert all(d.min_angle_deg <= report.g1_tolerance_deg and d.angle_deg > 45.0 for d in fading)
    assert report.max_smooth_normal_jump_deg < 1e-7  # the fading edges are not in the smooth maxima
    n = report.n_g1_edges + report.n_g0_edges + report.n_open_edges + report.n_sharp_edges + report.n_fading_edges
    assert n == len(report.edges)


def test_interior_nudge_beside_a_fading_crease_fails(bracket):
    """Moving the inner coefficients of a face that borders a fading crease breaks G1 on its
    smooth sides (the jump vanishes at both ends of those edges: no fading profile)."""
    report = check_continuity(bracket, all_edges=True)
    face = next(d.faces[0] for d in report.edges if d.kind == "fading")
    surface = _fresh(bracket)
    net = _net(surface, face)
    net[1:-1, 1:-1] += 0.02 * bracket.size * np.array([0.3, -0.2, 1.0])
    broken = check_continuity(surface, all_edges=True)
    assert not broken.g1 and broken.n_g0_edges >= 2 and broken.n_open_edges == 0
    assert {d.kind for d in broken.edges if face in d.faces} >= {"G0"}


def test_broken_tangent_plane_at_a_dart_fails(bracket):
    """A dart whose patches stop sharing one tangent plane is a defect: the coefficient next
    to the dart on the fading edge's curve moved in both patches that hold it (no gap), so the
    edge's jump no longer vanishes at the dart and it is reported G0, not fading.  (A move
    so large that the jump reaches the sharp angle at the dart too makes the edge "sharp",
    as any edge whose jump is that large all along: 1e-2 of the size does.)"""
    report = check_continuity(bracket, all_edges=True)
    d = next(d for d in report.edges if d.kind == "fading")
    surface = _fresh(bracket)
    tol = 1e-9 * bracket.size
    dart = _dart_point(bracket, d)
    a, b = _net(bracket, d.faces[0]), _net(bracket, d.faces[1])
    k = a.shape[0] - 1
    steps = {(0, 0): (1, 1), (k, 0): (-1, 1), (k, k): (-1, -1), (0, k): (1, -1)}
    (i, j), (si, sj) = next((c, s) for c, s in steps.items() if np.linalg.norm(a[c] - dart) < tol)
    on_edge = [p for p in (a[i + si, j], a[i, j + sj]) if np.linalg.norm(b - p, axis=-1).min() < tol]
    assert len(on_edge) == 1
    target = on_edge[0].copy()
    held = 0
    for _, _, _, net in surface.patches():
        hit = np.linalg.norm(net - target, axis=-1) < tol
        net[hit] += 1e-4 * bracket.size * np.array([0.31, -0.47, 0.83])
        held += int(hit.any())
    assert held == 2
    broken = check_continuity(surface, all_edges=True)
    assert not broken.g1 and broken.n_open_edges == 0
    assert next(e for e in broken.edges if e.edge == d.edge).kind == "G0"


def _corner_normals(net: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """(corner point, unit normal there) of a Bezier net: the cross product of the two edge
    tangents at the corner, oriented as S_u x S_v."""
    k = net.shape[0] - 1
    out = []
    for (i, j), (si, sj) in {(0, 0): (1, 1), (k, 0): (-1, 1), (k, k): (-1, -1), (0, k): (1, -1)}.items():
        v = np.cross(net[i + si, j] - net[i, j], net[i, j + sj] - net[i, j]) * si * sj
        out.append((net[i, j], v / np.linalg.norm(v)))
    return out


def _dart_point(surface, d) -> np.ndarray:
    """The end of fading edge d where its jump is 0: of the two patch corners its faces share,
    the one where their normals agree."""
    na = _corner_normals(_net(surface, d.faces[0]))
    nb = _corner_normals(_net(surface, d.faces[1]))
    tol = 1e-9 * surface.size
    shared = [(p, abs(1.0 - n @ q)) for p, n in na for r, q in nb if np.linalg.norm(p - r) < tol]
    assert len(shared) == 2
    point, mismatch = min(shared, key=lambda x: x[1])
    assert mismatch < 1e-12 and max(x[1] for x in shared) > 0.5  # a dart end and a crease end
    return point


def test_crease_between_two_darts_is_two_fading_edges():
    """A crease of two edges on a torus between two darts: each edge is sharp at the middle
    vertex and G1 at its dart, and each supports the other there."""
    m, n = 8, 6
    grid = torus_grid(m, n)
    ids = lambda a, b: (a % m) * n + (b % n)  # noqa: E731
    points = grid.vertices + np.random.default_rng(0).normal(scale=0.05, size=grid.vertices.shape)
    creases = {(ids(2, 0), ids(2, 1)): 10.0, (ids(2, 1), ids(2, 2)): 10.0}
    surface = patching.build(patching.from_arrays(points, grid.quads(), creases=creases, name="dart"))
    report = check_continuity(surface, sharp_angle_deg=1.0)
    assert report.g1 and report.n_fading_edges == 2 and report.n_sharp_edges == 0


def test_single_edge_crease_between_two_darts_is_not_recognised():
    """The documented limit: a crease of one edge between two darts vanishes at both ends, as
    a defect does, so it is reported G0 (the gate fails)."""
    m, n = 8, 6
    grid = torus_grid(m, n)
    ids = lambda a, b: (a % m) * n + (b % n)  # noqa: E731
    points = grid.vertices + np.random.default_rng(0).normal(scale=0.05, size=grid.vertices.shape)
    surface = patching.build(patching.from_arrays(points, grid.quads(), creases={(ids(2, 0), ids(2, 1)): 10.0}))
    report = check_continuity(surface, sharp_angle_deg=1.0)
    assert report.n_fading_edges == 0 and report.n_g0_edges >= 1 and not report.g1


def test_check_cli_require_g1_on_the_bracket(tmp_path, bracket, run_cli):
    good = write_step(to_shape(bracket), tmp_path / "bracket.step", "bracket")
    result = run_cli("check", good, "--require-g1")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 G0 only" in result.stdout and "fading creases" in result.stdout
    assert any(line.split()[-1] == "10" for line in result.stdout.splitlines() if line.startswith("fading creases ("))
    report = check_continuity(bracket, all_edges=True)
    face = next(d.faces[0] for d in report.edges if d.kind == "fading")
    surface = _fresh(bracket)
    _net(surface, face)[1:-1, 1:-1] += 0.02 * bracket.size
    bad = write_step(to_shape(surface), tmp_path / "nudged.step", "nudged")
    assert run_cli("check", bad, "--require-g1").returncode == 1
