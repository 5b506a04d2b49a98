"""The anchors' eigen-polyhedron angles in ``build`` ([FSLYJ] sec. 3.5 with [ZTL]'s modified
angles): the patched surface's point and tangent plane at the EP are the modified
eigen-polyhedron's, built from a first ring written here from section 3.5 step 1."""

from __future__ import annotations

import numpy as np
import pytest

import patching
from patching.errors import OptionError
from patching.rules.eigen_polyhedron import limit_point_weights, tangent_weights
from tests.helpers import ep_disc, lifted, shared_edge_normal_jumps


def first_ring(mesh, d, a):
    """[V, E_0.., F_0..] of [FSLYJ] sec. 3.5 step 1 at vertex 0 of ``ep_disc``: F_i bilinear in
    P_0, P_{E_i}, P_{F_i}, P_{E_{i+1}} at (w_i, w_{i+1}), w_i = (d_{i-2} + d_{i+2}) / (d_{i-2} +
    d_{i+2} + 2 d_i + 2 a_i); E_i = (d_{i-1} F_i + d_{i+1} F_{i-1}) / (d_{i-1} + d_{i+1});
    V = sum c_i F_i, c_i = d_{i-1} d_{i+2} / sum (eq. 3)."""
    n = d.size
    p = mesh.vertices
    # ep_disc numbers vertex (spoke i, ring 1) and the corner of face i in order of creation
    faces = [list(mesh.face(f)) for f in range(mesh.n_faces)]
    inner = [f for f in faces if 0 in f]
    spoke, corner = {}, {}
    for i, f in enumerate(inner):  # face i of the disc: [0, E_i, F_i, E_{i+1}]
        k = f.index(0)
        spoke[i], corner[i] = f[(k + 1) % 4], f[(k + 2) % 4]
    before = np.roll(d, 2) + np.roll(d, -2)
    w = before / (before + 2 * d + 2 * a)
    F = np.array([
        (1 - w[i]) * (1 - w[(i + 1) % n]) * p[0] + w[i] * (1 - w[(i + 1) % n]) * p[spoke[i]]
        + w[i] * w[(i + 1) % n] * p[corner[i]] + (1 - w[i]) * w[(i + 1) % n] * p[spoke[(i + 1) % n]]
        for i in range(n)
    ])
    E = np.array([(d[i - 1] * F[i] + d[(i + 1) % n] * F[i - 1]) / (d[i - 1] + d[(i + 1) % n]) for i in range(n)])
    c = np.roll(d, 1) * np.roll(d, -2)
    V = (c / c.sum()) @ F
    return np.vstack([V, E, F])


def ep_corner(surface, mesh):
    """(point, unit normal) of the patch corners at vertex 0."""
    for _, _, face, net in surface.patches():
        f = list(mesh.face(face))
        if 0 in f:
            k = f.index(0)
            c = [(0, 0), (-1, 0), (-1, -1), (0, -1)][k]
            nxt = [(1, 0), (-1, 1), (-2, -1), (0, -2)][k]
            prv = [(0, 1), (-2, 0), (-1, -2), (1, -1)][k]
            u = net[nxt] - net[c]
            v = net[prv] - net[c]
            normal = np.cross(u, v)
            return net[c], normal / np.linalg.norm(normal)
    raise AssertionError("no patch at the EP")


@pytest.mark.parametrize("n", [3, 5, 6])
def test_modified_angles_place_the_ep(n):
    rng = np.random.default_rng(n)
    d = rng.uniform(1.0, 6.0, (n, 3))
    mesh = lifted(ep_disc(n, d), seed=n)
    ring = first_ring(mesh, d[:, 0], d[:, 1])
    corners = {}
    for mode in ("standard", "modified"):
        surface = patching.build_operator(mesh, eigen_angles=mode).evaluate(mesh.vertices)
        point, normal = ep_corner(surface, mesh)
        limit = limit_point_weights(d[:, 0], angles=mode) @ ring
        t = tangent_weights(d[:, 0], angles=mode) @ ring
        ref = np.cross(t[0], t[1])
        ref /= np.linalg.norm(ref)
        assert np.allclose(point, limit, atol=1e-12)
        assert np.linalg.norm(np.cross(normal, ref)) < 1e-9
        assert shared_edge_normal_jumps(surface)[0] < 1e-7  # still G1
        corners[mode] = point
    # the modified angles differ from 2 pi / n for these intervals, and so does the point
    assert np.linalg.norm(corners["modified"] - corners["standard"]) > 1e-6


