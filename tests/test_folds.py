"""Folds: patches that stay G1 with their neighbours but whose normal flips inside them.  ``evaluation.normal_turning`` is the detector; the cases are coarse meshes whose
EPs are all adjacent, where the anchors of two EPs meet on one short edge."""

import numpy as np
import pytest

import patching
from export import write_obj
from patching.extraordinary.auxiliary_points import onward_interval
from patching.evaluation.sampling import normal_turning
from patching.topology.tables import Topology
from tests.helpers import ep_disc
from tests.helpers import CUBE_FACES, CUBE_VERTICES, with_random_intervals

CUBE = patching.from_arrays(CUBE_VERTICES, CUBE_FACES, name="cube")
#: no two neighbouring samples of a smooth patch turn by more than this (cos 60 degrees);
#: the folds found before the fixes had cosines from -0.01 down to -1.
TURNING = 0.5


def turning_pointwise(nets: np.ndarray, samples: int, singular: float = 1e-6) -> np.ndarray:
    """The detector written plainly: every sample's normal from ``evaluate_nets`` on the
    flattened grid (s first) and np.cross, the corners' singular normals left out."""
    from patching.bernstein import evaluate_nets

    u = np.linspace(0.0, 1.0, samples)
    s, t = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    _, ds, dt = evaluate_nets(nets, s, t, derivatives=True)
    n = np.cross(ds, dt).reshape(-1, samples, samples, 3)
    size = np.linalg.norm(n, axis=-1)
    n = n / np.maximum(size, 1e-300)[..., None]
    ok = size > singular * size.max(axis=(1, 2), keepdims=True)
    ok[:, 1:-1, :] = ok[:, :, 1:-1] = True
    worst = np.ones(nets.shape[0])
    for a in range(samples):
        for b in range(samples):
            for da, db in ((1, 0), (0, 1)):
                if a + da < samples and b + db < samples:
                    c = np.sum(n[:, a, b] * n[:, a + da, b + db], axis=-1)
                    worst = np.where(ok[:, a, b] & ok[:, a + da, b + db], np.minimum(worst, c), worst)
    return worst


@pytest.mark.parametrize("degree", [3, 5])
def test_detector_is_the_pointwise_one_in_chunks(degree, monkeypatch):
    """The chunked tensor-grid detector gives the pointwise one's cosines (chunks of 7 patches
    over 40: the last chunk short), on random nets, folded ones among them, and a net with a
    collapsed corner."""
    from patching.evaluation import sampling

    monkeypatch.setattr(sampling, "TURNING_CHUNK", 7)
    rng = np.random.default_rng(degree)
    u = np.linspace(0.0, 1.0, degree + 1)
    flat = np.stack(list(np.meshgrid(u, u, indexing="ij")) + [np.zeros((degree + 1,) * 2)], axis=-1)
    nets = flat + np.linspace(0.01, 0.4, 40)[:, None, None, None] * rng.normal(size=(40,) + flat.shape)
    nets[3, 0, :] = nets[3, 0, 0]  # side s = 0 collapsed to a point: two singular corners
    group = patching.PatchGroup(degree=degree, faces=np.arange(40), coefficients=nets)
    faces, worst = normal_turning(patching.BezierSurface((group,), None, "random", 1.0), samples=9)
    np.testing.assert_array_equal(faces, np.arange(40))
    np.testing.assert_allclose(worst, turning_pointwise(nets, 9), rtol=0, atol=1e-12)
    assert (worst < 0).any() and (worst > 0.9).any()  # folds and smooth patches both present


def test_detector_sees_a_fold_and_not_a_smooth_patch():
    u = np.linspace(0.0, 1.0, 6)
    flat = np.stack(list(np.meshgrid(u, u, indexing="ij")) + [np.zeros((6, 6))], axis=-1)
    folded = flat.copy()
    folded[:, 3:, 1] = 1.0 - folded[:, 3:, 1]  # the net turns back over itself along t
    group = patching.PatchGroup(degree=5, faces=np.array([0, 1]), coefficients=np.stack([flat, folded]))
    surface = patching.BezierSurface((group,), None, "two", 1.0)
    faces, worst = normal_turning(surface)
    assert worst[list(faces).index(0)] > 0.999
    assert worst[list(faces).index(1)] < -0.9


