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
    """A build123d ``Solid`` (closed) or ``Shell`` (open) from a surface, a mesh or a mesh file."""
    from .cad import to_build123d as _to_build123d

    return _to_build123d(source, angles, anchors, **options)


def to_cadquery(source, angles: str = "optimized", anchors: str = "eigen-polyhedron", **options):
    """A cadquery ``Workplane`` holding the Solid (closed) or Shell (open); ``.val()`` is the Shape."""
    from .cad import to_cadquery as _to_cadquery

    return _to_cadquery(source, angles, anchors, **options)


def write(surface: BezierSurface, path: str | os.PathLike, format: str | None = None, *, tolerance: float | None = None) -> Path:
    """Write ``surface`` atomically as step, iges, brep, stl, glb, obj or 3dm (default: from
    the suffix); ``tolerance`` is the tessellation's linear deflection (``export.formats``)."""
    from .formats import write as _write

    return _write(surface, path, format, tolerance=tolerance)


def write_step(shape, path: str | os.PathLike, product_name: str) -> Path:
    """Write a TopoDS_Shape atomically as STEP (millimetres, product ``product_name``)."""
    from .step import write_step as _write_step

    return _write_step(shape, path, product_name)


def read_step(path: str | os.PathLike):
    """Every root of a STEP file as one TopoDS_Shape (a compound if several)."""
    from .step import read_step as _read_step

    return _read_step(path)


def check_continuity(
    shape_or_path,
    samples_per_edge: int = 9,
    *,
    worst: int = 5,
    sharp_angle_deg: float = 10.0,
    g1_tolerance_deg: float = 1e-5,
    gap_tolerance: float = 1e-7,
    all_edges: bool = False,
    face_ids=None,
):
    """Validity, free edges, gaps and normal jumps (``ContinuityReport``) of a shape, a
    ``BezierSurface`` or a STEP, IGES or BREP file (DESIGN 5; ``export.continuity``).

    samples_per_edge: points per shared edge, ends included (>= 2); worst: edges listed in the
    report; sharp_angle_deg: a jump at least this large all along an edge makes it sharp;
    g1_tolerance_deg: the largest jump of a G1 edge; gap_tolerance: positional gap, relative
    to the diagonal, above which an edge is open; all_edges: keep every edge in the report;
    face_ids: face index -> id used in the report.
    """
    from .continuity import check_continuity as _check

    if isinstance(shape_or_path, (str, os.PathLike)):
        from .shapes_in import read_shape

        shape_or_path = read_shape(shape_or_path)
    return _check(shape_or_path, samples_per_edge, worst=worst, sharp_angle_deg=sharp_angle_deg,
                  g1_tolerance_deg=g1_tolerance_deg, gap_tolerance=gap_tolerance, all_edges=all_edges,
                  face_ids=face_ids)
