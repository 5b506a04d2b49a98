"""export.render and `nupatch render`: curvature from the patches against the graph formulas,
and the pictures judged by their pixels: many thin zebra stripes on a sphere-like part, a
stripe break at a G0 ridge and none at a G1 one, the legend beside the model, blending
functions with their maxima; headless with VTK and with matplotlib."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import patching
from export.render import (
    Picture,
    cameras,
    render,
    robust_range,
    sample_surface,
    style,
    zebra_parameter,
)
from export.render_blending import region_layout, iso_levels, iso_segments
from export.render_geometry import sample_patches
from patching.surface import PatchGroup
from tests.conftest import REPO
from tests.helpers import roof_mesh

Image = pytest.importorskip("PIL.Image")
ndimage = pytest.importorskip("scipy.ndimage")

TORUS = REPO / "models" / "torus_nonuniform.obj"
CUBE = patching.from_arrays(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]], name="cube",
)


def pixels(path) -> np.ndarray:
    with Image.open(path) as image:
        assert image.format == "PNG"
        return np.asarray(image.convert("RGB"), dtype=float)


def drawn(image: np.ndarray) -> np.ndarray:
    return ~np.all(image > 250, axis=-1)


def assert_drawn(image: np.ndarray, size: tuple[int, int]) -> None:
    assert image.shape == (size[1], size[0], 3)
    assert 0.05 < drawn(image).mean() < 0.95, "nothing (or only the model's box) drawn"
    assert image.std() > 20


def picture(mesh, tmp_path, name: str, mode: str, size=(240, 180), renderer="vtk", **look):
    surface = patching.build(mesh)
    pic = Picture(**look)
    coefficients = np.concatenate([g.coefficients.reshape(-1, 3) for g in surface.groups])
    from export.render import picture_pixel

    sampled = sample_surface(surface, picture_pixel(coefficients, size, pic, mode not in ("zebra", "shaded")))
    path = tmp_path / f"{name}.png"
    assert render(sampled, path, mode, size, renderer=renderer, picture=pic) == renderer
    return pixels(path), sampled, pic


# -- numbers --------------------------------------------------------------------------------


def test_curvature_from_the_patch_matches_the_graph_formulas():
    # z = a (x^2 + y^2) - b x y on [0, 1]^2 as a biquadratic Bezier net raised to degree 3 by
    # sample_patches' elevation (grouped with a cubic): the graph formulas are the reference.
    a, b = 0.7, 0.4
    c = np.array([0.0, 0.0, 1.0])  # x^2 = sum c_i B^2_i(x)
    xy = np.array([0.0, 0.5, 1.0])  # x = sum xy_i B^2_i(x); x y = sum xy_i xy_j B_i B_j
    net = np.zeros((1, 3, 3, 3))
    net[0, :, :, 0], net[0, :, :, 1] = np.meshgrid(xy, xy, indexing="ij")
    net[0, :, :, 2] = a * (c[:, None] + c[None, :]) - b * np.outer(xy, xy)
    flat = np.zeros((1, 4, 4, 3))
    flat[0, :, :, 0], flat[0, :, :, 1] = np.meshgrid(np.linspace(0, 1, 4), np.linspace(0, 1, 4), indexing="ij")
    flat[0, :, :, 0] += 5.0  # a plane beside it, to make the quadratic one be elevated
    surface = SimpleNamespace(groups=(PatchGroup(2, np.array([0]), net), PatchGroup(3, np.array([1]), flat)))
    s = sample_patches(surface, 7)
    x, y = np.meshgrid(np.linspace(0, 1, 7), np.linspace(0, 1, 7), indexing="ij")
    fx, fy, fxx, fyy, fxy = 2 * a * x - b * y, 2 * a * y - b * x, 2 * a, 2 * a, -b
    w = 1 + fx**2 + fy**2
    gauss = (fxx * fyy - fxy**2) / w**2
    # the normal S_x x S_y points up, the graph bends towards it: concave, so H < 0 here
    mean = -((1 + fy**2) * fxx - 2 * fx * fy * fxy + (1 + fx**2) * fyy) / (2 * w**1.5)
    np.testing.assert_allclose(s.points[0, ..., 2], a * (x**2 + y**2) - b * x * y, atol=1e-14)
    np.testing.assert_allclose(s.gaussian[0], gauss, rtol=1e-12)
    np.testing.assert_allclose(s.mean[0], mean, rtol=1e-12)
    # principal curvatures: eigenvalues of the shape operator, computed here independently
    for i, j in [(0, 0), (3, 5), (6, 6)]:
        grad = np.array([fx[i, j], fy[i, j]])
        first = np.eye(2) + np.outer(grad, grad)
        second = -np.array([[fxx, fxy], [fxy, fyy]]) / math.sqrt(w[i, j])
        k = np.sort(np.linalg.eigvals(np.linalg.solve(first, second)).real)[::-1]
        np.testing.assert_allclose([s.k1[0, i, j], s.k2[0, i, j]], k, rtol=1e-10)
    np.testing.assert_allclose(s.gaussian[1], 0.0, atol=1e-14)


def test_a_step_files_curvatures_from_opencascade_match_the_patches(tmp_path, run_cli):
    from scipy.spatial import cKDTree

    from export import write_step
    from export.brep import to_shape
    from export.render import sample_shape

    surface = patching.build(patching.read_mesh(TORUS))
    shape = to_shape(surface)
    patches = sample_surface(surface, 1.0, m=17)
    step = sample_shape(shape, 0.02)
    _, near = cKDTree(patches.points).query(step.points)
    for name in ("mean", "gaussian", "k1", "k2"):
        a, b = getattr(patches, name)[near], getattr(step, name)
        scale = np.nanpercentile(np.abs(a), 90)
        assert np.nanmedian(np.abs(a - b)) < 0.05 * scale, name  # same signs and sizes
    # the torus (tube radius ~1, ring ~3): convex outside (K > 0, H > 0), saddle inside
    ring = np.linalg.norm(patches.points[:, :2], axis=1)
    assert np.mean(patches.gaussian[ring > 3.3] > 0) > 0.95 and np.mean(patches.gaussian[ring < 2.7] < 0) > 0.95
    assert np.mean(patches.mean[ring > 3.3] > 0) > 0.95 and 0.3 < np.median(np.abs(patches.mean)) < 1.5
    # and through the command line
    path = write_step(shape, tmp_path / "ring.step", "ring")
    out = tmp_path / "ring.png"
    result = run_cli("render", path, "--curvature", "k1", "--mesh", "-o", out, "--size", "200x150", "--tolerance", "0.05")
    assert result.returncode == 0, result.stderr
    assert "vtk" in result.stderr and "X server" not in result.stderr  # VTK's warning silenced
    assert_drawn(pixels(out), (200, 150))


def test_zebra_parameter_is_the_reflected_rays_elevation():
    view, up = np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0])
    normals = np.array([[0.0, 0.0, 1.0], [np.sin(0.1), 0.0, np.cos(0.1)]])
    # Facing the camera the ray comes straight back; tilting the normal by a tilts it by 2a.
    np.testing.assert_allclose(zebra_parameter(normals, view, up), [0.0, 0.2], atol=1e-15)
    np.testing.assert_allclose(zebra_parameter(normals, view, up, 90.0), [0.0, 0.0], atol=1e-15)


def test_named_views_look_as_drawings_do():
    from export.render_camera import VIEWS, fit, frame

    expect = {  # (view direction, screen up, screen right)
        "front": ((0, 1, 0), (0, 0, 1), (1, 0, 0)),
        "right": ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
        "top": ((0, 0, -1), (0, 1, 0), (1, 0, 0)),
        "back": ((0, -1, 0), (0, 0, 1), (-1, 0, 0)),
    }
    for name, vectors in expect.items():
        np.testing.assert_allclose(np.array(frame(*VIEWS[name])), np.array(vectors, dtype=float), atol=1e-12)
    view, up, right = frame(*VIEWS["iso"])  # from front-right-top
    assert view @ [0, 1, 0] > 0 and view @ [-1, 0, 0] > 0 and view @ [0, 0, -1] > 0
    # the fitted camera puts the box's corners inside the viewport, filling it
    corners = np.array([[x, y, z] for x in (0, 4) for y in (0, 1) for z in (0, 2)], dtype=float)
    cam = fit(corners, *VIEWS["front"], (0, 0, 200, 100))
    xy = cam.project(corners)[:, :2]
    assert xy.min() >= 0 and xy[:, 0].max() <= 200 and xy[:, 1].max() <= 100
    assert np.ptp(xy[:, 0]) == pytest.approx(0.92 * 200)


def test_robust_range_ignores_spikes_and_is_symmetric_for_a_diverging_map():
    values = np.r_[np.linspace(-1.0, 2.0, 1000), 1e6, -1e5, np.nan]
    lo, hi = robust_range(values)
    assert lo == -hi and 1.8 < hi < 2.0
    weights = np.r_[np.ones(1000), 1e9, 1e-9, 1.0]  # the spike now covers most of the area
    assert robust_range(values, weights)[1] == 1e6
    assert robust_range(np.abs(values), diverging=False)[0] == 0.0


def test_iso_lines_lie_on_their_level_and_levels_are_round():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    triangles = np.array([[0, 1, 3], [0, 3, 2]])
    f = points @ np.array([0.3, 0.7, 0.0])  # linear: the segments are exact
    segs = iso_segments(points, triangles, f, (0.25, 0.5))
    assert len(segs) == 4
    np.testing.assert_allclose(np.sort(segs.reshape(-1, 3) @ [0.3, 0.7, 0.0]), [0.25] * 4 + [0.5] * 4)
    assert iso_levels(0.66) == (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    assert iso_levels(0.0) == ()


def test_the_graph_layout_of_a_support_is_a_planar_embedding():
    mesh = patching.read_mesh(REPO / "models" / "l_bracket.obj")
    ep = int(patching.Topology(mesh).extraordinary[0])
    operator = patching.build_operator(mesh)
    rows = np.unique(operator.matrix[:, ep].tocoo().row)
    faces_of_rows = np.concatenate([g.faces for g in operator.groups])
    starts = np.cumsum([0] + [len(g.faces) for g in operator.groups])
    support = set()
    for g, s0 in zip(operator.groups, starts):
        mine = rows[(rows >= g.row_offset) & (rows < g.row_offset + g.n_rows)]
        support |= set(faces_of_rows[s0 + (mine - g.row_offset) // (g.degree + 1) ** 2].tolist())
    faces = np.array(sorted(support))
    layout = region_layout(mesh, faces, mesh.name)
    assert np.allclose(np.linalg.norm(layout[ep]), 0.0, atol=0.35)  # the EP near the middle
    for f in faces.tolist():  # every face keeps its orientation: no fold in the layout
        q = np.array([layout[v] for v in mesh.face(f).tolist()])
        area = 0.5 * np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1])
        assert area > 0


# -- pixels ---------------------------------------------------------------------------------


def test_zebra_on_a_sphere_like_part_has_many_thin_stripes(tmp_path):
    image, _, _ = picture(CUBE, tmp_path, "cube", "zebra", size=(320, 240), supersample=2)  # default stripes
    part = drawn(image)
    grey = image.mean(axis=-1)
    row = 120
    inside = np.flatnonzero(part[row])
    dark = grey[row, inside[0] + 2 : inside[-1] - 2] < 60
    assert np.count_nonzero(dark[1:] != dark[:-1]) >= 20  # stripe edges along the middle line
    for band in (part & (grey < 60), part & (grey > 150)):
        labels, _n = ndimage.label(band)
        largest = np.bincount(labels.ravel())[1:].max()
        assert largest < 0.05 * part.sum()  # no flat black or white region
    # anti-aliased: stripe edges take intermediate greys (dark bands are below 16, light ones
    # above 120 even at grazing light), which a picture drawn without supersampling lacks
    jagged, _, _ = picture(CUBE, tmp_path, "jagged", "zebra", size=(320, 240), supersample=1)
    between = [np.mean((g > 40) & (g < 100) & drawn(im)) for im in (image, jagged) for g in [im.mean(axis=-1)]]
    assert between[0] > 0.02 and between[0] > 3 * between[1]


@pytest.mark.parametrize("crease", [True, False])
def test_a_g0_ridge_breaks_the_stripes_and_a_g1_ridge_does_not(tmp_path, crease):
    size = (240, 240)
    look = {"view": "top", "stripes": 6, "stripe_direction": 45.0, "supersample": 2}
    image, sampled, pic = picture(roof_mesh(crease=crease), tmp_path, f"tent{crease}", "zebra", size=size, **look)
    cam = cameras(sampled.points, size, pic, legend=False)[0]
    grey = image.mean(axis=-1) / 255.0
    x_ridge = round(cam.project(np.zeros((1, 3)))[0, 0])
    rows = slice(40, 200)  # inside the part, across its middle
    across = np.abs(grey[rows, x_ridge - 2] - grey[rows, x_ridge + 2]).mean()
    aside = np.abs(grey[rows, x_ridge - 42] - grey[rows, x_ridge - 38]).mean()  # a smooth place
    if crease:  # the bands jump across the ridge
        assert across > 0.4 and across > 5 * aside
    else:  # they bend across it: colours on both sides nearly alike
        assert across < 0.2 and across < 3 * aside


def test_curvature_legend_lies_beside_the_model_with_units(tmp_path, run_cli):
    out = tmp_path / "c.png"
    result = run_cli("render", REPO / "models" / "l_bracket.obj", "--curvature", "gaussian", "-o", out, "--size", "320x240", "-q")
    assert result.returncode == 0, result.stderr
    image = pixels(out)
    assert_drawn(image, (320, 240))
    columns = drawn(image).any(axis=0)
    gaps = np.flatnonzero(~columns)
    split = [g for g in gaps if columns[:g].any() and columns[g:].any()]
    assert split, "no white column between the model and the legend"
    model = drawn(image[:, : split[0]])
    legend = image[:, split[0] :]
    assert model.mean() > 0.2 and split[0] > 160
    saturated = np.ptp(legend, axis=-1) > 90  # the colour bar: reds and blues
    assert saturated.sum() > 200
    surface = patching.build(patching.read_mesh(REPO / "models" / "l_bracket.obj"))
    sampled = sample_surface(surface, 0.05)
    for mode, unit in (("mean", "1/mm"), ("gaussian", "1/mm²"), ("max-abs", "1/mm")):
        look = style(sampled, mode, Picture())
        assert look.legend[1] == unit
        lo, hi = look.range
        assert (lo == -hi) == (mode != "max-abs")
        values = {"mean": sampled.mean, "gaussian": sampled.gaussian}.get(mode)
        if values is not None:  # the spikes at corners and EPs do not set the range
            assert hi < 0.5 * np.nanmax(np.abs(values))


def test_blending_functions_mark_their_maxima_and_the_sheet_has_four_views(tmp_path):
    from export.render_blending import control_points, graph_sampled, surface_field

    mesh = patching.read_mesh(REPO / "models" / "l_bracket.obj")
    operator = patching.build_operator(mesh)
    surface = operator.evaluate(mesh.vertices)
    columns = control_points("ep", mesh, operator)
    m = 9
    sampled = surface_field(operator, surface, sample_surface(surface, 1.0, m=m), columns, m, "EPs")
    # one maximum a function ([FSLYJ]'s aim, kept on this mesh), marked at its highest sample
    assert len(sampled.field.markers) == len(columns)
    from patching.evaluation.sampling import column_values

    values = column_values(operator, columns, np.arange(surface.n_patches), m).reshape(-1, len(columns))
    at = np.linalg.norm(sampled.points[None] - sampled.field.markers[:, None], axis=-1).argmin(axis=1)
    assert np.linalg.norm(sampled.points[at] - sampled.field.markers, axis=1).max() < 1e-12
    np.testing.assert_allclose(values[at, np.arange(len(columns))], values.max(axis=0), rtol=1e-12)
    path = tmp_path / "b.png"
    render(sampled, path, "blending", (240, 180), picture=Picture(supersample=1))
    im = pixels(path)
    red = (im[..., 0] > 180) & (im[..., 1] < 60) & (im[..., 2] < 60)
    assert ndimage.label(red)[1] >= 3  # the maxima in view are marked
    graph = graph_sampled(operator, mesh, columns[:1], m, "EP")
    assert graph.field.values.max() == pytest.approx(graph.points[:, 2].max() / 0.7 * graph.field.values.max())
    assert np.abs(graph.points[:, 2]).min() < 1e-9  # down to zero at the support's rim
    render(graph, tmp_path / "g.png", "blending", (240, 180), picture=Picture(supersample=1))
    assert_drawn(pixels(tmp_path / "g.png"), (240, 180))
    image, _, _ = picture(CUBE, tmp_path, "sheet", "zebra", size=(240, 180), views=4, edges=True, supersample=1)
    for quadrant in (image[:90, :120], image[:90, 120:], image[90:, :120], image[90:, 120:]):
        assert 0.1 < drawn(quadrant).mean()


def test_another_surface_is_drawn_through_the_sources_hook(tmp_path, monkeypatch):
    from export import cli, cli_render
    from export.render import Sampled

    obj = tmp_path / "cube.obj"
    obj.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in CUBE.vertices)
                   + "".join("f " + " ".join(str(v + 1) for v in q) + "\n" for q in CUBE.quads()))

    def octahedron(args, mesh, pixel, lines):  # what another module would sample
        p = np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
        tri = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [1, 0, 5], [2, 1, 5], [3, 2, 5], [0, 3, 5]])
        assert 0 < pixel < 1 and mesh.n_faces == 6
        return Sampled(p, p.copy(), np.zeros(6), np.zeros(6), tri, np.zeros((0, 2, 3)))

    monkeypatch.setattr(cli_render, "SOURCES", [(lambda args: args.zebra, octahedron)])
    out = tmp_path / "o.png"
    assert cli.main(["render", str(obj), "--zebra", "-o", str(out), "--size", "120x90", "-q"]) == 0
    assert_drawn(pixels(out), (120, 90))


def test_matplotlib_fallback_draws_the_same_picture(tmp_path):
    vtk_image, _, _ = picture(CUBE, tmp_path, "v", "mean", size=(200, 150), supersample=1)
    mpl_image, _, _ = picture(CUBE, tmp_path, "m", "mean", size=(200, 150), renderer="matplotlib", supersample=1)
    assert_drawn(mpl_image, (200, 150))
    assert (drawn(vtk_image) != drawn(mpl_image)).mean() < 0.05  # same camera, same silhouette


@pytest.mark.parametrize("look, fragment", [
    ({"stripes": 0}, "--stripes 0"),
    ({"elevation": 100.0}, "-90 to 90"),
    ({"value_range": (1.0, 0.0)}, "LO < HI"),
    ({"views": 2}, "--views 2"),
])
def test_bad_picture_options_are_refused(look, fragment):
    with pytest.raises(patching.NupatchError, match=fragment.replace("(", r"\(")):
        Picture(**look)


@pytest.mark.parametrize("args, fragment", [
    (("--size", "big"), "WIDTHxHEIGHT"),
    (("-o", "{tmp}/x.jpg"), "must end in .png"),
    (("--zebra", "--curvature"), "not allowed with argument"),
    (("--graph",), "--graph draws a blending function"),
    (("--blending", "99999"), "control points (0 to"),
    (("--curvature", "--range", "1", "0"), "LO < HI"),
])
def test_cli_bad_render_options(tmp_path, run_cli, args, fragment):
    result = run_cli("render", TORUS, *(a.format(tmp=tmp_path) for a in args), *([] if "-o" in args else ["-o", tmp_path / "x.png"]))
    assert result.returncode == 2 and fragment in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and result.stderr.startswith("nupatch: error: ")
    assert list(tmp_path.iterdir()) == []
