"""``python -m simbench`` runs the command line."""

import sys

from simbench.cli import main

sys.exit(main())
