"""Evaluating patches: points and normals on grids, blending functions and their local maxima,
and the quality report per extraordinary point (``sampling``).  Bézier nets themselves are
evaluated by ``patching.bernstein.evaluate_nets``."""

from patching.bernstein import evaluate_nets
from patching.evaluation.sampling import (
    EPQuality,
    blending_function,
    blending_maxima,
    ep_quality,
    normal_turning,
    sample_surface,
    spoke_normal_jumps,
)

__all__ = ["evaluate_nets", "sample_surface", "normal_turning", "blending_function", "blending_maxima",
           "spoke_normal_jumps", "EPQuality", "ep_quality"]
