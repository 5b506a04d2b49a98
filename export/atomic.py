"""Atomic file writes: a temporary file in the target's directory, renamed only on success."""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import re
import secrets
import shutil
import stat
import sys
import tempfile
from pathlib import Path
from typing import Iterator

from patching.errors import OutputError

__all__ = [
    "STDOUT",
    "atomic_output",
    "atomic_write_text",
    "check_output_path",
    "is_temporary_name",
    "live_temporaries",
    "remove_stale_temporaries",
    "temporary_name",
    "umask",
]

#: The output name that means standard output (``-o -``).
STDOUT = "-"
#: Temporary and probe files: ``.nupatch-<8 hex of the target's name>-<pid>-<8 hex>.<kind>``,
#: at most 45 bytes whatever the target's name (NAME_MAX is 255), recognisable by a later run.
_TEMPORARY = re.compile(r"^\.nupatch-([0-9a-f]{8})-(\d+)-[0-9a-f]{8}\.(tmp|probe)$")
#: errno values that mean the file system refused more data: one line, exit 2, not a bug.
_FULL = {errno.ENOSPC: "no space left on the device", errno.EDQUOT: "disk quota exceeded",
         errno.EFBIG: "file too large for this file system or process limit"}
#: Temporary files this process has open, for ``export.signals``' last-resort cleanup.
_LIVE: set[str] = set()


def temporary_name(target: str, kind: str = "tmp") -> str:
    """A fresh hidden name for a temporary (``kind`` "tmp") or probe ("probe") file beside
    ``target``'s base name: fixed length, so it fits wherever ``target`` fits."""
    tag = hashlib.sha1(os.fsencode(target)).hexdigest()[:8]
    return f".nupatch-{tag}-{os.getpid()}-{secrets.token_hex(4)}.{kind}"


def is_temporary_name(name: str) -> bool:
    """True for a name ``temporary_name`` makes."""
    return _TEMPORARY.match(name) is not None


def live_temporaries() -> set[str]:
    """Paths of the temporary files this process is writing now (a live view)."""
    return _LIVE


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # EPERM: it exists, owned by someone else
        return True
    return True


