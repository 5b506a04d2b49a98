"""Reading a control polygon from OBJ text: ``v``, one ``l`` polyline, corner and vector tags.

Format (docs/cli.md, ``nupatch curve``): ``v x y z`` vertices; ``l i j k ...`` (1-based, negative
relative indices allowed, ``a/t`` forms) the polygon, closed when its last index repeats its
first; several ``l`` statements are joined when each starts where the previous ended.  Tags
in OpenSubdiv's syntax with 0-based vertex ids (the ``v`` numbering):

- ``t corner 1/1/0 v s``: sharpness s of vertex v (0 smooth, 0 < s < 10 semi-sharp,
  s >= 10 or ``inf`` infinitely sharp);
- ``t controlvector 1/3/0 v x y z`` (infinitely sharp) or ``t controlvector 1/4/0 v x y z s``:
  a control vector at vertex v ([KSD] sec. 4).

Unknown tags give a warning and are ignored; ``vt vn g o s usemtl mtllib`` are ignored.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputFileError, MeshError, TagError
from ..mesh import NupatchWarning

__all__ = ["Polyline", "parse_polyline", "read_polyline"]

_IGNORED = {"vt", "vn", "g", "o", "s", "usemtl", "mtllib", "vp", "f"}


@dataclass
class Polyline:
    """The parsed file: polygon points (n, 3), closed flag, per-vertex tags (polygon indices)."""

    points: np.ndarray
    closed: bool
    corners: dict[int, float] = field(default_factory=dict)
    vectors: dict[int, tuple[np.ndarray, float]] = field(default_factory=dict)
    name: str = "curve"
    #: polygon index -> "file:line" of the vertex, for messages
    vertex_ids: list[int] = field(default_factory=list)


def _number(token: str, what: str, loc: str) -> float:
    try:
        return float(token)
    except ValueError:
        raise InputFileError(f"cannot read {what} '{token}'", loc) from None


def _sharpness(token: str, vertex: int, loc: str) -> float:
    s = _number(token, "sharpness", loc)
    if math.isnan(s):
        raise TagError(f"sharpness of vertex {vertex} is NaN", loc)
    if s < 0:
        raise TagError(f"negative sharpness {token} of vertex {vertex}", loc)
    return math.inf if s >= 10 else s


def parse_polyline(text: str, source: str = "<string>", name: str = "curve") -> Polyline:
    """Parse OBJ text into a Polyline; errors name ``source`` and the line."""
    vertices: list[tuple[float, float, float]] = []
    chain: list[int] = []
    chain_loc = ""
    corner_tags: list[tuple[int, float, str]] = []
    vector_tags: list[tuple[int, np.ndarray, float, str]] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        loc = f"{source}:{lineno}"
        parts = line.split()
        key = parts[0]
        if key == "v":
            if len(parts) < 3:
                raise InputFileError("vertex needs at least two coordinates", loc)
            xyz = [_number(t, "coordinate", loc) for t in parts[1:4]]
            xyz += [0.0] * (3 - len(xyz))
            if not all(math.isfinite(c) for c in xyz):
                raise MeshError(f"non-finite coordinate of vertex {len(vertices)}", loc)
            vertices.append(tuple(xyz))  # type: ignore[arg-type]
        elif key == "l":
            idx = []
            for token in parts[1:]:
                head = token.split("/", 1)[0]
                try:
                    i = int(head)
                except ValueError:
                    raise InputFileError(f"cannot read polyline index '{token}'", loc) from None
                if i == 0:
                    raise MeshError("polyline index 0 (OBJ indices start at 1)", loc)
                i = len(vertices) + i if i < 0 else i - 1
                if not 0 <= i < len(vertices):
                    raise MeshError(f"polyline index {head} out of range ({len(vertices)} vertices so far)", loc)
                idx.append(i)
            if not idx:
                raise MeshError("empty polyline", loc)
            if chain and chain[-1] == idx[0]:
                chain.extend(idx[1:])
            elif chain:
                raise MeshError("a second polyline that does not continue the first (one curve per file)", loc)
            else:
                chain, chain_loc = idx, loc
        elif key == "t":
            if len(parts) < 3:
                raise InputFileError("tag needs a name and counts", loc)
            tag = parts[1]
            try:
                ni, nf, ns = (int(c) for c in parts[2].split("/"))
            except ValueError:
                raise InputFileError(f"cannot read tag counts '{parts[2]}'", loc) from None
            args = parts[3:]
            if len(args) < ni + nf + ns:
                raise InputFileError(f"tag {tag} announces {ni + nf + ns} values, has {len(args)}", loc)
            if tag == "corner":
                if (ni, nf) != (1, 1):
                    raise TagError("corner tag needs 1/1/0: vertex and sharpness", loc)
                try:
                    v = int(args[0])
                except ValueError:
                    raise InputFileError(f"cannot read vertex id '{args[0]}'", loc) from None
                corner_tags.append((v, _sharpness(args[1], v, loc), loc))
            elif tag == "controlvector":
                if ni != 1 or nf not in (3, 4):
                    raise TagError("controlvector tag needs 1/3/0 (vertex x y z) or 1/4/0 (... sharpness)", loc)
                try:
                    v = int(args[0])
                except ValueError:
                    raise InputFileError(f"cannot read vertex id '{args[0]}'", loc) from None
                vec = np.array([_number(t, "vector component", loc) for t in args[1:4]])
                if not np.isfinite(vec).all():
                    raise TagError(f"non-finite control vector at vertex {v}", loc)
                s = _sharpness(args[4], v, loc) if nf == 4 else math.inf
                vector_tags.append((v, vec, s, loc))
            else:
                warnings.warn(f"unknown tag '{tag}' ignored ({loc})", NupatchWarning, stacklevel=2)
        elif key in _IGNORED:
            continue
        else:
            raise InputFileError(f"not an OBJ statement: '{key}'", loc)
    if not chain:
        raise MeshError("no polyline ('l' statement)", source)
    closed = len(chain) > 2 and chain[-1] == chain[0]
    if closed:
        chain = chain[:-1]
    if len(chain) < 2:
        raise MeshError(f"a polyline of {len(chain)} vertex needs at least 2", chain_loc)
    if len(set(chain)) != len(chain):
        raise MeshError("the polyline visits a vertex twice", chain_loc)
    position = {v: k for k, v in enumerate(chain)}
    corners: dict[int, float] = {}
    for v, s, loc in corner_tags:
        if v not in position:
            raise TagError(f"corner on vertex {v}, which is not on the polyline", loc)
        corners[position[v]] = s
    vectors: dict[int, tuple[np.ndarray, float]] = {}
    for v, vec, s, loc in vector_tags:
        if v not in position:
            raise TagError(f"control vector on vertex {v}, which is not on the polyline", loc)
        vectors[position[v]] = (vec, s)
    points = np.array([vertices[v] for v in chain], dtype=np.float64)
    return Polyline(points, closed, corners, vectors, name, chain)


def read_polyline(path: str | os.PathLike) -> Polyline:
    """Read an OBJ polyline file (``parse_polyline``); the curve is named after the file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise InputFileError(f"cannot read the file ({exc.strerror})", str(path)) from None
    except UnicodeDecodeError:
        raise InputFileError("not a text file", str(path)) from None
    return parse_polyline(text, str(path), path.stem)
