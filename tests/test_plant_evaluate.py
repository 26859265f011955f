"""``tromplab plant evaluate``: a tested separation in the standard form, against hand computations.

The hand case: a feed of three density fractions, -1.4 (50 %, 10 % ash), 1.4-1.6 (25 %, 30 %)
and +1.6 (25 %, 70 %), closed by their neighbours' width to 1.2-1.4 and 1.6-1.8 (midpoints 1.3,
1.5, 1.7), separated with partitions to the reject 0.1, 0.5 and 0.9. Then (by hand):
clean coal 45 + 12.5 + 2.5 = 60 % at (450 + 375 + 175) / 60 = 16.667 % ash; an ideal cut of that
ash takes all of -1.4 and of 1.4-1.6: theoretical yield 75 %, yield error 15; the ideal 60 %
(all of -1.4 and 10 of 1.4-1.6) has (500 + 300) / 60 = 13.333 % ash, ash error 3.333; organic
efficiency 80 %; the partitions are symmetric about 1.5, the cut density; misplaced floats of
1.5 in the reject 5 + 12.5 / 2 = 11.25 %, sinks in the clean coal 12.5 / 2 + 2.5 = 8.75 %;
near-gravity material at 1.5 +/- 0.1: the fraction 1.4-1.6, 25 %.
"""

from __future__ import annotations

import filecmp

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.errors import InputError
from tromplab.plant import evaluate

from .conftest import DATASETS

FEED, ASH, PARTITION = np.array([50.0, 25.0, 25.0]), np.array([10.0, 30.0, 70.0]), np.array([0.1, 0.5, 0.9])


def _test_table(partition=PARTITION, *, product_ash: bool = False) -> pd.DataFrame:
    sinks_yield = float(np.sum(FEED * partition) / 100)
    table = pd.DataFrame({"test": "hand", "density_lower": [np.nan, 1.4, 1.6], "density_upper": [1.4, 1.6, np.nan],
                          "feed_pct": FEED, "floats_pct": FEED * (1 - partition) / (1 - sinks_yield),
                          "sinks_pct": FEED * partition / sinks_yield})  # fmt: skip
    if product_ash:
        return table.assign(floats_ash_pct=ASH, sinks_ash_pct=ASH)
    return table.assign(feed_ash_pct=ASH)


@pytest.mark.parametrize("product_ash", [False, True])
def test_the_evaluation_equals_the_hand_computation(product_ash):
    row = evaluate(_test_table(product_ash=product_ash)).evaluation.iloc[0]
    expected = {"clean_yield_pct": 60.0, "clean_ash_pct": 1000 / 60, "reject_ash_pct": (5 * 10 + 12.5 * 30 + 22.5 * 70) / 40,
                "feed_ash_pct": 30.0, "theoretical_yield_pct": 75.0, "yield_error_pct": 15.0, "theoretical_ash_pct": 800 / 60,
                "ash_error_pct": 1000 / 60 - 800 / 60, "organic_efficiency_pct": 80.0, "rho50": 1.5,
                "misplaced_floats_pct": 11.25, "misplaced_sinks_pct": 8.75, "near_gravity_pct": 25.0}  # fmt: skip
    for name, value in expected.items():
        assert_allclose(row[name], value, rtol=1e-7, err_msg=name)
    assert_allclose(row["imperfection"], row["ep"] / 0.5, rtol=1e-12)


def test_the_partition_coefficients_by_fraction():
    fractions = evaluate(_test_table()).fractions
    assert_allclose(fractions["partition_sinks"], PARTITION, rtol=1e-9)
    assert_allclose(fractions["clean_pct"] + fractions["reject_pct"], FEED, rtol=1e-9)
    assert_allclose(fractions["clean_pct"], FEED * (1 - PARTITION), rtol=1e-9)


def test_an_ideal_separation_on_a_fraction_bound_has_no_error():
    row = evaluate(_test_table(np.array([0.0, 1.0, 1.0]))).evaluation.iloc[0]
    assert_allclose([row["clean_yield_pct"], row["clean_ash_pct"]], [50.0, 10.0], rtol=1e-9)
    assert_allclose([row["yield_error_pct"], row["ash_error_pct"], row["organic_efficiency_pct"]], [0, 0, 100], atol=1e-9)
    # a step in the partitions leaves the fitted cut anywhere between the midpoints 1.3 and 1.5: what lies between
    # 1.4 and the cut in the reject is misplaced floats (the fraction's mass spread evenly), the clean coal none
    share_below = np.clip((row["rho50"] - 1.4) / 0.2, 0, 1)
    assert 1.3 < row["rho50"] < 1.5
    assert_allclose([row["misplaced_floats_pct"], row["misplaced_sinks_pct"]], [25 * share_below, 0], atol=1e-9)


def test_tests_without_ash_or_of_tracers_are_refused():
    with pytest.raises(InputError, match="no ash columns"):
        evaluate(_test_table().drop(columns="feed_ash_pct"))
    with pytest.raises(InputError, match="float-sink analyses of the products with ash, not tracers"):
        evaluate(DATASETS / "density_tracers_dmc_by_size_synthetic.csv")


def test_the_command_writes_what_the_api_saves(tmp_path, capsys):
    path = tmp_path / "test.csv"
    _test_table().to_csv(path, index=False)
    assert main(["plant", "evaluate", str(path), "-o", str(tmp_path / "cli")]) == 0
    capsys.readouterr()
    written = evaluate(path).save(tmp_path / "api")
    assert sorted(written) == ["evaluation.csv", "fractions.csv", "summary.txt"]
    for name in written:
        assert filecmp.cmp(tmp_path / "cli" / name, tmp_path / "api" / name, shallow=False), name
