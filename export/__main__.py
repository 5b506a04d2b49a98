"""``python -m export ARGS`` runs the ``nupatch`` command line (where the script is not on PATH)."""

import sys

from export.cli import main

sys.exit(main())
