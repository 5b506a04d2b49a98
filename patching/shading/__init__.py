"""Subdivision shading with semi-sharp creases ([ZBK]) for Loop and Catmull-Clark: limit
normals per region (``limit``), subdivided normals, blend weights and the blended field
(``operator``)."""

from .operator import DART_MODES, NORMAL_MODES, VARIANTS, ShadingOperator, SubdividedMesh, shading_operator, subdivide_with_normals

__all__ = ["DART_MODES", "NORMAL_MODES", "VARIANTS", "ShadingOperator", "SubdividedMesh", "shading_operator", "subdivide_with_normals"]
