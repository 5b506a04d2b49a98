"""The one place that knows which OpenCASCADE Python wheel (``OCP``) is installed.

OpenCASCADE reaches Python as the module ``OCP``, shipped by two wheels that write the same
files: ``cadquery-ocp`` (with VTK; cadquery 2.8 needs 7.9) and ``cadquery-ocp-novtk``
(build123d 0.12 needs 7.9, build123d 0.13 needs 8.0).  nupatch depends on neither: its
metadata asks for ``cadquery-ocp-proxy`` (the version tracker both wheels depend on) within the
supported range, and uses whichever wheel the user's CAD stack brought.  This module

- checks, once, at import: an ``OCP`` module must be present, come from one wheel only (two
  wheels overwrite each other's files, and ``pip check`` does not notice), and have a supported
  version (7.9 or 8.0).  Otherwise it raises ``OcpError``: one line saying what is wrong and
  the one command that repairs it;
- re-exports the OCP names that changed between versions under their OCP 7.9 names.  OCP 8.0
  made ``TopoDS`` (the casts ``TopoDS.Face_s``...) a namespace of plain functions, and moved the NCollection instances (``TColgp_Array2OfPnt``, ``TColStd_Array1OfReal``,
  ``TopTools_IndexedMapOfShape``, ...) from their toolkit modules to ``OCP.collections``
  under template names (``Array2_gp_Pnt``, ``Array1_double``,
  ``IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher``).  Every other module of ``export``
  imports these names from here, never from ``OCP`` directly.

``ocp_status()`` reports the same findings without raising (for ``nupatch`` and the tests).
"""

from __future__ import annotations

import importlib.metadata as md
from dataclasses import dataclass

from patching.errors import NupatchError

__all__ = [
    "SUPPORTED",
    "OcpError",
    "OcpStatus",
    "ocp_status",
    "require_ocp",
    "OCP_VERSION",
    "TopoDS",
    "TColgp_Array1OfPnt",
    "TColgp_Array1OfPnt2d",
    "TColgp_Array2OfPnt",
    "TColStd_Array1OfInteger",
    "TColStd_Array1OfReal",
    "TColStd_IndexedDataMapOfStringString",
    "TopTools_IndexedDataMapOfShapeListOfShape",
    "TopTools_IndexedMapOfShape",
    "import_cad_library",
    "box_bounds",
]

#: OpenCASCADE (major, minor) versions nupatch is tested on.
SUPPORTED = ((7, 9), (8, 0))
#: The wheels that install the ``OCP`` module, and the pip requirement of a supported one.
WHEELS = ("cadquery-ocp", "cadquery-ocp-novtk")
SUPPORTED_RANGE = ">=7.9.3,<8.1"
#: The extra of nupatch that brings an OpenCASCADE wheel where none is installed.
OCP_EXTRA = "pip install 'nupatch[ocp]'"


class OcpError(NupatchError, ImportError):
    """No usable OpenCASCADE: missing, two wheels mixed, or an unsupported version."""


@dataclass(frozen=True)
class OcpStatus:
    """What is installed: ``wheels`` {distribution: version}; ``module_version`` the ``OCP``
    module's own ``__version__`` (None if it does not import); ``problem`` the one-line
    diagnosis with its repair command, or None when OCP is usable."""

    wheels: dict
    module_version: str | None
    problem: str | None

    @property
    def ok(self) -> bool:
        return self.problem is None


def _installed_wheels() -> dict[str, str]:
    found = {}
    for name in WHEELS:
        try:
            found[name] = md.version(name)
        except md.PackageNotFoundError:
            pass
    return found


def _major_minor(version: str) -> tuple[int, int] | None:
    try:
        major, minor = version.split(".")[:2]
        return int(major), int(minor)
    except ValueError:
        return None


def _keep(wheels: dict[str, str]) -> str:
    """Which of two installed wheels to keep: the one a CAD library installed needs (cadquery
    needs cadquery-ocp, build123d cadquery-ocp-novtk), else the VTK one (a superset)."""
    for library, wheel in (("cadquery", "cadquery-ocp"), ("build123d", "cadquery-ocp-novtk")):
        try:
            md.version(library)
        except md.PackageNotFoundError:
            continue
        return wheel
    return "cadquery-ocp"


