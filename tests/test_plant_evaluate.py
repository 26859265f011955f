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
from tromplab.errors import InputError, OptionError
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


def test_tests_without_ash_or_tracers_without_washability_are_refused():
    with pytest.raises(InputError, match="no ash columns"):
        evaluate(_test_table().drop(columns="feed_ash_pct"))
    with pytest.raises(OptionError, match="washability is needed to evaluate a tracer test"):
        evaluate(DATASETS / "density_tracers_dmc_by_size_synthetic.csv")
    with pytest.raises(OptionError, match="washability is for tracer tests"):
        evaluate(_test_table(), washability=_tracer_washability())
    partition = pd.DataFrame({"test": "p", "density": [1.4, 1.5, 1.6], "partition_sinks": [0.1, 0.5, 0.9]})
    with pytest.raises(InputError, match="not partition"):
        evaluate(partition)


def test_the_command_writes_what_the_api_saves(tmp_path, capsys):
    path = tmp_path / "test.csv"
    _test_table().to_csv(path, index=False)
    assert main(["plant", "evaluate", str(path), "-o", str(tmp_path / "cli")]) == 0
    capsys.readouterr()
    written = evaluate(path).save(tmp_path / "api")
    assert sorted(written) == ["evaluation.csv", "fractions.csv", "summary.txt"]
    for name in written:
        assert filecmp.cmp(tmp_path / "cli" / name, tmp_path / "api" / name, shallow=False), name


# --- a tracer test with the washability of its feed -----------------------------------------------
def _tracer_counts() -> pd.DataFrame:
    """40 tracers recovered at 1.4, 1.5 and 1.6 with 10, 20 and 30 in the sinks: shares 1/4, 1/2, 3/4."""
    return pd.DataFrame({"test": "tracers", "density": [1.4, 1.5, 1.6], "placed": [40, 40, 42], "sinks": [10, 20, 30],
                         "floats": [30, 20, 10]})  # fmt: skip


def _tracer_washability() -> pd.DataFrame:
    """-1.45 (mean 1.40), 1.45-1.55 (mean 1.50), +1.55 (mean 1.60): 50, 25, 25 % at 10, 30, 70 % ash; the open fractions
    close symmetrically about their means, to 1.35-1.45 and 1.55-1.65."""
    return pd.DataFrame({"test": "feed", "density_lower": [np.nan, 1.45, 1.55], "density_upper": [1.45, 1.55, np.nan],
                         "mass_pct": [50, 25, 25], "ash_pct": [10, 30, 70], "density_mean": [1.4, 1.5, 1.6]})  # fmt: skip


@pytest.mark.parametrize("curve", ["normal", "logistic"])
def test_a_tracer_test_equals_the_hand_computation(curve):
    """The hand case of a tracer test (worked out here).

    The shares 1/4, 1/2, 3/4 at 1.4, 1.5, 1.6 lie on a normal curve and on a logistic curve (probit and logit of 1/4 and
    3/4 are symmetric), so either fitted curve passes through them: rho50 = 1.5, Ep = (1.6 - 1.4) / 2 = 0.1, I = 0.2.
    Applied to the washability at its mean densities: clean 50 x 3/4 + 25 / 2 + 25 / 4 = 56.25 % at
    (375 + 375 + 437.5) / 56.25 = 21.111 % ash; reject 43.75 % at (125 + 375 + 1312.5) / 43.75 = 41.429 %.  The ideal
    product of 21.111 % ash takes 50 + 25 and t of the +1.55 with (1250 + 1750 t) / (75 + 25 t) = 190 / 9: t = 3/11,
    theoretical yield 75 + 75/11 = 81.818 %; the ideal 56.25 % takes 50 + 6.25 at (500 + 187.5) / 56.25 = 12.222 % ash.
    At the cut 1.5 (mass spread evenly over 1.35-1.45, 1.45-1.55, 1.55-1.65): floats in the reject 12.5 + 12.5 / 2 =
    18.75 %, sinks in the clean coal 12.5 / 2 + 6.25 = 12.5 %; within 1.4-1.6: 25 + 25 + 12.5 = 62.5 %.
    """
    result = evaluate(_tracer_counts(), washability=_tracer_washability(), curve=curve)
    row = result.evaluation.iloc[0]
    expected = {"rho50": 1.5, "ep": 0.1, "imperfection": 0.2, "feed_ash_pct": 30.0, "clean_yield_pct": 56.25,
                "clean_ash_pct": 1187.5 / 56.25, "reject_ash_pct": 1812.5 / 43.75, "theoretical_yield_pct": 75 + 75 / 11,
                "yield_error_pct": 75 + 75 / 11 - 56.25, "theoretical_ash_pct": 687.5 / 56.25,
                "ash_error_pct": (1187.5 - 687.5) / 56.25, "organic_efficiency_pct": 100 * 56.25 / (75 + 75 / 11),
                "misplaced_floats_pct": 18.75, "misplaced_sinks_pct": 12.5, "near_gravity_pct": 62.5}  # fmt: skip
    for name, value in expected.items():
        assert_allclose(row[name], value, rtol=1e-6, err_msg=name)
    assert (row["cut"], row["cut_feed_pct"]) == ("single", 100.0)
    assert_allclose(result.fractions["clean_pct"], [37.5, 12.5, 6.25], rtol=1e-6)
    assert result.fractions["partition_sinks"].isna().all()  # the tracers measure the partition, not the fractions
    assert_allclose(result.tracers["partition_sinks"], [0.25, 0.5, 0.75], rtol=1e-12)
    assert_allclose(result.tracers["fitted_partition_sinks"], [0.25, 0.5, 0.75], rtol=1e-6)
    assert result.tracers["recovered"].tolist() == [40, 40, 40]


