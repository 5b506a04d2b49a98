"""Reading a STEP file that may be damaged: every entity read, every value finite, OCC silent.

``read_step_checked(path)`` is what ``check`` and ``render`` read STEP through
(``export.step.read_step`` calls it).  In order, before any OpenCASCADE algorithm runs:

1. the first bytes must be the ISO-10303-21 header (nothing else of the file is read if not);
2. every real literal of the file must be finite and at most ``MAX_COORDINATE`` in size
   (a ``1.E999`` coordinate reads as infinity, and OCC's transfer then loops forever or
   crashes): a scan of the text with quoted strings removed, so nothing is parsed by OCC yet;
3. ``STEPControl_Reader.ReadFile`` under ``occ_messages()``: OpenCASCADE writes its parse
   messages to the C++ ``std::cout`` in ANSI colour, which would break ``check --json``;
   they are captured at the file-descriptor level and only their text reaches our error;
4. the model's check list (``XSControl_WorkSession.ModelCheckList``) and global check must
   hold no fail: a truncated file, a syntax error, a reference to a missing ``#id`` or an
   entity of the wrong type are each a fail there, and OCC would otherwise read the rest and
   silently drop the faces that used the damaged entity;
5. after the transfer, every root must have been transferred and the shape must have as many
   faces as the model has face entities (``ADVANCED_FACE``, ``FACE_SURFACE``).

Any of these is an ``InputFileError`` "damaged STEP file: ..." (exit 2, one line).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import sys
import tempfile
from pathlib import Path
from typing import Iterator

from patching.errors import InputFileError
from patching.mesh import MAX_COORDINATE

__all__ = ["MAX_COORDINATE", "occ_messages", "check_step_reals", "require_step_header", "read_step_checked"]

#: Quoted STEP strings ('' is an escaped quote inside one): removed before scanning reals.
_STRING = re.compile(rb"'(?:[^']|'')*'")
#: Reals that can be out of range: with an exponent, or with more than 30 integer digits.
_RISKY_REAL = re.compile(rb"[+-]?(?:\d+\.\d*[eE][+-]?\d+|\d{31,}\.\d*)")
#: ANSI colour sequences OCC wraps its messages in.
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
#: Entity types that each make one face of the shape.
_FACE_ENTITIES = ("StepShape_AdvancedFace", "StepShape_FaceSurface")


def _fflush() -> None:
    with contextlib.suppress(Exception):
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def occ_messages() -> Iterator[list[str]]:
    """Capture what native code writes to file descriptors 1 and 2 during the block.

    Yields a list that, after the block, holds the captured lines without ANSI colour codes.
    Python's own ``sys.stdout``/``sys.stderr`` are flushed before, so nothing of ours is lost;
    OCC's printers (``Message_PrinterOStream`` on ``std::cout``) cannot be told apart from a
    C ``printf``, hence the descriptor-level redirection rather than a Message printer swap.
    """
    lines: list[str] = []
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    _fflush()
    saved = []
    with tempfile.TemporaryFile() as sink:
        try:
            for fd in (1, 2):
                try:
                    saved.append((fd, os.dup(fd)))
                except OSError:
                    continue
                os.dup2(sink.fileno(), fd)
            yield lines
        finally:
            _fflush()
            for fd, copy in saved:
                os.dup2(copy, fd)
                os.close(copy)
            sink.seek(0)
            text = sink.read().decode("utf-8", "replace")
            lines.extend(line.strip() for line in _ANSI.sub("", text).splitlines() if line.strip())


def require_step_header(path: str | os.PathLike) -> Path:
    """InputFileError unless ``path`` is a regular file starting with the ISO-10303-21 header
    (only its first 64 bytes are read: a FIFO or ``/dev/zero`` is refused, not drained)."""
    path = Path(path)
    try:
        if not path.is_file():
            if not path.exists():
                raise InputFileError("no such file", str(path))
            raise InputFileError("not a regular file", str(path))
        with open(path, "rb") as fh:
            head = fh.read(64)
    except OSError as exc:
        raise InputFileError(f"cannot read file: {exc.strerror}", str(path)) from None
    if not head.lstrip().startswith(b"ISO-10303-21"):
        raise InputFileError("not a STEP file (no ISO-10303-21 header)", str(path))
    return path


def check_step_reals(data: bytes, where: str) -> None:
    """InputFileError naming the line of the first real literal that is not finite or whose
    magnitude exceeds ``MAX_COORDINATE`` (strings blanked first, keeping line numbers)."""
    text = _STRING.sub(lambda m: b"''" + b"\n" * m.group().count(b"\n"), data)
    for match in _RISKY_REAL.finditer(text):
        token = match.group()
        value = float(token)
        if not (abs(value) <= MAX_COORDINATE):
            line = text.count(b"\n", 0, match.start()) + 1
            raise InputFileError(
                f"damaged STEP file: the real {token.decode()} is not finite or beyond {MAX_COORDINATE:g}",
                f"{where}:{line}",
            )


def _first_fails(reader, limit: int = 1) -> tuple[int, list[str]]:
    """(number of entities with a fail, the first fail messages) of the model just read."""
    model = reader.Model()
    messages: list[str] = []
    count = 0
    glob = model.GlobalCheck()
    for i in range(1, glob.NbFails() + 1):
        messages.append(glob.CFail(i))
    checks = reader.WS().ModelCheckList(False)
    checks.Start()
    while checks.More():
        check = checks.Value()
        if check.NbFails():
            count += 1
            if len(messages) < limit + glob.NbFails():
                messages.append(check.CFail(1))
        checks.Next()
    return max(count, glob.NbFails()), messages


def _face_entities(model) -> int:
    count = 0
    for i in range(1, model.NbEntities() + 1):
        if model.Value(i).DynamicType().Name() in _FACE_ENTITIES:
            count += 1
    return count


def read_step_checked(path: str | os.PathLike):
    """Read every root of the STEP file at ``path`` into one shape (module docstring's checks);
    InputFileError "damaged STEP file" for any entity lost on the way."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp
    from export.ocp_compat import TopTools_IndexedMapOfShape

    path = require_step_header(path)
    where = str(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputFileError(f"cannot read file: {exc.strerror}", where) from None
    check_step_reals(data, where)
    reader = STEPControl_Reader()
    with occ_messages() as log:
        status = reader.ReadFile(str(path))
    if status != IFSelect_RetDone:
        detail = next((line for line in log if "ERR" in line or "rror" in line), log[0] if log else str(status))
        raise InputFileError(f"damaged STEP file: {detail.strip('* ')}", where)
    failed, messages = _first_fails(reader)
    if failed:
        raise InputFileError(
            f"damaged STEP file: {failed} entit{'y' if failed == 1 else 'ies'} could not be read "
            f"({'; '.join(messages[:2])})",
            where,
        )
    with occ_messages():
        roots = reader.NbRootsForTransfer()
        transferred = reader.TransferRoots()
        shape = reader.OneShape()
    if roots == 0 or shape.IsNull():
        raise InputFileError("the STEP file holds no shape", where)
    if transferred < roots:
        raise InputFileError(f"damaged STEP file: {roots - transferred} of {roots} roots could not be transferred", where)
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    expected = _face_entities(reader.Model())
    if faces.Extent() < expected:
        raise InputFileError(f"damaged STEP file: {expected - faces.Extent()} of {expected} faces were lost in the transfer", where)
    return shape
