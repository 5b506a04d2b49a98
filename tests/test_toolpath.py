"""Tool paths ([FSLYJ] sec. 4.3): segmentation, Fermat spiral, and an independent check of the
G-code: parsed back, ball centres densified, against dense samples of the BezierSurface taken
with ``patching.evaluation.sample_surface`` (not the tool path's own evaluator), in KD-trees."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import export
import patching
from patching.evaluation import evaluate_nets, sample_surface
from patching.mesh.primitives import open_grid
from patching.toolpath import fermat_spiral, segment, tool_path
from patching.bernstein import common_nets
from patching.toolpath.path import side_normals, up_faces
from patching.toolpath.segmentation import cut_weight, dual_edges, spanning_tree
from patching.topology.features import sharp_edges

REPO = Path(__file__).resolve().parents[1]
MODELS = REPO / "models"


# -- independent helpers ---------------------------------------------------------------------
def segments_cross(p: np.ndarray) -> bool:
    """True when two non-adjacent segments of the polyline p (N, 2) intersect or touch
    (orientation tests on every pair whose midpoints lie within the longest segment's length,
    which includes every pair that meets)."""
    a, b = p[:-1], p[1:]
    scale = np.abs(p).max() + 1.0
    eps = 1e-12 * scale * scale
    reach = np.linalg.norm(b - a, axis=1).max() * (1 + 1e-9) + 2e-9 * scale
    pairs = cKDTree(0.5 * (a + b)).query_pairs(reach, output_type="ndarray")
    i, j = np.sort(pairs, axis=1).T
    i, j = i[j > i + 1], j[j > i + 1]

    def orient(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    ai, bi, aj, bj = a[i], b[i], a[j], b[j]
    d1, d2 = orient(ai, bi, aj), orient(ai, bi, bj)
    d3, d4 = orient(aj, bj, ai), orient(aj, bj, bi)
    if np.any((d1 * d2 < -eps) & (d3 * d4 < -eps)):
        return True
    # touching: an end point of one segment on the other segment
    for x, s0, s1 in ((aj, ai, bi), (bj, ai, bi), (ai, aj, bj), (bi, aj, bj)):
        ab = s1 - s0
        t = np.clip(np.sum((x - s0) * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-300), 0, 1)
        if np.any(np.linalg.norm(x - (s0 + t[:, None] * ab), axis=-1) < 1e-9 * scale):
            return True
    return False


def parse_gcode(text: str):
    """Moves of a program as (kind 'G0'/'G1', x, y, z) after modal completion, plus header lines."""
    pos = np.array([np.nan, np.nan, np.nan])
    moves = []
    for line in text.splitlines():
        code = re.sub(r"\(.*?\)", "", line).strip()
        if not code:
            continue
        words = {w[0]: w[1:] for w in code.split()}
        if "G" in words and words["G"] in ("0", "1") and any(k in words for k in "XYZ"):
            for axis, k in enumerate("XYZ"):
                if k in words:
                    pos[axis] = float(words[k])
            moves.append(("G" + words["G"], *pos))
    return moves


def densify(points: np.ndarray, step: float) -> np.ndarray:
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    out = [points[:1]]
    for a, b, s in zip(points[:-1], points[1:], seg):
        k = max(int(np.ceil(s / step)), 1)
        out.append(a + np.outer(np.arange(1, k + 1) / k, b - a))
    return np.concatenate(out)


def bump_grid() -> patching.ControlMesh:
    """Open clamped 10 x 8 grid with a round bump of height 0.8 and a dip (ours)."""
    g = open_grid(10, 8, [0, 1, 1, 2, 1, 1, 1, 1, 0], [0, 1, 1, 1, 2, 1, 0], height=0.0, name="bump")
    v = g.vertices.copy()
    r2 = (v[:, 0] - 4.0) ** 2 + (v[:, 1] - 3.5) ** 2
    v[:, 2] = 0.8 * np.exp(-r2 / 3.0) - 0.3 * np.exp(-((v[:, 0] - 7.0) ** 2 + (v[:, 1] - 2.0) ** 2) / 1.5)
    return g.with_positions(v)


def check_program(mesh_path, out: Path, radius: float, scallop: float, tolerance: float, report: dict):
    """The independent check of the acceptance list on a written program.  mesh_path: the
    control mesh (sampled by ``sample_surface``), or (points, unit normals) sampled elsewhere."""
    if isinstance(mesh_path, tuple):
        pts, nrm = mesh_path
    else:
        _, pts, nrm = sample_surface(patching.build(patching.read_mesh(mesh_path)), 41)
    text = out.read_text()
    assert "G21" in text and "G90" in text and f"radius {radius:g}" in text
    moves = parse_gcode(text)
    kinds = [m[0] for m in moves]
    pieces = report["pieces"]
    assert kinds.count("G0") <= pieces + 2
    # Pieces: runs of G1 between rapids; each continuous (no rapid inside), all G1 inside.
    runs, current = [], []
    for kind, *p in moves:
        if kind == "G0":
            if current:
                runs.append(np.array(current))
            current = []
        else:
            current.append(p)
    runs.append(np.array(current))
    runs = [r for r in runs if len(r)]
    assert len(runs) == pieces
    # Dense samples of the surface (independent evaluator), KD-tree.
    pts, nrm = pts.reshape(-1, 3), nrm.reshape(-1, 3)
    tree = cKDTree(pts)
    centres = []
    for run in runs:  # each run starts with its plunge and ends with its retract
        c = run + np.array([0.0, 0.0, radius])
        centres.append(densify(c, 0.25 * np.sqrt(radius * tolerance)))
    dense = np.concatenate(centres)
    d, _ = tree.query(dense)
    assert d.min() >= radius - tolerance, f"gouge: a ball centre {d.min():.6f} from the surface"
    # Coverage: every reachable up-facing sample within H + T of a ball.
    up = nrm[:, 2] >= 0.1
    touch, _ = tree.query(pts[up] + radius * nrm[up])
    reach = touch >= radius - tolerance
    assert reach.mean() > 0.95
    dist, _ = cKDTree(dense).query(pts[up][reach])
    assert (dist - radius).max() <= scallop + tolerance, f"scallop {(dist - radius).max():.5f}"
    return runs


@pytest.fixture(scope="module")
def bump_obj(tmp_path_factory):
    path = tmp_path_factory.mktemp("tp") / "bump.obj"
    export.write_obj(bump_grid(), path)
    return path


# -- spiral ----------------------------------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(
    st.integers(1, 4),
    st.integers(1, 4),
    st.lists(st.floats(0.1, 10.0), min_size=3, max_size=3),
    st.lists(st.floats(0.1, 10.0), min_size=3, max_size=3),
)
def test_spiral_simple_boundary_ends_and_coverage(nu, nv, du, dv):
    """The connected Fermat spiral starts and ends on the rectangle's boundary (opposite
    corners), never crosses itself, and every point of the rectangle lies within half a pass of
    it in the density's metric (g constant per third of each side, neighbouring thirds up to
    100x apart)."""
    check_spiral(nu, nv, du, dv)


def test_spiral_coverage_across_a_sixfold_density_jump():
    """Found by hypothesis over densities 0.5..6 in a first version that placed the points
    along each side linearly in (u, v): the third of density 6 beside two of density 1 was
    covered to 0.54 passes, not 0.5."""
    check_spiral(2, 3, [1.0, 1.0, 6.0], [1.0, 1.25, 2.75])


def check_spiral(nu, nv, du, dv):
    ug, vg = np.linspace(0, nu, 61), np.linspace(0, nv, 61)
    gu = np.array(du)[np.minimum((ug / nu * 3).astype(int), 2)]
    gv = np.array(dv)[np.minimum((vg / nv * 3).astype(int), 2)]
    path = fermat_spiral(ug, gu, vg, gv)
    assert np.allclose(path[0], [0, 0]) and np.allclose(path[-1], [nu, nv])
    assert np.all(path >= -1e-12) and np.all(path <= np.array([nu, nv]) + 1e-12)
    assert not segments_cross(path)
    # coverage in pass units: map u -> G_u(u), v -> G_v(v) (passes), distances there <= 0.5 + slack
    def passes(x, grid, g):
        c = np.concatenate([[0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(grid))])
        return np.interp(x, grid, c)

    dense = densify(path, 0.01)
    q = np.stack([passes(dense[:, 0], ug, gu), passes(dense[:, 1], vg, gv)], 1)
    a, b = np.meshgrid(np.linspace(0, nu, 80), np.linspace(0, nv, 80), indexing="ij")
    probe = np.stack([passes(a.ravel(), ug, gu), passes(b.ravel(), vg, gv)], 1)
    d, _ = cKDTree(q).query(probe)
    assert d.max() <= 0.5 + 0.02  # half a pass, contour corners included


def test_segments_cross_detects_a_crossing():
    assert segments_cross(np.array([[0, 0], [1, 1], [1, 0], [0, 1.0]]))
    assert not segments_cross(np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]))


# -- segmentation ----------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["clamped_grid", "l_bracket", "square_frame", "machined_bracket", "torus_nonuniform"])
@pytest.mark.parametrize("method", ["tree", "greedy", "best"])
def test_segmentation_covers_up_faces_once_with_one_parametrisation(name, method):
    """Every up-facing face in exactly one piece; the cells of a piece meet pointwise along
    their shared sides; no piece spans a sharp edge (the features' crease tags)."""
    mesh = patching.read_mesh(MODELS / f"{name}.obj")
    surface = patching.build(mesh)
    faces, nets, _ = common_nets(surface)
    up = up_faces(faces, nets)
    up &= mesh.face_sizes[faces] == 4
    pieces = segment(mesh, faces[up], side_normals(mesh, faces, nets), method=method)
    covered = np.concatenate([p.faces.ravel() for p in pieces])
    assert np.array_equal(np.sort(covered), np.sort(faces[up]))  # every face in exactly one piece
    coeff = {int(f): c for g in surface.groups for f, c in zip(g.faces, g.coefficients)}
    u = np.linspace(0, 1, 7)
    for p in pieces:
        nu, nv = p.shape
        # turn every net into piece coordinates and check the grid's neighbours meet
        # pointwise along their shared sides (one map of the rectangle), with the patches'
        # own evaluator.
        def side(i, j, which, p=p):
            net = np.rot90(coeff[int(p.faces[i, j])], -int(p.rotation[i, j]), axes=(0, 1))
            s, t = {"right": (np.ones(7), u), "left": (np.zeros(7), u), "top": (u, np.ones(7)), "bottom": (u, np.zeros(7))}[which]
            return evaluate_nets(net[None], s, t)[0]

        scale = surface.size
        for i in range(nu):
            for j in range(nv):
                if i + 1 < nu:
                    assert np.abs(side(i, j, "right") - side(i + 1, j, "left")).max() < 1e-9 * scale
                if j + 1 < nv:
                    assert np.abs(side(i, j, "top") - side(i, j + 1, "bottom")).max() < 1e-9 * scale
    topo = patching.Topology(mesh)
    sharp = sharp_edges(topo)
    for p in pieces:
        for a, b in [(p.faces[i, j], p.faces[i + 1, j]) for i in range(p.shape[0] - 1) for j in range(p.shape[1])] + [
            (p.faces[i, j], p.faces[i, j + 1]) for i in range(p.shape[0]) for j in range(p.shape[1] - 1)
        ]:
            shared = np.intersect1d(mesh.face(int(a)), mesh.face(int(b)))
            assert shared.size == 2
            assert not sharp[topo.edge_id(int(shared[0]), int(shared[1]))]
    if name == "machined_bracket":
        assert sharp.any()
    if name == "clamped_grid":
        assert len(pieces) == 1 and pieces[0].shape in ((6, 4), (4, 6))


def kruskal_weight(n: int, a: np.ndarray, b: np.ndarray, w: np.ndarray) -> tuple[float, int]:
    """Textbook Kruskal with a union-find: (total weight, edge count) of a minimum spanning forest."""
    parent = list(range(n))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    total, count = 0.0, 0
    for k in np.argsort(w, kind="stable"):
        ra, rb = find(int(a[k])), find(int(b[k]))
        if ra != rb:
            parent[ra] = rb
            total += float(w[k])
            count += 1
    return total, count


@pytest.mark.parametrize("name", ["l_bracket", "square_frame"])
def test_segmentation_tree_is_a_minimum_spanning_tree_and_best_cuts_least(name):
    """The tree the segmentation starts from is a minimum spanning forest of the dual graph
    (its weight and size equal a textbook Kruskal's), and the kept segmentation's total cut
    weight is no higher than either method's (the plain greedy's included)."""
    mesh = patching.read_mesh(MODELS / f"{name}.obj")
    surface = patching.build(mesh)
    faces, nets, _ = common_nets(surface)
    up = up_faces(faces, nets) & (mesh.face_sizes[faces] == 4)
    normals = side_normals(mesh, faces, nets)
    f, kf, g, _, w = dual_edges(mesh, faces[up], normals)
    chosen = spanning_tree(mesh.n_faces, f, g, w)
    total, count = kruskal_weight(mesh.n_faces, f, g, w)
    assert chosen.sum() == count and w[chosen].sum() == pytest.approx(total, rel=1e-12)
    costs = {m: cut_weight(segment(mesh, faces[up], normals, method=m), f, kf, g, w) for m in ("tree", "greedy", "best")}
    assert costs["best"] <= min(costs["tree"], costs["greedy"]) + 1e-9
    assert costs["best"] > 0  # these models need cuts


# -- whole command, independent check --------------------------------------------------------
def test_bump_grid_program_checks(bump_obj, tmp_path, run_cli):
    out = tmp_path / "bump.nc"
    r, h = 0.5, 0.02
    res = run_cli("toolpath", bump_obj, "-o", out, "--tool", f"ball:{r}", "--scallop", h, "--json")
    assert res.returncode == 0, res.stderr
    import json

    report = json.loads(res.stdout)
    t = report["tolerance"]
    assert t == pytest.approx(h / 4)
    assert report["max_scallop"] <= h and report["max_chord_error"] <= t and report["min_clearance"] >= r - t
    assert report["time_min"] == pytest.approx(report["cut_length"] / 1000.0 + report["rapid_length"] / 5000.0)
    check_program(bump_obj, out, r, h, t, report)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["l_bracket", "machined_bracket", "square_frame", "clamped_grid"])
