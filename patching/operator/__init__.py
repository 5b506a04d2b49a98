"""The operator M from control points to Bézier coefficients, and the refinement before it.

``build`` (entry point: options and input checked once, then a dispatch), ``refinement``
(how many subdivision steps semi-sharp tags and n-gons need, the uniform path), ``adaptive``
(the feature-adaptive path) with ``split_sides`` (T-junctions as split B-rep sides),
``assembly`` (M of an all-quad mesh), ``refusals`` (inputs no closed surface has),
``archive`` (M as named arrays and the key of what it depends on, for caches between processes).
"""

from patching.operator.build import build, build_operator
from patching.operator.refinement import patched_mesh
from patching.surface import OperatorGroup, SurfaceOperator

__all__ = ["build", "build_operator", "patched_mesh", "OperatorGroup", "SurfaceOperator"]
