"""nupatch's edge to CAD: BezierSurface -> OpenCASCADE B-rep -> files (STEP).

Public API (STYLE 4): ``to_shape`` (B-rep), ``to_step`` (build and write atomically),
``to_build123d`` / ``to_cadquery`` (the B-rep as a CAD library's object), ``write`` (any
format of ``export.formats``),
``check_continuity`` (validity, gaps and normal jumps of a B-rep or STEP file).
"""

from __future__ import annotations

import os
from pathlib import Path

from patching.surface import BezierSurface

__all__ = ["to_shape", "to_step", "to_build123d", "to_cadquery", "write", "write_step", "read_step", "check_continuity"]


def to_shape(surface: BezierSurface):
    """The B-rep (TopoDS_Shape) of a surface: a solid when closed, else a shell."""
    from .brep import to_shape as _to_shape

    return _to_shape(surface)


def to_step(surface: BezierSurface, path: str | os.PathLike) -> Path:
    """Build the B-rep of ``surface`` and write it atomically to ``path`` (millimetres, product
    named ``surface.name``)."""
    from .step import write_step as _write_step

    return _write_step(to_shape(surface), path, surface.name)


def to_build123d(source, angles: str = "optimized", anchors: str = "eigen-polyhedron", **options):
    """A build123d ``Solid`` (closed) or ``Shell`` (open) from a surface, a mesh or a mesh file;
    an ``Edge`` on the exact limit of a ``patching.curves.curve.Curve``."""
    from .cad import to_build123d as _to_build123d

    from patching.curves.curve import Curve

    if isinstance(source, Curve):
        from .curves import to_build123d as _curve_to_build123d

        return _curve_to_build123d(source)

    return _to_build123d(source, angles, anchors, **options)


def to_cadquery(source, angles: str = "optimized", anchors: str = "eigen-polyhedron", **options):
    """A cadquery ``Workplane`` holding the Solid (closed) or Shell (open); ``.val()`` is the Shape;
    a ``Wire`` on the exact limit of a ``patching.curves.curve.Curve``."""
    from .cad import to_cadquery as _to_cadquery

    from patching.curves.curve import Curve

    if isinstance(source, Curve):
        from .curves import to_cadquery as _curve_to_cadquery

        return _curve_to_cadquery(source)

    return _to_cadquery(source, angles, anchors, **options)


def write(surface: BezierSurface, path: str | os.PathLike, format: str | None = None, *, tolerance: float | None = None) -> Path:
    """Write ``surface`` atomically as step, iges, brep, stl, glb or obj (default: from the
    suffix); ``tolerance`` is the tessellation's linear deflection (``export.formats``)."""
    from .formats import write as _write

    return _write(surface, path, format, tolerance=tolerance)


def write_step(shape, path: str | os.PathLike, product_name: str) -> Path:
    from .step import write_step as _write_step

    return _write_step(shape, path, product_name)


def read_step(path: str | os.PathLike):
    from .step import read_step as _read_step

    return _read_step(path)


def check_continuity(shape_or_path, **kwargs):
    from .continuity import check_continuity as _check

    return _check(shape_or_path, **kwargs)