def test_tracer_tests_find_the_washability_named_after_them(tmp_path):
    tracers = pd.concat([_tracer_counts(), _tracer_counts().assign(test="other", sinks=[5, 20, 35], floats=[35, 20, 5])])
    leaner = _tracer_washability().assign(test="other", ash_pct=[5, 30, 70])
    both = pd.concat([_tracer_washability().assign(test="tracers"), leaner])
    rows = evaluate(tracers, washability=both).evaluation.set_index("test")
    assert_allclose(rows.loc["tracers", "clean_ash_pct"], 1187.5 / 56.25, rtol=1e-6)
    assert rows.loc["other", "feed_ash_pct"] == pytest.approx(27.5)
    path = tmp_path / "wash.csv"
    both.assign(test=["a", "a", "a", "b", "b", "b"]).to_csv(path, index=False)
    with pytest.raises(InputError, match="no washability for the tracer test tracers") as error:
        evaluate(tracers, washability=path)
    assert (error.value.source, error.value.column) == (str(path), "test")


# --- a three-product test -----------------------------------------------------------------------
THREE_FEED, THREE_ASH = np.array([40.0, 25.0, 20.0, 15.0]), np.array([5.0, 20.0, 45.0, 80.0])
#: Logistic partitions to sinks at the midpoints 1.3, 1.5, 1.7, 1.9: P(rho50 + k Ep) = 3^k / (1 + 3^k).
PRIMARY = np.array([1 / 4, 1 / 2, 3 / 4, 9 / 10])  # rho50 1.5, Ep 0.2
SECONDARY = np.array([1 / 10, 1 / 4, 1 / 2, 3 / 4])  # rho50 1.7, Ep 0.2, of the primary's sinks


def _three_product_table(*, stated_yields: bool = False, product_ash: bool = False) -> pd.DataFrame:
    clean = THREE_FEED * (1 - PRIMARY)
    middlings = THREE_FEED * PRIMARY * (1 - SECONDARY)
    reject = THREE_FEED * PRIMARY * SECONDARY
    table = pd.DataFrame({"test": "three", "density_lower": [np.nan, 1.4, 1.6, 1.8], "density_upper": [1.4, 1.6, 1.8, np.nan],
                          "feed_pct": THREE_FEED, "clean_pct": 100 * clean / clean.sum(),
                          "middlings_pct": 100 * middlings / middlings.sum(), "reject_pct": 100 * reject / reject.sum()})  # fmt: skip
    if stated_yields:
        table = table.drop(columns="feed_pct").assign(clean_yield=0.49, middlings_yield=0.2925)
    if product_ash:
        return table.assign(clean_ash_pct=THREE_ASH, middlings_ash_pct=THREE_ASH, reject_ash_pct=THREE_ASH)
    return table.assign(feed_ash_pct=THREE_ASH)


