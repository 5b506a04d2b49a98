"""Rhino .3dm output (export/rhino.py): read back with rhino3dm itself and compared point by
point with the faces of the STEP file of the same build."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

rhino3dm = pytest.importorskip("rhino3dm")

import patching  # noqa: E402
from export.formats import FORMATS, write  # noqa: E402
from export.step import read_step  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
GRID = np.linspace(0.0, 1.0, 7)


def step_face_points(path: Path) -> list[np.ndarray]:
    """(49, 3) points of every STEP face's surface on a 7 x 7 parameter grid, face order."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp

    from export.ocp_compat import TopoDS, TopTools_IndexedMapOfShape

    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(read_step(path), TopAbs_FACE, faces)
    out = []
    for k in range(1, faces.Extent() + 1):
        srf = BRep_Tool.Surface_s(TopoDS.Face_s(faces.FindKey(k)))
        u0, u1, v0, v1 = srf.Bounds()
        assert (u0, u1, v0, v1) == (0.0, 1.0, 0.0, 1.0)
        out.append(np.array([srf.Value(u, v).Coord() for u in GRID for v in GRID]))
    return out


def rhino_surface_points(path: Path):
    model = rhino3dm.File3dm.Read(str(path))
    assert model.Settings.ModelUnitSystem == rhino3dm.UnitSystem.Millimeters
    names, points = [], []
    for obj in model.Objects:
        srf = obj.Geometry
        assert isinstance(srf, rhino3dm.NurbsSurface)
        du, dv = srf.Domain(0), srf.Domain(1)
        assert (du.T0, du.T1, dv.T0, dv.T1) == (0.0, 1.0, 0.0, 1.0)
        names.append(obj.Attributes.Name)
        pts = []
        for u in GRID:
            for v in GRID:
                p = srf.PointAt(u, v)
                pts.append((p.X, p.Y, p.Z))
        points.append(np.array(pts))
    return names, points


@pytest.mark.parametrize("model", ["l_bracket", "machined_bracket"])
def test_3dm_surfaces_equal_the_step_faces(tmp_path, model):
    mesh = patching.read_mesh(REPO / "models" / f"{model}.obj")
    surface = patching.build(mesh)
    write(surface, tmp_path / "a.step")
    write(surface, tmp_path / "a.3dm")
    names, rhino = rhino_surface_points(tmp_path / "a.3dm")
    step = step_face_points(tmp_path / "a.step")
    assert len(rhino) == len(step) == surface.n_patches
    faces = [face for _, _, face, _ in surface.patches()]
    assert names == [f"{model} face {f}" for f in faces]
    # match each STEP face to the 3dm surface through its centre, then compare all 49 points
    centres = np.array([p[24] for p in rhino])
    worst = 0.0
    used = set()
    for pts in step:
        k = int(np.argmin(np.linalg.norm(centres - pts[24], axis=1)))
        used.add(k)
        worst = max(worst, float(np.abs(rhino[k] - pts).max()))
    assert len(used) == len(step)  # one to one
    assert worst <= 1e-9 * surface.size, worst


def test_3dm_through_the_cli_and_the_registry(tmp_path, run_cli):
    assert "3dm" in FORMATS
    out = tmp_path / "part.3dm"
    result = run_cli("build", REPO / "models" / "clamped_grid.obj", "-o", out, "-q")
    assert result.returncode == 0, result.stderr
    model = rhino3dm.File3dm.Read(str(out))
    mesh = patching.read_mesh(REPO / "models" / "clamped_grid.obj")
    surface = patching.build(mesh)
    assert len(model.Objects) == surface.n_patches  # faces on its zero-interval (clamping) strips give none
    assert sorted(o.Attributes.Name for o in model.Objects) == sorted(f"clamped_grid face {f}" for _, _, f, _ in surface.patches())
    assert all(o.Geometry.IsValid for o in model.Objects)
    assert {o.Geometry.Degree(0) for o in model.Objects} <= {3, 5}
    result = run_cli("build", REPO / "models" / "clamped_grid.obj", "-o", tmp_path / "x.out", "--format", "3dm", "-q")
    assert result.returncode == 0 and (tmp_path / "x.out").stat().st_size > 0


def test_without_rhino3dm_one_line_names_the_extra(tmp_path):
    code = (
        "import sys; sys.modules['rhino3dm'] = None\n"
        "from export.cli import main\n"
        f"sys.exit(main(['build', {str(REPO / 'models' / 'clamped_grid.obj')!r}, '-o', {str(tmp_path / 'a.3dm')!r}, '-q']))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                            env=dict(os.environ, PYTHONPATH=str(REPO)))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "nupatch[rhino]" in lines[0], result.stderr
    assert not list(tmp_path.iterdir())
