"""G-code for a 3-axis ball-end tool path (``patching.toolpath``): RS-274 in millimetres.

Layout: comments naming the tool and parameters, ``G21 G90 G17 G94``, one rapid ``G0 Z`` to the
safe height, then per piece a rapid ``G0 X Y`` above its first point, a vertical feed plunge
``G1 Z``, the piece's points as ``G1 X Y Z`` (the feed given once), and a vertical feed retract
``G1 Z`` to the safe height; ``M30`` at the end.  So a path of p pieces has p + 1 rapid moves.
The programmed point is the tool tip, the ball centre minus R z.  Vertical plunges and
retracts are safe: the drop-cutter placed every centre above all surface points within R of
its axis.  The file is written atomically (``export.atomic.atomic_output``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from patching.errors import NupatchError
from patching.toolpath import ToolPath

from .atomic import atomic_output

__all__ = ["RAPID_RATE", "SUFFIXES", "gcode_lines", "machining_figures", "safe_height", "write_gcode"]

SUFFIXES = (".nc", ".gcode")
#: rapid rate assumed by the time estimate, mm/min.
RAPID_RATE = 5000.0
DIGITS = 5


def safe_height(path: ToolPath, top: float) -> float:
    """Tip height for moves between pieces: the surface's top plus max(R, 1 mm)."""
    return float(max(top, path.tips[:, 2].max()) + max(path.radius, 1.0))


def _xyz(p: np.ndarray) -> str:
    return f"X{p[0]:.{DIGITS}f} Y{p[1]:.{DIGITS}f} Z{p[2]:.{DIGITS}f}"


def gcode_lines(path: ToolPath, feed: float, safe: float, name: str = "") -> list[str]:
    """The program as lines (module docstring)."""
    r = path.radius
    lines = [
        f"(nupatch toolpath{': ' + name if name else ''})",
        f"(tool: ball-end mill, radius {r:g} mm, diameter {2 * r:g} mm, axis +Z; programmed point = tool tip)",
        f"(scallop {path.scallop:g} mm, chord tolerance {path.tolerance:g} mm, feed {feed:g} mm/min)",
        f"(pieces {len(path.pieces)}, points {len(path.tips)}, safe height Z{safe:.{DIGITS}f})",
        "G21 G90 G17 G94",
        f"G0 Z{safe:.{DIGITS}f}",
    ]
    starts = np.flatnonzero(np.r_[True, np.diff(path.piece) != 0])
    ends = np.r_[starts[1:], len(path.piece)]
    for k, (a, b) in enumerate(zip(starts, ends)):
        tips = path.tips[a:b]
        lines.append(f"(piece {k + 1} of {len(starts)}: {path.pieces[k].shape[0]} x {path.pieces[k].shape[1]} faces)")
        lines.append(f"G0 X{tips[0, 0]:.{DIGITS}f} Y{tips[0, 1]:.{DIGITS}f}")
        lines.append(f"G1 Z{tips[0, 2]:.{DIGITS}f} F{feed:g}")
        lines.extend(f"G1 {_xyz(p)}" for p in tips[1:])
        lines.append(f"G1 Z{safe:.{DIGITS}f}")
    lines.append("M30")
    return lines


def machining_figures(path: ToolPath, feed: float, safe: float) -> dict:
    """Lengths (mm) of feed and rapid moves as written, and the estimated time (min)."""
    starts = np.flatnonzero(np.r_[True, np.diff(path.piece) != 0])
    ends = np.r_[starts[1:], len(path.piece)]
    cut, rapid = 0.0, 0.0
    at = None
    for a, b in zip(starts, ends):
        tips = path.tips[a:b]
        cut += float(np.linalg.norm(np.diff(tips, axis=0), axis=1).sum()) + 2 * (safe - 0.5 * (tips[0, 2] + tips[-1, 2]))
        if at is not None:
            rapid += float(np.linalg.norm(tips[0, :2] - at))
        at = tips[-1, :2]
    return {
        "feed": feed,
        "cut_length": cut,
        "rapid_length": rapid,
        "rapid_moves": len(starts) + 1,
        "time_min": cut / feed + rapid / RAPID_RATE,
    }


def write_gcode(path: ToolPath, out: str | os.PathLike, feed: float, top: float, name: str = "") -> Path:
    """Write the program to ``out`` (.nc or .gcode) atomically; returns the path."""
    out = Path(out)
    if out.suffix.lower() not in SUFFIXES:
        raise NupatchError(f"toolpath writes G-code: OUT must end in {' or '.join(SUFFIXES)}", str(out))
    if not (np.isfinite(feed) and feed > 0):
        raise NupatchError(f"the feed must be finite and > 0 mm/min, not {feed:g}", "--feed")
    text = "\n".join(gcode_lines(path, feed, safe_height(path, top), name)) + "\n"
    with atomic_output(out) as tmp:
        tmp.write_text(text)
    return out