@pytest.mark.parametrize("stated_yields, product_ash", [(False, False), (True, False), (False, True)])
def test_a_three_product_test_equals_the_hand_computation(stated_yields, product_ash):
    """The hand case of a three-product test (worked out here), each cut evaluated on its own feed.

    Feed -1.4, 1.4-1.6, 1.6-1.8, +1.8 (closed to 1.2 and 2.0, midpoints 1.3 ... 1.9): 40, 25, 20, 15 % at 5, 20, 45,
    80 % ash (28 % in all).  Primary partitions 1/4, 1/2, 3/4, 9/10 (logistic, rho50 1.5, Ep 0.2): clean coal 30, 12.5,
    5, 1.5 = 49 % at (150 + 250 + 225 + 120) / 49 = 745/49 % ash; its sinks 10, 12.5, 15, 13.5 = 51 % at 2055/51 %.
    Ideal product of 745/49 % ash: 65 + 20 t with (700 + 900 t) / (65 + 20 t) = 745/49, t = 14125/29200; the ideal 49 %:
    40 + 9 at (200 + 180) / 49 = 380/49 %.  At the cut 1.5: floats in the reject 10 + 12.5 / 2 = 16.25, sinks in the clean
    coal 6.25 + 5 + 1.5 = 12.75; near-gravity (1.4-1.6) 25 %.
    Secondary partitions of the primary's sinks 1/10, 1/4, 1/2, 3/4 (rho50 1.7, Ep 0.2): middlings 9, 9.375, 7.5, 3.375 =
    29.25 at 840/29.25 % ash, reject 1, 3.125, 7.5, 10.125 = 21.75 at 1215/21.75 %, each per cent of the cut's feed (51).
    Ideal product of 840/29.25 %: 37.5 + 13.5 t with (975 + 1080 t) / (37.5 + 13.5 t) = 840/29.25, t = 2981.25/20250; the
    ideal 29.25: 10 + 12.5 + 6.75 at (50 + 250 + 303.75) / 29.25.  At 1.7: floats in the reject 1 + 3.125 + 3.75 = 7.875,
    sinks in the middlings 3.75 + 3.375 = 7.125; near-gravity (1.6-1.8) 15.
    """
    result = evaluate(_three_product_table(stated_yields=stated_yields, product_ash=product_ash), curve="logistic")
    primary, secondary = (row for _, row in result.evaluation.iterrows())
    to_cut = 100 / 51  # per cent of the secondary's feed
    t_primary, t_secondary = 14125 / 29200, 2981.25 / 20250
    expected_primary = {"cut_feed_pct": 100.0, "rho50": 1.5, "ep": 0.2, "imperfection": 0.4, "feed_ash_pct": 28.0,
                        "clean_yield_pct": 49.0, "clean_ash_pct": 745 / 49, "reject_ash_pct": 2055 / 51,
                        "theoretical_yield_pct": 65 + 20 * t_primary, "yield_error_pct": 65 + 20 * t_primary - 49,
                        "theoretical_ash_pct": 380 / 49, "ash_error_pct": 365 / 49,
                        "organic_efficiency_pct": 100 * 49 / (65 + 20 * t_primary), "misplaced_floats_pct": 16.25,
                        "misplaced_sinks_pct": 12.75, "near_gravity_pct": 25.0}  # fmt: skip
    theoretical = (37.5 + 13.5 * t_secondary) * to_cut
    expected_secondary = {"cut_feed_pct": 51.0, "rho50": 1.7, "ep": 0.2, "imperfection": 0.2 / 0.7, "feed_ash_pct": 2055 / 51,
                          "clean_yield_pct": 29.25 * to_cut, "clean_ash_pct": 840 / 29.25, "reject_ash_pct": 1215 / 21.75,
                          "theoretical_yield_pct": theoretical, "yield_error_pct": theoretical - 29.25 * to_cut,
                          "theoretical_ash_pct": 603.75 / 29.25, "ash_error_pct": (840 - 603.75) / 29.25,
                          "organic_efficiency_pct": 100 * 29.25 * to_cut / theoretical,
                          "misplaced_floats_pct": 7.875 * to_cut, "misplaced_sinks_pct": 7.125 * to_cut,
                          "near_gravity_pct": 15 * to_cut}  # fmt: skip
    for row, expected in ((primary, expected_primary), (secondary, expected_secondary)):
        for name, value in expected.items():
            assert_allclose(row[name], value, rtol=1e-6, err_msg=f"{row['cut']} {name}")
    assert (primary["cut"], secondary["cut"]) == ("primary", "secondary")
    fractions = result.fractions.set_index("cut")
    assert_allclose(fractions.loc["primary", "partition_sinks"], PRIMARY, rtol=1e-9)
    assert_allclose(fractions.loc["secondary", "partition_sinks"], SECONDARY, rtol=1e-9)
    assert_allclose(fractions.loc["secondary", "feed_pct"], np.array([10, 12.5, 15, 13.5]) * to_cut, rtol=1e-9)


