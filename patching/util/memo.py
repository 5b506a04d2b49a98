"""An in-process memo that a batched solver can fill: ``functools.lru_cache``'s interface
(``cache_clear``, ``cache_info``) plus ``known`` and ``prime``, so that a caller holding many
local problems of one kind can ask which are already solved, solve the rest in one vectorised
call and put the results in, after which the one-problem function returns them unchanged.

Eviction is first in, first out once ``maxsize`` entries are held (a build meets a few
thousand distinct configurations; the bound only keeps a long-lived process from growing).
Switching ``set_batching(False)`` makes the batched callers solve problem by problem through
the one-problem functions (the reference path the tests compare the batched one against).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Hashable
from typing import Any, NamedTuple

__all__ = ["Memo", "memo", "batching", "set_batching"]

_batching = [True]


def batching() -> bool:
    """True (the default) when local problems are solved in batches."""
    return _batching[0]


def set_batching(on: bool) -> bool:
    """Batch local problems (True) or solve them one by one; returns the previous setting."""
    previous, _batching[0] = _batching[0], bool(on)
    return previous


class CacheInfo(NamedTuple):
    hits: int
    misses: int
    maxsize: int
    currsize: int


class Memo:
    """``fn`` memoised on its positional arguments (module docstring)."""

    def __init__(self, fn: Callable[..., Any], maxsize: int = 8192) -> None:
        functools.update_wrapper(self, fn)
        self._fn = fn
        self._maxsize = maxsize
        self._values: dict[Hashable, Any] = {}
        self._hits = self._misses = 0
        self._lock = threading.Lock()  # builds in threads share the memo (as lru_cache allows)

    def __call__(self, *args: Hashable) -> Any:
        try:
            value = self._values[args]
        except KeyError:
            self._misses += 1
            value = self._fn(*args)
            self.prime(args, value)
            return value
        self._hits += 1
        return value

    def known(self, args: tuple) -> bool:
        """True if ``self(*args)`` would not compute."""
        return args in self._values

    def prime(self, args: tuple, value: Any) -> None:
        """Store ``value`` as the result for ``args``."""
        with self._lock:
            if args not in self._values and len(self._values) >= self._maxsize:
                del self._values[next(iter(self._values))]
            self._values[args] = value

    def cache_clear(self) -> None:
        with self._lock:
            self._values.clear()
        self._hits = self._misses = 0

    def cache_info(self) -> CacheInfo:
        return CacheInfo(self._hits, self._misses, self._maxsize, len(self._values))


def memo(maxsize: int = 8192) -> Callable[[Callable[..., Any]], Memo]:
    """Decorator: ``@memo()`` makes a :class:`Memo`."""
    return lambda fn: Memo(fn, maxsize)
