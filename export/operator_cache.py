"""The on-disk cache of whole operators M, read back as memory maps.

M depends on the mesh's topology, intervals, tags and the options only
(``patching.operator.archive``), so a build of a mesh whose control points moved takes M from
the last build of the same mesh instead of assembling it again: on the pawn (semi-sharp,
adaptive) 3.5-4.4 s of a 10-11 s build, on benchmarks/build.py's half-EP mesh 1.2-1.9 s.  The entry
is mapped, not read: its pages come from the page cache when M is used, without the fresh
memory that assembling M touches (docs/speed.md, "Whole operators").

Entries live beside the solve cache (``export.solve_cache.cache_directory``), under
``operators/<key>.npop``: a magic line, the header's length, a JSON header (the key, the
operator's scalars, each array's name, dtype, shape and offset, and a SHA-256 of the data
region), then the arrays, each at a 64-byte boundary of a data region that starts at a 4 KiB
boundary.  ``load`` trusts an entry only when its magic, key, layout and digest check out and
``operator_from_arrays`` accepts its arrays; anything else is a miss (and the next build
rewrites the entry).  Entries are written by a thread of the build's own after M is built,
to a temporary file renamed into place (``export.atomic``), so concurrent builds each replace
an entry whole and a reader never sees half of one; an interrupt (Ctrl-C, SIGTERM) abandons
the write, removing its temporary file.  A loaded operator's arrays are copy-on-write maps of
the file: an entry removed or replaced while mapped stays readable (POSIX).

Size cap: ``$NUPATCH_OPERATOR_CACHE_MB`` MB (default 1,024; an operator of the half-EP
mesh's 15k bi-quintic patches is 170 MB, the pawn's 230 MB).  After a write that takes the
entries over the cap, the least recently used go, down to ``EVICT_TO`` of it (as in the solve
cache); a read refreshes an entry's mtime once an hour at most.  An operator larger than the
cap is not written.  ``--no-cache`` and
``NUPATCH_NO_CACHE=1`` turn this cache off with the solve cache; OS errors make it a no-op.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import mmap
import os
import re
import struct
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from export.solve_cache import cache_directory, cache_disabled, closed_at_end, evict_least_recent, megabytes_from_env
from patching.mesh.control_mesh import ControlMesh
from patching.operator.archive import operator_arrays, operator_from_arrays, operator_key
from patching.options import BuildOptions
from patching.surface import SurfaceOperator

__all__ = ["OperatorCache", "operator_cache_max_bytes", "using_operator_cache", "operator_for"]

MAGIC = b"NUPATCH-OPERATOR 1\n"
#: Environment variable with the size cap in MB (module docstring).
MAX_MB_ENV = "NUPATCH_OPERATOR_CACHE_MB"
DEFAULT_MAX_MB = 1024.0
#: Where the data region starts (a page boundary: the maps of its arrays start on pages).
DATA_ALIGN = 4096
#: Each array's offset in the data region is a multiple of this.
ARRAY_ALIGN = 64
#: The writer writes and checks for an abandon this many bytes at a time.
CHUNK = 16 << 20
_ENTRY = re.compile(r"^[0-9a-f]{64}\.npop$")


def operator_cache_max_bytes() -> int:
    """The size cap: ``$NUPATCH_OPERATOR_CACHE_MB`` MB (a non-negative number), else 1,024 MB."""
    return megabytes_from_env(MAX_MB_ENV, DEFAULT_MAX_MB)


class _Abandoned(Exception):
    """The write was abandoned (an interrupted build); its temporary file is removed."""


def _layout(arrays: dict[str, np.ndarray]) -> tuple[list[list], int]:
    """([name, dtype, shape, offset, nbytes] per array, bytes of the data region)."""
    rows, at = [], 0
    for name, a in arrays.items():
        at = -(-at // ARRAY_ALIGN) * ARRAY_ALIGN
        rows.append([name, a.dtype.str, list(a.shape), at, int(a.nbytes)])
        at += int(a.nbytes)
    return rows, at


def _data_start(header_length: int) -> int:
    """Offset of the data region: the first page boundary after the magic, the header's
    length and the header."""
    return -(-(len(MAGIC) + 8 + header_length) // DATA_ALIGN) * DATA_ALIGN


def _pieces(arrays: dict[str, np.ndarray], rows: list[list]) -> Iterator[memoryview]:
    """The data region as it is written: padding and each array's bytes, in order."""
    at = 0
    for name, _, _, offset, nbytes in rows:
        if offset > at:
            yield memoryview(bytes(offset - at))
        if nbytes:
            yield memoryview(np.ascontiguousarray(arrays[name])).cast("B")
        at = offset + nbytes


