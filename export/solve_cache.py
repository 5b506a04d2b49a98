"""The on-disk store of solved local configurations (``patching.util.solve_cache``).

Entries live in the user's cache directory: ``$NUPATCH_CACHE_DIR`` if set, else
``$XDG_CACHE_HOME/nupatch`` (``~/.cache/nupatch`` when XDG_CACHE_HOME is unset), under
``solves/<2 hex>/<key>``.  Each entry is written to a temporary file beside it and renamed
into place (``export.atomic``), so concurrent builds writing the same entry each replace it
whole and a reader never sees half an entry; a build's entries are written by a thread of its
own while the build goes on, and the build waits for them at its end.  An unreadable, truncated or corrupted entry is
ignored (``patching.util.solve_cache.decode`` checks its digests) and rewritten by the solve.
Any OS error (read-only or full disk, no home directory) makes the store a no-op, never a
failed build.  ``nupatch build --no-cache`` or ``NUPATCH_NO_CACHE=1`` disable it.

Size cap: least recently used entries go first.  A read refreshes an entry's mtime (at most
once per ``DiskStore.refresh_after`` seconds, so a warm build does not rewrite thousands of
inodes), so mtime is the entry's last write or use whatever the file system does with atime.
After a build that wrote entries, ``evict`` lists the entries and, if they hold more than
``max_bytes`` (``$NUPATCH_CACHE_MAX_MB`` MB, default 256), removes the oldest until they hold
at most ``EVICT_TO`` of it.  Concurrent builds stay safe: an entry removed under a reader that
has it open is still read whole (POSIX unlink), one removed before it is opened is a miss that
the solve rewrites, two evictors removing the same file ignore the second removal, and an
entry renamed into place after the listing is the newest and is kept.  Temporary files of
writes in progress are never touched (``export.atomic`` removes those a killed run left).
"""

from __future__ import annotations

import contextlib
import os
import queue
import re
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from patching.util.solve_cache import SolveStore, set_store

__all__ = ["DiskStore", "cache_directory", "cache_disabled", "cache_max_bytes", "closed_at_end", "evict_least_recent", "megabytes_from_env", "using_disk_cache"]

#: Environment variable that disables the cache (any value but "", "0").
NO_CACHE_ENV = "NUPATCH_NO_CACHE"
#: Environment variable with the size cap in MB (module docstring).
MAX_MB_ENV = "NUPATCH_CACHE_MAX_MB"
DEFAULT_MAX_MB = 256.0
#: An eviction removes entries until they hold at most this share of the cap (so that the
#: next few builds do not each evict again).
EVICT_TO = 0.8
_ENTRY = re.compile(r"^[0-9a-f]{64}$")


def cache_directory() -> Path:
    """Where the cache lives (module docstring)."""
    explicit = os.environ.get("NUPATCH_CACHE_DIR")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "nupatch"


def cache_disabled() -> bool:
    """True when ``NUPATCH_NO_CACHE`` asks for no cache."""
    return os.environ.get(NO_CACHE_ENV, "") not in ("", "0")


def cache_max_bytes() -> int:
    """The size cap: ``$NUPATCH_CACHE_MAX_MB`` MB (a non-negative number), else 256 MB."""
    return megabytes_from_env(MAX_MB_ENV, DEFAULT_MAX_MB)


def megabytes_from_env(name: str, default_mb: float) -> int:
    """Bytes of the environment variable ``name`` read as MB (non-negative; unset, empty or
    not a number: ``default_mb``)."""
    text = os.environ.get(name, "")
    try:
        mb = float(text) if text else default_mb
    except ValueError:
        mb = default_mb
    return int(max(mb, 0.0) * 1e6) if mb == mb else int(default_mb * 1e6)


def evict_least_recent(found: list[tuple[float, int, str]], cap: int) -> int:
    """If the files ``found`` ((mtime, size, path)) hold more than ``cap`` bytes, remove the
    least recently used until they hold at most ``EVICT_TO`` of it; returns how many this
    call removed.  Safe beside other builds (module docstring): a file another build removed
    first is skipped, one that cannot be removed is left."""
    total = sum(size for _, size, _ in found)
    if total <= cap:
        return 0
    goal = int(EVICT_TO * cap)
    removed = 0
    for _, size, path in sorted(found):
        if total <= goal:
            break
        try:
            os.remove(path)
            removed += 1
        except FileNotFoundError:
            pass  # another build evicted it first
        except OSError:
            continue
        total -= size
    return removed


@contextlib.contextmanager
def closed_at_end(close: Callable[[bool], None]) -> Iterator[None]:
    """Run the block, then ``close(interrupted)``: True when the block was interrupted
    (KeyboardInterrupt: Ctrl-C, and SIGTERM/SIGHUP as ``export.signals.Terminated``), so
    that a cache drops the writes not yet begun instead of waiting for them."""
    interrupted = False
    try:
        yield
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        close(interrupted)


