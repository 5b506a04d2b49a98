"""NURSS ([SZSS98]) as a subdivision rule set: ``rules.nurss`` and ``subdivide(rules="nurss")``.

References written here: Catmull-Clark's masks (uniform intervals), the bicubic B-spline's
midpoint knot insertion through blossoms (``tests.reference_bspline``, valence 4), OpenCASCADE's
knot insertion on a torus (``test_subdivision``'s reference, through the dispatch)."""

from __future__ import annotations

import numpy as np
import pytest

from patching.rules.nurss import nurss_local_matrix
from patching.subdivision.catmark import subdivision_operator
from tests.reference_bspline import blossom_weights
from patching.mesh.primitives import torus_grid
from tests.reference_refinement import occ_refined_poles, polar_disk, refined_ids, ring_ids


def catmull_clark_ring(n: int) -> np.ndarray:
    """Catmull-Clark on [V, E_0.., F_0..]: face = centroid, edge = (V + E_i + F'_{i-1} + F'_i) / 4,
    vertex = (Q + 2 R + (n - 3) V) / n (Q: mean new face point, R: mean edge midpoint)."""
    size = 2 * n + 1
    m = np.zeros((size, size))
    for i in range(n):
        m[1 + n + i, [0, 1 + i, 1 + (i + 1) % n, 1 + n + i]] = 0.25
    for i in range(n):
        m[1 + i, 0] += 0.25
        m[1 + i, 1 + i] += 0.25
        m[1 + i] += 0.25 * (m[1 + n + (i - 1) % n] + m[1 + n + i])
    q = m[1 + n :].mean(axis=0)
    r = np.zeros(size)
    r[0] = 0.5
    r[1 : 1 + n] = 0.5 / n
    m[0] = (q + 2 * r) / n
    m[0, 0] += (n - 3) / n
    return m


@pytest.mark.parametrize("n", [3, 5, 6, 8])
def test_equal_intervals_are_catmull_clark(n):
    # a few operations on weights of size 1: round-off
    assert np.abs(nurss_local_matrix(np.full(n, 2.7)) - catmull_clark_ring(n)).max() < 1e-15


def test_uniform_mesh_is_catmull_clark_through_the_dispatch():
    """Equal intervals everywhere (not 1): S of rules nurss is OpenSubdiv's Catmull-Clark."""
    mesh = polar_disk(5, rings=2, spoke_intervals=[2.5] * 5, outer="spoke")
    s_nurss, _ = subdivision_operator(mesh, rules="nurss")
    s_osd, _ = subdivision_operator(mesh, rules="opensubdiv")
    assert abs(s_nurss - s_osd).max() < 1e-15


def _curve_rules(behind: float, left: float, right: float, beyond: float):
    """Midpoint insertion on the line P3 P4 P5 (P4 the vertex; legs behind, left, right, beyond)
    by blossoms: vertex point f(m56, t6, m67), edge points f(t5, m56, t6) and f(t6, m67, t7),
    each as weights over (P3, P4, P5)."""
    t = np.concatenate([[0.0], np.cumsum([behind, left, right, beyond, 1.0])])  # t4..t9
    m56, m67 = (t[1] + t[2]) / 2, (t[2] + t[3]) / 2
    args = np.array([[[m56, t[2], m67], [t[1], m56, t[2]], [t[2], m67, t[3]]]])
    w = blossom_weights(t[None], args)[0]  # (3, 4) over P3..P6
    assert np.abs(w[:, 3]).max() < 1e-14
    return w[0, :3], w[1, :3], w[2, :3]  # vertex, edge to P3, edge to P5


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_valence_4_is_bicubic_knot_insertion(seed):
    """Any spoke intervals at valence 4 (interval beyond E_i equal to d_i, the local rule's
    reading): NURSS's 1-ring rows are the tensor product of midpoint knot insertion."""
    d = np.random.default_rng(seed).uniform(0.2, 20.0, 4)
    vs, es_m, es_p = _curve_rules(d[2], d[2], d[0], d[0])  # s: E_2 - V - E_0
    vt, et_m, et_p = _curve_rules(d[3], d[3], d[1], d[1])  # t: E_3 - V - E_1
    # grid position (s, t) in {-1, 0, 1}^2 -> local index [V, E_0.., F_0..]
    where = {(0, 0): 0, (1, 0): 1, (0, 1): 2, (-1, 0): 3, (0, -1): 4, (1, 1): 5, (-1, 1): 6, (-1, -1): 7, (1, -1): 8}
    rows = {0: (vs, vt), 1: (es_p, vt), 2: (vs, et_p), 3: (es_m, vt), 4: (vs, et_m),
            5: (es_p, et_p), 6: (es_m, et_p), 7: (es_m, et_m), 8: (es_p, et_m)}
    ref = np.zeros((9, 9))
    for r, (ws, wt) in rows.items():
        for (a, b), col in where.items():
            ref[r, col] = ws[a + 1] * wt[b + 1]
    # both exact rational formulas in intervals up to 20: round-off
    assert np.abs(nurss_local_matrix(d) - ref).max() < 1e-13


