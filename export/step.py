"""STEP files through OpenCASCADE's STEPControl: atomic, deterministic writes (docs/surface.md).

``write_step`` writes AP214 (``AUTOMOTIVE_DESIGN``) in millimetres with the product named
``product_name``.  The file appears only complete: OCC writes a temporary file in the target
directory, its status must be ``IFSelect_RetDone``, then ``os.replace`` renames it into
place (``export.atomic.atomic_output``).  Two writes of one shape differ only in the header's FILE_NAME statement (its time
stamp, and the file's base name, which it carries).

OCC writes reals with 13 significant digits (``StepData_StepWriter``'s fixed FloatWriter(12)),
so a file read back matches the shape to ~1e-13 relative, not to the last bit.  The
``write.step.*`` settings are process-global ``Interface_Static`` values: they are set for
one write and restored after, so writes must not run in parallel threads of one process.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from .ocp_compat import OCP_VERSION  # noqa: F401  (first: one line if OpenCASCADE is missing or mixed)
from OCP.APIHeaderSection import APIHeaderSection_MakeHeader
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.Message import Message, Message_Gravity
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
from OCP.StepBasic import StepBasic_Product
from OCP.TCollection import TCollection_HAsciiString
from OCP.TopoDS import TopoDS_Shape


from export.atomic import atomic_output

__all__ = ["StepError", "write_step", "write_step_file", "read_step", "quiet_occ"]

#: STEP schema written; AP214 is read by every CAD system we know of.
SCHEMA = "AP214IS"


class StepError(RuntimeError):
    """OpenCASCADE failed to translate or write a shape it should accept: a bug."""


@contextlib.contextmanager
def quiet_occ():
    """Raise the default messenger's printers to failures only (OCC prints transfer statistics)."""
    printers = list(Message.DefaultMessenger_s().Printers())
    levels = [p.GetTraceLevel() for p in printers]
    for p in printers:
        p.SetTraceLevel(Message_Gravity.Message_Fail)
    try:
        yield
    finally:
        for p, level in zip(printers, levels):
            p.SetTraceLevel(level)


@contextlib.contextmanager
def _static_values(values: dict[str, str]):
    """Set Interface_Static parameters for one write, restoring the previous values after."""
    old = {key: Interface_Static.CVal_s(key) for key in values}
    try:
        for key, value in values.items():
            if not Interface_Static.SetCVal_s(key, value):
                raise StepError(f"Interface_Static refuses {key} = {value!r}")
        yield
    finally:
        for key, value in old.items():
            Interface_Static.SetCVal_s(key, value)


def _name_products(writer: STEPControl_Writer, product_name: str, file_name: str) -> None:
    """Give every PRODUCT entity the id and name ``product_name``; the header FILE_NAME the file's."""
    model = writer.Model()
    found = 0
    products = model.Entities()
    products.SelectType(StepBasic_Product.get_type_descriptor_s(), True)  # in C++, not 14k isinstance calls
    while products.More():
        entity = products.Value()
        entity.SetId(TCollection_HAsciiString(product_name))
        entity.SetName(TCollection_HAsciiString(product_name))
        found += 1
        products.Next()
    if not found:
        raise StepError("the STEP model has no PRODUCT entity to name")
    header = APIHeaderSection_MakeHeader(model)
    header.SetName(TCollection_HAsciiString(file_name))
    from .reproducible import apply_to_step_header

    apply_to_step_header(header)  # SOURCE_DATE_EPOCH's time stamp where set
    header.Apply(model)


def write_step(shape: TopoDS_Shape, path: str | os.PathLike, product_name: str, *, check: bool = True) -> Path:
    """Write ``shape`` to ``path`` as AP214 STEP in millimetres, atomically; return the path.

    With ``check`` the shape must pass ``BRepCheck_Analyzer`` (else ``StepError``); pass
    False for a shape that ``to_shape`` has just checked (1.4 s saved on 10,000 faces).
    An output directory that is missing or not writable raises ``OutputError``; on any
    failure a file already at ``path`` is left untouched and no temporary file remains
    (``export.atomic.atomic_output``, the wrapper every format shares).
    """
    path = Path(path)
    if shape.IsNull() or (check and not BRepCheck_Analyzer(shape).IsValid()):
        raise StepError(f"refusing to write an invalid shape to {path}")
    with atomic_output(path, empty_error=StepError) as tmp:
        write_step_file(shape, tmp, product_name, path.name)
    return path


def write_step_file(shape: TopoDS_Shape, tmp: Path, product_name: str, file_name: str) -> None:
    """Write ``shape`` as STEP to ``tmp`` (not atomic: callers wrap it in ``atomic_output``),
    with ``file_name`` in the header, the name the file will have."""
    writer = STEPControl_Writer()  # also registers the write.step.* parameters
    statics = {
        "write.step.schema": SCHEMA,
        "write.step.unit": "MM",
        "write.step.product.name": product_name,
    }
    with quiet_occ(), _static_values(statics):
        status = writer.Transfer(shape, STEPControl_AsIs)
        if status != IFSelect_RetDone:
            raise StepError(f"STEPControl_Writer.Transfer returned {status} for {file_name}")
        _name_products(writer, product_name, file_name)
        status = writer.Write(str(tmp))
    if status != IFSelect_RetDone:
        raise StepError(f"STEPControl_Writer.Write returned {status} for {file_name}")


def read_step(path: str | os.PathLike) -> TopoDS_Shape:
    """Read every root of the STEP file at ``path`` into one shape (a compound if several).

    Through ``export.step_check.read_step_checked``: a damaged file (an entity that failed to
    read, a missing ``#id``, a non-finite real, faces lost in the transfer) is an
    InputFileError, and OpenCASCADE's messages are captured, never printed."""
    from .step_check import read_step_checked

    return read_step_checked(path)
