"""Subdivision curves of degree 2..7 with semi-sharp creases and control vectors ([KSD]).

Stages (each importing only from the ones before): ``knots`` (B-spline coefficient maps),
``uniform`` (degree-d Lane-Riesenfeld operators), ``creases`` (crease rules solved from
S M = M T), ``runs`` (polygons cut at sharp vertices: refinement and exact limit),
``control_vectors`` ([KSD] sec. 4), ``polyline`` (OBJ ``l`` + tags), ``curve`` (the Curve
object).
"""

from .curve import BSplineCurve, Curve
from .polyline import Polyline, parse_polyline, read_polyline

__all__ = ["BSplineCurve", "Curve", "Polyline", "parse_polyline", "read_polyline"]
