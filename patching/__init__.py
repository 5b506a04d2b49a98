"""nupatch geometry: control meshes with knot intervals to Bézier patches (pure numpy/scipy).

Public API (STYLE 4): ``read_mesh`` (OBJ file) and ``from_arrays`` give a ControlMesh;
``build_operator`` gives the sparse operator M (coefficients = M @ points); ``build`` gives the
BezierSurface.  No OpenCASCADE here: ``export`` turns surfaces into B-reps and files.
"""

from .errors import (
    InputFileError,
    KnotError,
    MeshError,
    NupatchError,
    OutputError,
    TagError,
    UnsupportedError,
)
from .mesh import ControlMesh, NupatchWarning, from_arrays
from .obj import read_obj as read_mesh
from .obj import write_obj
from .operator import ANCHOR_RULES, G1_SOLVES, INTERIOR_RULES, SurfaceOperator, build, build_operator
from .surface import BezierSurface, PatchGroup, PatchTopology
from .topology import Topology


def ep_quality(operator, mesh, **kwargs):
    """Per-EP quality report (``evaluation.ep_quality``): normal jumps across spoke edges and
    the local maxima of the blending functions around each EP."""
    from .evaluation import ep_quality as _ep_quality

    return _ep_quality(operator, mesh, **kwargs)

__version__ = "0.1.0"

__all__ = [
    "ANCHOR_RULES",
    "INTERIOR_RULES",
    "G1_SOLVES",
    "BezierSurface",
    "ControlMesh",
    "InputFileError",
    "KnotError",
    "MeshError",
    "NupatchError",
    "NupatchWarning",
    "OutputError",
    "PatchGroup",
    "PatchTopology",
    "SurfaceOperator",
    "TagError",
    "Topology",
    "UnsupportedError",
    "build",
    "build_operator",
    "ep_quality",
    "from_arrays",
    "read_mesh",
    "write_obj",
]
