"""Monitoring over time: surveys, EWMA charts, equality tests, change flags, the bundled series."""

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.curves.curve_fit import fit_formula
from tromplab.errors import InputError
from tromplab.trend import (
    SeriesDesign,
    equality_test,
    ewma_chart,
    flag_changes,
    monitor_surveys,
    read_surveys,
    simulate_surveys,
    surveys_from_frame,
)
from tromplab.workbench import fit_experiments

from .conftest import DATASETS

BUNDLED = DATASETS / "classifier_trend_surveys.csv"


@pytest.fixture(scope="module")
def bundled():
    return monitor_surveys(read_surveys(BUNDLED), formula="plitt_bypass")


def test_bundled_series_changes_are_found_and_nothing_before_them(bundled):
    flags = bundled.survey_flags()
    assert list(flags.loc[flags["baseline"], "survey"]) == [f"S{i:02d}" for i in range(1, 9)]
    # bypass step at S13 and cut drift from S19 (datasets/CATALOGUE.md)
    assert not flags.loc[flags["survey"] < "S13", "changed"].any()
    points = bundled.change_points()
    assert points[0] in ("S13", "S14", "S15")
    assert any("S19" <= p <= "S22" for p in points[1:])
    step = flags.set_index("survey").loc["S14"]
    assert "bypass" in step["alarms"] and step["p_baseline"] < 1e-6
    cut = flags.set_index("survey").loc["S22":"S24", "alarms"]
    assert all("d_cut" in alarms for alarms in cut)


def test_bundled_series_is_what_its_generator_writes():
    # analysis/make_trend_series.py: default SeriesDesign, seed 14 (datasets/CATALOGUE.md)
    generated = simulate_surveys(SeriesDesign(), seed=14)
    bundled = pd.read_csv(BUNDLED, comment="#")
    pd.testing.assert_frame_equal(bundled, generated, check_dtype=False)


def test_bundled_series_tidy_table_holds_values_intervals_and_truth(bundled):
    table = bundled.table
    assert list(table["quantity"].unique()) == ["d_cut", "ep", "eta", "bypass"]
    assert len(table) == 24 * 4
    assert (table["low"] <= table["value"]).all() and (table["value"] <= table["high"]).all()
    truth = pd.read_csv(BUNDLED, comment="#").drop_duplicates("survey").set_index("survey")
    fitted = table[table["quantity"] == "bypass"].set_index("survey")["value"]
    assert np.mean(np.abs(fitted - truth["bypass_true"])) < 0.02
    cut = table[table["quantity"] == "d_cut"].set_index("survey")["value"]
    assert_allclose(cut, truth["d_cut_true"], rtol=0.06)


def test_no_change_series_give_no_change_points_at_the_stated_rate():
    # docs/trend.md: about 1 % of monitored surveys carry a false flag (L 3.5, 200 seeded series);
    # these 4 short seeded series (24 monitored surveys in all) must have none.
    design = SeriesDesign(n_surveys=14, bypass_step_at=None, drift_from=None)
    found = []
    for seed in range(4):
        result = monitor_surveys(
            surveys_from_frame(simulate_surveys(design, seed=300 + seed)), formula="plitt_bypass", baseline=8, consecutive=False
        )
        found += result.change_points()
    assert found == []


def test_ewma_chart_follows_its_definition():
    values = np.array([10.0, 10.4, 9.7, 10.1, 9.8, 10.0, 11.5, 12.0])
    base = [0, 1, 2, 3, 4]
    z, low, high, centre, sigma = ewma_chart(values, base, lam=0.2, width=3.0)
    assert_allclose(centre, np.mean(values[:5]))
    assert_allclose(sigma, np.std(values[:5], ddof=1))
    expected, level = [], centre
    for value in values[5:]:
        level = 0.2 * value + 0.8 * level
        expected.append(level)
    assert_allclose(z[5:], expected)
    assert np.isnan(z[:5]).all()
    first = 3.0 * sigma * np.sqrt(0.2 / 1.8 * (1 - 0.8**2) + 0.2**2 / 5)
    assert_allclose(high[5] - centre, first)
    assert_allclose(centre - low[5], first)


def test_flags_need_both_an_ewma_alarm_and_a_rejected_equality_test():
    values = {"d_cut": np.array([100, 101, 99, 100, 100.5, 99.5, 130, 131.0])}
    base = [0, 1, 2, 3, 4, 5]
    _, alarms, changed, points = flag_changes(values, np.array([np.nan] * 6 + [1e-9, 1e-9]), base)
    assert alarms["d_cut"][6:].all() and changed[6:].all() and list(np.flatnonzero(points)) == [6]
    _, _, changed, _ = flag_changes(values, np.array([np.nan] * 6 + [0.2, 0.2]), base)
    assert not changed.any()


def test_equality_test_accepts_one_curve_and_rejects_a_changed_one():
    design = SeriesDesign(n_surveys=3, bypass_step_at=2, bypass_step=0.15, drift_from=None, jitter_cut=0.0, jitter_bypass=0.0)
    surveys = surveys_from_frame(simulate_surveys(design, seed=5))
    same = equality_test([surveys[0].points], [surveys[1].points], "plitt_bypass")
    changed = equality_test([surveys[0].points, surveys[1].points], [surveys[2].points], "plitt_bypass")
    assert same.p_value > 0.01 and changed.p_value < 1e-6
    assert (same.df_extra, same.df_full) == (3, 24 - 6)


