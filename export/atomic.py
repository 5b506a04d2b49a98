"""The one atomic-write wrapper of every export format (DESIGN 3, STYLE 5).

``atomic_output(path)`` yields a temporary path in the target's directory; the writer writes
there, and only when the block ends without an exception, the file is non-empty and on disk
(``fsync``) is it renamed onto ``path`` (``os.replace``, atomic on POSIX).  On any failure
the temporary file is removed and a file already at ``path`` is untouched.  The file gets the
mode a plain ``open()`` would give it (0666 minus the umask), not mkstemp's private 0600.

This is the STEP writer's logic of ``export.step`` made general; the early directory checks
are ``patching.atomic.check_output_path``'s, so the CLI can refuse a bad output path before
any work.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from patching.errors import OutputError

__all__ = ["atomic_output", "umask"]


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

    A missing or unwritable directory, or a ``path`` that is a directory, raises
    ``OutputError`` naming it.  A writer that leaves an empty file raises ``empty_error``.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise OutputError("the output path is a directory", str(path))
    if not directory.is_dir():
        raise OutputError("output directory does not exist", str(directory))
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
