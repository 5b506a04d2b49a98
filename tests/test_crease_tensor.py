"""Along an interior crease the non-uniform step reads the crease curve's knots.

A regular grid with a straight crease along one vertex line and unequal knot intervals along
the crease: the crease vertex rule is the crease curve's knot insertion ([TLC] eq. 11), and the
smooth points beside a crease vertex that takes no eigen-polyhedron rule (its four spokes of
equal intervals) are tensor products whose factor along the crease is the same vertex rule.  So
both must read the same intervals beyond the vertex: the next crease interval.  The reference
is Boehm's knot insertion written here on the crease curve's knot vector, not our curve
rules.
"""

from __future__ import annotations

import numpy as np
import pytest

import patching
from patching.subdivision.catmark import subdivision_operator
from patching.topology import Topology

N = 10
CREASE_ROW = 5
#: Intervals of the strips along the crease (edges (i, j)-(i, j+1)): crease vertices j = 3 and
#: j = 6 have four equal spokes, their next crease interval beyond is 2 and 3.
ALONG = [1.0, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 3.0, 1.0]


def vid(i: int, j: int) -> int:
    return i * (N + 1) + j


def grid(sharpness: float) -> patching.ControlMesh:
    xs, ys = np.meshgrid(np.arange(N + 1.0), np.arange(N + 1.0), indexing="ij")
    verts = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1)
    faces = [[vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)] for i in range(N) for j in range(N)]
    intervals = {(vid(0, j), vid(0, j + 1)): d for j, d in enumerate(ALONG)}
    creases = {(vid(CREASE_ROW, j), vid(CREASE_ROW, j + 1)): sharpness for j in range(N)}
    return patching.from_arrays(verts, faces, intervals=intervals, creases=creases)


def boehm_insert(t: np.ndarray, u: float) -> tuple[np.ndarray, np.ndarray]:
    """Boehm's insertion of knot u into the cubic knot vector t: (new knots, A) with new
    coefficients = A @ old coefficients (Q_i = (1 - a_i) P_{i-1} + a_i P_i,
    a_i = (u - t_i) / (t_{i+3} - t_i) on the three affected points)."""
    n = t.size - 4
    k = int(np.searchsorted(t, u, side="right")) - 1  # t_k <= u < t_{k+1}
    a = np.zeros((n + 1, n))
    for i in range(n + 1):
        if i <= k - 3:
            a[i, i] = 1.0
        elif i >= k + 1:
            a[i, i - 1] = 1.0
        else:
            w = (u - t[i]) / (t[i + 3] - t[i])
            a[i, i - 1], a[i, i] = 1.0 - w, w
    return np.insert(t, k + 1, u), a


def knot_insertion_vertex_weights(intervals: list[float], i: int) -> np.ndarray:
    """Weights of the refined point at control point i of a cubic B-spline over P_0..P_N whose
    edge P_j P_{j+1} carries ``intervals[j]`` (docs/knots.md: t_{j+3} - t_{j+2}), after inserting
    the midpoint of every interval (Boehm, one knot at a time): (N + 1,) over the old points.
    The end intervals lie outside the curve's domain [t_3, t_N] and are not split: the points
    at 2 <= i <= N - 2 do not read them."""
    inner = np.concatenate([[0.0], np.cumsum(intervals)])
    t = np.concatenate([[inner[0] - 2.0, inner[0] - 1.0], inner, [inner[-1] + 1.0, inner[-1] + 2.0]])
    refined = np.eye(t.size - 4)
    for mid in 0.5 * (inner[1:-2] + inner[2:-1]):
        t, a = boehm_insert(t, float(mid))
        refined = a @ refined
    row = int(np.flatnonzero(t == inner[i])[0]) - 2  # the point whose middle knot is P_i's, t_{i+2}
    return refined[row]


@pytest.mark.parametrize("sharpness", [2.0, 10.0])
@pytest.mark.parametrize("j", [3, 6])
def test_points_beside_an_equal_spoke_crease_vertex_read_the_crease_knots(sharpness, j):
    mesh = grid(sharpness)
    s, _ = subdivision_operator(mesh)
    topo = Topology(mesh)
    crease = [vid(CREASE_ROW, k) for k in range(N + 1)]
    expected = knot_insertion_vertex_weights(ALONG, j)
    near = slice(j - 1, j + 2)
    assert np.abs(expected[near]).sum() == pytest.approx(1.0)  # the vertex rule's three points
    vertex_row = s[mesh.n_faces + topo.n_edges + crease[j]].toarray().ravel()
    np.testing.assert_allclose(vertex_row[crease], expected, rtol=0, atol=1e-14)  # [TLC] eq. 11
    # both crossing edges at the vertex: their weights on the crease points are the edge
    # rule across (a number) times the vertex rule along
    for i in (CREASE_ROW - 1, CREASE_ROW + 1):
        e = topo.edge_id(vid(i, j), crease[j])
        row = s[mesh.n_faces + e].toarray().ravel()
        along = row[crease][near]
        np.testing.assert_allclose(along / along.sum(), expected[near], rtol=0, atol=1e-14)


def test_reference_is_the_uniform_rule_on_equal_intervals():
    """The Boehm reference itself: 1/8, 6/8, 1/8 on equal intervals."""
    w = knot_insertion_vertex_weights([1.0] * 6, 3)
    np.testing.assert_allclose(w, [0, 0, 0.125, 0.75, 0.125, 0, 0], atol=1e-15)
