"""``python -m tromplab``: the same command line as the ``tromplab`` script."""

import sys

from .cli import main

if __name__ == "__main__":  # importing the module (pytest's doctest collection does) runs nothing
    sys.exit(main())
