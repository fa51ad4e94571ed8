"""``python -m bfemp`` runs the command line."""

import sys

from bfemp.cli import main

sys.exit(main())