def ocp_status() -> OcpStatus:
    """Diagnose the installed OpenCASCADE without raising (see the module docstring)."""
    wheels = _installed_wheels()
    try:
        import OCP

        module_version = str(getattr(OCP, "__version__", "")) or None
        import_error = None
    except ImportError as exc:  # absent, or broken by a second wheel's files
        module_version, import_error = None, exc
    if len(wheels) > 1:
        keep = _keep(wheels)
        drop = next(w for w in wheels if w != keep)
        listed = " and ".join(f"{w} {v}" for w, v in wheels.items())
        return OcpStatus(wheels, module_version, (
            f"two OpenCASCADE wheels ({listed}) have written the same OCP module over each other; repair with: "
            f"pip uninstall -y {drop} && pip install --force-reinstall --no-deps {keep}=={wheels[keep]}"
        ))
    if import_error is not None:
        if wheels:
            wheel, version = next(iter(wheels.items()))
            return OcpStatus(wheels, None, (
                f"the OCP module of {wheel} {version} does not import ({' '.join(str(import_error).split())}); "
                f"repair with: pip install --force-reinstall --no-deps {wheel}=={version}"
            ))
        return OcpStatus(wheels, None, (
            f"OpenCASCADE (the OCP module) is not installed: {OCP_EXTRA} "
            "(or install cadquery or build123d, which bring it)"
        ))
    version = _major_minor(module_version or "")
    if version not in SUPPORTED:
        wheel = next(iter(wheels), "cadquery-ocp-novtk")
        supported = " and ".join(f"{a}.{b}" for a, b in SUPPORTED)
        return OcpStatus(wheels, module_version, (
            f"OpenCASCADE OCP {module_version} is not supported (nupatch works with {supported}); "
            f"repair with: pip install '{wheel}{SUPPORTED_RANGE}'"
        ))
    for wheel, dist_version in wheels.items():
        # the module's version is in its extension; a mismatch means files of two installs
        if module_version and _major_minor(dist_version) != version:
            return OcpStatus(wheels, module_version, (
                f"the OCP module is version {module_version} but {wheel} {dist_version} is installed: files of two "
                f"installs are mixed; repair with: pip install --force-reinstall --no-deps {wheel}=={dist_version}"
            ))
    return OcpStatus(wheels, module_version, None)


def require_ocp() -> str:
    """The OCP module's version, or OcpError with the one-line diagnosis."""
    status = ocp_status()
    if not status.ok:
        raise OcpError(status.problem)
    return status.module_version or ""


OCP_VERSION = require_ocp()

if _major_minor(OCP_VERSION) >= (8, 0):
    from OCP.TopoDS import TopoDS as _topods  # noqa: E402

    class TopoDS:
        """OCP 7.9's ``TopoDS`` class of static casts (``TopoDS.Face_s``): OCP 8.0 made
        ``TopoDS`` a namespace of plain functions (``TopoDS.Face``)."""

        Vertex_s = staticmethod(_topods.Vertex)
        Edge_s = staticmethod(_topods.Edge)
        Wire_s = staticmethod(_topods.Wire)
        Face_s = staticmethod(_topods.Face)
        Shell_s = staticmethod(_topods.Shell)
        Solid_s = staticmethod(_topods.Solid)
        CompSolid_s = staticmethod(_topods.CompSolid)
        Compound_s = staticmethod(_topods.Compound)

    from OCP.collections import (  # noqa: E402
        Array1_double as TColStd_Array1OfReal,
        Array1_gp_Pnt as TColgp_Array1OfPnt,
        Array1_gp_Pnt2d as TColgp_Array1OfPnt2d,
        Array1_int as TColStd_Array1OfInteger,
        Array2_gp_Pnt as TColgp_Array2OfPnt,
        IndexedDataMap_TCollection_AsciiString_TCollection_AsciiString as TColStd_IndexedDataMapOfStringString,
        IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as TopTools_IndexedDataMapOfShapeListOfShape,
        IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as TopTools_IndexedMapOfShape,
    )
else:
    from OCP.TopoDS import TopoDS  # noqa: E402
    from OCP.TColgp import TColgp_Array1OfPnt, TColgp_Array1OfPnt2d, TColgp_Array2OfPnt  # noqa: E402
    from OCP.TColStd import (  # noqa: E402
        TColStd_Array1OfInteger,
        TColStd_Array1OfReal,
        TColStd_IndexedDataMapOfStringString,
    )
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape, TopTools_IndexedMapOfShape  # noqa: E402


def import_cad_library(name: str):
    """``import build123d`` or ``import cadquery``, or OcpError naming nupatch's extra for it."""
    import importlib

    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name:
            raise
        raise OcpError(f"{name} is not installed: pip install 'nupatch[{name}]'", name) from None


def box_bounds(box) -> tuple[float, float, float, float, float, float]:
    """(xmin, ymin, zmin, xmax, ymax, zmax) of a ``Bnd_Box``: OCP 8's ``Get()`` returns a
    ``Bnd_Box::Limits`` struct that its bindings cannot convert, so the corners are read."""
    return (*box.CornerMin().Coord(), *box.CornerMax().Coord())
