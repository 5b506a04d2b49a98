"""Argument checks of the public Python API: the project's own errors, naming the argument.

Every public entry point (``from_arrays``, ``build``, ``build_operator``,
``SurfaceOperator.evaluate``, ``export.check_continuity``) calls these before any work, so a
wrong type or shape is a MeshError, KnotError or TagError that names the argument, never a
TypeError from deep inside numpy, a silently truncated float index, or OpenCASCADE's
``Standard_NullObject`` later.  The geometric checks here (``check_points``) also refuse
degenerate control nets: all used points on a line (a surface of no area), or, for a closed
surface, on a plane (it encloses no volume); the bounding size is that of the used points only.
"""

from __future__ import annotations

import math
import numbers
from typing import Any, Mapping

import numpy as np

from .errors import MeshError, NupatchError, TagError

__all__ = [
    "DEGENERATE_RATIO",
    "as_points",
    "as_faces",
    "as_edge_tag",
    "as_vertex_tag",
    "as_holes",
    "as_name",
    "as_choice",
    "check_points",
    "used_size",
]

#: Singular values of the centred used points below this fraction of the largest are zero: the
#: points lie on a line (second) or a plane (third).  1e-12: far above round-off (1e-16 x
#: size) and far below any real model's thickness.
DEGENERATE_RATIO = 1e-12


def _real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def as_points(points: Any, argument: str = "vertices", rows: int | None = None, error=MeshError) -> np.ndarray:
    """(n, 3) float64 finite points, else ``error`` naming ``argument`` (and the first bad row)."""
    if isinstance(points, (str, bytes)) or points is None:
        raise error(f"{argument} must be an (n, 3) array of numbers, not {type(points).__name__}", argument)
    try:
        array = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise error(f"{argument} must be an (n, 3) array of numbers ({exc})", argument) from None
    if array.ndim != 2 or array.shape[1] != 3:
        raise error(f"{argument} must have shape (n, 3), got {array.shape}", argument)
    if rows is not None and array.shape[0] != rows:
        raise error(f"{argument} must have {rows} rows (one per control point), got {array.shape[0]}", argument)
    bad = np.flatnonzero(~np.isfinite(array).all(axis=1))
    if bad.size:
        raise error(f"{argument} row {int(bad[0])} is not finite ({array[bad[0]].tolist()})", argument)
    return array


def as_faces(faces: Any, argument: str = "faces") -> list[np.ndarray] | np.ndarray:
    """An (f, k) int64 array or a list of int64 index arrays; MeshError for a flat list, a 3-D
    array, float indices that are not whole numbers, or anything not made of integers."""
    if isinstance(faces, (str, bytes)) or faces is None or isinstance(faces, numbers.Number):
        raise MeshError(f"{argument} must be a list of index lists or an (f, k) array, not {type(faces).__name__}", argument)
    if isinstance(faces, np.ndarray):
        if faces.ndim != 2:
            raise MeshError(f"{argument} must be an (f, k) array or a list of index lists, got shape {faces.shape}", argument)
        return _integers(faces, argument)
    try:
        items = list(faces)
    except TypeError:
        raise MeshError(f"{argument} must be a list of index lists, not {type(faces).__name__}", argument) from None
    out = []
    for f, face in enumerate(items):
        try:
            ndim = np.ndim(face)
        except ValueError:  # ragged nesting
            ndim = -1
        if isinstance(face, (str, bytes)) or ndim != 1:
            raise MeshError(
                f"{argument}[{f}] must be a list of vertex indices, got {type(face).__name__}"
                + (" (faces given as one flat list?)" if ndim == 0 else ""),
                argument,
            )
        out.append(_integers(face, f"{argument}[{f}]"))
    return out


def _integers(values: Any, argument: str) -> np.ndarray:
    array = np.asarray(values)
    if array.dtype == object or array.dtype.kind not in "iuf" or array.dtype == bool:
        raise MeshError(f"{argument} must hold integer vertex indices, got {array.dtype} values", argument)
    if array.dtype.kind == "f":
        if not np.all(np.isfinite(array)) or np.any(array != np.round(array)):
            raise MeshError(f"{argument} holds non-integer indices", argument)
    return array.astype(np.int64)


def _integer(value: Any, what: str, argument: str, error) -> int:
    if isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, bool):
        return int(value)
    if _real(value) and float(value).is_integer():
        return int(value)
    raise error(f"{argument}: {what} {value!r} is not an integer id", argument)