def test_uniform_intervals_give_the_same_operator():
    """[ZTL]'s angles are 2 pi / n for uniform intervals: the same M."""
    mesh = ep_disc(5)
    a = patching.build_operator(mesh).matrix
    b = patching.build_operator(mesh, eigen_angles="modified").matrix
    assert abs(a - b).max() < 1e-13


def test_option_checked():
    with pytest.raises(OptionError, match="eigen_angles"):
        patching.BuildOptions(eigen_angles="fancy")


def test_cli_eigen_angles(run_cli, tmp_path):
    from export import write_obj

    src = tmp_path / "disc.obj"
    d = np.random.default_rng(1).uniform(1.0, 4.0, (5, 3))
    write_obj(lifted(ep_disc(5, d)), src)
    out = tmp_path / "disc.step"
    ok = run_cli("build", src, "-o", out, "--eigen-angles", "modified", "-q")
    assert ok.returncode == 0, ok.stderr
    assert out.stat().st_size > 0
    bad = run_cli("build", src, "-o", tmp_path / "bad.step", "--eigen-angles", "fancy")
    assert bad.returncode == 2
    assert len(bad.stderr.strip().splitlines()) == 1 and bad.stderr.startswith("nupatch: error:")
    assert not (tmp_path / "bad.step").exists()


# --- anchors fitted to the limit surface ([FSLYJ] Fig. 17)

def test_limit_targets_are_the_nurbs_on_regular_faces():
    """On a regular torus the subdivision limit is the bicubic B-spline: the targets at the
    level-2 vertices' parameters are the patches' own points there."""
    from patching.bernstein import evaluate_nets
    from patching.extraordinary.limit_fit import limit_targets
    from patching.mesh.primitives import torus_grid

    mesh = torus_grid(6, 5, u_intervals=[1, 2, 3, 1.5, 2.5, 1], v_intervals=[1, 3, 2, 1, 2])
    nets = {f: net for _, _, f, net in patching.build(mesh).patches()}
    faces = np.array([0, 7, 13])
    params, targets = limit_targets(mesh, faces)
    assert params.shape == (3, 25, 2)
    points = (targets @ mesh.vertices).reshape(3, 25, 3)
    for i, f in enumerate(faces.tolist()):
        expect = evaluate_nets(nets[f][None], params[i, :, 0], params[i, :, 1])[0]
        assert np.abs(expect - points[i]).max() < 1e-12


@pytest.mark.parametrize("n", [3, 5])
def test_limit_fit_is_closer_to_the_limit_and_g1(n):
    from patching.bernstein import evaluate_nets
    from patching.extraordinary.limit_fit import limit_targets

    d = np.random.default_rng(10 + n).uniform(1.0, 5.0, (n, 3))
    mesh = lifted(ep_disc(n, d), seed=n)
    ring = np.flatnonzero([0 in mesh.face(f) for f in range(mesh.n_faces)])
    params, targets = limit_targets(mesh, ring)
    goal = (targets @ mesh.vertices).reshape(ring.size, -1, 3)
    misfit = {}
    for rule in ("eigen-polyhedron", "limit-fit"):
        surface = patching.build_operator(mesh, anchors=rule).evaluate(mesh.vertices)
        nets = {f: net for _, _, f, net in surface.patches()}
        misfit[rule] = np.sqrt(sum(
            ((evaluate_nets(nets[int(f)][None], params[i, :, 0], params[i, :, 1])[0] - goal[i]) ** 2).sum()
            for i, f in enumerate(ring.tolist())
        ))
        assert shared_edge_normal_jumps(surface)[0] < 1e-7
    assert misfit["limit-fit"] < misfit["eigen-polyhedron"]
