"""Zero knot intervals (multiple knots, docs/knots.md) with semi-sharp creases: the steps that
build_operator takes for the creases split a zero strip into 2^k zero strips, which is knot
insertion of the same knot (the surface is the input's), not a tear; tears are judged on the
user's mesh and named by its ids.  Refused, in one line naming the user's ids: semi-sharp tags
next to a zero interval (the subdivision rules there jump away from the intervals' eps -> 0
limit and fold the patches), infinitely sharp tags next to a zero interval when the mesh is
subdivided (the same jump: a valid solid 0.968 away from its eps limit), and zero intervals on
the adaptive path (the patches of several levels leave the B-rep open).  [TLC]'s tagged
rules themselves take a zero spoke and give their eps -> 0 limit (subdivision_rules); the
build does not use them there yet, because that limit opens the zero strip."""

import numpy as np
import pytest

import export
import patching
from patching.operator.adaptive import child_parameters
from patching.rules.eigen_polyhedron import BilinearError
from patching.errors import KnotError, UnsupportedError
from patching.evaluation.sampling import evaluate_nets
from patching.rules.catmark import CORNER, CREASE, DART, tagged_rules_batch
from tests.helpers import torus_mesh as torus

M, N = 12, 10  # torus(12, 10): vertex (i, k) is 10 i + k, face (i, k) is [10 i + k, 10 (i + 1) + k, ...]
V, F, _ = torus(M, N)
UV = np.random.default_rng(0).uniform(0.0, 1.0, (25, 2))
ONE_STRIP = {(0, 10): 0.0}  # the faces of row i = 0: a double knot
TWO_STRIPS = {(0, 10): 0.0, (10, 20): 0.0}  # rows 0 and 1: a triple knot, C0 (legal)


def mesh(intervals, creases=None):
    return patching.from_arrays(V, F, intervals=intervals, creases=creases or {}, name="torus")


def nets(surface):
    """{face id: Bezier net} of a surface (all bicubic here: the torus has no EP)."""
    return {int(f): net for g in surface.groups for f, net in zip(g.faces, g.coefficients)}


def with_eps(intervals, eps):
    return {e: eps if d == 0 else d for e, d in intervals.items()}


def far_from(f0, row, col):
    """Input face f0 at least 3 rows or 3.5 columns (cyclic) from the crease at (row, col)."""
    i, k = divmod(f0, N)
    return min(abs(i - row), M - abs(i - row)) >= 3 or min(abs(k - col), N - abs(k - col)) >= 3.5


def distance_to_nurbs_far_from_crease(surface, steps, reference, row, col):
    """Largest distance between the patches of ``surface`` (``steps`` steps below the input)
    on input faces far from the crease and the crease-free surface (the exact NURBS) there, at
    the same parameters of the input face; and the number of patches compared."""
    ref = nets(reference)
    worst, count = 0.0, 0
    for face, net in nets(surface).items():
        f0, s, t = face, UV[:, 0].copy(), UV[:, 1].copy()
        for _ in range(steps):  # child face 4 f + corner on a quad mesh, finest corner first
            f0, corner = divmod(f0, 4)
            s, t = child_parameters(corner, s, t)
        if not far_from(f0, row, col) or f0 not in ref:
            continue
        here = evaluate_nets(net[None], UV[:, 0], UV[:, 1])[0]
        there = evaluate_nets(ref[f0][None], s, t)[0]
        worst, count = max(worst, float(np.abs(here - there).max())), count + 1
    return worst, count


def distance_to_eps(surface, intervals, creases, eps):
    """Largest difference of the Bezier nets from those of the mesh whose zero intervals are
    eps (the same refined faces, face by face; the eps mesh also has the zero strips').  The
    eps mesh has no zero interval, so build would refine it adaptively (beyond 1,024 global
    faces): its global refinement is asked for, as the zero mesh's is taken."""
    a, b = nets(surface), nets(patching.build(mesh(with_eps(intervals, eps), creases), refinement="global"))
    assert a.keys() < b.keys()
    return max(float(np.abs(a[f] - b[f]).max()) for f in a)


