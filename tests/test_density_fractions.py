"""One convention for the bounds of density fractions, shared by every density reader (tromplab.density.fractions)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.density.fractions import density_fractions
from tromplab.density.readers import read_density
from tromplab.density.washability import read_washability
from tromplab.errors import InputError
from tromplab.loading.tables import Table

# the same five fractions, as a float-sink analysis of two products and as a washability table of the feed
BOUNDS = [("", "1.3"), ("1.3", "1.4"), ("1.4", "1.5"), ("1.5", "1.6"), ("1.6", "")]
FLOAT_SINK = ["30,42.0,2.0", "25,34.0,4.0", "15,16.0,12.7", "10,5.0,21.7", "20,3.0,59.6"]
WASHABILITY = ["30,3", "25,8", "15,15", "10,30", "20,70"]


def _tables(bounds, mean=None):
    """The two files of the same fractions: (float-sink text, washability text)."""
    extra_head = ",density_mean" if mean is not None else ""
    rows = [f"{low},{high}" + ("" if mean is None else f",{mean[i]}") for i, (low, high) in enumerate(bounds)]
    float_sink = f"test,density_lower,density_upper{extra_head},feed_pct,floats_pct,sinks_pct\n"
    float_sink += "".join(f"A,{row},{values}\n" for row, values in zip(rows, FLOAT_SINK))
    washability = f"test,density_lower,density_upper{extra_head},mass_pct,ash_pct\n"
    washability += "".join(f"A,{row},{values}\n" for row, values in zip(rows, WASHABILITY))
    return float_sink, washability


def _read_both(tmp_path, bounds, mean=None):
    float_sink, washability = _tables(bounds, mean)
    (tmp_path / "fs.csv").write_text(float_sink, encoding="utf-8")
    (tmp_path / "wash.csv").write_text(washability, encoding="utf-8")
    return read_density(tmp_path / "fs.csv")[0].points, read_washability(tmp_path / "wash.csv")[0]


@pytest.mark.parametrize(
    "bounds, mean",
    [
        (BOUNDS, None),
        ([("0", "1.3"), *BOUNDS[1:]], None),  # a 0 lower bound is the open float fraction
        (BOUNDS, ["1.27", "", "1.46", "", "2.31"]),  # open ends closed about their measured mean
        ([("1.2", "1.3"), *BOUNDS[1:4], ("1.6", "1.9")], None),  # closed at both ends
    ],
)
def test_both_readers_give_the_same_bounds_and_densities(tmp_path, bounds, mean):
    points, washability = _read_both(tmp_path, bounds, mean)
    assert_allclose(points["density_lower"], washability.density_lower, rtol=0, atol=0)
    assert_allclose(points["density_upper"], washability.density_upper, rtol=0, atol=0)
    assert_allclose(points["density"], washability.density, rtol=0, atol=0)
    assert np.isnan(washability.density_lower[0]) == (bounds[0][0] in ("", "0"))


@pytest.mark.parametrize(
    "change, row, column, words",
    [
        ({2: ("1.35", "1.5")}, 4, "density_lower", "fraction 1.35-1.5 overlaps the fraction 1.3-1.4"),
        ({2: ("1.45", "1.5")}, 4, "density_lower", "fraction 1.45-1.5 leaves a gap to the fraction 1.3-1.4"),
        ({3: ("1.2", "1.6")}, 5, "density_lower", "density fractions not increasing: 1.2-1.6 follows 1.4-1.5"),
        ({1: ("1.3", "")}, 3, "density_upper", "only the lightest fraction may be open below and only the heaviest open above"),
        ({1: ("1.4", "1.3")}, 3, "density_lower", "lower bound 1.4 is not below the upper bound 1.3"),
        ({1: ("", "")}, 3, "density_lower", "the fraction has neither a lower nor an upper bound"),
        ({1: ("1.3", "40")}, 3, "density_upper", "relative density 40 outside 0.5..25"),
        ({4: ("1.6", "0")}, 6, "density_upper", "relative density 0 outside 0.5..25"),
    ],
)
def test_both_readers_refuse_the_same_bad_bounds_with_the_same_error(tmp_path, change, row, column, words):
    bounds = [change.get(i, pair) for i, pair in enumerate(BOUNDS)]
    errors = []
    for path, text, reader in zip(("fs.csv", "wash.csv"), _tables(bounds), (read_density, read_washability)):
        (tmp_path / path).write_text(text, encoding="utf-8")
        with pytest.raises(InputError) as caught:
            reader(tmp_path / path)
        errors.append(caught.value)
    for error in errors:
        assert (error.row, error.column) == (row, column) and words in str(error)
    assert str(errors[0]).replace("fs.csv", "wash.csv") == str(errors[1])


def test_a_mean_density_outside_its_fraction_is_the_same_error_for_both(tmp_path):
    errors = []
    float_sink, washability = _tables(BOUNDS, ["", "1.45", "", "", ""])
    for path, text, reader in (("fs.csv", float_sink, read_density), ("wash.csv", washability, read_washability)):
        (tmp_path / path).write_text(text, encoding="utf-8")
        with pytest.raises(InputError) as caught:
            reader(tmp_path / path)
        errors.append(caught.value)
    assert str(errors[0]).replace("fs.csv", "wash.csv") == str(errors[1])
    assert errors[0].column == "density_mean" and "mean density 1.45 lies outside its fraction 1.3-1.4" in str(errors[0])


def test_open_fractions_are_closed_by_a_stated_bound_then_the_mean_then_the_neighbour():
    frame = pd.DataFrame(
        {"density_lower": [np.nan, 1.3, 1.4], "density_upper": [1.3, 1.4, np.nan], "density_mean": [1.27, np.nan, np.nan]}
    )
    table = Table(frame, np.arange(2, 5), "t.csv")
    fractions = density_fractions(table)
    assert_allclose([fractions.closed_lower[0], fractions.closed_upper[-1]], [1.24, 1.5], rtol=0, atol=1e-12)
    assert fractions.density_from == ("mean", "midpoint", "midpoint")
    assert fractions.notes == (
        "the float below 1.3 is placed as the fraction 1.24-1.3 (symmetric about its mean density 1.27)",
        "the sink above 1.4 is placed as the fraction 1.4-1.5 (the width of its neighbour)",
    )
    stated = density_fractions(table, float_lower=1.1, sink_upper=2.0)
    assert_allclose([stated.closed_lower[0], stated.closed_upper[-1]], [1.1, 2.0], rtol=0, atol=0)
    with pytest.raises(InputError, match="at least 3 are needed"):
        density_fractions(table.subset(np.arange(2)), minimum=3)
