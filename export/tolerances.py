"""Every tolerance of the export side, defined once (no OpenCASCADE import: the command line
reads them without loading OCC).

Lengths are relative to the model's size (``BezierSurface.size``, the diagonal of its
control points) unless said otherwise.
"""

from __future__ import annotations

import math

from patching.errors import NupatchError

__all__ = [
    "RELATIVE_TOLERANCE", "CONFUSION", "GAP_TOLERANCE", "G1_TOLERANCE_DEG", "SHARP_ANGLE_DEG",
    "N_WORST", "TESSELLATION_RELATIVE", "MIN_TESSELLATION", "ANGULAR_DEFLECTION", "check_tolerance",
]

#: Tolerance of the B-rep's vertices, edges and faces, times the size.
RELATIVE_TOLERANCE = 1e-7
#: OpenCASCADE's Precision::Confusion (absolute): no B-rep tolerance and no tessellation
#: deflection goes below it.
CONFUSION = 1e-7
#: Largest gap of a G0 edge in ``nupatch check``, relative to the diagonal: the B-rep's own
#: tolerance (relative to the control points' diagonal, which is at least the surface's).
GAP_TOLERANCE = RELATIVE_TOLERANCE
#: Largest normal jump (degrees) of a G1 edge: 100x the worst G1 residual reported for the
#: bi-quintic EP patches (~1e-7 deg at interval ratio 20; 1e-11 deg measured on an L-shaped
#: polycube with intervals 0.5 to 3), 1e6x round-off of C1 neighbours (~1e-11 deg).
G1_TOLERANCE_DEG = 1e-5
#: A normal jump above this (degrees) is a sharp edge in ``nupatch check``, not a defect: 10 deg
#: is far above any defect the constructions leave.
SHARP_ANGLE_DEG = 10.0
#: Edges listed per criterion (normal jump, then gap) by ``nupatch check``.
N_WORST = 5
#: Default linear deflection of a tessellation (STL, glTF, OBJ), times the size.
TESSELLATION_RELATIVE = 1e-3
#: Smallest linear deflection (absolute): below Precision::Confusion BRepMesh_IncrementalMesh
#: throws (Standard_NumericError).
MIN_TESSELLATION = CONFUSION
#: Angular deflection of a tessellation (radians): OpenCASCADE's usual 0.5.
ANGULAR_DEFLECTION = 0.5


def check_tolerance(tolerance, option: str = "--tolerance") -> float:
    """The one check of a linear deflection every command shares: a finite number at least
    MIN_TESSELLATION, else a NupatchError naming ``option``.  Returns it as a float."""
    try:
        value = float(tolerance)
    except (TypeError, ValueError):
        raise NupatchError(f"tessellation tolerance must be a number, not {tolerance!r}", option) from None
    if not (math.isfinite(value) and value >= MIN_TESSELLATION):
        raise NupatchError(
            f"tessellation tolerance must be finite and at least {MIN_TESSELLATION:g} (OpenCASCADE's precision), not {value:g}",
            option,
        )
    return value
