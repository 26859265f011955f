"""A monitoring file (date and survey columns, as ``tromplab trend`` reads) fits as it is."""

import pandas as pd
import pytest

import tromplab
from tromplab.cli import main
from tromplab.errors import InputError

from .conftest import DATASETS

SURVEYS = DATASETS / "classifier_trend_surveys.csv"


def test_fit_reads_the_trend_file_and_carries_date_and_survey(tmp_path):
    assert main(["fit", str(SURVEYS), "-o", str(tmp_path / "out"), "--figures", "none", "-q"]) == 0
    fits = pd.read_csv(tmp_path / "out" / "fits.csv")
    averages = pd.read_csv(tmp_path / "out" / "averages.csv")
    assert list(fits.columns[:3]) == ["experiment", "date", "survey"]
    assert list(averages.columns[:3]) == ["experiment", "date", "survey"]
    source = pd.read_csv(SURVEYS, comment="#")
    expected = source.drop_duplicates("survey").set_index("survey")["date"]
    for table in (fits, averages):
        assert (table.set_index("survey")["date"].groupby(level=0).first() == expected.loc[sorted(expected.index)]).all()
    assert not [c for c in fits.columns if c.endswith("_true")]


def test_experiments_are_ordered_by_date_and_a_survey_with_two_dates_is_refused(tmp_path):
    source = pd.read_csv(SURVEYS, comment="#")
    shuffled = source.iloc[::-1].reset_index(drop=True)
    experiments = tromplab.read_experiments(shuffled)
    dates = [p.meta["date"] for p in experiments.points]
    assert dates == sorted(dates) and len(dates) == source["survey"].nunique()
    broken = source.copy()
    broken.loc[3, "date"] = "2031-01-01"
    with pytest.raises(InputError, match="survey S01 has two dates") as refused:
        tromplab.read_experiments(broken)
    assert refused.value.column == "date"


def test_without_a_date_the_survey_names_the_experiments_in_file_order():
    frame = pd.DataFrame(
        {
            "survey": ["b"] * 4 + ["a"] * 4,
            "size": [10, 20, 40, 80] * 2,
            "partition_fine": [0.95, 0.8, 0.3, 0.05, 0.9, 0.7, 0.35, 0.1],
        }
    )
    points, _ = tromplab.read_experiments(frame)
    assert [p.experiment for p in points] == ["b", "a"]
    assert [p.meta for p in points] == [{"survey": "b"}, {"survey": "a"}]
    fits = tromplab.fit_experiments(points, formulas=["plitt"]).fits_table()
    assert list(fits.columns[:2]) == ["experiment", "survey"] and "date" not in fits.columns