@pytest.mark.parametrize("s", [1.0, 2.0, 3.0])
def test_zero_strip_with_a_semi_sharp_crease_is_the_nurbs_away_from_it_and_the_eps_limit(s):
    """On main before: refused as 'three zero knot intervals in a row' naming refined ids."""
    creases = {(33, 34): s}  # row 3, columns 3-4: away from the zero strip (row 0)
    surface = patching.build(mesh(ONE_STRIP, creases))
    steps = int(np.ceil(s))
    assert surface.n_patches == (M - 1) * N * 4**steps  # the zero strip's faces give none
    worst, count = distance_to_nurbs_far_from_crease(surface, steps, patching.build(mesh(ONE_STRIP)), 3, 3.5)
    assert count > 0.7 * surface.n_patches
    assert worst < 1e-12 * surface.size  # measured 3e-15 (size 8)
    # Continuous in the interval: the eps meshes come to it linearly.
    d6, d8 = (distance_to_eps(surface, ONE_STRIP, creases, eps) for eps in (1e-6, 1e-8))
    assert d8 < 1e-6 * surface.size  # measured 1.5e-8
    assert 90 < d6 / d8 < 110


def test_zero_strip_with_a_semi_sharp_crease_exports_a_valid_g1_solid():
    surface = patching.build(mesh(ONE_STRIP, {(33, 34): 2.0}))
    report = export.check_continuity(export.to_shape(surface))
    assert report.valid and report.n_solids == 1 and report.n_free_edges == 0
    assert report.max_gap_relative < 1e-12  # measured 1.7e-16
    assert report.g1 and report.n_sharp_edges == 0  # largest normal jump 3.6e-12 degrees


