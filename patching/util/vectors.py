"""Small vector helpers for large arrays of 3-vectors."""

from __future__ import annotations

import numpy as np

__all__ = ["cross3"]


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (length 3) of equally shaped arrays: (a1 b2 - a2 b1,
    a2 b0 - a0 b2, a0 b1 - a1 b0), the products and differences ``np.cross`` forms, so the
    same floats to the bit; without its copies of non-contiguous inputs (the transposed
    results of ``patching.bernstein.contract``) and its moving of axes, ~2x faster on the
    (patches, samples, 3) arrays of a build."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=np.result_type(a, b))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out
