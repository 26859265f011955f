"""One validated way in: files, Excel sheets and DataFrames meet the same checks and messages."""

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_array_equal

import tromplab
from tromplab.errors import InputError
from tromplab.loading.points import TrompPoints

from .conftest import DATASETS

POINTS = pd.DataFrame(
    {
        "experiment": ["a", "a", "a", "a", "b", "b", "b", "b"],
        "size": [10, 20, 40, 80, 10, 20, 40, 80],
        "partition_fine_pct": [97, 90, 55, 10, 95, 80, 40, 8],
    }
)
LAB = DATASETS / "double_deck_screen_decks_lab.csv"


def _same_points(first, second):
    assert [p.experiment for p in first] == [p.experiment for p in second]
    for a, b in zip(first, second):
        assert_array_equal(a.size, b.size)
        assert_array_equal(a.partition_fine, b.partition_fine)


def test_dataframe_csv_and_excel_sheet_give_the_same_points(tmp_path):
    POINTS.to_csv(tmp_path / "points.csv", index=False)
    with pd.ExcelWriter(tmp_path / "points.xlsx") as writer:
        POINTS.head(1).to_excel(writer, sheet_name="other", index=False)
        POINTS.to_excel(writer, sheet_name="tromp", index=False)
    from_frame = tromplab.read_points(POINTS)
    _same_points(from_frame, tromplab.read_points(tmp_path / "points.csv"))
    _same_points(from_frame, tromplab.read_points(tmp_path / "points.xlsx", sheet="tromp"))
    assert_array_equal(from_frame[0].partition_fine, [0.97, 0.9, 0.55, 0.1])


@pytest.mark.parametrize(
    "column, value, reason",
    [
        ("size", "ten", "'ten' is not a number"),
        ("size", np.nan, "value is missing (blank or NaN)"),
        ("size", -5, "size must be positive, got -5"),
        ("partition_fine_pct", 140, "partition 140 outside 0..100"),
        ("size", 40, "duplicate size 40 in the same experiment"),
    ],
)
def test_dataframe_errors_are_the_files_errors_with_the_row_label(tmp_path, column, value, reason):
    frame = POINTS.astype(object).copy()
    frame.loc[3, column] = value
    frame.to_csv(tmp_path / "points.csv", index=False)
    with pytest.raises(InputError) as from_file:
        tromplab.read_points(tmp_path / "points.csv")
    with pytest.raises(InputError) as from_frame:
        tromplab.read_points(frame.set_index(pd.Index([f"r{i}" for i in range(len(frame))])))
    assert from_file.value.reason.startswith(reason) and from_frame.value.reason.startswith(reason)
    assert from_file.value.column == from_frame.value.column == column
    assert from_file.value.row == 5  # line 5 of the CSV: header on line 1
    assert from_frame.value.row == "r3"
    assert str(from_frame.value).startswith(f"DataFrame, row r3, column '{column}': ")


@pytest.mark.filterwarnings("ignore::tromplab.loading.lab.YieldWarning")  # the exercise's stated yield, as in test_lab
def test_lab_table_from_a_dataframe_with_keyword_options():
    frame = pd.read_csv(LAB, comment="#")
    from_file = tromplab.read_lab(LAB)
    from_frame = tromplab.read_lab(frame)
    for a, b in zip(from_file, from_frame):  # "row" is the file line for one, the index label for the other
        pd.testing.assert_frame_equal(a.classes.drop(columns="row"), b.classes.drop(columns="row"))
        assert b.classes["row"].tolist() == list(frame.index[frame["experiment"] == a.experiment])
    given = tromplab.read_lab(frame.drop(columns="fine_yield"), fine_yield=0.263924)
    assert given[0].fine_yield == pytest.approx(0.263924)
    points, balances = tromplab.read_experiments(frame)
    assert [p.experiment for p in points] == ["deck_20mesh", "deck_65mesh"] and len(balances) == 2
    with pytest.raises(TypeError, match="unknown lab option"):
        tromplab.read_lab(frame, fine_yeild=0.3)
    bad = frame.astype(object)
    bad.loc[2, "feed_pct"] = "x"
    with pytest.raises(InputError, match=r"^DataFrame, row 2, column 'feed_pct'"):
        tromplab.read_lab(bad)


@pytest.mark.parametrize(
    "size, partition, message",
    [
        ([10, 20, 40], [97, 90, 70], "look like percentages; divide by 100"),
        ([10, 20, 20], [0.9, 0.5, 0.4], "duplicate size 20"),
        ([10, 20, 40], [0.9, np.nan, 0.1], "not a finite number"),
        ([10, np.inf, 40], [0.9, 0.5, 0.1], "not a finite number"),
        ([-10, 20, 40], [0.9, 0.5, 0.1], "size must be positive"),
        ([10, 20, 40], [0.9, 0.5], "size has 3 values and partition_fine 2"),
        ([10, 20, 40], [0.9, -0.5, 0.1], "partition -0.5 outside 0..1"),
        ([10, 20, 40], [1.2, 0.5, 0.1], r"partition 1.2 outside 0..1$"),
    ],
)
def test_tromp_points_refuse_bad_values(size, partition, message):
    with pytest.raises(InputError, match=message) as error:
        TrompPoints("run", size, partition)
    assert str(error.value).startswith("experiment 'run'")


def test_bootstrap_samples_may_repeat_sizes():
    sample = TrompPoints("run", [10, 10, 40], [0.9, 1.03, 0.1], resampled=True)
    assert_array_equal(sample.size, [10, 10, 40])