def test_regular_non_uniform_torus_is_occ_knot_insertion():
    rng = np.random.default_rng(4)
    m, n = 5, 6
    du, dv = rng.uniform(1, 20, m), rng.uniform(1, 20, n)
    mesh = torus_grid(m, n, du, dv)
    mesh = mesh.with_positions(mesh.vertices + rng.normal(scale=0.2, size=mesh.vertices.shape))
    _, child = subdivision_operator(mesh, rules="nurss")
    vid, _ = refined_ids(mesh, np.arange(m * n).reshape(m, n), np.arange(m * n).reshape(m, n))
    reference = occ_refined_poles(mesh.vertices.reshape(m, n, 3), du, dv)
    # Boehm's algorithm against our masks, coordinates of size 4: round-off
    assert np.abs(child.vertices[vid] - reference).max() <= 1e-12 * 8.0


def test_ep_rows_in_s_are_the_nurss_matrix_and_the_rest_is_seed():
    n = 5
    mesh = polar_disk(n, spoke_intervals=[1.0, 3.0, 1.5, 4.0, 2.0], outer="spoke")
    s, child = subdivision_operator(mesh, rules="nurss")
    seed, _ = subdivision_operator(mesh, rules="seed")
    parent, kids, d = ring_ids(mesh, 0)
    assert np.abs(s[kids][:, parent].toarray() - nurss_local_matrix(d)).max() < 1e-15
    assert abs(s[kids].toarray().sum() - s[kids][:, parent].toarray().sum()) < 1e-12  # closed 1-ring
    others = np.setdiff1d(np.arange(s.shape[0]), kids)
    assert abs(s[others] - seed[others]).max() < 1e-15
    assert np.abs(np.asarray(s.sum(axis=1)).ravel() - 1).max() < 1e-14
    assert abs(s[kids] - seed[kids]).max() > 1e-3  # and the EP rows do differ from [LFS16]'s


def test_eigenvalues_at_eps():
    """Valence 4: the curve's 1, 1/2, 1/4 in tensor products, 1/2 twice, any intervals.  Equal
    intervals: Catmull-Clark's double subdominant lambda.  Unequal at n != 4: 1 stays simple and
    dominant, but the subdominant pair splits ([TLC] sec. 3: NURSS "cannot ensure the second
    and third eigenvalues to be identical")."""
    ev = np.sort(np.abs(np.linalg.eigvals(nurss_local_matrix([1.0, 7.0, 2.0, 0.5]))))[::-1]
    assert np.abs(ev - [1, 0.5, 0.5, 0.25, 0.25, 0.25, 0.125, 0.125, 0.0625]).max() < 1e-12
    for n in (3, 5, 7):
        c = np.cos(2 * np.pi / n)
        lam = (c + 5 + np.sqrt((c + 9) * (c + 1))) / 16
        ev = np.sort(np.abs(np.linalg.eigvals(nurss_local_matrix(np.full(n, 3.0)))))[::-1]
        assert abs(ev[0] - 1) < 1e-13 and abs(ev[1] - lam) < 1e-12 and abs(ev[2] - lam) < 1e-12
        d = np.ones(n)
        d[1] = 4.0
        ev = np.sort(np.abs(np.linalg.eigvals(nurss_local_matrix(d))))[::-1]
        assert abs(ev[0] - 1) < 1e-13 and ev[1] < 1 - 1e-3
        assert ev[1] - ev[2] > 1e-3


def test_cli_subdivide_nurss(tmp_path, run_cli):
    from patching import read_mesh

    src = tmp_path / "disk.obj"
    from patching.mesh import format_obj

    src.write_text(format_obj(polar_disk(5, rings=2, spoke_intervals=[1.0, 3.0, 1.0, 2.0, 2.0])))
    out = tmp_path / "out.obj"
    r = run_cli("subdivide", src, "-n", "1", "--rules", "nurss", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "t nupatch_rules 0/0/1 nurss" in out.read_text()
    expected = subdivision_operator(read_mesh(src), rules="nurss")[1].vertices
    assert np.abs(read_mesh(out).vertices - expected).max() < 1e-12
    bad = tmp_path / "bad.obj"
    r = run_cli("subdivide", src, "-n", "1", "--rules", "nurss", "--crease-method", "chaikin", "-o", bad)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and not bad.exists()