@pytest.mark.parametrize("formula", ["plitt_bypass", "shuvalov"])
@pytest.mark.slow
def test_the_batched_trend_gives_the_one_by_one_fits_and_tests(formula):
    """monitor_surveys fits the surveys and the pooled equality tests with the batched engine
    ((11), whose measured efficiency differs per survey, pools one by one): the charted values
    and p-values are those of single lmfit fits and equality_test per survey."""
    surveys = sorted(surveys_from_frame(simulate_surveys(SeriesDesign(n_surveys=14), seed=3)), key=lambda s: s.date)
    result = monitor_surveys(surveys, formula=formula, baseline=6)
    table = result.table[result.table["quantity"] == "d_cut"].reset_index(drop=True)
    single = [fit_formula(s.points, formula) for s in surveys]
    assert_allclose(table["value"], [fit.d_cut for fit in single], rtol=1e-5)
    baseline = [s.points for s in surveys[:6]]
    for i in (6, 9, 13):
        expected = equality_test(baseline, [surveys[i].points], formula).p_value
        assert table.loc[i, "p_baseline"] == pytest.approx(expected, rel=1e-4, abs=1e-12)
        previous = equality_test([surveys[i - 1].points], [surveys[i].points], formula).p_value
        assert table.loc[i, "p_previous"] == pytest.approx(previous, rel=1e-4, abs=1e-12)


def test_read_surveys_names_bad_input(tmp_path):
    frame = pd.read_csv(BUNDLED, comment="#")
    frame.drop(columns=["date", "survey"]).to_csv(tmp_path / "nodate.csv", index=False)
    with pytest.raises(InputError, match="'date' or 'survey' column"):
        read_surveys(tmp_path / "nodate.csv")
    bad = frame.copy()
    bad.loc[5, "date"] = "last tuesday"
    bad.to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(InputError, match=r"row 7, column 'date': 'last tuesday' is not a date"):
        read_surveys(tmp_path / "bad.csv")
    two = frame.copy()
    two.loc[3, "date"] = "2025-01-07"
    two.to_csv(tmp_path / "two.csv", index=False)
    with pytest.raises(InputError, match="survey S01 has two dates"):
        read_surveys(tmp_path / "two.csv")


@pytest.mark.slow
def test_trend_command_writes_table_charts_and_report(tmp_path, capsys):
    frame = pd.read_csv(BUNDLED, comment="#")
    frame = frame[frame["survey"] <= "S14"].drop(columns=["survey"])  # surveys keyed by date alone
    frame.to_csv(tmp_path / "surveys.csv", index=False)
    out = tmp_path / "out"
    code = main(
        [
            "trend",
            str(tmp_path / "surveys.csv"),
            "-o",
            str(out),
            "--formula",
            "plitt_bypass",
            "--baseline",
            "2025-01-06:2025-03-03",
            "--size-unit",
            "um",
        ]
    )
    assert code == 0
    table = pd.read_csv(out / "trend.csv")
    assert set(table["survey"]) == {d for d in frame["date"]}
    assert table.loc[table["baseline"], "survey"].nunique() == 9
    assert set(table.loc[table["quantity"].isin(["d_cut", "ep"]), "unit"]) == {"um"}
    html = (out / "trend_report.html").read_text()
    assert "Monitoring over time" in html and "Control chart of bypass" in html and "data:image/png;base64" in html
    assert (out / "trend_bypass.png").stat().st_size > 0
    assert "2025-04-07" in capsys.readouterr().out
    assert main(["trend", str(tmp_path / "surveys.csv"), "-o", str(out), "--baseline", "2"]) == 1
    assert "at least 3 surveys" in capsys.readouterr().err


def test_best_ranked_formula_is_used_when_none_is_given():
    design = SeriesDesign(n_surveys=5, bypass_step_at=None, drift_from=None)
    surveys = surveys_from_frame(simulate_surveys(design, seed=2))
    result = monitor_surveys(surveys, baseline=3, consecutive=False)
    assert result.formula_id == fit_experiments([s.points for s in surveys]).ranking_table().iloc[0]["formula"]
    assert list(result.table["quantity"].unique()) == ["d_cut", "ep", "eta"]  # no bypass among the nine


def test_trend_section_joins_an_ordinary_report_after_its_sections(bundled):
    from tromplab.output.report import SECTIONS, Report
    from tromplab.trend import add_trend_section

    report = Report("survey report", "surveys.csv")
    add_trend_section(report, bundled, size_unit="um", figures=False)
    assert report.order == (*SECTIONS, "trend")
    html = report.html()
    assert html.index("Input summary") < html.index("Monitoring over time")
    assert "Change points: S14, S19, S22." in html
    assert "Charted quantities" in report.markdown()


def test_read_surveys_takes_a_lab_table_with_dates(tmp_path):
    from tromplab.loading.lab import read_experiments

    lab = pd.read_csv(DATASETS / "double_deck_screen_decks_lab.csv", comment="#")
    lab["date"] = lab["experiment"].map({"deck_20mesh": "2025-02-01", "deck_65mesh": "2025-01-15"})
    lab.drop(columns=["experiment"]).to_csv(tmp_path / "lab.csv", index=False)
    surveys = read_surveys(tmp_path / "lab.csv")
    assert [s.name for s in surveys] == ["2025-01-15", "2025-02-01"]  # sorted by date
    expected, _ = read_experiments(DATASETS / "double_deck_screen_decks_lab.csv")
    by_name = {p.experiment: p for p in expected}
    assert_allclose(surveys[0].points.partition_fine, by_name["deck_65mesh"].partition_fine)
    assert_allclose(surveys[1].points.size, by_name["deck_20mesh"].size)
