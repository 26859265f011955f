"""Write tests/reference/other_curves.csv: mpmath reference values of the other tools' curves.

A thin wrapper: the generator (``reference_text``, with the sources of every expression in
its docstring) lives beside the file it writes, in tests/reference/make_other_curve_references.py,
where the test suite regenerates the file and compares.  Needs mpmath; run from anywhere:
``python analysis/make_other_curve_references.py``.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tests.reference.make_other_curve_references import main  # noqa: E402

if __name__ == "__main__":
    main()
