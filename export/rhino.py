"""Rhino ``.3dm`` output through rhino3dm (docs/cli.md): one NurbsSurface per patch.

A Bézier patch of degree d with the (d+1, d+1) net P_ij is the NURBS surface of order d+1 in
both directions with the knot vectors [0]*d + [1]*d (Rhino omits the two end knots that
OpenCASCADE and STEP repeat) and weights 1, poles P_ij at (u, v) index (i, j), so the surface
point at (u, v) is the patch point at (s, t) = (u, v), exactly as in the STEP face built from
the same net (``export.brep``).  Units: millimetres.  Each surface is an object named
``<product> face <mesh face id>`` (and ``patch <row>`` in its user strings), so that a Rhino
user finds the face the patch came from.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from patching.errors import NupatchError
from patching.surface import BezierSurface

__all__ = ["RHINO_VERSION", "nurbs_surface", "write_3dm"]

#: The .3dm file version written (Rhino 7 and 8 read it).
RHINO_VERSION = 7


def _rhino3dm():
    try:
        import rhino3dm
    except ModuleNotFoundError:
        raise NupatchError("writing .3dm needs rhino3dm: pip install 'nupatch[rhino]'", "3dm") from None
    return rhino3dm


def nurbs_surface(net: np.ndarray):
    """The ``rhino3dm.NurbsSurface`` of one Bézier net (d+1, d+1, 3) (module docstring)."""
    r = _rhino3dm()
    n = net.shape[0]
    d = n - 1
    srf = r.NurbsSurface.Create(3, False, n, n, n, n)
    for k in range(2 * d):
        knot = 0.0 if k < d else 1.0
        srf.KnotsU[k] = knot
        srf.KnotsV[k] = knot
    for i in range(n):
        for j in range(n):
            x, y, z = (float(c) for c in net[i, j])
            srf.Points[i, j] = r.Point4d(x, y, z, 1.0)
    return srf


def write_3dm(surface: BezierSurface, path: str | Path) -> None:
    """Write every patch of ``surface`` to the .3dm file ``path`` (not atomic by itself: the
    format registry calls it on the temporary file of ``export.atomic.atomic_output``)."""
    r = _rhino3dm()
    model = r.File3dm()
    model.Settings.ModelUnitSystem = r.UnitSystem.Millimeters
    model.ApplicationName = "nupatch"
    for row, _, face, net in surface.patches():
        attributes = r.ObjectAttributes()
        attributes.Name = f"{surface.name} face {face}"
        attributes.SetUserString("nupatch.patch", str(row))
        attributes.SetUserString("nupatch.face", str(face))
        model.Objects.AddSurface(nurbs_surface(net), attributes)
    if not model.Write(str(path), RHINO_VERSION):
        raise RuntimeError(f"rhino3dm could not write {path}")