def test_product_yields_by_least_squares_recover_the_balance():
    from tromplab.plant.three_products import product_yields

    rng = np.random.default_rng(3)
    products = rng.dirichlet(np.ones(6), size=3)
    feed = products.T @ np.array([0.55, 0.25, 0.20])
    yields, residual_sd = product_yields(feed, *products)
    assert_allclose(yields, [0.55, 0.25, 0.20], rtol=1e-12)
    assert residual_sd < 1e-12


@pytest.mark.parametrize(
    "change, row, column, words",
    [
        (lambda t: t.assign(middlings_pct=t["middlings_pct"].where(t.index != 2, -1.0)), 4, "middlings_pct", "outside"),
        (lambda t: t.assign(clean_pct=t["clean_pct"] * 1.1), None, "clean_pct", "adds up to 110"),
        (lambda t: t.assign(feed_ash_pct=[5, np.nan, 45, 80]), 3, "feed_ash_pct", "the clean hold this fraction but no ash"),
        (lambda t: t.assign(density_lower=[np.nan, 1.4, 1.7, 1.8]), 4, "density_lower", "leaves a gap"),
        (lambda t: t.drop(columns="feed_pct"), None, None, "without a feed analysis"),
    ],
)
def test_bad_three_product_tests_are_refused_naming_file_row_and_column(tmp_path, change, row, column, words):
    path = tmp_path / "three.csv"
    change(_three_product_table()).to_csv(path, index=False)
    with pytest.raises(InputError, match=words) as error:
        evaluate(path, curve="logistic")
    assert error.value.source == str(path)
    assert (error.value.row, error.value.column) == (row, column)


def test_three_product_yields_given_on_rows_are_checked(tmp_path):
    table = _three_product_table(stated_yields=True)
    with pytest.raises(InputError, match="give both clean_yield and middlings_yield") as error:
        evaluate(table.drop(columns="middlings_yield"))
    assert error.value.column == "middlings_yield"
    path = tmp_path / "three.csv"
    table.assign(clean_yield=[0.49, 0.49, 0.5, 0.49]).to_csv(path, index=False)
    with pytest.raises(InputError, match="clean_yield differs between rows") as error:
        evaluate(path)
    assert (error.value.row, error.value.column) == (4, "clean_yield")
    with pytest.raises(OptionError, match="floats_yield is for two-product tests"):
        evaluate(table, floats_yield=0.5)


def test_the_command_evaluates_tracers_with_the_washability(tmp_path, capsys):
    tracers, wash = tmp_path / "tracers.csv", tmp_path / "wash.csv"
    _tracer_counts().to_csv(tracers, index=False)
    _tracer_washability().to_csv(wash, index=False)
    assert main(["plant", "evaluate", str(tracers), "--washability", str(wash), "-o", str(tmp_path / "cli")]) == 0
    capsys.readouterr()
    written = evaluate(tracers, washability=wash).save(tmp_path / "api")
    assert sorted(written) == ["evaluation.csv", "fractions.csv", "summary.txt", "tracers.csv"]
    for name in written:
        assert filecmp.cmp(tmp_path / "cli" / name, tmp_path / "api" / name, shallow=False), name
    assert main(["plant", "evaluate", str(tracers), "-o", str(tmp_path / "none")]) == 2
    assert "--washability is needed to evaluate a tracer test" in capsys.readouterr().err
    assert not (tmp_path / "none").exists()
