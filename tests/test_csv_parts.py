"""The tables' CSV text formatted by the workers and joined by the main process."""

import pickle

import numpy as np
import pandas as pd
import pytest

from tromplab._synthetic import synthetic
from tromplab.loading.points import TrompPoints
from tromplab.output.csv_parts import csv_from_parts, csv_part
from tromplab.parallel import fanout
from tromplab.workbench import fit_experiments


def _awkward_table() -> pd.DataFrame:
    """Columns of every kind ``fits.csv`` has, with the values that CSV quotes or leaves empty."""
    return pd.DataFrame(
        {
            "experiment": ["a", 'b "quoted"', "c,comma", "d\nnewline", "e", "f"],
            "n": [5, 6, 7, 8, 9, 10],
            "ssr": [1e-17, np.nan, 0.1 + 0.2, 1.0, -2.5e300, np.inf],
            "adequate": [True, False, True, True, False, True],
            "warnings": ["", "x; y", None, "z", "", "w"],
        }
    )


def test_joined_parts_are_the_whole_table_byte_for_byte():
    table = _awkward_table()
    parts = [csv_part(table.iloc[0:2]), csv_part(table.iloc[2:5])]
    assert csv_from_parts(table, parts) == table.to_csv(index=False)  # the last row formatted from the table
    assert csv_from_parts(table, [*parts, csv_part(table.iloc[5:])]) == table.to_csv(index=False)


def test_parts_formatted_in_another_layout_are_not_joined():
    table = _awkward_table()
    as_floats = table.iloc[:3].astype({"n": float})  # "5.0", where the table writes "5"
    assert csv_from_parts(table, [csv_part(as_floats)]) is None
    assert csv_from_parts(table, [csv_part(table.iloc[:3][["n", "experiment", "ssr", "adequate", "warnings"]])]) is None
    assert csv_from_parts(table.iloc[:2], [csv_part(table.iloc[:3])]) is None  # more rows than the table
    assert csv_from_parts(table, []) is None


@pytest.mark.slow
def test_the_workers_format_the_rows_the_results_folder_writes(tmp_path, monkeypatch):
    monkeypatch.setattr(fanout, "CHUNK_SIZE", 3)  # several chunks from a small batch
    batch = [synthetic(seed) for seed in range(7)]
    bench = fit_experiments(batch, formulas=["plitt", "11", "lognormal"], jobs=2, partition_to="coarse")
    for name, table in (("fits", bench.fits_table()), ("averages", bench.averages())):
        parts = bench.formatted_parts(name)
        assert len(parts) == 3
        assert csv_from_parts(table, parts) == table.to_csv(index=False)
    bench.save(tmp_path / "out", figures="none")
    assert (tmp_path / "out" / "fits.csv").read_text(encoding="utf-8") == bench.fits_table().to_csv(index=False)
    assert pickle.loads(pickle.dumps(bench)).formatted_parts("fits") is None  # a saved batch formats again
    assert fit_experiments(batch[:2], formulas=["plitt"], jobs=1).formatted_parts("fits") is None  # one process


@pytest.mark.slow
def test_a_batch_with_failed_experiments_is_formatted_whole(monkeypatch):
    """The failed experiments' empty cells turn integer columns into floats in the whole
    table ("10.0"), so the workers' rows ("10") are not joined."""
    monkeypatch.setattr(fanout, "CHUNK_SIZE", 2)
    batch = [synthetic(seed) for seed in range(4)] + [TrompPoints("two points", [1.0, 2.0], [0.9, 0.1])]
    bench = fit_experiments(batch, formulas=["plitt"], jobs=2)
    table = bench.fits_table()
    assert bench.formatted_parts("fits") and csv_from_parts(table, bench.formatted_parts("fits")) is None
    assert table["n"].dtype == float
