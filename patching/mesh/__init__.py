"""Control meshes in: the mesh as arrays plus tags (``control_mesh``), OBJ with OpenSubdiv's
tags (``obj``), meshes made from parameters (``primitives``).  A new input format is a new
module here that returns a ``ControlMesh`` (formats that need a third-party library, such as
USD, live in ``export``)."""

from patching.mesh.control_mesh import INFINITELY_SHARP, MAX_COORDINATE, ControlMesh, NupatchWarning, from_arrays
from patching.mesh.obj import format_obj, parse_obj, read_obj

__all__ = ["ControlMesh", "NupatchWarning", "INFINITELY_SHARP", "MAX_COORDINATE", "from_arrays", "read_obj", "parse_obj", "format_obj"]