def test_rotate_back_undoes_rotate():
    """Topology.rotate_back, which onward_interval walks with, on an open mesh: the inverse of
    rotate wherever rotate stays inside, -1 across the boundary."""
    mesh = ep_disc(5)
    topo = Topology(mesh)
    h = np.arange(topo.origin.size)
    turned = topo.rotate(h)
    inside = turned >= 0
    np.testing.assert_array_equal(topo.rotate_back(turned[inside]), h[inside])
    back = topo.rotate_back(h)
    np.testing.assert_array_equal(topo.rotate(back[back >= 0]), h[back >= 0])
    assert (topo.rotate_back(h[topo.twin < 0]) == -1).all()


def test_first_ring_points_of_adjacent_eps_never_cross():
    """Section 3.5 step 1 at both ends of an edge between two EPs: w + w' < 1 (the reading of
    a_i at an irregular E_i, ``onward_interval``).  The former reading a_i = d_i gives
    w = 0.55 at each end of the cube's short edges."""
    mesh = with_random_intervals(CUBE, 5.0, seed=0)
    topo = Topology(mesh)
    iv = topo.halfedge_interval
    h = np.arange(topo.origin.size)
    behind = 0.5 * (iv[topo.rotate(topo.rotate(h))] + iv[topo.rotate_back(topo.rotate_back(h))])  # (d_{i-2} + d_{i+2}) / 2 at P_0
    a = onward_interval(topo, h)
    w = behind / (behind + iv + a)
    w_far = w[topo.twin]
    assert np.all(w + w_far < 1.0)
    np.testing.assert_allclose(a, behind[topo.twin])  # the far end's own "behind" interval
    assert (iv[h] / (iv[h] + 2 * behind)).min() < 0.5 < (behind / (behind + 2 * iv)).max()  # the old reading crossed


@pytest.mark.parametrize("anchors", ["eigen-polyhedron", "extraction", "faired"])
@pytest.mark.parametrize("angles", ["optimized", "uniform"])
def test_cube_with_random_intervals_does_not_fold(anchors, angles):
    """Every vertex of the cube is a valence-3 EP.  With strip intervals drawn from [1, 5],
    6 of 20 draws folded with the default anchors (adjacent normals at cos -1) before the
    a_i reading, and 7 of 20 with faired anchors before their damping."""
    worst = []
    for seed in range(20):
        mesh = with_random_intervals(CUBE, 5.0, seed=seed)
        _, turning = normal_turning(patching.build(mesh, angles=angles, anchors=anchors))
        worst.append(turning.min())
    assert min(worst) > TURNING, f"folded draws: {[k for k, w in enumerate(worst) if w <= TURNING]}"


def test_fairing_never_raises_the_thin_plate_energy_of_the_defaults():
    """The damped block-Jacobi step (anchor_fairing): on a mesh of coupled EPs the faired
    surface is at least as fair as the default one, in the energy it minimises."""
    from patching.extraordinary.anchor_fairing import thin_plate_matrices

    def energy(surface):
        total = 0.0
        for g in surface.groups:
            iss, ist, itt = thin_plate_matrices(g.degree)
            nets = g.coefficients.reshape(len(g.faces), -1, 3)
            spans = Topology(mesh).face_spans[g.faces]
            for net, (delta, eps) in zip(nets, spans):
                q = eps / delta**3 * iss + 2.0 / (delta * eps) * ist + delta / eps**3 * itt
                total += float(np.einsum("ic,ij,jc->", net, q, net))
        return total

    for seed in range(5):
        mesh = with_random_intervals(CUBE, 5.0, seed=seed)
        default = energy(patching.build(mesh))
        faired = energy(patching.build(mesh, anchors="faired"))
        assert faired <= default * (1 + 1e-12)