def test_two_zero_strips_in_a_row_with_s1_is_the_c0_nurbs():
    """A triple knot (C0, legal): refused on main before.  G1 everywhere but along the knot's
    line, where the rows of input faces 11 and 2 meet (faces 0 to 19 have no patch)."""
    creases = {(55, 56): 1.0}
    surface = patching.build(mesh(TWO_STRIPS, creases))
    worst, count = distance_to_nurbs_far_from_crease(surface, 1, patching.build(mesh(TWO_STRIPS)), 5, 5.5)
    assert count > 0 and worst < 1e-12 * surface.size  # measured 3e-15
    d6, d8 = (distance_to_eps(surface, TWO_STRIPS, creases, eps) for eps in (1e-6, 1e-8))
    assert d8 < 1e-6 * surface.size and 90 < d6 / d8 < 110  # measured 5.8e-6, 5.8e-8
    report = export.check_continuity(surface, all_edges=True)  # faces named by their mesh ids
    assert report.valid and report.n_solids == 1 and report.n_free_edges == 0
    assert report.max_gap_relative < 1e-12
    rows = {e.faces: {a // 4 // N for a in e.faces} for e in report.edges if e.kind != "G1"}
    assert rows and all(r == {M - 1, 2} for r in rows.values()), rows


@pytest.mark.parametrize("creases", [{}, {(55, 56): 2.0}])
def test_three_zero_strips_in_a_row_are_refused_naming_the_input(creases):
    with pytest.raises(KnotError) as err:
        patching.build_operator(mesh({(0, 10): 0.0, (10, 20): 0.0, (20, 30): 0.0}, creases))
    message = str(err.value)
    assert "\n" not in message
    assert "around face 10 (edge 10-20)" in message, message


@pytest.mark.parametrize(
    "creases, edge, tag",
    [
        ({(10, 11): 1.0}, "0-10", "crease 10-11"),  # built on main before, folded (180-degree jumps)
        ({(10, 11): 2.0}, "0-10", "crease 10-11"),
        ({(11, 21): 2.0}, "1-11", "crease 11-21"),
        ({(1, 11): 3.0, (11, 21): 3.0}, "1-11", "crease 1-11"),
    ],
)
def test_semi_sharp_tags_next_to_a_zero_interval_are_refused_in_one_line(creases, edge, tag):
    with pytest.raises(UnsupportedError) as err:
        patching.build_operator(mesh(ONE_STRIP, creases))
    message = str(err.value)
    assert "\n" not in message
    assert f"edge {edge} " in message and f"semi-sharp {tag} " in message, message


def test_semi_sharp_corner_next_to_a_zero_interval_is_refused():
    with pytest.raises(UnsupportedError, match=r"edge 0-10 at the semi-sharp corner 10 "):
        patching.build_operator(patching.from_arrays(V, F, intervals=ONE_STRIP, corners={10: 2.0}))


def test_zero_interval_on_the_adaptive_path_is_refused_in_one_line():
    """s = 7 is refined adaptively (patching.operator.adaptive), whose patches of several levels left
    an open shell with a zero strip (no solid, 2,560 free edges)."""
    with pytest.raises(UnsupportedError) as err:
        patching.build_operator(mesh(ONE_STRIP, {(33, 34): 7.0}))
    message = str(err.value)
    assert "\n" not in message
    assert "edge 0-10" in message and "adaptive" in message, message


# [TLC]'s generalised eigen-polyhedron rules at a zero spoke (subdivision_rules): the rule at
# 0 is the limit of the rules at eps -> 0 where the formulas are defined there, and raises where
# they are not.  Before: every zero spoke was a ValueError ("finite positive intervals").
TAGGED = [(DART, n, (0,), False) for n in range(3, 7)]
TAGGED += [(CREASE, n, (0, k), False) for n in range(4, 7) for k in range(2, n - 1)]
TAGGED += [(CREASE, n, (0, n - 1), True) for n in range(3, 7)]
TAGGED += [(CORNER, n, (0, k), False) for n in range(3, 7) for k in range(1, n)]


@pytest.mark.parametrize("kind, n, sharp, boundary", TAGGED)
def test_tagged_rules_at_one_zero_spoke_are_the_eps_limit(kind, n, sharp, boundary):
    rng = np.random.default_rng(n + 10 * kind)
    for k in range(n):
        d = rng.uniform(0.5, 2.0, n)
        rows = []
        for eps in (0.0, 1e-6, 1e-8):
            r = tagged_rules_batch(kind, np.where(np.arange(n) == k, eps, d)[None], sharp, boundary)
            rows.append(r.matrix[0][r.defined])
        assert np.isfinite(rows[0]).all()
        d6, d8 = (float(np.abs(m - rows[0]).max()) for m in rows[1:])
        assert d8 < 1e-6, (k, d8)  # measured 1e-10 to 3e-8: O(eps)
        # linear in eps, or round-off where the rows do not read the zero spoke (valence 4)
        assert d6 < 1e-14 or 90 < d6 / d8 < 110, (k, d6, d8)


@pytest.mark.parametrize(
    "kind, n, sharp, zeros",
    [
        (DART, 4, (0,), (1, 3)),  # opposite zero spokes: l = 0, a degenerate polyhedron
        (CREASE, 4, (0, 2), (1, 3)),
        (CREASE, 4, (0, 2), (0, 2)),  # both sharp spokes zero: T is 0/0
        (DART, 5, (0,), (1, 2)),  # two zero spokes next to each other at a dart
    ],
)
def test_tagged_rules_at_degenerate_zero_spokes_raise_in_one_line(kind, n, sharp, zeros):
    d = np.ones(n)
    d[list(zeros)] = 0.0
    with pytest.raises(BilinearError) as err:
        tagged_rules_batch(kind, d[None], sharp, False)
    assert "\n" not in str(err.value)


RING = {(10 + k, 10 + (k + 1) % N): 10.0 for k in range(N)}  # infinitely sharp, beside the strip


def test_sharp_crease_ring_beside_a_zero_strip_without_steps_is_the_eps_limit():
    """No subdivision: the patches at 0 are the eps limit (measured 5.9e-8 at eps = 1e-8)."""
    surface = patching.build(mesh(ONE_STRIP, RING))
    d6, d8 = (distance_to_eps(surface, ONE_STRIP, RING, eps) for eps in (1e-6, 1e-8))
    assert d8 < 1e-6 * surface.size and 90 < d6 / d8 < 110


@pytest.mark.parametrize("s", [1.0, 2.0])
def test_sharp_crease_ring_beside_a_zero_strip_with_steps_is_refused_in_one_line(s):
    """A semi-sharp crease elsewhere makes build_operator subdivide.  On main before: a valid
    solid 0.968 away from its eps limit (knot insertion at the ring's vertices, the eigen-
    polyhedron rules at eps); with the eps-limit rules the patches beside the strip do not
    close up (invalid B-rep).  Refused, naming the user's zero edge and crease."""
    with pytest.raises(UnsupportedError) as err:
        patching.build_operator(mesh(ONE_STRIP, {**RING, (55, 56): s}))
    message = str(err.value)
    assert "\n" not in message
    assert "edge 0-10 " in message and "sharp crease 10-11 " in message, message
