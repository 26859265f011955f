"""``python -m tromplab``: the same command line as the ``tromplab`` script, with the same signal handling."""

import sys

from ._launch import main

if __name__ == "__main__":  # importing the module (pytest's doctest collection does) runs nothing
    sys.exit(main())
