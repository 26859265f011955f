"""Density inputs: tracer counts, float-sink analyses and partitions read as the lab writes them."""

import math
import re

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from tromplab.density.readers import density_layout, read_density
from tromplab.density.registry import DENSITY_CURVES, get_density_curve
from tromplab.density.simulation import float_sink_table
from tromplab.errors import InputError
from tromplab.loading.lab import estimate_fine_yield

from .conftest import write

TRACERS = "test,density,placed,sinks,floats\nA,1.40,30,1,28\nA,1.50,30,14,15\nA,1.60,30,29,1\nA,1.70,30,30,0\n"


def test_tracer_counts_lost_and_partition(tmp_path):
    sample = read_density(write(tmp_path, TRACERS, "tracers.csv"))[0]
    assert sample.layout == "tracers" and sample.test == "A"
    assert sample.points["lost"].tolist() == [1, 1, 0, 0]
    assert sample.points["recovered"].tolist() == [29, 29, 30, 30]
    assert_allclose(sample.points["partition_sinks"], [1 / 29, 14 / 29, 29 / 30, 1.0])
    assert "2 of 120 tracers lost (1.7 %), not counted" in sample.notes
    assert sample.points["row"].tolist() == [2, 3, 4, 5]


def test_tracers_without_placed_and_a_density_with_none_recovered(tmp_path):
    text = "density,sinks,floats\n1.4,0,20\n1.5,0,0\n1.6,12,8\n1.7,20,0\n"
    sample = read_density(write(tmp_path, text, "run7.csv"))[0]
    assert sample.test == "run7"  # named after the file without a test column
    assert sample.points["placed"].isna().all() and sample.points["lost"].isna().all()
    assert sample.points["used"].tolist() == [True, False, True, True]
    assert any("no tracer recovered at density 1.5: left out" in note for note in sample.notes)
    # the points the fits use: made once (the tables and the fits ask for them a dozen times), in order, renumbered
    assert sample.used is sample.used
    assert sample.used["density"].tolist() == [1.4, 1.6, 1.7] and sample.used.index.tolist() == [0, 1, 2]
    pd.testing.assert_frame_equal(sample.used, sample.points[sample.points["used"]].reset_index(drop=True))


def test_tracers_of_several_sizes_are_separate_samples(tmp_path):
    text = (
        "test,density,sinks,floats,size_lower_mm,size_upper_mm\n"
        "A,1.4,1,29,2,8\nA,1.5,15,15,2,8\nA,1.6,29,1,2,8\n"
        "A,1.4,3,27,8,\nA,1.5,15,15,8,\nA,1.6,27,3,8,\n"
    )
    samples = read_density(write(tmp_path, text))
    assert [s.size_fraction for s in samples] == ["2-8 mm", "+8 mm"]
    assert [s.label for s in samples] == ["A (2-8 mm)", "A (+8 mm)"]


@pytest.mark.parametrize(
    ("text", "row", "column", "words"),
    [
        ("density,placed,sinks,floats\n1.4,30,-1,29\n1.5,30,15,15\n", 2, "sinks", "negative count -1"),
        ("density,placed,sinks,floats\n1.4,30,1,29\n1.5,30,16,15\n", 3, "placed", "sinks + floats = 31 is more than the 30"),
        ("density,placed,sinks,floats\n1.5,30,1,29\n1.4,30,15,15\n", 3, "density", "densities not increasing: 1.4 follows 1.5"),
        ("density,placed,sinks,floats\n1.4,30,1,29\n1.4,30,15,15\n", 3, "density", "densities not increasing"),
        ("density,placed,sinks,floats\n1.4,30,1.5,28\n1.5,30,15,15\n", 2, "sinks", "is not a whole number of tracers"),
        ("density,partition_sinks\n1.4,0.1\n1.5,50\n", 3, "partition_sinks", "outside 0..1: give it as a share"),
        ("density,sinks,floats\n145,1,29\n150,15,15\n", 2, "density", "relative density 145 outside"),
    ],
)
def test_bad_counts_and_densities_name_file_row_and_column(tmp_path, text, row, column, words):
    path = write(tmp_path, text, "bad.csv")
    with pytest.raises(InputError, match=re.escape(words)) as caught:
        read_density(path)
    assert caught.value.source == str(path) and caught.value.row == row and caught.value.column == column


