"""One exception family for everything a user can get wrong.

Every message names the problem and, in ``where``, the place: file and line, or vertex,
edge and face ids.  The CLI prints ``nupatch: error: <what> (<where>)`` and exits 2; any
other exception is a bug.
"""

from __future__ import annotations

__all__ = [
    "NupatchError",
    "MeshError",
    "KnotError",
    "TagError",
    "UnsupportedError",
    "InputFileError",
    "OutputError",
    "OptionError",
]


class NupatchError(ValueError):
    """Bad input: ``what`` went wrong ``where``."""

    def __init__(self, what: str, where: str = "") -> None:
        self.what = what
        self.where = where
        super().__init__(f"{what} ({where})" if where else what)


class InputFileError(NupatchError):
    """A file that cannot be read, or is not what it claims to be."""


class MeshError(NupatchError):
    """Malformed or non-manifold connectivity, or bad coordinates."""


class KnotError(NupatchError):
    """Negative, non-finite or conflicting knot intervals."""


class TagError(NupatchError):
    """A tag that names something that does not exist, or a bad sharpness."""


class UnsupportedError(NupatchError):
    """Valid input that this version cannot build yet: refused, never a wrong surface."""


class OutputError(NupatchError):
    """The output cannot be written where asked."""


class OptionError(NupatchError):
    """An option given a value outside its choices (``options.BuildOptions``)."""