@pytest.mark.slow
def test_ep_quality_reports_folds():
    """``ep_quality``'s ``fold``: the smallest normal cosine on an EP's patches; the cube's EPs
    are clean, and where the seed's per-EP steps fold catmark_lefthanded (which the default
    joint solve removes: test_cluster_fairing) an EP reports it."""
    from patching.evaluation.sampling import ep_quality
    from tests.conftest import shape_files

    mesh = with_random_intervals(CUBE, 5.0, seed=0)
    assert min(q.fold for q in ep_quality(patching.build_operator(mesh), mesh, samples=9)) > TURNING
    shapes = [p for p in shape_files() if p.stem == "catmark_lefthanded"]
    if not shapes:
        pytest.skip("../shared/opensubdiv-shapes is absent")
    mesh = with_random_intervals(patching.read_mesh(shapes[0]), 5.0, seed=len(shapes[0].stem))
    op = patching.build_operator(mesh, g1_solve="seed")
    faces, turning = normal_turning(op.evaluate(mesh.vertices), samples=17)
    topo = Topology(mesh)
    corners = np.unique(mesh.quads()[faces[turning < 0.0]])
    folded_eps = np.intersect1d(corners, topo.extraordinary)
    assert 0 < folded_eps.size < 0.1 * topo.extraordinary.size  # a few EPs, not the whole plate
    assert min(q.fold for q in ep_quality(op, mesh, samples=17, eps=folded_eps, topology=topo)) < 0.0


def ep_rich_sphere(seed: int) -> patching.ControlMesh:
    """benchmarks/build.py's "coarse" mesh in small: an icosphere's triangles split into quads
    (half the vertices EPs of valence 3, 5, 6), strip intervals drawn from {1, 2, 5}."""
    import trimesh

    from patching.subdivision.catmark import subdivide

    base = trimesh.creation.icosphere(subdivisions=2)
    quad = subdivide(patching.from_arrays(base.vertices, base.faces), 1, rules="opensubdiv")
    topo = Topology(quad)
    values = np.random.default_rng(seed).choice([1.0, 2.0, 5.0], topo.n_strips)
    first = np.unique(topo.edge_strip, return_index=True)[1]
    intervals = {tuple(int(x) for x in topo.edges[e]): float(values[topo.edge_strip[e]]) for e in first}
    return patching.from_arrays(quad.vertices, quad.quads(), intervals=intervals)


@pytest.mark.parametrize("seed", range(4))
def test_spoke_curves_do_not_fold_where_intervals_run_against_the_net(seed):
    """Red stage 2's target q_hat + (s - s_hat) / 2 (g1_patches, "spoke curves"): with the
    extraction's q the black step's P30 overshot and 4 to 16 of these 960 patches folded
    (cosines down to -0.999) in each of the four draws."""
    mesh = ep_rich_sphere(seed)
    _, turning = normal_turning(patching.build(mesh), samples=9)
    assert turning.min() > TURNING


def test_nupatch_build_warns_of_folds_and_still_writes(cli_main, tmp_path):
    """`nupatch build` names folds in one warning line (evaluation.normal_turning on 9 x 9
    samples) and writes the file; a clean surface gets no such line.  The folded case is
    catmark_lefthanded under the seed's per-EP steps (`--g1-solve seed`); the default joint
    solve does not fold it."""
    clean = tmp_path / "cube.obj"
    write_obj(with_random_intervals(CUBE, 5.0, seed=0), clean)
    done = cli_main("build", clean, "-o", tmp_path / "cube.step", "-q")
    assert done.returncode == 0 and "fold" not in done.stderr
    from tests.conftest import shape_files

    shapes = [p for p in shape_files() if p.stem == "catmark_lefthanded"]
    if not shapes:
        pytest.skip("../shared/opensubdiv-shapes is absent")
    folded = tmp_path / "lefthanded.obj"
    write_obj(with_random_intervals(patching.read_mesh(shapes[0]), 5.0, seed=len(shapes[0].stem)), folded)
    done = cli_main("build", folded, "-o", tmp_path / "lefthanded.step", "-q", "--g1-solve", "seed")
    assert done.returncode == 0 and (tmp_path / "lefthanded.step").stat().st_size > 0
    lines = [line for line in done.stderr.splitlines() if "fold over themselves" in line]
    assert len(lines) == 1 and lines[0].startswith("nupatch: warning: ")
