"""Fitting the G1 spline to triangle meshes ([FSLYJ] sec. 4.1): remesher adapter
(``remesh``), the input's sharp edges as creases (``features``), foot points
(``projection``), least squares through M and the distance models (``solve``), the
alternation, the input checks and the report (``fit``), distances for the report
(``distance``)."""

from .fit import FitReport, FitResult, InputLabels, check_triangles, default_faces, fit
from .remesh import REMESHERS, quad_remesh

__all__ = ["FitReport", "FitResult", "InputLabels", "REMESHERS", "check_triangles", "default_faces", "fit", "quad_remesh"]
