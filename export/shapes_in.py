"""B-rep files read back for ``nupatch check``: STEP, IGES and OpenCASCADE's BREP.

``read_shape(path)`` tells the format from the file's first bytes (STEP: ``ISO-10303-21``;
BREP: ``DBRep_DrawableShape`` or ``CASCADE Topology``; IGES: an 80-column start record with
``S`` in column 73), not from the suffix, and reads every root into one shape.
"""

from __future__ import annotations

import os
from pathlib import Path

from patching.errors import InputFileError

__all__ = ["SHAPE_FORMATS", "shape_format", "read_shape"]

SHAPE_FORMATS = ("step", "iges", "brep")


def shape_format(path: str | os.PathLike) -> str:
    """'step', 'iges' or 'brep' from the file's first bytes (InputFileError otherwise)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(200)
    except FileNotFoundError:
        raise InputFileError("no such file", str(path)) from None
    except IsADirectoryError:
        raise InputFileError("is a directory", str(path)) from None
    except OSError as exc:
        raise InputFileError(f"cannot read file: {exc.strerror}", str(path)) from None
    text = head.lstrip()
    if text.startswith(b"ISO-10303-21"):
        return "step"
    if text.startswith(b"DBRep_DrawableShape") or text.startswith(b"CASCADE Topology"):
        return "brep"
    first = head.split(b"\n", 1)[0].rstrip(b"\r")
    if len(first) >= 73 and first[72:73] == b"S":
        return "iges"
    raise InputFileError("not a STEP file, nor IGES or BREP (unknown header)", str(path))


def read_shape(path: str | os.PathLike):
    """The TopoDS_Shape of a STEP, IGES or BREP file (every root, a compound if several)."""
    path = Path(path)
    fmt = shape_format(path)
    if fmt == "step":
        from .step import read_step

        return read_step(path)
    from .ocp_compat import OCP_VERSION  # noqa: F401  (one line if OpenCASCADE is missing)
    from .step import quiet_occ

    if fmt == "brep":
        from OCP.BRep import BRep_Builder
        from OCP.BRepTools import BRepTools
        from OCP.TopoDS import TopoDS_Shape

        shape = TopoDS_Shape()
        with quiet_occ():
            ok = BRepTools.Read_s(shape, str(path), BRep_Builder())
        if not ok or shape.IsNull():
            raise InputFileError("not a readable BREP file", str(path))
        return shape
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.IGESControl import IGESControl_Reader

    reader = IGESControl_Reader()
    with quiet_occ():
        status = reader.ReadFile(str(path))
        if status != IFSelect_RetDone:
            raise InputFileError(f"not a readable IGES file ({status})", str(path))
        reader.TransferRoots()
        shape = reader.OneShape()
    if shape.IsNull():
        raise InputFileError("the IGES file holds no shape", str(path))
    return shape