def test_shipped_model_program_checks(name, tmp_path, run_cli):
    src = MODELS / f"{name}.obj"
    out = tmp_path / f"{name}.gcode"
    r, h, t = 0.4, 0.02, 0.004
    res = run_cli("toolpath", src, "-o", out, "--tool", f"ball:{r}", "--scallop", h, "--tolerance", t, "--json", "--picture", tmp_path / "p.png")
    assert res.returncode == 0, res.stderr
    import json

    report = json.loads(res.stdout)
    assert report["pieces"] >= (1 if name == "clamped_grid" else 2)
    check_program(src, out, r, h, t, report)
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_python_api_spiral_enters_and_leaves_at_boundary_and_is_simple():
    mesh = bump_grid()
    surface = patching.build(mesh)
    tp = tool_path(surface, mesh, 0.5, 0.03)
    assert tp.centres.shape == tp.normals.shape == tp.contacts.shape == (len(tp.piece), 3)
    assert np.allclose(tp.tips, tp.centres - [0, 0, 0.5])
    assert np.allclose(np.linalg.norm(tp.normals, axis=1), 1.0)
    for k, piece in enumerate(tp.pieces):
        uv = tp.parameters[tp.piece == k]
        nu, nv = piece.shape
        for end in (uv[0], uv[-1]):
            assert min(end[0], end[1], nu - end[0], nv - end[1]) < 1e-9
        assert not segments_cross(uv)


