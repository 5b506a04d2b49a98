"""Control meshes from any input nupatch reads: OBJ, USD, or ``-`` (standard input).

``read_control_mesh(source, intervals)`` picks the reader from the suffix (``.usd .usda .usdc
.usdz``: ``export.usd``; anything else: OBJ), reads ``-`` from standard input (``.usda`` text
when it starts with ``#usda``, else OBJ text; binary ``.usdc`` cannot stream) and applies the
``--intervals`` rule (``patching.topology.intervals``).  ``add_intervals_argument`` adds that option to
a sub-command's parser (build, subdivide, info, render).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import patching
from patching.errors import InputFileError
from patching.topology.intervals import INTERVAL_RULES, with_intervals
from patching.mesh import ControlMesh

from .usd import USD_SUFFIXES

__all__ = ["STDIN", "read_control_mesh", "add_intervals_argument", "is_usd"]

#: The file name that means standard input (or output).
STDIN = "-"


def is_usd(source: str | os.PathLike) -> bool:
    return Path(source).suffix.lower() in USD_SUFFIXES


def read_control_mesh(source: str | os.PathLike, intervals: str = "tags") -> ControlMesh:
    """The control mesh of an OBJ or USD file, or of standard input for ``-``, with knot
    intervals by ``intervals`` (tags, uniform, chord, centripetal)."""
    if str(source) == STDIN:
        data = sys.stdin.buffer.read()
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise InputFileError(f"standard input is not UTF-8 text (byte {exc.start}); binary USD cannot stream", "<stdin>") from None
        if text.lstrip().startswith("#usda"):
            from .usd import parse_usda

            mesh = parse_usda(text, "<stdin>", "stdin")
        else:
            from patching.mesh.obj import parse_obj

            mesh = parse_obj(text, source="<stdin>", name="stdin")
    elif is_usd(source):
        from .usd import read_usd

        mesh = read_usd(source)
    else:
        mesh = patching.read_mesh(source)
    return with_intervals(mesh, intervals)


def add_intervals_argument(parser) -> None:
    """``--intervals tags|uniform|chord|centripetal`` (docs/input.md)."""
    parser.add_argument(
        "--intervals", choices=INTERVAL_RULES, default="tags",
        help="knot intervals: tags (the mesh's, default 1), uniform (all 1), chord (each untagged strip "
        "the mean length of its edges), centripetal (its square root)",
    )
