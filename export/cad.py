"""The surface as an object of a CAD scripting library: build123d and cadquery.

Both libraries wrap OpenCASCADE's ``TopoDS_Shape`` in their own classes; the environment holds
one OCP module (docs/architecture.md, "Dependencies"), so the B-rep of ``export.brep.to_shape`` is
handed over as it is, without a file or a copy: a closed surface is a ``Solid``, an open one a
``Shell``.  The source may be a ``BezierSurface``, a ``ControlMesh`` or the path of a mesh file;
for the last two, a ``BuildOptions`` (or its fields as keywords) chooses how it is built.

The libraries are imported on first use (cadquery alone takes about a second to import).
"""

from __future__ import annotations

import os

import patching
from patching.mesh import ControlMesh
from patching.options import BuildOptions
from patching.surface import BezierSurface

__all__ = ["as_surface", "to_build123d", "to_cadquery"]


def as_surface(
    source: BezierSurface | ControlMesh | str | os.PathLike,
    options: BuildOptions | None = None,
    **option_fields: str,
) -> BezierSurface:
    """The BezierSurface of a surface (returned as is), a control mesh, or a mesh file (OBJ),
    OBJ or USD, built with ``options`` (or its fields as keywords: angles, anchors, interior, g1_solve,
    refinement)."""
    if isinstance(source, BezierSurface):
        return source
    if isinstance(source, (str, os.PathLike)):
        from .inputs import read_control_mesh

        source = read_control_mesh(source)
    if isinstance(source, ControlMesh):
        return patching.build(source, BuildOptions.of(options, **option_fields))
    raise TypeError(f"expected a BezierSurface, a ControlMesh or a mesh path, not {type(source).__name__}")


def _shape(source, options: BuildOptions | None, option_fields: dict):
    from export.brep import to_shape

    return to_shape(as_surface(source, options, **option_fields))


def to_build123d(source: BezierSurface | ControlMesh | str | os.PathLike, options: BuildOptions | None = None, **option_fields: str):
    """A ``build123d.Solid`` (closed surface) or ``build123d.Shell`` (open surface).

    The object is valid (``BRepCheck_Analyzer``, checked by ``to_shape``) and takes part in
    build123d's booleans (``part - Box(...)``), fillets and exports like any other.
    """
    from .ocp_compat import import_cad_library
    from OCP.TopAbs import TopAbs_SOLID

    build123d = import_cad_library("build123d")
    shape = _shape(source, options, option_fields)
    if shape.ShapeType() == TopAbs_SOLID:
        return build123d.Solid(shape)
    return build123d.Shell(shape)


def to_cadquery(source: BezierSurface | ControlMesh | str | os.PathLike, options: BuildOptions | None = None, **option_fields: str):
    """A ``cadquery.Workplane`` on the XY plane holding one ``cadquery.Solid`` (closed surface)
    or ``cadquery.Shell`` (open surface); ``.val()`` gives that Shape."""
    from .ocp_compat import import_cad_library

    cadquery = import_cad_library("cadquery")
    shape = cadquery.Shape.cast(_shape(source, options, option_fields))
    return cadquery.Workplane("XY").add(shape)