# -- bad input -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "extra",
    [
        ["--tool", "ball:0", "--scallop", "0.01"],
        ["--tool", "ball:-1", "--scallop", "0.01"],
        ["--tool", "ball:nan", "--scallop", "0.01"],
        ["--tool", "flat:1", "--scallop", "0.01"],
        ["--tool", "ball:0.5", "--scallop", "0.5"],
        ["--tool", "ball:0.5", "--scallop", "0.9"],
        ["--tool", "ball:0.5", "--scallop", "nan"],
        ["--tool", "ball:0.5", "--scallop", "0.01", "--tolerance", "nan"],
        ["--tool", "ball:0.5", "--scallop", "0.01", "--tolerance", "0"],
        ["--tool", "ball:0.5", "--scallop", "0.01", "--feed", "nan"],
        ["--tool", "ball:0.5", "--scallop", "0.01", "--feed", "-5"],
    ],
)
def test_bad_parameters_exit_2_one_line_no_file(extra, bump_obj, tmp_path, capsys):
    from export.cli import main

    out = tmp_path / "x.nc"
    code = main(["toolpath", str(bump_obj), "-o", str(out), *extra])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("nupatch: error:")
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_nothing_facing_up_and_nan_mesh(tmp_path, run_cli):
    down = bump_grid()
    flipped = patching.from_arrays(down.vertices, np.array([f[::-1] for f in down.quads()]))
    export.write_obj(flipped, tmp_path / "down.obj")
    lines = (tmp_path / "down.obj").read_text().splitlines()
    first_v = next(i for i, line in enumerate(lines) if line.startswith("v "))
    parts = lines[first_v].split()
    parts[3] = "nan"
    lines[first_v] = " ".join(parts)
    (tmp_path / "nan.obj").write_text("\n".join(lines) + "\n")
    for src, word in ((tmp_path / "down.obj", "faces up"), (tmp_path / "nan.obj", "")):
        out = tmp_path / f"{src.stem}.nc"
        res = run_cli("toolpath", src, "-o", out, "--tool", "ball:0.5", "--scallop", "0.02", "--picture", tmp_path / "p.png")
        assert res.returncode == 2, res.stderr
        err = res.stderr.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("nupatch: error:") and word in err[0]
        assert not out.exists() and not (tmp_path / "p.png").exists()