class DiskStore:
    """Entries as files under ``root/solves`` (module docstring)."""

    #: A read refreshes an entry's mtime when it is older than this (seconds).
    refresh_after = 3600.0

    def __init__(self, root: str | os.PathLike | None = None, max_bytes: int | None = None, background: bool = False) -> None:
        """background: ``put`` hands the entry to a writer thread and returns (``close``
        waits for it): a first build writes thousands of small files, 0.6-2.6 s of system
        time on this machine's disk for the half-EP mesh's 3,845, which then overlap with
        the rest of the build (the B-rep) instead of adding to it."""
        self.root = Path(root) if root is not None else cache_directory()
        self._solves = os.path.join(self.root, "solves")
        self.max_bytes = cache_max_bytes() if max_bytes is None else int(max_bytes)
        self.written = 0  # entries this store wrote (bytes)
        self.background = background
        self._pending: queue.SimpleQueue | None = None
        self._writer: threading.Thread | None = None

    def path(self, key: str) -> Path:
        return Path(self._solves, key[:2], key)

    def get(self, key: str) -> bytes | None:
        path = os.path.join(self._solves, key[:2], key)
        try:
            with open(path, "rb") as f:
                data = f.read()
                if time.time() - os.fstat(f.fileno()).st_mtime > self.refresh_after:
                    os.utime(f.fileno())  # recently used (module docstring)
        except OSError:
            return None
        return data

    def put(self, key: str, data: bytes) -> None:
        if not self.background:
            self._write(key, data)
            return
        if self._writer is None:
            self._pending = queue.SimpleQueue()
            self._writer = threading.Thread(target=self._drain, name="nupatch-cache-writer", daemon=True)
            self._writer.start()
        self._pending.put((key, data))

    def close(self, abandon: bool = False) -> None:
        """Wait for the writer thread to write every entry handed to it (background stores);
        abandon: drop the entries it has not begun (an interrupted run: the current one ends
        whole or, under SIGTERM's watchdog, as a removed temporary file)."""
        if self._writer is None:
            return
        if abandon:
            with contextlib.suppress(queue.Empty):
                while True:
                    self._pending.get_nowait()
        self._pending.put(None)
        self._writer.join()
        self._writer = None

    def _drain(self) -> None:
        while (item := self._pending.get()) is not None:
            self._write(*item)

    def _write(self, key: str, data: bytes) -> None:
        from export.atomic import atomic_output

        path = self.path(key)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_output(path, durable=False) as tmp:  # readers check the digests
                tmp.write_bytes(data)
            self.written += len(data)
        except Exception:  # noqa: BLE001 - a cache that cannot write is no cache, not an error
            pass

    def entries(self) -> list[tuple[float, int, str]]:
        """(mtime, size, path) of every entry; files that vanish meanwhile are left out."""
        out = []
        try:
            buckets = [b.path for b in os.scandir(self._solves) if len(b.name) == 2 and b.is_dir(follow_symlinks=False)]
        except OSError:
            return out
        for bucket in buckets:
            try:
                with os.scandir(bucket) as it:
                    for entry in it:
                        if _ENTRY.match(entry.name):
                            try:
                                st = entry.stat(follow_symlinks=False)
                            except OSError:
                                continue
                            out.append((st.st_mtime, st.st_size, entry.path))
            except OSError:
                continue
        return out

    def evict(self, max_bytes: int | None = None) -> int:
        """If the entries hold more than ``max_bytes`` (default ``self.max_bytes``), remove the
        least recently used until they hold at most ``EVICT_TO`` of it; returns how many
        this call removed (module docstring: safe beside other builds)."""
        return evict_least_recent(self.entries(), self.max_bytes if max_bytes is None else int(max_bytes))


@contextlib.contextmanager
def using_disk_cache(enabled: bool = True, root: str | os.PathLike | None = None) -> Iterator[SolveStore | None]:
    """Install the disk store for the block (unless ``enabled`` is False or the environment
    disables it), restoring the previous store after.  Entries are written by a background
    thread (``DiskStore(background=True)``); the block's end waits for them, or, when the
    block is interrupted (KeyboardInterrupt, SIGTERM), drops those not yet begun."""
    store = DiskStore(root, background=True) if enabled and not cache_disabled() else None
    previous = set_store(store)

    def close(interrupted: bool) -> None:
        set_store(previous)
        if store is not None:
            store.close(abandon=interrupted)
            if store.written and not interrupted:
                with contextlib.suppress(OSError):
                    store.evict()

    with closed_at_end(close):
        yield store
