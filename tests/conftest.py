import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tromplab.curves.formulas import FORMULAS

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = Path(__file__).resolve().parent / "reference"
DATASETS = ROOT / "datasets"

#: A small, valid lab table of per-class percentages (open top class), for tests that break it.
LAB_CLASS_HEADER = "size_lower,size_upper,feed_pct,fine_pct,coarse_pct\n"
LAB_CLASS_ROWS = (
    "800,,5,0,9.2",
    "400,800,15,1,25.3",
    "200,400,30,16.3,35.4",
    "100,200,25,31.8,16.7",
    "50,100,15,25.9,7.7",
    "10,50,10,25,5.7",
)


#: Tromp points of two experiments (A, B) of six sizes, as CSV text.
TWO_EXPERIMENT_POINTS = "experiment,size,partition_fine\n" + "\n".join(
    f"{e},{s},{p}" for e in ("A", "B") for s, p in zip((10, 20, 40, 80, 160, 320), (0.97, 0.9, 0.7, 0.35, 0.1, 0.02))
)


def strip_unit(header: str) -> str:
    """A workbook header read back as the column name: the inverse of
    :func:`tromplab.output.workbook.header_with_unit` (``"d_cut [mm]"`` -> ``"d_cut"``)."""
    return re.sub(r" \[[^\]]*\]$", "", str(header))


def write(tmp_path, text, name="points.csv"):
    """Write ``text`` to ``tmp_path / name`` and return the path."""
    path = tmp_path / name
    path.write_text(text)
    return path


def reference(name: str) -> pd.DataFrame:
    """A reference table of tests/reference (comment lines give its provenance)."""
    return pd.read_csv(REFERENCE / name, comment="#")


def dataset(name: str) -> pd.DataFrame:
    return pd.read_csv(DATASETS / name, comment="#")


def shapes_across_bounds(formula, count=7):
    """Shapes spread over the admissible range (bounds included) of a formula."""
    low, high = formula.shape_bounds
    slopes = -np.geomspace(0.3, 8.0, count - 2)
    inner = [formula.clip_shape(formula.shape_for_slope(s)) for s in slopes]
    return sorted({low, high, *inner})


formula_ids = pytest.mark.parametrize("formula", FORMULAS, ids=[f.id for f in FORMULAS])


def reference_rows(name: str) -> list:
    """Rows of a reference table as named tuples, for ``pytest.mark.parametrize``."""
    return list(reference(name).itertuples(index=False))