def test_bad_output_suffix(bump_obj, tmp_path, capsys):
    from export.cli import main

    code = main(["toolpath", str(bump_obj), "-o", str(tmp_path / "x.txt"), "--tool", "ball:0.5", "--scallop", "0.02"])
    assert code == 2 and len(capsys.readouterr().err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


# -- torus, STEP input -----------------------------------------------------------------------
def test_closed_torus_program_checks(tmp_path, capsys):
    """A closed torus control mesh (non-uniform knots, one zero strip) through the whole
    command (in-process): the up-facing half machined without gouge within H + T."""
    from export.cli import main

    src = MODELS / "torus_nonuniform.obj"
    out = tmp_path / "torus.nc"
    r, h = 0.5, 0.05
    code = main(["toolpath", str(src), "-o", str(out), "--tool", f"ball:{r}", "--scallop", str(h), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    import json

    report = json.loads(captured.out)
    check_program(src, out, r, h, report["tolerance"], report)


def occ_samples(step: Path, n: int = 41) -> tuple[np.ndarray, np.ndarray]:
    """Points and outward unit normals on an n x n grid of every face of a STEP file, by
    OpenCASCADE's own surfaces (``Geom_Surface.D1``; REVERSED faces flipped)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepTools import BRepTools
    from OCP.gp import gp_Pnt, gp_Vec
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer

    from export.ocp_compat import TopoDS

    pts, nrm = [], []
    explorer = TopExp_Explorer(export.read_step(step), TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face_s(explorer.Current())
        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
        surf = BRep_Tool.Surface_s(face)
        sign = -1.0 if face.Orientation() == TopAbs_REVERSED else 1.0
        for u in np.linspace(u0, u1, n):
            for v in np.linspace(v0, v1, n):
                p, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
                surf.D1(u, v, p, du, dv)
                c = np.cross([du.X(), du.Y(), du.Z()], [dv.X(), dv.Y(), dv.Z()]) * sign
                pts.append([p.X(), p.Y(), p.Z()])
                nrm.append(c / max(np.linalg.norm(c), 1e-300))
        explorer.Next()
    return np.array(pts), np.array(nrm)


def test_step_input_program_checks(bump_obj, tmp_path, capsys):
    """``toolpath PART.step``: the bump exported as STEP (one B-spline face per patch), read
    back through OpenCASCADE, its faces welded into one rectangle of patches (one piece, as
    from the mesh), and the program checked against OpenCASCADE's own samples of the file."""
    step = tmp_path / "bump.step"
    export.to_step(patching.build(patching.read_mesh(bump_obj)), step)
    out = tmp_path / "bump.nc"
    r, h = 0.5, 0.03
    from export.cli import main

    code = main(["toolpath", str(step), "-o", str(out), "--tool", f"ball:{r}", "--scallop", str(h), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    import json

    report = json.loads(captured.out)
    assert report["pieces"] == 1
    check_program(occ_samples(step, 25), out, r, h, report["tolerance"], report)


def test_step_trimmed_or_rational_faces_refused(tmp_path, capsys):
    """A triangular plane face (trimmed) and a cylinder (rational faces): one line naming the
    face, exit 2, no file."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakePolygon
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Pnt

    poly = BRepBuilderAPI_MakePolygon(gp_Pnt(0, 0, 0), gp_Pnt(4, 0, 0), gp_Pnt(0, 4, 0), True)
    export.write_step(BRepBuilderAPI_MakeFace(poly.Wire(), True).Face(), tmp_path / "tri.step", "tri")
    export.write_step(BRepPrimAPI_MakeCylinder(2.0, 3.0).Shape(), tmp_path / "cyl.step", "cyl")
    for name, word in (("tri", "trimmed"), ("cyl", "rational")):
        out = tmp_path / f"{name}.nc"
        from export.cli import main

        code = main(["toolpath", str(tmp_path / f"{name}.step"), "-o", str(out), "--tool", "ball:0.5", "--scallop", "0.02"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2, err
        assert len(err) == 1 and err[0].startswith("nupatch: error:") and word in err[0] and "face" in err[0], err
        assert not out.exists()
