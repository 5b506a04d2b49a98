"""A persistent cache of solved local configurations, behind a store the caller installs.

Some local problems of a build are solved numerically and cost far more than their size
suggests in a fresh process: the angle configurations of [FSLYJ] sec. 3.3 are small
optimisations, the eigen-structures of [TLC] sec. 3 and the G1 operators of [FSLYJ] sec. 3.4
stacked LAPACK calls.  Their inputs are few numbers (valence, interval pattern,
sharp spokes, options), so a solved configuration can be kept between processes.

``patching`` writes no files: it asks the installed store (``set_store``; none by default, so
``patching.build`` in a script is unchanged and pure), and ``export.solve_cache`` provides the
on-disk store that the command line installs.  An entry is keyed by a SHA-256 of the problem's
name, the SHA-256 of the package's source files (so any change to the code, or another branch's
version of it, misses the old entries instead of trusting them), and the problem's arguments; it carries the same digest and a digest of its payload.  ``lookup``
trusts an entry only when both digests match, the arrays have the expected count, shapes and
finite values, and the caller's ``validate`` accepts them; anything else is ignored (and the
entry rewritten by the fresh solve).  Values are float64 bit for bit, so a cached solve gives
the same surface as a fresh one, to the last bit.
"""

from __future__ import annotations

import hashlib
import math
import struct
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol

import numpy as np

__all__ = ["SolveStore", "MemoryStore", "current_store", "set_store", "source_digest", "entry_key", "encode", "decode", "lookup", "lookup_many"]

_MAGIC = b"NPSC1\n"


class SolveStore(Protocol):
    """Where entries live: bytes by a hexadecimal key.  ``get`` returns None for a missing or
    unreadable entry and never raises; ``put`` may silently drop an entry."""

    def get(self, key: str) -> bytes | None: ...

    def put(self, key: str, data: bytes) -> None: ...


class MemoryStore:
    """A store in a dict (tests, and scripts that want the cache without files)."""

    def __init__(self) -> None:
        self.entries: dict[str, bytes] = {}

    def get(self, key: str) -> bytes | None:
        return self.entries.get(key)

    def put(self, key: str, data: bytes) -> None:
        self.entries[key] = data


_store: SolveStore | None = None


def set_store(store: SolveStore | None) -> SolveStore | None:
    """Install ``store`` (None: no persistent cache) for this process; returns the previous one."""
    global _store
    previous, _store = _store, store
    return previous


def current_store() -> SolveStore | None:
    """The installed store, or None."""
    return _store


_digest: list[str] = []


def source_digest() -> str:
    """SHA-256 of every ``.py`` file of the ``patching`` package (paths and contents), read
    once a process: a local solve may call code anywhere in the package, so any change to it
    (an edit, another branch, an upgrade) misses every old entry instead of trusting it."""
    if not _digest:
        root = Path(__file__).resolve().parent.parent
        h = hashlib.sha256()
        for path in sorted(root.rglob("*.py")):
            h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
        _digest.append(h.hexdigest())
    return _digest[0]


def entry_key(problem: str, args: tuple) -> str:
    """The key of one problem: its name, the package's source digest and ``repr`` of its
    arguments (floats' repr round-trips exactly)."""
    text = f"{problem}\0{source_digest()}\0{args!r}"
    return hashlib.sha256(text.encode()).hexdigest()


def encode(key: str, arrays: Sequence[np.ndarray]) -> bytes:
    """An entry: magic, the key, a digest of the payload, then each array as (ndim, shape,
    float64 little-endian data)."""
    parts = [struct.pack("<I", len(arrays))]
    for a in arrays:
        a = np.ascontiguousarray(a, dtype="<f8")
        parts.append(struct.pack(f"<I{a.ndim}Q", a.ndim, *a.shape))
        parts.append(a.tobytes())
    payload = b"".join(parts)
    return _MAGIC + key.encode() + hashlib.sha256(payload).digest() + payload