def _value(value: Any, key: Any, argument: str, error) -> float:
    if not _real(value):
        raise error(f"{argument}[{key!r}] = {value!r} is not a number", argument)
    return float(value)


def _mapping(tag: Any, argument: str, error) -> Mapping:
    if tag is None:
        return {}
    if not isinstance(tag, Mapping):
        raise error(f"{argument} must be a dict, not {type(tag).__name__}", argument)
    return tag


def as_edge_tag(tag: Any, argument: str, error=TagError) -> dict[tuple[int, int], float]:
    """{(a, b): value} with integer vertex pairs and real values, else ``error`` naming ``argument``."""
    out = {}
    for key, value in _mapping(tag, argument, error).items():
        if isinstance(key, (str, bytes)) or not isinstance(key, (tuple, list)) or len(key) != 2:
            raise error(f"{argument} keys must be vertex pairs (a, b), not {key!r}", argument)
        a, b = (_integer(x, "vertex", argument, error) for x in key)
        out[(a, b)] = _value(value, key, argument, error)
    return out


def as_vertex_tag(tag: Any, argument: str = "corners") -> dict[int, float]:
    """{v: value} with integer vertex ids and real values, else TagError naming ``argument``."""
    out = {}
    for key, value in _mapping(tag, argument, TagError).items():
        out[_integer(key, "vertex", argument, TagError)] = _value(value, key, argument, TagError)
    return out


def as_holes(holes: Any, argument: str = "holes") -> list[int]:
    """A sequence of integer face ids, else TagError naming ``argument``."""
    if holes is None:
        return []
    if isinstance(holes, (str, bytes, numbers.Number)) or isinstance(holes, Mapping):
        raise TagError(f"{argument} must be a sequence of face ids, not {type(holes).__name__}", argument)
    try:
        items = list(holes)
    except TypeError:
        raise TagError(f"{argument} must be a sequence of face ids, not {type(holes).__name__}", argument) from None
    return [_integer(h, "face", argument, TagError) for h in items]


def as_name(name: Any, argument: str = "name") -> str:
    """A non-empty product name (str), else MeshError naming ``argument``."""
    if not isinstance(name, str) or not name.strip():
        raise MeshError(f"{argument} must be a non-empty string, not {name!r}", argument)
    return name


def as_choice(value: Any, choices, argument: str) -> str:
    """``value`` if it is one of ``choices``, else NupatchError listing them."""
    if not isinstance(value, str) or value not in choices:
        raise NupatchError(f"{argument} must be one of {', '.join(map(repr, choices))}, not {value!r}", argument)
    return value


def used_size(points: np.ndarray, used: np.ndarray | None = None) -> float:
    """Diagonal of the bounding box of the used points (all points if ``used`` is None): the
    length tolerances are relative to; a stray unused vertex does not change it."""
    p = points if used is None else points[used]
    return float(np.linalg.norm(np.ptp(p, axis=0))) if len(p) else 0.0


def check_points(points: np.ndarray, used: np.ndarray | None = None, closed: bool = False, where: str = "mesh") -> None:
    """MeshError for a degenerate net: the used points all on one line (a surface of no area).
    The singular values of the centred points, relative to the largest, are compared with
    DEGENERATE_RATIO.  A closed surface whose points lie on a plane is not refused here: it
    encloses no volume, and the B-rep makes each such component a shell with a warning
    (``export.brep``), judged on its own scale.  ``closed`` is kept for callers."""
    p = points if used is None else points[used]
    if len(p) < 3:  # no patch at all: build() names the cause (holes, zero intervals)
        return
    sv = np.linalg.svd(p - p.mean(axis=0), compute_uv=False)
    if sv[0] == 0.0:  # all on one point: the B-rep names the first side of no length
        return
    if sv[1] <= DEGENERATE_RATIO * sv[0]:
        raise MeshError("degenerate geometry: all control points lie on a line, the surface has no area", where)


def finite_number(value: Any, argument: str, *, positive: bool = False, integer: bool = False) -> float:
    """A finite real (> 0 if ``positive``, whole if ``integer``), else NupatchError naming it."""
    if not _real(value) or not math.isfinite(float(value)) or (positive and not float(value) > 0) or (
        integer and not float(value).is_integer()
    ):
        kind = "a whole number" if integer else "a finite number"
        raise NupatchError(f"{argument} must be {kind}{' > 0' if positive else ''}, not {value!r}", argument)
    return float(value)
