"""The on-disk store of solved local configurations (``patching.util.solve_cache``).

Entries live in the user's cache directory: ``$NUPATCH_CACHE_DIR`` if set, else
``$XDG_CACHE_HOME/nupatch`` (``~/.cache/nupatch`` when XDG_CACHE_HOME is unset), under
``solves/<2 hex>/<key>``.  Each entry is written to a temporary file beside it and renamed
into place (``export.atomic``), so concurrent builds writing the same entry each replace it
whole and a reader never sees half an entry.  An unreadable, truncated or corrupted entry is
ignored (``patching.util.solve_cache.decode`` checks its digests) and rewritten by the solve.
Any OS error (read-only or full disk, no home directory) makes the store a no-op, never a
failed build.  ``nupatch build --no-cache`` or ``NUPATCH_NO_CACHE=1`` disable it.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from patching.util.solve_cache import SolveStore, set_store

__all__ = ["DiskStore", "cache_directory", "cache_disabled", "using_disk_cache"]

#: Environment variable that disables the cache (any value but "", "0").
NO_CACHE_ENV = "NUPATCH_NO_CACHE"


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


class DiskStore:
    """Entries as files under ``root/solves`` (module docstring)."""

    def __init__(self, root: str | os.PathLike | None = None) -> None:
        self.root = Path(root) if root is not None else cache_directory()
        self._solves = os.path.join(self.root, "solves")

    def path(self, key: str) -> Path:
        return Path(self._solves, key[:2], key)

    def get(self, key: str) -> bytes | None:
        try:
            with open(os.path.join(self._solves, key[:2], key), "rb") as f:
                return f.read()
        except OSError:
            return None

    def put(self, key: str, data: bytes) -> None:
        from export.atomic import atomic_output

        path = self.path(key)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_output(path, durable=False) as tmp:  # readers check the digests
                tmp.write_bytes(data)
        except Exception:  # noqa: BLE001 - a cache that cannot write is no cache, not an error
            pass


@contextlib.contextmanager
def using_disk_cache(enabled: bool = True, root: str | os.PathLike | None = None) -> Iterator[SolveStore | None]:
    """Install the disk store for the block (unless ``enabled`` is False or the environment
    disables it), restoring the previous store after."""
    store = DiskStore(root) if enabled and not cache_disabled() else None
    previous = set_store(store)
    try:
        yield store
    finally:
        set_store(previous)
