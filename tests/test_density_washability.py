"""Washability tables and the products a partition curve makes of them (tromplab.density.washability)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import optimize, stats

from tromplab.cli import main
from tromplab.density import predict_density
from tromplab.density.washability import (
    PREDICTION_COLUMNS,
    partition_curve,
    predict,
    predict_products,
    read_washability,
    rho50_for_floats_ash,
    washability_from_arrays,
)
from tromplab.errors import InputError, OptionError

from .conftest import DATASETS, write

WASHABILITY = DATASETS / "density_washability_synthetic.csv"
Z75 = stats.norm.ppf(0.75)

GOOD = """test,density_lower,density_upper,mass_pct,ash_pct
a,,1.3,40,3
a,1.3,1.4,30,10
a,1.4,1.6,20,25
a,1.6,,10,70
"""


# --- reading -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "change, fragment",
    [
        (lambda t: t.replace("1.3,1.4,30,10", "1.3,1.4,-30,10"), "row 3, column 'mass_pct': -30 is outside [0, inf]"),
        (lambda t: t.replace("1.4,1.6,20,25", "1.4,1.6,20,125"), "row 4, column 'ash_pct': 125 is outside [0, 100]"),
        (lambda t: t.replace("a,1.4,1.6", "a,1.35,1.6"), "row 4, column 'density_lower': fraction 1.35-1.6 overlaps the fraction 1.3-1.4"),
        (lambda t: t.replace("a,1.4,1.6", "a,1.45,1.6"), "row 4, column 'density_lower': fraction 1.45-1.6 leaves a gap to"),
        (lambda t: t.replace("a,1.3,1.4,30", "a,1.3,1.2,30"), "row 3, column 'density_lower': lower bound 1.3 is not below"),
        (lambda t: t.replace("a,1.6,,10", "a,,1.35,10"), "row 5, column 'density_lower': density fractions not increasing: -1.35 follows"),
        (lambda t: t.replace("a,1.3,1.4,30,10\na,1.4,1.6,20,25", "a,1.4,1.6,20,25\na,1.3,1.4,30,10"), "row 4, column 'density_lower': density fractions not increasing: 1.3-1.4 follows 1.4-1.6"),
        (lambda t: t.replace("a,1.6,,10,70", "a,1.6,,20,70"), "column 'mass_pct': test 'a': mass_pct adds up to 110"),
        (lambda t: t.replace("a,1.3,1.4", " ,1.3,1.4"), "row 3, column 'test': test name is blank"),
        (lambda t: t.replace("ash_pct", "ash_pc"), "unknown column(s) 'ash_pc' (did you mean 'ash_pct'?)"),
        (lambda t: t.replace("1.3,1.4,30,10", "1.3,1.4,thirty,10"), "row 3, column 'mass_pct': 'thirty' is not a number"),
        (lambda t: t.replace("ash_pct\n", "ash_pct,density_mean\n").replace("a,1.3,1.4,30,10", "a,1.3,1.4,30,10,1.45"),
         "row 3, column 'density_mean': mean density 1.45 lies outside its fraction 1.3-1.4"),
    ],
)  # fmt: skip
def test_a_bad_washability_table_is_refused_naming_file_row_and_column(tmp_path, change, fragment):
    path = write(tmp_path, change(GOOD), "feed.csv")
    with pytest.raises(InputError) as error:
        read_washability(path)
    assert "feed.csv" in str(error.value) and fragment in str(error.value)


def test_fractions_are_read_light_to_heavy_and_names_stay_text(tmp_path):
    (light,) = read_washability(write(tmp_path, GOOD.replace("a,", "007,"), "light.csv"))
    assert light.test == "007" and light.rows.tolist() == [2, 3, 4, 5]
    # the open ends closed by their neighbour's width: floats 1.2-1.3, sinks 1.6-1.8
    np.testing.assert_allclose(light.density, [1.25, 1.35, 1.5, 1.7], rtol=0, atol=1e-12)
    lines = GOOD.splitlines()
    heavy_first = "\n".join([lines[0], *reversed(lines[1:])]) + "\n"
    with pytest.raises(InputError, match="row 3, column 'density_lower': density fractions not increasing"):
        read_washability(write(tmp_path, heavy_first, "heavy.csv"))


def test_mean_densities_replace_midpoints_and_close_open_fractions_about_themselves():
    w = washability_from_arrays([np.nan, 1.3, 1.4], [1.3, 1.4, np.nan], [60, 25, 15], [4, 15, 60], [1.27, np.nan, 2.0])
    np.testing.assert_allclose(w.density, [1.27, 1.35, 2.0], rtol=0, atol=1e-12)
    assert w.density_from == ("mean", "midpoint", "mean")
    np.testing.assert_allclose([w.closed_lower[0], w.closed_upper[-1]], [1.24, 2.6], rtol=0, atol=1e-12)
    stated = read_washability(
        pd.DataFrame({"density_lower": [np.nan, 1.3], "density_upper": [1.3, np.nan], "mass_pct": [50, 50], "ash_pct": [5, 50]}),
        float_lower_density=1.1,
        sink_upper_density=2.5,
    )[0]
    np.testing.assert_allclose(stated.density, [1.2, 1.9], rtol=0, atol=1e-12)


def test_two_open_fractions_need_stated_bounds():
    frame = pd.DataFrame(
        {"density_lower": [np.nan, 1.3], "density_upper": [1.3, np.nan], "mass_pct": [50, 50], "ash_pct": [5, 50]}
    )
    with pytest.raises(InputError, match="needs a closed neighbour"):
        read_washability(frame)


def test_the_synthetic_data_set_has_two_feeds_that_add_up_to_100():
    feeds = read_washability(WASHABILITY)
    assert [w.test for w in feeds] == ["raw_50x12mm", "raw_12x0.5mm"]
    raw = pd.read_csv(WASHABILITY, comment="#")
    for w in feeds:
        rows = raw[raw["test"] == w.test]
        np.testing.assert_allclose(w.feed_ash_pct, np.sum(rows.mass_pct * rows.ash_pct) / rows.mass_pct.sum(), rtol=1e-12)


# --- washability curves --------------------------------------------------------------------------
def test_cumulative_floats_and_sinks_are_the_running_sums_computed_by_hand(tmp_path):
    (w,) = read_washability(write(tmp_path, GOOD, "feed.csv"))
    table = w.cumulative_table()
    np.testing.assert_allclose(table.cumulative_floats_mass_pct, [40, 70, 90, 100])
    # (40*3 + 30*10)/70 = 6, (420 + 500)/90, (920 + 700)/100
    np.testing.assert_allclose(table.cumulative_floats_ash_pct, [3, 6, 920 / 90, 16.2], rtol=1e-12)
    np.testing.assert_allclose(table.cumulative_sinks_mass_pct, [100, 60, 30, 10])
    np.testing.assert_allclose(table.cumulative_sinks_ash_pct, [16.2, 1500 / 60, 1200 / 30, 70], rtol=1e-12)
    # near-gravity material at each upper bound: +/-0.1 about 1.3 = 1.2..1.4 (all of -1.3 and 1.3-1.4),
    # about 1.4 = 1.3..1.5 (all of 1.3-1.4, half of 1.4-1.6), about 1.6 = 1.5..1.7 (half of 1.4-1.6, half of +1.6)
    np.testing.assert_allclose(table.near_gravity_pct[:3], [70, 40, 15], rtol=1e-12)
    assert np.isnan(table.near_gravity_pct.iloc[3])


def test_near_gravity_material_counts_the_share_of_a_fraction_inside_the_band(tmp_path):
    (w,) = read_washability(write(tmp_path, GOOD, "feed.csv"))
    # 1.45 +/- 0.1 = 1.35..1.55: half of 1.3-1.4 (15) and 0.75 of 1.4-1.6 (15)
    assert w.near_gravity_pct(1.45) == pytest.approx(30.0, abs=1e-12)
    # beyond the closed range nothing is added: 1.05..1.25 holds the lower half of the floats 1.2-1.3
    assert w.near_gravity_pct(1.15) == pytest.approx(20.0, abs=1e-12)
    assert w.near_gravity_pct(1.45, band=0.05) == pytest.approx(10.0, abs=1e-12)  # 1.40..1.50: half of 1.4-1.6


def test_theoretical_yield_solves_the_ash_of_a_partial_fraction_exactly(tmp_path):
    (w,) = read_washability(write(tmp_path, GOOD, "feed.csv"))
    # 6 % ash: exactly the floats of 1.4 (70 %); 8 %: 70 + t*20 with (420 + 25*20 t)/(70 + 20 t) = 8
    assert w.theoretical_yield_pct(6.0) == pytest.approx(70.0, abs=1e-12)
    t = (8 * 70 - 420) / (20 * (25 - 8))
    assert w.theoretical_yield_pct(8.0) == pytest.approx(70 + 20 * t, abs=1e-12)
    assert w.theoretical_yield_pct(16.2) == 100.0 and w.theoretical_yield_pct(30.0) == 100.0
    assert np.isnan(w.theoretical_yield_pct(2.0))  # cleaner than the lightest fraction


def test_a_non_monotone_ash_takes_the_largest_yield_of_the_target_ash():
    # the middle fraction is cleaner than the light one: cumulative ash 10, 7.5, then rising
    w = washability_from_arrays([np.nan, 1.4, 1.6], [1.4, 1.6, np.nan], [40, 40, 20], [10, 5, 60])
    assert w.theoretical_yield_pct(7.5) == pytest.approx(80.0, abs=1e-12)
    yield_9 = w.theoretical_yield_pct(9.0)  # on the last fraction: (600 + 60*20 t)/(80 + 20 t) = 9
    assert yield_9 == pytest.approx(80 + 20 * (9 * 80 - 600) / (20 * (60 - 9)), abs=1e-12)


# --- prediction ----------------------------------------------------------------------------------------
def _independent_floats(path, rho50, ep):
    """Yield and ash of the floats by a few lines of numpy from the file itself (normal curve)."""
    raw = pd.read_csv(path, comment="#")
    results = {}
    for test, rows in raw.groupby("test", sort=False):
        lower, upper = rows.density_lower.to_numpy(), rows.density_upper.to_numpy()
        width_first, width_last = upper[1] - lower[1], upper[-2] - lower[-2]
        mean = rows.density_mean.to_numpy()
        lower = np.where(np.isnan(lower), np.where(np.isnan(mean), upper - width_first, 2 * mean - upper), lower)
        upper = np.where(np.isnan(upper), np.where(np.isnan(mean), lower + width_last, 2 * mean - lower), upper)
        rho = np.where(np.isnan(mean), (lower + upper) / 2, mean)
        mass = rows.mass_pct.to_numpy() / rows.mass_pct.sum() * 100
        to_floats = mass * stats.norm.sf((rho - rho50) / (ep / Z75))
        results[test] = (to_floats.sum(), np.sum(to_floats * rows.ash_pct.to_numpy()) / to_floats.sum())
    return results


@pytest.mark.parametrize("rho50, ep", [(1.55, 0.035), (1.42, 0.02), (1.8, 0.12)])
def test_the_command_matches_a_direct_computation_of_the_floats_to_1e_9(tmp_path, capsys, rho50, ep):
    out = tmp_path / "pred.csv"
    code = main(
        ["density", "predict", str(WASHABILITY), "--curve", "normal", "--rho50", str(rho50), "--ep", str(ep), "-o", str(out)]
    )
    assert code == 0
    written = pd.read_csv(out)
    expected = _independent_floats(WASHABILITY, rho50, ep)
    assert list(written.columns) == list(PREDICTION_COLUMNS)
    for row in written.itertuples():
        floats_yield, floats_ash = expected[row.test]
        assert abs(row.floats_yield_pct - floats_yield) < 1e-9 and abs(row.floats_ash_pct - floats_ash) < 1e-9
        assert abs(row.floats_yield_pct + row.sinks_yield_pct - 100) < 1e-9
        total_ash = row.floats_yield_pct * row.floats_ash_pct + row.sinks_yield_pct * row.sinks_ash_pct
        feed = pd.read_csv(WASHABILITY, comment="#").query("test == @row.test")
        assert abs(total_ash / 100 - np.sum(feed.mass_pct * feed.ash_pct) / 100) < 1e-9  # the ash balances


def test_the_python_api_writes_the_command_s_file_byte_for_byte(tmp_path, capsys):
    cli_out, api_out = tmp_path / "cli.csv", tmp_path / "api.csv"
    options = ["--curve", "gompertz", "--rho50", "1.5", "1.6", "--ep", "0.04", "--light-limit", "0.02", "--heavy-limit", "0.97"]
    assert main(["density", "predict", str(WASHABILITY), *options, "-o", str(cli_out), "--table", str(tmp_path / "w.csv")]) == 0
    predicted = predict_density(WASHABILITY, curve="gompertz", rho50=[1.5, 1.6], ep=0.04, light_limit=0.02, heavy_limit=0.97)
    predicted.save(api_out, table=tmp_path / "w_api.csv")
    assert (tmp_path / "w.csv").read_bytes() == (tmp_path / "w_api.csv").read_bytes()
    assert cli_out.read_bytes() == api_out.read_bytes()
    table = predict(WASHABILITY, curve="gompertz", rho50=[1.5, 1.6], ep=0.04, light_limit=0.02, heavy_limit=0.97)
    assert table.to_csv(index=False).encode() == cli_out.read_bytes()
    assert set(table.curve) == {"gompertz_limits"} and len(table) == 4
    washability = pd.read_csv(tmp_path / "w.csv")
    assert len(washability) == 20 and washability.cumulative_floats_mass_pct.max() == pytest.approx(100.0)


def test_a_curve_with_limits_has_the_stated_cut_and_probable_error():
    record, partition = partition_curve("logistic", rho50=1.55, ep=0.04, light_limit=0.03, heavy_limit=0.95)
    assert record.id == "logistic_limits"
    quartile = {p: optimize.brentq(lambda r, p=p: partition(r) - p, 1.0, 3.0, xtol=1e-14) for p in (0.25, 0.5, 0.75)}
    assert quartile[0.5] == pytest.approx(1.55, abs=1e-10)
    assert (quartile[0.75] - quartile[0.25]) / 2 == pytest.approx(0.04, abs=1e-10)
    assert partition(np.array([0.5]))[0] == pytest.approx(0.03, abs=1e-6) and partition(np.array([5.0]))[0] == pytest.approx(0.95)


def test_organic_efficiency_is_at_most_100_when_ash_rises_with_density():
    (feed, fine) = read_washability(WASHABILITY)
    rng = np.random.default_rng(32)
    for _ in range(200):
        curve = rng.choice(["normal", "logistic", "gompertz"])
        rho50, ep = rng.uniform(1.3, 1.9), rng.uniform(0.005, 0.2)
        for w in (feed, fine):
            prediction = predict_products(w, partition_curve(curve, rho50=rho50, ep=ep)[1])
            assert prediction.organic_efficiency_pct <= 100 + 1e-9
            assert prediction.theoretical_yield_pct >= prediction.floats_yield_pct - 1e-9
    # an ideal cut at a bound is the washability curve itself: efficiency 100
    step = predict_products(feed, lambda rho: (rho > 1.5).astype(float))
    assert step.floats_yield_pct == pytest.approx(32 + 18.5 + 10.2 + 6.1 + 4.3, abs=1e-9)  # the floats of 1.50
    assert step.organic_efficiency_pct == pytest.approx(100.0, abs=1e-9)


@pytest.mark.slow
def test_the_target_ash_sweep_finds_the_cut_density_of_that_floats_ash(tmp_path, capsys):
    out = tmp_path / "pred.csv"
    assert main(["density", "predict", str(WASHABILITY), "--target-ash", "7", "9", "--ep", "0.05", "-o", str(out)]) == 0
    table = pd.read_csv(out)
    assert table.target_ash_pct.tolist() == [7, 9, 7, 9]
    np.testing.assert_allclose(table.floats_ash_pct, table.target_ash_pct, rtol=0, atol=1e-9)
    for row in table.itertuples():  # the independent computation at the cut found gives the target ash
        assert abs(_independent_floats(WASHABILITY, row.rho50, 0.05)[row.test][1] - row.target_ash_pct) < 1e-9
    assert (table.groupby("test").rho50.diff().dropna() > 0).all()  # a dirtier product needs a heavier cut


@pytest.mark.slow
def test_an_unreachable_target_ash_is_said_in_words_and_exits_3(tmp_path, capsys):
    out = tmp_path / "pred.csv"
    assert main(["density", "predict", str(WASHABILITY), "--target-ash", "1", "--ep", "0.05", "-o", str(out)]) == 3
    table = pd.read_csv(out)
    assert table.rho50.isna().all() and table.note.str.contains("no cut density between").all()
    (feed, _) = read_washability(WASHABILITY)
    rho50, note = rho50_for_floats_ash(feed, 50.0, lambda r: partition_curve("normal", rho50=r, ep=0.05)[1])
    assert np.isnan(rho50) and "floats ash from" in note


@pytest.mark.parametrize(
    "options, fragment",
    [
        (["--rho50", "0.9", "--ep", "0.03"], "--rho50: must be a relative density above 1"),
        (["--rho50", "1.5", "--ep", "0"], "--ep: must be a positive finite number"),
        (["--rho50", "1.5", "--ep", "0.03", "--light-limit", "0.3"], "--light-limit must lie in [0, 0.25)"),
        (["--target-ash", "120", "--ep", "0.03"], "--target-ash: must lie strictly between 0 and 100"),
        (["--rho50", "1.5", "--target-ash", "8", "--ep", "0.03"], "not allowed with argument"),
        (["--ep", "0.03"], "one of the arguments --rho50 --target-ash is required"),
    ],
)
def test_bad_options_are_usage_errors_and_write_nothing(tmp_path, capsys, options, fragment):
    out = tmp_path / "pred.csv"
    assert main(["density", "predict", str(WASHABILITY), *options, "-o", str(out)]) == 2
    error = capsys.readouterr().err
    assert fragment in error and error.startswith("tromplab density predict: error") and not out.exists()


def test_the_api_refuses_the_same_options_in_its_own_words():
    with pytest.raises(OptionError, match="^rho50 must be a relative density above 1"):
        predict(WASHABILITY, rho50=0.9, ep=0.03)
    with pytest.raises(OptionError, match="^heavy_limit must lie in"):
        predict(WASHABILITY, rho50=1.5, ep=0.03, heavy_limit=0.6)
    with pytest.raises(OptionError, match="^curve "):
        predict(WASHABILITY, curve="weibull", rho50=1.5, ep=0.03)
    with pytest.raises(OptionError, match="give exactly one"):
        predict(WASHABILITY, ep=0.03)


def test_bad_input_exits_1_and_writes_nothing(tmp_path, capsys):
    path = write(tmp_path, GOOD.replace("1.3,1.4,30,10", "1.3,1.4,-30,10"), "feed.csv")
    out = tmp_path / "pred.csv"
    assert main(["density", "predict", str(path), "--rho50", "1.5", "--ep", "0.03", "-o", str(out)]) == 1
    assert "feed.csv, row 3, column 'mass_pct'" in capsys.readouterr().err and not out.exists()


def test_a_fitted_curve_predicts_with_its_own_partition():
    from tromplab.density.fitting import fit_density_curve
    from tromplab.density.readers import read_density

    points = pd.DataFrame({"density": [1.45, 1.5, 1.55, 1.6, 1.65], "partition_sinks": [0.04, 0.2, 0.55, 0.86, 0.97]})
    fit = fit_density_curve(read_density(points)[0], "logistic")
    (feed, _) = read_washability(WASHABILITY)
    row = predict(feed, curve=fit).iloc[0]
    direct = predict_products(feed, fit.partition)
    assert row.floats_yield_pct == direct.floats_yield_pct and row.floats_ash_pct == direct.floats_ash_pct
    assert row.curve == "logistic" and row.rho50 == fit.indices.rho50 and row.ep == fit.indices.ep
    with pytest.raises(OptionError, match="come from the fit"):
        predict(feed, curve=fit, rho50=1.5)


def test_fractions_of_exactly_the_target_ash_are_taken_whole():
    w = washability_from_arrays([np.nan, 1.4, 1.6], [1.4, 1.6, np.nan], [40, 30, 30], [5, 5, 50])
    assert w.theoretical_yield_pct(5.0) == pytest.approx(70.0, abs=1e-12)
    assert np.isnan(w.theoretical_yield_pct(4.999))


def test_the_command_offers_every_registry_curve():
    from tromplab.cli.density_predict import PREDICT_CURVES
    from tromplab.density.registry import DENSITY_CURVES, PLAIN_CURVES
    from tromplab.options import PLAIN_DENSITY_CURVES

    # declared in tromplab.options so that building the parser imports no numerical library
    assert PREDICT_CURVES == tuple(curve.id for curve in DENSITY_CURVES)
    assert PLAIN_DENSITY_CURVES == tuple(curve.id for curve in PLAIN_CURVES)
