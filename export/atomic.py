"""The one atomic-write wrapper of every export format (DESIGN 3, STYLE 5).

``atomic_output(path)`` is ``patching.atomic.atomic_path``: a temporary file in the target's
directory, fsync'd and renamed onto ``path`` only if the writer succeeds; on any failure the
temporary file is removed and a file already at ``path`` is untouched.  It lives in
``patching`` (pure Python) so that the OBJ writer of ``subdivide`` uses the same code.
"""

from __future__ import annotations

from patching.atomic import atomic_path as atomic_output
from patching.atomic import umask

__all__ = ["atomic_output", "umask"]
