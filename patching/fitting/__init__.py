"""Fitting the G1 spline to triangle meshes ([FSLYJ] sec. 4.1): remesher adapter
(``remesh``), foot points (``projection``), least squares through M (``solve``), the
alternation and its report (``fit``), distances for the report (``distance``)."""

from .fit import FitReport, FitResult, check_triangles, default_faces, fit
from .remesh import REMESHERS, quad_remesh

__all__ = ["FitReport", "FitResult", "REMESHERS", "check_triangles", "default_faces", "fit", "quad_remesh"]
