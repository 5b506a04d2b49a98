"""Exactness against OpenCASCADE's own B-splines (docs/verification.md), read back from the STEP file.

Reference: a Geom_BSplineSurface built from the same poles and knots (docs/knots.md mapping),
split into Bézier patches by OCC's GeomConvert_BSplineSurfaceToBezierSurface.  Every face read
back from our STEP must carry the poles of one of those patches (up to re-parametrisation);
equal poles mean equal surfaces, and the largest pole difference bounds the distance.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from OCP.BRep import BRep_Tool
from OCP.Geom import Geom_BezierSurface, Geom_BSplineSurface
from OCP.GeomConvert import GeomConvert_BSplineSurfaceToBezierSurface
from OCP.gp import gp_Pnt
from export.ocp_compat import TColgp_Array2OfPnt
from export.ocp_compat import TColStd_Array1OfInteger, TColStd_Array1OfReal
from OCP.TopAbs import TopAbs_FACE
from OCP.TopExp import TopExp_Explorer
from export.ocp_compat import TopoDS

import patching
from export import read_step, to_step
from patching.mesh.primitives import open_grid, torus_grid
from tests.helpers import dihedral

# Relative to the mesh size: poles go through STEP as text with 15+ significant digits and
# through two different but exact algorithms (blossoms here, knot insertion in OCC).
EXACT = 1e-12


def _knots(intervals, clamp: bool):
    values = np.concatenate([[0.0], np.cumsum(intervals)])
    if clamp:  # drop the zero outer intervals: OCC wants distinct knots with multiplicities
        values, mults = np.unique(values, return_counts=True)
        mults[0] += 2 if mults[0] == 2 else 0
        mults[-1] += 2 if mults[-1] == 2 else 0
    else:
        mults = np.ones(values.size, dtype=int)
    k = TColStd_Array1OfReal(1, values.size)
    m = TColStd_Array1OfInteger(1, values.size)
    for i, (v, mu) in enumerate(zip(values, mults)):
        k.SetValue(i + 1, float(v))
        m.SetValue(i + 1, int(mu))
    return k, m


def _reference_patches(grid: np.ndarray, du, dv, periodic: bool) -> list[np.ndarray]:
    """OCC's Bézier patches of the B-spline with poles grid[a, b] (docs/knots.md)."""
    m, n, _ = grid.shape
    poles = TColgp_Array2OfPnt(1, m, 1, n)
    for k in range(1, m + 1):
        for l in range(1, n + 1):
            a, b = ((k - 2) % m, (l - 2) % n) if periodic else (k - 1, l - 1)
            poles.SetValue(k, l, gp_Pnt(*map(float, grid[a, b])))
    uk, um = _knots(du, clamp=not periodic)
    vk, vm = _knots(dv, clamp=not periodic)
    surf = Geom_BSplineSurface(poles, uk, vk, um, vm, 3, 3, periodic, periodic)
    conv = GeomConvert_BSplineSurfaceToBezierSurface(surf)
    out = []
    for i in range(1, conv.NbUPatches() + 1):
        for j in range(1, conv.NbVPatches() + 1):
            out.append(_poles(conv.Patch(i, j)))
    return out


def _poles(surface) -> np.ndarray:
    nu, nv = surface.NbUPoles(), surface.NbVPoles()
    return np.array([[[surface.Pole(i, j).X(), surface.Pole(i, j).Y(), surface.Pole(i, j).Z()] for j in range(1, nv + 1)] for i in range(1, nu + 1)])


def _step_face_poles(path) -> list[np.ndarray]:
    shape = read_step(path)
    out = []
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        handle = BRep_Tool.Surface_s(TopoDS.Face_s(explorer.Current()))
        assert isinstance(handle, (Geom_BSplineSurface, Geom_BezierSurface)), type(handle)
        out.append(_poles(handle))
        explorer.Next()
    return out


def _assert_same_patch_sets(ours: list[np.ndarray], reference: list[np.ndarray], size: float) -> float:
    worst = 0.0
    centres = np.array([r.mean(axis=(0, 1)) for r in reference])
    for net in ours:
        candidates = np.argsort(np.linalg.norm(centres - net.mean(axis=(0, 1)), axis=1))[:4]
        best = min(
            np.abs(t - net).max() for c in candidates for t in dihedral(reference[c]) if t.shape == net.shape
        )
        worst = max(worst, best)
    assert worst <= EXACT * size, f"largest pole difference {worst / size:.3e} of the size"
    return worst


@settings(max_examples=6, deadline=None)
@given(st.integers(4, 8), st.integers(4, 7), st.integers(0, 2**31))
def test_torus_step_faces_lie_on_occ_periodic_bspline(tmp_path_factory, m, n, seed):
    rng = np.random.default_rng(seed)
    du, dv = rng.uniform(1, 20, m), rng.uniform(1, 20, n)  # max/min up to 20
    mesh = torus_grid(m, n, du, dv, name="torus")
    mesh = mesh.with_positions(mesh.vertices + rng.normal(scale=0.1, size=mesh.vertices.shape))
    path = tmp_path_factory.mktemp("exact") / "torus.step"
    surface = patching.build(mesh)
    to_step(surface, path)
    ours = _step_face_poles(path)
    assert len(ours) == m * n
    reference = _reference_patches(mesh.vertices.reshape(m, n, 3), du, dv, periodic=True)
    _assert_same_patch_sets(ours, reference, surface.size)


def test_clamped_open_grid_equals_occ_clamped_bspline(tmp_path):
    du = [0, 1, 2.5, 1, 4, 0]
    dv = [0, 3, 1, 1, 0]
    mesh = open_grid(7, 6, du, dv, name="grid")
    rng = np.random.default_rng(3)
    mesh = mesh.with_positions(mesh.vertices + rng.normal(scale=0.2, size=mesh.vertices.shape))
    surface = patching.build(mesh)
    path = tmp_path / "grid.step"
    to_step(surface, path)
    ours = _step_face_poles(path)
    assert len(ours) == 4 * 3
    reference = _reference_patches(mesh.vertices.reshape(7, 6, 3), du, dv, periodic=False)
    assert len(reference) == 4 * 3
    _assert_same_patch_sets(ours, reference, surface.size)


def test_a_wrong_interval_is_detected(tmp_path):
    """The comparison can fail: the same poles with one interval changed do not match."""
    du, dv = [1, 2, 3, 1, 1], [1, 1, 2, 1]
    mesh = torus_grid(5, 4, du, dv)
    path = tmp_path / "t.step"
    to_step(patching.build(mesh), path)
    wrong = _reference_patches(mesh.vertices.reshape(5, 4, 3), [1, 2, 4, 1, 1], dv, periodic=True)
    with pytest.raises(AssertionError, match="largest pole difference"):
        _assert_same_patch_sets(_step_face_poles(path), wrong, 1.0)
