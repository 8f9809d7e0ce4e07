"""``python -m pysindy_mme.cli`` runs the command line (same as ``pysindy-mme``)."""

import sys

from .main import main

sys.exit(main())
