"""``python -m hpdob`` runs the command-line interface."""

import sys

from ._entry import main  # first: it installs the signal handlers (hpdob._entry)

sys.exit(main())
