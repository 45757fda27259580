"""``python -m simbench.cli`` runs the command line (as ``python -m simbench`` does)."""

import sys

from simbench.cli import main

sys.exit(main())
