"""``build_operator(method="t-spline")``: the [SSEL13] baseline ([FSLYJ]'s [32])."""

from __future__ import annotations

import numpy as np
import pytest

import patching
from patching.errors import OptionError
from patching.mesh.primitives import torus_grid
from patching.topology.tables import Topology
from tests.helpers import ep_disc, lifted, shared_edge_normal_jumps


def ssel13_vertex_point(mesh) -> np.ndarray:
    """The EP's Bezier point of [SSEL13]'s extraction, as [FSLYJ] sec. 3.5 step 1 writes it:
    F_i = w_i w_{i+1} P_{F_i} + (1 - w_i) w_{i+1} P_{E_{i+1}} + (1 - w_{i+1}) w_i P_{E_i}
    + (1 - w_i)(1 - w_{i+1}) P_0, w_i = (d_{i-2} + d_{i+2}) / (d_{i-2} + d_{i+2} + 2 d_i + 2 a_i),
    V = sum_i d_{i-1} d_{i+2} F_i / sum (eq. 3).  EP = vertex 0, every E_i regular."""
    t = Topology(mesh)
    h = t.one_ring(0)
    d = t.halfedge_interval[h]
    a = t.halfedge_interval[t.rotate(t.rotate(t.twin[h]))]  # straight on beyond E_i
    p = mesh.vertices
    e, f = p[t.dest[h]], p[t.dest[t.next[h]]]
    w = (np.roll(d, 2) + np.roll(d, -2)) / (np.roll(d, 2) + np.roll(d, -2) + 2 * d + 2 * a)
    wn = np.roll(w, -1)
    face = (w * wn)[:, None] * f + ((1 - w) * wn)[:, None] * np.roll(e, -1, axis=0)
    face += ((1 - wn) * w)[:, None] * e + ((1 - w) * (1 - wn))[:, None] * p[0]
    c = np.roll(d, 1) * np.roll(d, -2)
    return (c[:, None] * face).sum(axis=0) / c.sum()


def _corners(surface) -> np.ndarray:
    out = []
    for _, deg, _, net in surface.patches():
        out += [net[0, 0], net[deg, 0], net[0, deg], net[deg, deg]]
    return np.array(out)


@pytest.mark.parametrize("n", [3, 5, 6])
def test_t_spline_patches_are_g1_with_the_extractions_own_vertex_point(n):
    rng = np.random.default_rng(n)
    mesh = lifted(ep_disc(n, rng.uniform(1, 5, (n, 3))), seed=n)
    op = patching.build_operator(mesh, method="t-spline")
    assert np.abs(np.asarray(op.matrix.sum(axis=1)).ravel() - 1).max() < 1e-13
    surface = op.evaluate(mesh.vertices)
    corner = ssel13_vertex_point(mesh)
    dist = np.linalg.norm(_corners(surface) - corner, axis=1)
    assert np.count_nonzero(dist < 1e-12) == n  # the n patches around the EP meet there
    default = _corners(patching.build_operator(mesh).evaluate(mesh.vertices))
    assert np.linalg.norm(default - corner, axis=1).min() > 1e-4  # [FSLYJ]: [LFS16]'s limit point
    angle, gap = shared_edge_normal_jumps(surface)
    # G0 and G1 from a constrained dense solve on coordinates of size 1: round-off
    assert gap < 1e-12 and angle < 1e-8, (angle, gap)


def test_t_spline_changes_only_the_ep_neighbourhood():
    """A torus has no EP: both methods are the bicubic B-spline, row for row."""
    rng = np.random.default_rng(3)
    mesh = torus_grid(5, 6, rng.uniform(1, 4, 5), rng.uniform(1, 4, 6))
    a = patching.build_operator(mesh, method="t-spline").matrix
    b = patching.build_operator(mesh).matrix
    assert abs(a - b).max() == 0.0


def test_t_spline_fixes_angles_anchors_and_g1_solve():
    mesh = ep_disc(5)
    for bad in ({"anchors": "faired"}, {"angles": "default"}, {"g1_solve": "seed"}):
        with pytest.raises(OptionError, match="t-spline"):
            patching.build_operator(mesh, method="t-spline", **bad)
    uniform = patching.build_operator(mesh, method="t-spline", angles="uniform").matrix
    assert abs(uniform - patching.build_operator(mesh, method="t-spline").matrix).max() == 0.0


def test_cli_build_method_t_spline(tmp_path, run_cli):
    from patching.mesh import format_obj

    src = tmp_path / "disc.obj"
    src.write_text(format_obj(lifted(ep_disc(5, np.random.default_rng(0).uniform(1, 5, (5, 3))))))
    out = tmp_path / "disc.step"
    r = run_cli("build", src, "--method", "t-spline", "-o", out, "-q")
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size > 0
    bad = tmp_path / "bad.step"
    r = run_cli("build", src, "--method", "t-spline", "--anchors", "faired", "-o", bad, "-q")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and not bad.exists()
    assert "t-spline" in r.stderr
