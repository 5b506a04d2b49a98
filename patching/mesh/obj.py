"""OBJ control meshes with OpenSubdiv tags and the project's ``interval`` tag (docs/input.md).

Reads ``v x y z``, ``f a b c ...`` (1-based, ``a/t/n`` forms, negative relative indices) and
``t NAME nint/nfloat/nstring ints... floats... strings...`` with 0-based vertex ids:
``interval`` and ``crease`` (vertex pairs; one value for all pairs or one per pair), ``corner``
(vertices; one value or one per vertex), ``hole`` (faces), ``interpolateboundary`` (0, 1, 2),
``smoothtriangles`` ([OSD]'s regression form ``0/0/1 catmark|smooth``, as ``far_utils.h``
reads it; Hbr's ``1/0/0 2`` is the same rule, ``1/0/0 1`` Hbr's older one, which OpenSubdiv 3
dropped: ignored with a warning), ``creasemethod`` ([OSD]'s ``0/0/1 chaikin``; ``normal``,
its name for uniform creasing, or ``uniform``).
Edge sharpness as [ZBK] sec. 3.5's implementation writes it: ``fs s_0 .. s_{k-1}`` gives the
next face's k edges, ``as y s_0 .. s_{k-1}`` the next y faces' edges, value i on the edge from
the face's vertex i to vertex i + 1 in the file's order (the paper says "clockwise", meaning
its half-edge order; we take the face's own vertex order); each value > 0 becomes a crease tag
on that edge (10 or more: infinitely sharp); where two faces or a ``t crease`` line give one
edge different values, the largest wins, as in [ZBK].  ``vn`` lines are ignored with one
warning (normals are computed, never read).  Every error names the file and line.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from pathlib import Path

import numpy as np

from patching.errors import InputFileError, KnotError, MeshError, TagError
from patching.mesh.control_mesh import ControlMesh, NupatchWarning, from_arrays

__all__ = ["read_obj", "parse_obj", "format_obj"]

# Statements an OBJ file may carry that say nothing about the control mesh.
_IGNORED = {"maplib", "usemap", "vt", "vp", "o", "g", "s", "usemtl", "mtllib", "l", "p", "cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole_", "scrv", "sp", "end", "con", "mg", "bevel", "c_interp", "d_interp", "lod", "shadow_obj", "trace_obj", "ctech", "stech", "call", "csh"}
_KNOWN_TAGS = {"interval", "crease", "corner", "hole", "interpolateboundary", "smoothtriangles", "creasemethod", "nupatch_rules"}


def read_obj(path: str | os.PathLike) -> ControlMesh:
    """Read an OBJ control mesh; the product name is the file's stem."""
    path = Path(path)
    where = str(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(65536)  # sniffed first: /dev/zero or a binary file is not read to its end
            if b"\0" in head:
                raise InputFileError("not an OBJ file (binary data)", where)
            data = head + fh.read()
    except FileNotFoundError:
        raise InputFileError("no such file", where) from None
    except IsADirectoryError:
        raise InputFileError("is a directory, not an OBJ file", where) from None
    except OSError as exc:
        raise InputFileError(f"cannot read file: {exc.strerror or exc}", where) from None
    if b"\0" in data[:65536]:
        raise InputFileError("not an OBJ file (binary data)", where)
    try:
        text = data.decode("utf-8-sig")  # a byte-order mark (Windows editors) is no statement
    except UnicodeDecodeError as exc:
        raise InputFileError(f"not an OBJ file (not UTF-8 text at byte {exc.start})", where) from None
    if text.lstrip().startswith("ISO-10303-21"):
        raise InputFileError("this is a STEP file, not an OBJ control mesh", where)
    return parse_obj(text, source=path.name, name=path.stem)


def _number(token: str, what: str, loc: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise InputFileError(f"cannot read {what} '{token}' as a number", loc) from None
    return value


#: OBJ's white space between tokens: ASCII only.  str.split() would also split on U+2028,
#: U+0085, form feeds and the like, and str.splitlines() would start a new statement there.
_BLANK = re.compile(r"[ \t\r\f\v]+")


def _statements(text: str):
    """Yield (line number, statement text) for the non-empty statements of OBJ text: physical
    lines end at "\n" only (a "\r" before it is dropped), a line ending in "\\" continues on
    the next one (the OBJ specification's continuation), "#" starts a comment, tokens are
    separated by ASCII blanks and rejoined by single spaces."""
    pending: list[str] = []
    first = 0
    for lineno, raw in enumerate(text.split("\n"), start=1):
        if raw.endswith("\r"):
            raw = raw[:-1]
        if not pending:
            first = lineno
        stripped = raw.rstrip(" \t\r\f\v")
        if stripped.endswith("\\") and "#" not in stripped:
            pending.append(stripped[:-1])
            continue
        pending.append(raw)
        line = " ".join(pending).split("#", 1)[0]
        pending = []
        tokens = [t for t in _BLANK.split(line) if t]
        if tokens:
            yield first, " ".join(tokens)
    if pending:
        tokens = [t for t in _BLANK.split(" ".join(pending).split("#", 1)[0]) if t]
        if tokens:
            yield first, " ".join(tokens)


def parse_obj(text: str, source: str = "<string>", name: str = "mesh") -> ControlMesh:
    """Parse OBJ text; ``source`` names the file in error messages."""
    vertices: list[tuple[float, float, float]] = []
    faces: list[list[int]] = []
    intervals: dict[tuple[int, int], float] = {}
    creases: dict[tuple[int, int], float] = {}
    corners: dict[int, float] = {}
    holes: list[int] = []
    interpolate_boundary = 1
    options = {"triangle_subdivision": "catmark", "crease_method": "uniform"}  # mesh-wide tags other than interpolateboundary
    locations: dict[tuple, str] = {}
    pending: list[tuple[list[float], str]] = []  # fs/as sharpness waiting for their faces
    face_sharp: dict[tuple[int, int], float] = {}
    warned_vn = False

    for lineno, line in _statements(text):
        loc = f"{source}:{lineno}"
        parts = line.split(" ")
        key = parts[0]
        if key == "v":
            if len(parts) < 4:
                raise InputFileError("vertex needs three coordinates", loc)
            xyz = tuple(_number(t, "coordinate", loc) for t in parts[1:4])
            if not all(math.isfinite(c) for c in xyz):
                raise MeshError(f"non-finite coordinate of vertex {len(vertices)}", loc)
            locations[("vertex", len(vertices))] = loc
            vertices.append(xyz)  # type: ignore[arg-type]
        elif key == "f":
            face = []
            for token in parts[1:]:
                head = token.split("/", 1)[0]
                try:
                    index = int(head)
                except ValueError:
                    raise InputFileError(f"cannot read face index '{token}'", loc) from None
                if index == 0:
                    raise MeshError("face index 0 (OBJ indices start at 1)", loc)
                if index < 0:
                    index = len(vertices) + index + 1
                    if index <= 0:
                        raise MeshError(f"relative face index {head} points before the first vertex", loc)
                face.append(index - 1)
            if len(face) < 3:
                raise MeshError(f"face with {len(face)} vertices, at least 3 needed", loc)
            locations[("face", len(faces))] = loc
            faces.append(face)
            if pending:
                values, where = pending.pop(0)
                if len(values) != len(face):
                    raise InputFileError(f"edge sharpness for a face of {len(face)} vertices has {len(values)} values ({where})", loc)
                for i, value in enumerate(values):
                    if value > 0:
                        a, b = face[i], face[(i + 1) % len(face)]
                        key = (min(a, b), max(a, b))
                        face_sharp[key] = max(face_sharp.get(key, 0.0), value)
                        locations.setdefault(("crease", key), where)
        elif key in ("fs", "as"):
            args = parts[1:]
            count = 1
            if key == "as":
                try:
                    count = int(args[0])
                except (ValueError, IndexError):
                    raise InputFileError("'as' needs a face count and sharpness values", loc) from None
                if count < 1:
                    raise InputFileError(f"'as' face count must be >= 1, got {count}", loc)
                args = args[1:]
            values = [_number(t, "sharpness", loc) for t in args]
            if not values or any(math.isnan(x) or x < 0 for x in values):
                raise TagError(f"'{key}' needs sharpness values >= 0", loc)
            pending.extend([(values, loc)] * count)
        elif key == "vn":
            if not warned_vn:
                warnings.warn(NupatchWarning(f"vn normals ignored: normals are computed from the mesh ({loc})"), stacklevel=2)
                warned_vn = True
        elif key == "t":
            interpolate_boundary = _parse_tag(
                parts, loc, intervals, creases, corners, holes, interpolate_boundary, locations, options
            )
        elif key in _IGNORED:
            continue
        else:
            raise InputFileError(f"not an OBJ statement: '{key}'", loc)

    if pending:
        raise InputFileError(f"edge sharpness for {len(pending)} face(s) after the last face", pending[0][1])
    for key, value in face_sharp.items():
        creases[key] = max(creases.get(key, 0.0), value)
    if not faces:
        raise MeshError("empty mesh: no faces", source)
    n = len(vertices)
    for f, face in enumerate(faces):
        for v in face:
            if v >= n:
                raise MeshError(
                    f"face index {v + 1} out of range (the file has {n} vertices)", locations[("face", f)]
                )
    return from_arrays(
        np.array(vertices, dtype=np.float64).reshape(-1, 3),
        faces,
        intervals=intervals,
        creases=creases,
        corners=corners,
        holes=holes,
        interpolate_boundary=interpolate_boundary,
        name=name,
        locations=locations,
        triangle_subdivision=options["triangle_subdivision"],
        crease_method=options["crease_method"],
    )


def _parse_tag(parts, loc, intervals, creases, corners, holes, interpolate_boundary, locations, options) -> int:
    if len(parts) < 3:
        raise InputFileError("tag needs a name and counts nint/nfloat/nstring", loc)
    tag = parts[1]
    try:
        nint, nfloat, nstring = (int(x) for x in parts[2].split("/"))
    except ValueError:
        raise InputFileError(f"tag counts '{parts[2]}' are not nint/nfloat/nstring", loc) from None
    args = parts[3:]
    if min(nint, nfloat, nstring) < 0 or len(args) != nint + nfloat + nstring:
        raise InputFileError(f"tag '{tag}' declares {nint}/{nfloat}/{nstring} arguments, has {len(args)}", loc)
    try:
        ints = [int(a) for a in args[:nint]]
    except ValueError:
        raise InputFileError(f"tag '{tag}' has a non-integer id", loc) from None
    floats = [_number(a, f"{tag} value", loc) for a in args[nint : nint + nfloat]]
    strings = args[nint + nfloat :]
    if tag == "controlvector":  # read by nupatch subdivide (patching.curves.surface_vectors)
        warnings.warn(NupatchWarning(f"control vector ignored: only 'nupatch subdivide' and 'nupatch build' of a grid use them ({loc})"), stacklevel=3)
        return interpolate_boundary
    if tag not in _KNOWN_TAGS:
        warnings.warn(NupatchWarning(f"unknown tag '{tag}' ignored ({loc})"), stacklevel=3)
        return interpolate_boundary
    if tag in ("interval", "crease"):
        if nint == 0 or nint % 2:
            raise InputFileError(f"{tag} tag needs vertex pairs, got {nint} ids", loc)
        pairs = [(ints[k], ints[k + 1]) for k in range(0, nint, 2)]
        values = _values_for(tag, floats, len(pairs), loc)
        error = KnotError if tag == "interval" else TagError
        target = intervals if tag == "interval" else creases
        for (a, b), value in zip(pairs, values):
            if math.isnan(value) or value < 0 or (tag == "interval" and math.isinf(value)):
                raise error(f"{tag} {value} of edge {a}-{b} must be finite and >= 0", loc)
            key = (min(a, b), max(a, b))
            if key in target and math.isclose(target[key], value, rel_tol=1e-12, abs_tol=0.0):
                value = target[key]  # equal up to decimal round-off: the first one stands
            if key in target and target[key] != value:
                raise error(
                    f"edge {a}-{b} has two {tag} values, {target[key]!r} and {value!r}",
                    f"{locations[(tag, key)]} and {loc}",
                )
            target[key] = value
            locations[(tag, key)] = loc
    elif tag == "corner":
        values = _values_for(tag, floats, nint, loc)
        for v, s in zip(ints, values):
            if math.isnan(s) or s < 0:
                raise TagError(f"corner sharpness {s} of vertex {v} must be >= 0", loc)
            if v in corners and math.isclose(corners[v], s, rel_tol=1e-12, abs_tol=0.0):
                s = corners[v]
            if v in corners and corners[v] != s:
                raise TagError(f"vertex {v} has two corner values, {corners[v]!r} and {s!r}", f"{locations[('corner', v)]} and {loc}")
            corners[v] = s
            locations[("corner", v)] = loc
    elif tag == "hole":
        for f in ints:
            holes.append(f)
            locations[("hole", f)] = loc
    elif tag == "nupatch_rules":
        pass  # the subdivision rules a refined mesh was made with (nupatch subdivide): a record
    elif tag == "interpolateboundary":
        if nint != 1 or ints[0] not in (0, 1, 2):
            raise TagError("interpolateboundary takes one integer 0, 1 or 2", loc)
        return ints[0]
    elif tag == "smoothtriangles":
        locations[("tag", "smoothtriangles")] = loc
        if nstring == 1 and nint == 0 and strings[0] in ("catmark", "smooth"):
            options["triangle_subdivision"] = strings[0]
        elif nint == 1 and nstring == 0 and ints[0] == 2:  # Hbr's k_New: OpenSubdiv 3's TRI_SUB_SMOOTH
            options["triangle_subdivision"] = "smooth"
        elif nint == 1 and nstring == 0 and ints[0] == 1:
            warnings.warn(NupatchWarning(f"smoothtriangles 1 (Hbr's old triangle rule, not in OpenSubdiv 3) ignored ({loc})"), stacklevel=3)
        else:
            raise TagError("smoothtriangles takes one string, catmark or smooth (t smoothtriangles 0/0/1 smooth)", loc)
    elif tag == "creasemethod":
        locations[("tag", "creasemethod")] = loc
        # OpenSubdiv's readers (far_utils.h) and RenderMan say "normal" for CREASE_UNIFORM.
        method = {"uniform": "uniform", "normal": "uniform", "chaikin": "chaikin"}.get(strings[0] if nstring else "")
        if nint or nfloat or nstring != 1 or method is None:
            raise TagError("creasemethod takes one string, uniform (or normal) or chaikin (t creasemethod 0/0/1 chaikin)", loc)
        options["crease_method"] = method
    return interpolate_boundary


def _values_for(tag: str, floats: list[float], count: int, loc: str) -> list[float]:
    if len(floats) == 1:
        return floats * count
    if len(floats) == count:
        return floats
    raise InputFileError(f"{tag} tag has {len(floats)} values for {count} items (give 1 or {count})", loc)


def format_obj(mesh: ControlMesh, comment: str = "") -> str:
    """The OBJ text of a control mesh with its tags, so that ``parse_obj`` reads it back
    (``export.write_obj`` writes it to a file atomically)."""
    # One %-format of a repeated template per kind of line: the loop over lines runs in C
    # (37k faces: 0.39 s before, line by line).  "%r" is repr, as f"{x!r}" was, and "%d" of a
    # Python int is str(), so the text is the same to the byte.
    parts = [f"# {line}\n" for line in comment.splitlines()]
    parts.append(_repeat("v %r %r %r\n", mesh.vertices.tolist()))
    parts.append(_face_text(mesh))
    parts.append(_repeat("t interval 2/1/0 %d %d %r\n", [(a, b, d) for (a, b), d in sorted(mesh.intervals.items())]))
    parts.append(_repeat("t crease 2/1/0 %d %d %r\n", [(a, b, c) for (a, b), c in sorted(mesh.creases.items())]))
    parts.append(_repeat("t corner 1/1/0 %d %r\n", sorted(mesh.corners.items())))
    parts.append(_repeat("t hole 1/0/0 %d\n", [(f,) for f in sorted(mesh.holes)]))
    parts.append(f"t interpolateboundary 1/0/0 {mesh.interpolate_boundary}\n")
    if mesh.triangle_subdivision != "catmark":
        parts.append(f"t smoothtriangles 0/0/1 {mesh.triangle_subdivision}\n")
    if mesh.crease_method != "uniform":
        parts.append(f"t creasemethod 0/0/1 {mesh.crease_method}\n")
    return "".join(parts)


def _repeat(template: str, rows: list) -> str:
    """``template`` filled with each row (a sequence of its fields), all rows in one format."""
    if not rows:
        return ""
    return (template * len(rows)) % tuple(x for row in rows for x in row)


def _face_text(mesh: ControlMesh) -> str:
    """The ``f`` lines, 1-based, in face order, as ``"f %d %d ...\n"`` would write them, formatted
    with numpy: every index's decimal digits in a row of a byte table (``f`` before a face's
    first index, a newline after its last, zero bytes as padding), the zero bytes dropped.
    A Python format per line costs ~1 us a face (37k faces: 0.12 s against 0.02 s)."""
    if mesh.face_sizes.size == 0:
        return ""
    x = mesh.face_vertices + 1
    width = len(str(int(x.max())))
    x = x.astype(np.int32 if width < 10 else np.int64)
    table = np.zeros((x.size, width + 3), np.uint8)
    table[mesh.face_offsets[:-1], 0] = ord("f")
    table[:, 1] = ord(" ")
    rest = x
    for place in range(width):  # column width + 1 - place: the digit of 10^place
        rest, digit = np.divmod(rest, 10)
        digit += ord("0")
        if place:
            digit *= x >= 10**place  # no leading zeros
        table[:, width + 1 - place] = digit
    table[mesh.face_offsets[1:] - 1, width + 2] = ord("\n")
    return table[table != 0].tobytes().decode("ascii")
