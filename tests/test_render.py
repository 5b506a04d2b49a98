"""export.render and `nupatch render`: headless PNGs of the requested size, not blank,
zebra and curvature different."""

from __future__ import annotations

import numpy as np
import pytest

import patching
from export.brep import to_shape
from export.render import render, sample_shape, zebra_parameter
from tests.conftest import REPO

Image = pytest.importorskip("PIL.Image")

TORUS = REPO / "models" / "torus_nonuniform.obj"


@pytest.fixture(scope="module")
def sampled():
    surface = patching.build(patching.read_mesh(TORUS))
    return sample_shape(to_shape(surface), 0.02)


def pixels(path) -> np.ndarray:
    with Image.open(path) as image:
        assert image.format == "PNG"
        return np.asarray(image.convert("RGB"), dtype=float)


def assert_drawn(image: np.ndarray, size: tuple[int, int]) -> None:
    assert image.shape == (size[1], size[0], 3)
    background = np.all(image > 250, axis=-1)  # white
    assert 0.05 < 1 - background.mean() < 0.95, "nothing (or only the model's box) drawn"
    assert image.std() > 20


def test_sampled_curvature_of_the_torus_is_plausible(sampled):
    # Tube radius ~1 and ring radius ~3: |H| ~ 0.5 to 1 on most of it, K > 0 outside, < 0 inside.
    assert np.all(np.abs(np.linalg.norm(sampled.normals, axis=1) - 1) < 1e-12)
    assert 0.3 < np.median(np.abs(sampled.mean)) < 1.5
    outer = np.linalg.norm(sampled.points[:, :2], axis=1) > 3.3
    assert np.mean(sampled.gaussian[outer] > 0) > 0.95 and np.mean(sampled.gaussian[~outer & (np.linalg.norm(sampled.points[:, :2], axis=1) < 2.7)] < 0) > 0.95


def test_zebra_parameter_is_the_reflected_rays_elevation():
    view, up = np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0])
    normals = np.array([[0.0, 0.0, 1.0], [np.sin(0.1), 0.0, np.cos(0.1)]])
    # Facing the camera the ray comes straight back; tilting the normal by a tilts it by 2a.
    np.testing.assert_allclose(zebra_parameter(normals, view, up), [0.0, 0.2], atol=1e-15)


@pytest.mark.parametrize("renderer", ["vtk", "matplotlib"])
def test_images_have_the_size_are_not_blank_and_zebra_differs_from_curvature(tmp_path, sampled, renderer):
    size = (320, 240)
    images = {}
    for mode in ("zebra", "mean", "shaded"):
        path = tmp_path / f"{mode}.png"
        assert render(sampled, path, mode, size, overlay=mode == "shaded", renderer=renderer) == renderer
        images[mode] = pixels(path)
        assert_drawn(images[mode], size)
    zebra, curvature = images["zebra"], images["mean"]
    # Zebra is black and white stripes; the curvature map is coloured.
    assert np.abs(zebra - curvature).mean() > 10
    drawn = ~np.all(zebra > 250, axis=-1)
    assert np.mean(np.all(zebra[drawn] < 40, axis=-1)) > 0.15  # black stripes
    assert np.ptp(curvature, axis=-1).max() > 100  # saturated colours


def test_cli_renders_a_step_file_and_a_mesh(tmp_path, run_cli):
    step = tmp_path / "ring.step"
    assert run_cli("build", TORUS, "-o", step, "-q").returncode == 0
    out = tmp_path / "ring.png"
    result = run_cli("render", step, "--curvature", "gaussian", "--mesh", "-o", out, "--size", "200x150")
    assert result.returncode == 0, result.stderr
    assert "vtk" in result.stderr and "X server" not in result.stderr  # VTK's warning silenced
    assert_drawn(pixels(out), (200, 150))
    result = run_cli("render", TORUS, "--zebra", "-o", tmp_path / "z.png", "--size", "160x120", "-q")
    assert result.returncode == 0 and result.stderr == "", result.stderr
    assert_drawn(pixels(tmp_path / "z.png"), (160, 120))


@pytest.mark.parametrize("args, fragment", [
    (("--size", "big"), "WIDTHxHEIGHT"),
    (("--size", "10x10"), "16 to 8192"),
    (("-o", "{tmp}/x.jpg"), "must end in .png"),
    (("--zebra", "--curvature"), "not allowed with argument"),
])
def test_cli_bad_render_options(tmp_path, run_cli, args, fragment):
    result = run_cli("render", TORUS, *(a.format(tmp=tmp_path) for a in args) , *([] if "-o" in args else ["-o", tmp_path / "x.png"]))
    assert result.returncode == 2 and fragment in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and result.stderr.startswith("nupatch: error: ")
    assert list(tmp_path.iterdir()) == []
