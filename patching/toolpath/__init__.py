"""CNC tool paths on the patched surface ([FSLYJ] sec. 4.3): the control mesh cut into
regular pieces (``segmentation``), a connected Fermat spiral in each (``spiral``), 3-axis
ball-end machining from +Z without gouging (``geometry``, ``path``).

``tool_path(surface, mesh, radius, scallop, tolerance)`` returns a ``ToolPath``: arrays of
piece id, ball centres, tool tips, contact points and unit normals, with a check report."""

from .path import UP, ToolPath, check_parameters, tool_path
from .segmentation import Piece, segment
from .spiral import fermat_spiral

__all__ = ["UP", "Piece", "ToolPath", "check_parameters", "fermat_spiral", "segment", "tool_path"]
