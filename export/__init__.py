"""nupatch's edge to CAD: BezierSurface -> OpenCASCADE B-rep -> files (STEP and others).

Public API: ``build_file`` (a mesh file to an output file, as ``nupatch build`` does),
``to_shape`` (B-rep), ``to_step`` (write atomically), ``to_build123d`` / ``to_cadquery`` (the
B-rep as a CAD library's object), ``write`` (any format of ``export.formats``), ``write_obj``
(a control mesh with its tags), ``check_continuity`` (validity, gaps and normal jumps of a
B-rep or STEP file).  Modules: ``pipeline`` (read -> build -> B-rep -> write), ``brep`` and
``pack`` (B-reps), ``formats`` (the writers' registry), ``step``, ``continuity``, ``render``,
``cad``, ``atomic`` (atomic writes), ``tolerances`` (every tolerance, once), ``cli``.
"""

from __future__ import annotations

import os
from pathlib import Path

from patching.options import BuildOptions

from export.tolerances import G1_TOLERANCE_DEG, GAP_TOLERANCE, N_WORST, SHARP_ANGLE_DEG
from patching.surface import BezierSurface

__all__ = ["build_file", "to_shape", "to_step", "to_build123d", "to_cadquery", "write", "write_obj", "write_step", "read_step", "check_continuity"]


def build_file(mesh, out=None, format: str | None = None, *, options: BuildOptions | None = None, pack: bool | None = None,
               tolerance: float | None = None) -> Path:
    """Build the mesh file ``mesh`` and write ``out`` (``export.pipeline.build_file``)."""
    from export.pipeline import build_file as _build_file

    return _build_file(mesh, out, format, options=options, pack=pack, tolerance=tolerance)


def to_shape(surface: BezierSurface):
    """The B-rep (TopoDS_Shape) of a surface: a solid when closed, else a shell."""
    from export.brep import to_shape as _to_shape

    return _to_shape(surface)


def to_step(surface: BezierSurface, path: str | os.PathLike) -> Path:
    """Build the B-rep of ``surface`` and write it atomically to ``path`` (millimetres, product
    named ``surface.name``)."""
    from export.step import write_step as _write_step

    return _write_step(to_shape(surface), path, surface.name)


def to_build123d(source, options: BuildOptions | None = None, **option_fields: str):
    """A build123d ``Solid`` (closed) or ``Shell`` (open) from a surface, a mesh or a mesh file;
    an ``Edge`` on the exact limit of a ``patching.curves.Curve``."""
    from patching.curves.curve import Curve

    if isinstance(source, Curve):
        from export.curves import to_build123d as _curve_to_build123d

        return _curve_to_build123d(source)
    from export.cad import to_build123d as _to_build123d

    return _to_build123d(source, options, **option_fields)


def to_cadquery(source, options: BuildOptions | None = None, **option_fields: str):
    """A cadquery ``Workplane`` holding the Solid (closed) or Shell (open), ``.val()`` the Shape;
    a ``Wire`` on the exact limit of a ``patching.curves.Curve``."""
    from patching.curves.curve import Curve

    if isinstance(source, Curve):
        from export.curves import to_cadquery as _curve_to_cadquery

        return _curve_to_cadquery(source)
    from export.cad import to_cadquery as _to_cadquery

    return _to_cadquery(source, options, **option_fields)


def write(surface: BezierSurface, path: str | os.PathLike, format: str | None = None, *, tolerance: float | None = None) -> Path:
    """Write ``surface`` atomically as step, iges, brep, stl, glb, obj or 3dm (default: from
    the suffix); ``tolerance`` is the tessellation's linear deflection (``export.formats``)."""
    from .formats import write as _write

    return _write(surface, path, format, tolerance=tolerance)


def write_obj(mesh, path: str | os.PathLike, comment: str = "") -> None:
    """Write a control mesh with its tags as OBJ (``patching.mesh.format_obj``), atomically, so
    that ``patching.read_mesh`` reads it back."""
    from patching.mesh import format_obj

    from .atomic import atomic_write_text

    atomic_write_text(path, format_obj(mesh, comment))


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
    worst: int = N_WORST,
    sharp_angle_deg: float = SHARP_ANGLE_DEG,
    g1_tolerance_deg: float = G1_TOLERANCE_DEG,
    gap_tolerance: float = GAP_TOLERANCE,
    all_edges: bool = False,
    face_ids=None,
):
    """Validity, free edges, gaps and normal jumps (``ContinuityReport``) of a shape, a
    ``BezierSurface`` or a STEP, IGES or BREP file (docs/verification.md; ``export.continuity``).

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
