"""Random sharp features never give a wrong surface: small closed and opened meshes
with random infinitely sharp edges (darts, corners, creases through and around EPs, turning
creases), random corner tags, every boundary mode and random strip intervals either are
refused with one line of the error family, or build patches that are G1 across every smooth
edge and end on the crease B-spline along every sharp one (tests/edge_checks.py).

This is how the singular valence-4 ring of ``features.refuse_singular_rings`` (corner tags next
to EPs, now built with ``g1_patches.FOUR_FAN``) was found."""

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import patching
from patching.errors import NupatchError
from patching.mesh.primitives import polycube
from tests.edge_checks import crease_deviation, edge_jumps
from tests.helpers import quad_mesh_with_eps, with_random_intervals

BASES = {
    "cube": lambda: quad_mesh_with_eps("cube"),
    "bipyramid-3": lambda: quad_mesh_with_eps("bipyramid-3"),
    "bipyramid-5": lambda: quad_mesh_with_eps("bipyramid-5"),
    "bipyramid-6": lambda: quad_mesh_with_eps("bipyramid-6"),
    "l-polycube": lambda: polycube([(0, 0, 0), (1, 0, 0), (0, 1, 0)], 2),
    "frame": lambda: polycube([(x, y, 0) for x in range(3) for y in range(3) if (x, y) != (1, 1)], 1),
}


@st.composite
def tagged_meshes(draw):
    base = BASES[draw(st.sampled_from(sorted(BASES)))]()
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    faces = [list(base.face(f)) for f in range(base.n_faces)]
    if draw(st.booleans()):  # open it: drop one or two faces
        drop = set(rng.choice(len(faces), size=int(rng.integers(1, 3)), replace=False).tolist())
        faces = [f for i, f in enumerate(faces) if i not in drop]
    points = base.vertices + rng.normal(scale=0.03, size=base.vertices.shape)
    edges = {tuple(sorted((f[k], f[(k + 1) % 4]))) for f in faces for k in range(4)}
    edges = sorted(edges)
    sharp = rng.choice(len(edges), size=int(rng.integers(0, max(1, len(edges) // 3))), replace=False)
    creases = {edges[e]: np.inf for e in sharp.tolist()}
    used = sorted({v for f in faces for v in f})
    corners = {int(v): 10.0 for v in rng.choice(used, size=draw(st.integers(0, 2)), replace=False)}
    mode = draw(st.sampled_from([0, 1, 2]))
    ratio = draw(st.sampled_from([1.0, 5.0, 20.0]))
    return points, faces, creases, corners, mode, ratio, int(rng.integers(1000))


@pytest.mark.slow
@settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
@given(tagged_meshes())
def test_random_sharp_features_build_g1_or_are_refused_in_one_line(case):
    points, faces, creases, corners, mode, ratio, seed = case
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            mesh = patching.from_arrays(points, faces, creases=creases, corners=corners, interpolate_boundary=mode, name="fuzz")
            mesh = with_random_intervals(mesh, ratio, seed) if ratio > 1 else mesh
            surface = patching.build(mesh)
        except NupatchError as exc:
            assert str(exc) and "\n" not in str(exc)
            return
    _, gaps, angles, sharp = edge_jumps(mesh, surface)
    assert np.isfinite(gaps).all() and gaps.max(initial=0.0) <= 1e-10 * surface.size
    assert angles[~sharp].max(initial=0.0) <= 1e-6
    assert crease_deviation(mesh, surface) <= 1e-9 * surface.size
