"""nupatch geometry: control meshes with knot intervals to Bézier patches (pure numpy/scipy).

The data flows one way, one sub-package a stage: ``mesh`` (control meshes in) -> ``topology``
(tables and sharp features) -> ``rules`` and ``subdivision`` (refinement as sparse operators)
-> ``extraordinary`` (the construction at EPs) -> ``operator`` (the sparse M, coefficients =
M @ points) -> ``surface`` (patches) -> ``evaluation``.  No OpenCASCADE here: ``export`` turns
surfaces into B-reps and files.

Public API: ``read_mesh`` (OBJ file) and ``from_arrays`` give a ControlMesh;
``build_operator`` gives the SurfaceOperator (M); ``build`` gives the BezierSurface;
``BuildOptions`` holds the choices of a build.
"""

from patching.errors import (
    InputFileError,
    KnotError,
    MeshError,
    NupatchError,
    OptionError,
    OutputError,
    TagError,
    UnsupportedError,
)
from patching.mesh import ControlMesh, NupatchWarning, from_arrays
from patching.mesh.obj import read_obj as read_mesh
from patching.operator import SurfaceOperator, build, build_operator, patched_mesh
from patching.options import ANCHORS, ANGLES, G1_SOLVES, INTERIORS, REFINEMENTS, BuildOptions
from patching.surface import BezierSurface, PatchGroup, PatchTopology
from patching.topology import Topology

#: Former names of the option choices, kept for scripts written against them.
ANCHOR_RULES = ANCHORS
INTERIOR_RULES = INTERIORS


def ep_quality(operator, mesh, **kwargs):
    """Per-EP quality report (``evaluation.ep_quality``): normal jumps across spoke edges and
    the local maxima of the blending functions around each EP."""
    from patching.evaluation import ep_quality as _ep_quality

    return _ep_quality(operator, mesh, **kwargs)


__version__ = "0.1.0"

__all__ = [
    "ANCHORS",
    "ANGLES",
    "ANCHOR_RULES",
    "INTERIORS",
    "INTERIOR_RULES",
    "G1_SOLVES",
    "REFINEMENTS",
    "BezierSurface",
    "BuildOptions",
    "ControlMesh",
    "InputFileError",
    "KnotError",
    "MeshError",
    "NupatchError",
    "NupatchWarning",
    "OptionError",
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
    "patched_mesh",
    "read_mesh",
]