FLOAT_SINK = (
    "test,density_lower,density_upper,feed_pct,floats_pct,sinks_pct\n"
    "A,,1.3,30,42.0,2.0\nA,1.3,1.4,25,34.0,4.0\nA,1.4,1.5,15,16.0,12.7\nA,1.5,1.6,10,5.0,21.7\nA,1.6,,20,3.0,59.6\n"
)


@pytest.mark.parametrize(
    ("replace", "row", "column", "words"),
    [
        (("A,1.4,1.5,", "A,1.35,1.5,"), 4, "density_lower", "fraction 1.35-1.5 overlaps the fraction 1.3-1.4"),
        (("A,1.4,1.5,", "A,1.45,1.5,"), 4, "density_lower", "fraction 1.45-1.5 leaves a gap to the fraction 1.3-1.4"),
        (("A,1.5,1.6,", "A,1.2,1.6,"), 5, "density_lower", "density fractions not increasing: 1.2-1.6 follows 1.4-1.5"),
        (("A,1.3,1.4,25", "A,1.3,,25"), 3, "density_upper", "only the heaviest open above"),
        (("A,1.6,,20,3.0", "A,1.6,,20,-3.0"), 6, "floats_pct", "negative amount -3"),
    ],
)
def test_bad_fractions_name_file_row_and_column(tmp_path, replace, row, column, words):
    path = write(tmp_path, FLOAT_SINK.replace(*replace), "fs.csv")
    with pytest.raises(InputError, match=re.escape(words)) as caught:
        read_density(path)
    assert caught.value.row == row and caught.value.column == column


def test_analysis_not_summing_to_100_is_refused(tmp_path):
    with pytest.raises(InputError, match="sum to 110.00 % instead of 100 %") as caught:
        read_density(write(tmp_path, FLOAT_SINK.replace("A,1.6,,20,3.0", "A,1.6,,20,13.0")))
    assert caught.value.column == "floats_pct"


def test_float_sink_balance_is_the_lab_tables_yield_estimate(tmp_path):
    sample = read_density(write(tmp_path, FLOAT_SINK, "fs.csv"))[0]
    points = sample.points
    feed, floats, sinks = (
        np.array(column) / 100 for column in ([30, 25, 15, 10, 20], [42, 34, 16, 5, 3], [2, 4, 12.7, 21.7, 59.6])
    )
    estimate = estimate_fine_yield(feed / feed.sum(), sinks / sinks.sum(), floats / floats.sum())
    assert sample.yield_source == "least-squares estimate"
    assert_allclose(sample.floats_yield, 1 - estimate.value, rtol=1e-12)
    y = sample.floats_yield
    f, s = floats / floats.sum(), sinks / sinks.sum()
    assert_allclose(points["partition_sinks"], (1 - y) * s / ((1 - y) * s + y * f), rtol=1e-12)
    assert_allclose(points["weight"], (1 - y) * s + y * f, rtol=1e-12)  # the feed as the products recombine
    # the open ends take the width of their neighbour: the float below 1.3 sits at 1.25, the sink above 1.6 at 1.65
    assert_allclose(points["density"], [1.25, 1.35, 1.45, 1.55, 1.65])


def test_stated_yield_is_used_and_a_contradiction_said(tmp_path):
    text = FLOAT_SINK.replace("sinks_pct\n", "sinks_pct,floats_yield\n").replace(
        "\nA,,1.3,30,42.0,2.0", "\nA,,1.3,30,42.0,2.0,0.4"
    )
    sample = read_density(write(tmp_path, text))[0]
    assert sample.floats_yield == 0.4 and sample.yield_source == "column floats_yield"
    assert any("contradicts the float-sink analyses" in note for note in sample.notes)