def decode(key: str, data: bytes, count: int) -> list[np.ndarray] | None:
    """The arrays of an entry for ``key``, or None if it is not exactly one well-formed entry
    for that key with ``count`` finite arrays."""
    head = _MAGIC + key.encode()
    start = len(head) + 32
    if len(data) < start + 4 or not data.startswith(head):
        return None
    payload = memoryview(data)[start:]
    if hashlib.sha256(payload).digest() != data[len(head):start]:
        return None
    try:
        if struct.unpack_from("<I", payload, 0)[0] != count:
            return None
        at, out = 4, []
        for _ in range(count):
            (ndim,) = struct.unpack_from("<I", payload, at)
            shape = struct.unpack_from(f"<{ndim}Q", payload, at + 4)
            at += 4 + 8 * ndim
            size = math.prod(shape)
            if at + 8 * size > len(payload):
                return None
            a = np.frombuffer(payload, dtype="<f8", count=size, offset=at).reshape(shape).copy()
            if not np.isfinite(a).all():
                return None
            out.append(a)
            at += 8 * size
    except (struct.error, ValueError):
        return None
    return out if at == len(payload) else None


def lookup(
    problem: str,
    args: tuple,
    count: int,
    solve: Callable[[], Sequence[np.ndarray]],
    validate: Callable[[list[np.ndarray]], bool],
) -> list[np.ndarray]:
    """The ``count`` float arrays ``solve()`` returns, from the installed store when it holds a
    valid entry for (problem, the solver's source, args), else solved and stored.  Without a
    store, ``solve()``.  ``validate`` judges a decoded entry (True: trust it)."""
    store = _store
    if store is None:
        return [np.asarray(a, dtype=float) for a in solve()]
    key = entry_key(problem, args)
    data = store.get(key)
    if data is not None:
        arrays = decode(key, data, count)
        if arrays is not None:
            try:
                ok = bool(validate(arrays))
            except (ValueError, IndexError, TypeError):
                ok = False
            if ok:
                return arrays
    arrays = [np.asarray(a, dtype=float) for a in solve()]
    if len(arrays) != count:
        raise ValueError(f"solve_cache.lookup: {problem} gave {len(arrays)} arrays, not {count}")
    store.put(key, encode(key, arrays))
    return arrays


def lookup_many(
    problem: str,
    args_list: Sequence[tuple],
    count: int,
    solve_many: Callable[[list[tuple]], Sequence[Sequence[np.ndarray]]],
    validate: Callable[[tuple, list[np.ndarray]], bool],
) -> list[list[np.ndarray]]:
    """``lookup`` for many problems of one kind at once: the entries the installed store holds
    (each judged by ``validate(args, arrays)``) are read, and all the others are solved by one
    call ``solve_many([args, ...])`` (a batched solver: one result per args, in order) and
    stored, each under the same key as ``lookup`` would use, so the two share entries."""
    store = _store
    out: list[list[np.ndarray] | None] = [None] * len(args_list)
    keys: list[str] = []
    if store is not None:
        keys = [entry_key(problem, args) for args in args_list]
        for i, (key, args) in enumerate(zip(keys, args_list)):
            data = store.get(key)
            arrays = decode(key, data, count) if data is not None else None
            if arrays is not None:
                try:
                    ok = bool(validate(args, arrays))
                except (ValueError, IndexError, TypeError):
                    ok = False
                if ok:
                    out[i] = arrays
    missing = [i for i, arrays in enumerate(out) if arrays is None]
    if missing:
        solved = solve_many([args_list[i] for i in missing])
        if len(solved) != len(missing):
            raise ValueError(f"solve_cache.lookup_many: {problem} gave {len(solved)} results for {len(missing)} problems")
        for i, result in zip(missing, solved):
            arrays = [np.asarray(a, dtype=float) for a in result]
            if len(arrays) != count:
                raise ValueError(f"solve_cache.lookup_many: {problem} gave {len(arrays)} arrays, not {count}")
            out[i] = arrays
            if store is not None:
                store.put(keys[i], encode(keys[i], arrays))
    return out  # type: ignore[return-value]