def remove_stale_temporaries(path: str | os.PathLike) -> list[Path]:
    """Remove the temporary and probe files that an earlier run on ``path`` left behind (killed
    by SIGKILL, or a power cut): those named for ``path`` whose process no longer runs.  Files
    of a live process (a concurrent writer) are left alone.  Returns the removed paths."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    tag = hashlib.sha1(os.fsencode(path.name)).hexdigest()[:8]
    removed = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(directory):
            m = _TEMPORARY.match(entry.name)
            if m and m.group(1) == tag and not _pid_alive(int(m.group(2))):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)
                    removed.append(Path(entry.path))
    return removed


def _output_directory(path: Path) -> Path:
    """The directory an output goes into; OutputError if it is missing, if path is a directory,
    or if path exists and is not a regular file (a device, a FIFO, a socket: never replaced)."""
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise OutputError("output directory does not exist", str(parent))
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return parent
    except OSError as exc:
        raise OutputError(f"cannot inspect the output ({exc.strerror})", str(path)) from None
    if stat.S_ISDIR(mode):
        raise OutputError("the output path is a directory", str(path))
    if not stat.S_ISREG(mode):
        kind = ("a character device" if stat.S_ISCHR(mode) else "a block device" if stat.S_ISBLK(mode)
                else "a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a special file")
        raise OutputError(f"the output is {kind}, not a regular file: only regular files are replaced (-o - writes to stdout)", str(path))
    return parent


def _full_disk(exc: BaseException, where: str, tmp: Path | None = None) -> OutputError | None:
    """OutputError for an ENOSPC/EDQUOT/EFBIG failure (as OSError, or hidden in a writer that
    only says it failed while the directory has no space left or the file reached the
    process's RLIMIT_FSIZE); None otherwise."""
    if isinstance(exc, OSError) and exc.errno in _FULL:
        return OutputError(_FULL[exc.errno], where)
    if isinstance(exc, (OSError, RuntimeError)) and tmp is not None:
        with contextlib.suppress(Exception):
            import resource

            limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
            if limit != resource.RLIM_INFINITY and os.stat(tmp).st_size >= limit:
                return OutputError(_FULL[errno.EFBIG], where)
    if isinstance(exc, (OSError, RuntimeError)):
        with contextlib.suppress(OSError):
            fs = os.statvfs(Path(where).parent if str(Path(where).parent) else ".")
            if fs.f_bavail * fs.f_frsize < 64 * 1024 or (fs.f_files and fs.f_favail == 0):
                return OutputError(_FULL[errno.ENOSPC], where)
    return None


def check_output_path(path: str | os.PathLike) -> Path:
    """Refuse early an output whose directory is missing or not writable, or that is a special
    file (OutputError); ``-`` (standard output) is accepted as it is."""
    if str(path) == STDOUT:
        return Path(STDOUT)
    path = Path(path)
    parent = _output_directory(path)
    remove_stale_temporaries(path)
    # Probe by creating a file: permission bits do not tell for root or read-only mounts.
    probe = parent / temporary_name(path.name, "probe")
    # The name is this process's alone (pid and random bits), so removing it in ``finally`` is
    # safe even when the open failed; a signal that unwinds between the open and the removal
    # (SIGTERM and SIGHUP raise in the main thread: export.signals) leaves no probe behind.
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.close(fd)
    except OSError as exc:
        full = _full_disk(exc, str(path))
        if full is not None and exc.errno in _FULL:
            raise full from None
        raise OutputError(f"output directory is not writable ({exc.strerror})", str(parent)) from None
    finally:
        with contextlib.suppress(OSError):
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
def atomic_output(path: str | os.PathLike, empty_error: type[Exception] = OutputError, durable: bool = True) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` if the block succeeds.

    Only when the block ends without an exception, the file is non-empty and on disk (fsync)
    is it renamed onto ``path`` (``os.replace``, atomic on POSIX); on any failure the temporary
    file is removed and a file already at ``path`` is untouched.  A new file gets the mode a
    plain ``open()`` would give it (0666 minus the umask); a replaced file keeps its mode and,
    where allowed, its owner and group.  Only a regular file is replaced: a missing or
    unwritable directory, a ``path`` that is a directory, a device or a FIFO raise OutputError
    naming it; a full disk or quota (ENOSPC, EDQUOT, EFBIG) is an OutputError too; a writer
    that leaves an empty file raises ``empty_error``.  Temporary names are ``temporary_name``'s
    (they fit any legal name); those a killed run left for ``path`` are removed first.
    ``path`` ``-`` is standard output: the file is made in the temporary directory and copied
    to stdout only once complete, so a failure writes nothing there either.  ``durable=False``
    skips the fsync (still atomic for readers; a crash may leave the old file or a damaged new
    one: for files whose readers check them, such as ``export.solve_cache``'s entries).
    """
    to_stdout = str(path) == STDOUT
    path = Path(path)
    if to_stdout:
        directory = Path(tempfile.gettempdir())
        old = None
    else:
        directory = _output_directory(path)
        remove_stale_temporaries(path)
        try:
            old = os.stat(path)
        except OSError:
            old = None
    tmp = directory / temporary_name(path.name)
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as exc:
        full = _full_disk(exc, str(path)) if exc.errno in _FULL else None
        if full is not None:
            raise full from None
        raise OutputError(f"cannot write in {directory}: {exc.strerror}", str(path)) from exc
    os.close(fd)
    _LIVE.add(str(tmp))
    try:
        if old is not None:
            os.chmod(tmp, stat.S_IMODE(old.st_mode))
            with contextlib.suppress(OSError):
                os.chown(tmp, old.st_uid, old.st_gid)
        else:
            os.chmod(tmp, 0o666 & ~umask())
        yield tmp
        with open(tmp, "rb") as written:
            if os.fstat(written.fileno()).st_size == 0:
                raise empty_error(f"the writer left an empty file for {path}")
            if to_stdout:
                sys.stdout.flush()
                shutil.copyfileobj(written, sys.stdout.buffer)
                sys.stdout.flush()
            elif durable:
                os.fsync(written.fileno())  # the data is on disk before the name points at it
        if not to_stdout:
            os.replace(tmp, path)
    except BaseException as exc:
        full = _full_disk(exc, str(path), tmp) if not to_stdout and not isinstance(exc, (OutputError, KeyboardInterrupt)) else None
        with contextlib.suppress(OSError):
            tmp.unlink()
        if full is not None:
            raise full from None
        raise
    finally:
        _LIVE.discard(str(tmp))
        if to_stdout:
            with contextlib.suppress(OSError):
                tmp.unlink()


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
