"""``-`` as the output file: standard output, for formats written in one piece.

Every writer of ``export.formats`` (and ``subdivide``'s OBJ) writes a temporary file; for ``-``
that file's bytes are copied to standard output once it is complete, so that a failed build
prints nothing (the same guarantee as the atomic rename for files).  Binary formats (stl, glb,
3dm, and STEP/IGES/BREP are text) are refused when standard output is a terminal.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from pathlib import Path

from patching.errors import NupatchError

__all__ = ["STDOUT", "BINARY_FORMATS", "check_stream_output", "output_stream"]

STDOUT = "-"
BINARY_FORMATS = ("stl", "glb", "3dm")


def check_stream_output(out: str | os.PathLike, fmt: str, several: bool = False) -> bool:
    """True if ``out`` is ``-`` (and it may be used: one mesh, not binary to a terminal)."""
    if str(out) != STDOUT:
        return False
    if several:
        raise NupatchError("-o - (standard output) takes one mesh, not several", "command line")
    if fmt in BINARY_FORMATS and sys.stdout.isatty():
        raise NupatchError(f"{fmt} is binary: redirect standard output to a file or a pipe", "-o -")
    return True


@contextlib.contextmanager
def output_stream(out: str | os.PathLike, suffix: str):
    """Yield the path to write: ``out`` itself, or for ``-`` a temporary file (with ``suffix``)
    whose bytes go to standard output when the block ends without an exception."""
    if str(out) != STDOUT:
        yield Path(out)
        return
    with tempfile.TemporaryDirectory(prefix="nupatch-") as directory:
        tmp = Path(directory) / f"stdout{suffix}"
        yield tmp
        sys.stdout.flush()
        with open(tmp, "rb") as fh:
            while chunk := fh.read(1 << 20):
                sys.stdout.buffer.write(chunk)
        sys.stdout.buffer.flush()
