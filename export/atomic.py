"""Atomic file writes: a temporary file in the target's directory, renamed only on success."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from patching.errors import OutputError

__all__ = ["atomic_output", "atomic_write_text", "check_output_path", "umask"]


def _output_directory(path: Path) -> Path:
    """The directory an output goes into; OutputError if it is missing or path is a directory."""
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise OutputError("output directory does not exist", str(parent))
    if path.is_dir():
        raise OutputError("the output path is a directory", str(path))
    return parent


def check_output_path(path: str | os.PathLike) -> Path:
    """Refuse early an output whose directory is missing or not writable (OutputError)."""
    path = Path(path)
    parent = _output_directory(path)
    # Probe by creating a file: permission bits do not tell for root or read-only mounts.
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=parent)
    except OSError as exc:
        raise OutputError(f"output directory is not writable ({exc.strerror})", str(parent)) from None
    os.close(fd)
    os.unlink(probe)
    return path


def umask() -> int:
    """The process umask, read without changing it where /proc allows."""
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, empty_error: type[Exception] = OutputError) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` if the block succeeds.

    Only when the block ends without an exception, the file is non-empty and on disk (fsync)
    is it renamed onto ``path`` (``os.replace``, atomic on POSIX); on any failure the temporary
    file is removed and a file already at ``path`` is untouched.  The file gets the mode a
    plain ``open()`` would give it (0666 minus the umask), not mkstemp's private 0600.  A
    missing or unwritable directory, or a ``path`` that is a directory, raises OutputError
    naming it; a writer that leaves an empty file raises ``empty_error``.
    """
    path = Path(path)
    directory = _output_directory(path)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise OutputError(f"cannot write in {directory}: {exc.strerror}", str(path)) from exc
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        os.chmod(tmp, 0o666 & ~umask())
        yield tmp
        with open(tmp, "rb") as written:
            if os.fstat(written.fileno()).st_size == 0:
                raise empty_error(f"the writer left an empty file for {path}")
            os.fsync(written.fileno())  # the data is on disk before the name points at it
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")