class OperatorCache:
    """Whole operators as files under ``root/operators`` (module docstring)."""

    #: A read refreshes an entry's mtime when it is older than this (seconds).
    refresh_after = 3600.0

    def __init__(self, root: str | os.PathLike | None = None, max_bytes: int | None = None, background: bool = True) -> None:
        """background: ``save`` writes in a thread of its own (``close`` waits for it)."""
        self.root = Path(root) if root is not None else cache_directory()
        self.directory = self.root / "operators"
        self.max_bytes = operator_cache_max_bytes() if max_bytes is None else int(max_bytes)
        self.background = background
        self.written = 0  # bytes this cache wrote
        self.hits = 0
        self._writers: list[threading.Thread] = []
        self._abandon = threading.Event()

    def path(self, key: str) -> Path:
        return self.directory / f"{key}.npop"

    # -- reading -----------------------------------------------------------------------------
    def load(self, key: str, name: str) -> SurfaceOperator | None:
        """The operator of ``key``, named ``name``, on copy-on-write maps of its entry; None
        when there is none or it does not check out (module docstring).  Never raises."""
        try:
            with open(self.path(key), "rb") as f:
                if time.time() - os.fstat(f.fileno()).st_mtime > self.refresh_after:
                    with contextlib.suppress(OSError):
                        os.utime(f.fileno())  # recently used
                view = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_COPY)
        except (OSError, ValueError):  # ValueError: an empty file cannot be mapped
            return None
        try:
            op = self._read(view, key, name)
        except Exception:  # noqa: BLE001 - a damaged entry is a miss, whatever is damaged
            return None
        if op is not None:
            self.hits += 1
        return op

    @staticmethod
    def _read(view: mmap.mmap, key: str, name: str) -> SurfaceOperator | None:
        size = len(view)
        head = len(MAGIC) + 8
        if size < head or view[: len(MAGIC)] != MAGIC:
            return None
        (length,) = struct.unpack("<Q", view[len(MAGIC) : head])
        if head + length > size:
            return None
        header = json.loads(bytes(view[head : head + length]).decode("utf-8"))
        start = _data_start(length)
        if header.get("key") != key or start + int(header["data_bytes"]) != size:
            return None
        region = memoryview(view)[start:]
        if hashlib.sha256(region).hexdigest() != header["digest"]:
            return None
        arrays = {}
        for array_name, dtype, shape, offset, nbytes in header["arrays"]:
            dtype = np.dtype(dtype)
            count = int(np.prod(shape, dtype=np.int64))
            if dtype.hasobject or count * dtype.itemsize != nbytes or offset + nbytes > len(region):
                return None
            a = np.frombuffer(region, dtype=dtype, count=count, offset=offset).reshape(shape)
            # M's arrays stay maps; the groups' and the patch topology's are copied out, as the
            # surface keeps them after M is dropped, and a view would keep the whole file mapped
            # (half-EP mesh: 150 MB more at the STEP writer's peak).
            arrays[array_name] = a if array_name.startswith("m_") else a.copy()
        return operator_from_arrays(arrays, header["scalars"], name)

    # -- writing -----------------------------------------------------------------------------
    def save(self, key: str, op: SurfaceOperator) -> None:
        """Write ``op`` as the entry of ``key`` (in a thread when ``background``); an operator
        larger than the cap is not written.  Never raises."""
        arrays, scalars = operator_arrays(op)
        rows, data_bytes = _layout(arrays)
        if data_bytes > self.max_bytes:
            return
        if not self.background:
            self._write(key, arrays, scalars, rows, data_bytes)
            return
        writer = threading.Thread(target=self._write, args=(key, arrays, scalars, rows, data_bytes),
                                  name="nupatch-operator-writer", daemon=True)
        self._writers.append(writer)
        writer.start()

    def _write(self, key: str, arrays: dict, scalars: dict, rows: list[list], data_bytes: int) -> None:
        from export.atomic import atomic_output

        try:
            digest = hashlib.sha256()
            for piece in _pieces(arrays, rows):
                if self._abandon.is_set():
                    raise _Abandoned
                digest.update(piece)
            header = {"key": key, "scalars": scalars, "arrays": rows, "data_bytes": data_bytes, "digest": digest.hexdigest()}
            text = json.dumps(header).encode("utf-8")
            prefix = MAGIC + struct.pack("<Q", len(text)) + text
            start = _data_start(len(text))
            self.directory.mkdir(parents=True, exist_ok=True)
            with atomic_output(self.path(key), durable=False) as tmp:  # readers check the digest
                with open(tmp, "wb") as f:
                    f.write(prefix + bytes(start - len(prefix)))
                    for piece in _pieces(arrays, rows):
                        for at in range(0, len(piece), CHUNK):
                            if self._abandon.is_set():
                                raise _Abandoned
                            f.write(piece[at : at + CHUNK])
            self.written += start + data_bytes
        except Exception:  # noqa: BLE001 - a cache that cannot write is no cache, not an error
            pass

    def close(self, abandon: bool = False) -> None:
        """Wait for the writes in progress (abandon, or an interrupt while waiting: stop them
        at their next chunk, leaving no file), then, if this cache wrote an entry, evict down
        to the cap."""
        if abandon:
            self._abandon.set()
        try:
            for writer in self._writers:
                writer.join()
        except KeyboardInterrupt:  # interrupted while waiting: stop the writes, then go on up
            self._abandon.set()
            for writer in self._writers:
                writer.join()
            raise
        finally:
            self._writers.clear()
        if self.written and not abandon:
            self.evict()

    # -- size --------------------------------------------------------------------------------
    def entries(self) -> list[tuple[float, int, str]]:
        """(mtime, size, path) of every entry; files that vanish meanwhile are left out."""
        out = []
        try:
            with os.scandir(self.directory) as it:
                for entry in it:
                    if _ENTRY.match(entry.name):
                        with contextlib.suppress(OSError):
                            st = entry.stat(follow_symlinks=False)
                            out.append((st.st_mtime, st.st_size, entry.path))
        except OSError:
            pass
        return out

    def evict(self, max_bytes: int | None = None) -> int:
        """If the entries hold more than ``max_bytes`` (default the cap), remove the least
        recently used until they hold at most ``EVICT_TO`` of it (``evict_least_recent``);
        returns how many this call removed.  A removed entry that another build has mapped
        stays readable to it."""
        return evict_least_recent(self.entries(), self.max_bytes if max_bytes is None else int(max_bytes))


@contextlib.contextmanager
def using_operator_cache(enabled: bool = True, root: str | os.PathLike | None = None) -> Iterator[OperatorCache | None]:
    """An ``OperatorCache`` for the block (None when ``enabled`` is False or the environment
    disables the caches); the block's end waits for its writes, or abandons them when the
    block is interrupted (KeyboardInterrupt, SIGTERM)."""
    cache = OperatorCache(root) if enabled and not cache_disabled() else None

    def close(interrupted: bool) -> None:
        if cache is not None:
            cache.close(abandon=interrupted)

    with closed_at_end(close):
        yield cache


def operator_for(mesh: ControlMesh, options: BuildOptions, cache: OperatorCache | None) -> SurfaceOperator:
    """``patching.build_operator(mesh, options)``, taken from ``cache`` when it holds the
    operator of the same topology, intervals, tags and options, else built and handed to it."""
    import patching

    key = operator_key(mesh, options) if cache is not None else None
    if key is not None:
        op = cache.load(key, mesh.name)
        if op is not None:
            return op
    op = patching.build_operator(mesh, options)
    if key is not None:
        cache.save(key, op)
    return op
