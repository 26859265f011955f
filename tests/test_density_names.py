"""Test names of density inputs are text as written, and the density files carry no formula."""

import pandas as pd
import pytest

from tromplab.cli import main

from .conftest import DATASETS

TRACERS = DATASETS / "density_tracers_dmc_by_size_synthetic.csv"


def _tests_named(tmp_path, names):
    lines = [line for line in TRACERS.read_text().splitlines() if not line.startswith("#")]
    header, rows = lines[0], [row for row in lines[1:] if row.split(",")[1] == "2.0"]
    body = [row.replace("dmc_tracers", name, 1) for name in names for row in rows]
    path = tmp_path / "tracers.csv"
    path.write_text("\n".join([header, *body]) + "\n")
    return path


@pytest.mark.slow
def test_tests_001_1_and_na_are_three_tests_and_a_formula_name_is_written_as_text(tmp_path):
    names = ["001", "1", "NA", "=1+1"]
    assert main(["density", "fit", str(_tests_named(tmp_path, names)), "-o", str(tmp_path / "out"), "--curves", "normal"]) == 0
    written = (tmp_path / "out" / "fits.csv").read_text().splitlines()
    first_cells = [line.split(",")[0] for line in written[1:]]
    assert first_cells == ["001", "1", "NA", "'=1+1"]  # the spreadsheet's text mark on the formula-like name
    fits = pd.read_csv(tmp_path / "out" / "fits.csv", dtype={"test": str}, keep_default_na=False)
    assert fits["n_points"].tolist() == [16, 16, 16, 16]  # each test its own points, none merged