def test_mean_density_replaces_the_midpoint(tmp_path):
    text = FLOAT_SINK.replace("sinks_pct\n", "sinks_pct,density_mean\n").replace(
        "A,1.3,1.4,25,34.0,4.0", "A,1.3,1.4,25,34.0,4.0,1.37"
    )
    text = "\n".join(line + ("," if line.count(",") == 5 and i else "") for i, line in enumerate(text.splitlines())) + "\n"
    assert_allclose(read_density(write(tmp_path, text))[0].points["density"], [1.25, 1.37, 1.45, 1.55, 1.65])
    with pytest.raises(InputError, match="mean density 1.45 lies outside its fraction 1.3-1.4") as caught:
        read_density(write(tmp_path, text.replace("1.37", "1.45")))
    assert caught.value.column == "density_mean"


@pytest.mark.parametrize("curve", DENSITY_CURVES, ids=[c.id for c in DENSITY_CURVES])
@pytest.mark.parametrize("with_feed", [True, False])
def test_float_sink_tables_of_a_known_curve_give_its_partition_exactly(curve, with_feed):
    params = curve.from_indices(rho50=1.55, ep=0.05, **({"light_limit": 0.02, "heavy_limit": 0.97} if curve.has_limits else {}))
    bounds = np.round(np.arange(1.30, 1.851, 0.05), 2)
    feed = np.linspace(20, 2, bounds.size + 1)
    table = float_sink_table(curve, params, bounds, feed, with_feed=with_feed)
    sample = read_density(table)[0]
    assert_allclose(sample.points["partition_sinks"], curve.partition(sample.points["density"], **params), rtol=1e-10, atol=1e-13)


def test_layouts_are_told_apart_by_columns():
    assert density_layout(["density", "partition_sinks"]) == "partition"
    assert density_layout(["size", "partition_fine"]) is None
    with pytest.raises(InputError, match="not a density table"):
        read_density(pd.DataFrame({"size": [1, 2], "partition_fine": [0.1, 0.9]}))


def test_unknown_column_is_refused_with_a_suggestion(tmp_path):
    with pytest.raises(InputError, match="'flaots' \\(did you mean 'floats'\\?\\)"):
        read_density(write(tmp_path, "density,sinks,floats,flaots\n1.4,1,2,3\n1.5,2,2,3\n"))


def test_dataframe_rows_are_named_by_index_label():
    frame = pd.DataFrame({"density": [1.4, 1.5], "sinks": [1, -2], "floats": [3, 3]}, index=["a", "b"])
    with pytest.raises(InputError, match="DataFrame, row b, column 'sinks': negative count -2"):
        read_density(frame)


def test_open_size_fraction_label():
    frame = pd.DataFrame(
        {"density": [1.4, 1.5], "sinks": [1, 2], "floats": [3, 3], "size_lower_mm": [0, 0], "size_upper_mm": [0.5, 0.5]}
    )
    sample = read_density(frame)[0]
    assert sample.size_fraction == "-0.5 mm" and math.isnan(sample.size_lower)
    assert get_density_curve("normal") is not None


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 40), st.integers(0, 40), st.integers(0, 5)), min_size=2, max_size=12),
    st.floats(1.2, 1.9),
)
@pytest.mark.slow
def test_tracer_counts_read_as_written(counts, start):
    density = np.round(start + 0.01 * np.arange(len(counts)), 2)
    sinks, floats, lost = (np.array(column) for column in zip(*counts))
    frame = pd.DataFrame({"density": density, "placed": sinks + floats + lost, "sinks": sinks, "floats": floats})
    recovered = sinks + floats
    if (recovered > 0).sum() < 2:
        with pytest.raises(InputError, match="usable densities"):
            read_density(frame)
        return
    points = read_density(frame)[0].points
    assert points["lost"].tolist() == lost.tolist() and points["recovered"].tolist() == recovered.tolist()
    used = recovered > 0
    assert points["used"].tolist() == used.tolist()
    assert_allclose(points["partition_sinks"][used], sinks[used] / recovered[used])


def test_a_csv_and_the_same_dataframe_read_alike(tmp_path):
    frame = pd.read_csv(write(tmp_path, TRACERS, "tracers.csv"))
    from_file, from_frame = read_density(tmp_path / "tracers.csv")[0], read_density(frame)[0]
    pd.testing.assert_frame_equal(from_file.points.drop(columns="row"), from_frame.points.drop(columns="row"))
    assert from_file.notes == from_frame.notes
