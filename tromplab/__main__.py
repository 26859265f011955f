"""``python -m tromplab``: the same command line as the ``tromplab`` script."""

import sys

from .cli import main

sys.exit(main())
