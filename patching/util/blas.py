"""One BLAS thread for the many small dense solves of a build.

The construction solves thousands of small dense problems (angle configurations, red
operators, cluster fairings: matrices of tens to a few hundred rows).  OpenBLAS, which numpy
and scipy bring, runs each on as many threads as there are cores, and its threads spin while
they wait for work: on matrices this small that only costs time, and as soon as another
process (or ``nupatch build -j 2``, or our own sparse-product threads) wants the cores, every
call waits for the spinning threads.  Measured on catmark_lefthanded (434 faces, 30 EP
clusters, 2 cores): five builds 12.5 s alone and 41 s with a second build running, against
1.6 s and 1.5 s under this limit.  ``threadpoolctl`` (the scikit-learn developers'
tool for exactly this, already installed with build123d's scikit-learn) sets the limit for the
duration of a call and restores it after, so a caller's own numpy work keeps its threads.
"""

from __future__ import annotations

import functools
from typing import Callable, TypeVar

from threadpoolctl import threadpool_limits

__all__ = ["one_blas_thread"]

F = TypeVar("F", bound=Callable)


def one_blas_thread(fn: F) -> F:
    """Run ``fn`` with BLAS limited to one thread (module docstring); 0.7 ms per call."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
