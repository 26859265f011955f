"""Gross errors that the circuit names and the user acts on: serial elimination with
compensation (elimination.csv), the nodal test, exclude=/--exclude; and the error model
evaluated at the reconciled values on surveys as a lab reports them."""

import importlib.util
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tromplab.circuit import ErrorModel, reconcile
from tromplab.circuit.elimination import ELIMINATION_COLUMNS
from tromplab.circuit.simulation import example_plant, grinding_circuit, lab_survey, simulate_survey, survey_table
from tromplab.cli import main
from tromplab.errors import OptionError

FLOWMETERS = {"screen_feed": 0.01, "oversize": 0.05, "middlings": 0.05, "cyclone_overflow": 0.05}


def _flowmeter_off(tmp_path, seed: int = 3):
    """The example plant with four flowmeters, the middlings' 8 of its sds low, as a lab reports it."""
    truth = example_plant()
    drawn = simulate_survey(truth, np.random.default_rng(seed), flows=FLOWMETERS, gross=("middlings", -1, -8.0))
    path = tmp_path / "survey.csv"
    survey_table(drawn).to_csv(path, index=False)
    sheet = tmp_path / "sheet.csv"
    truth.flowsheet.to_frame().to_csv(sheet, index=False)
    return sheet, path


def test_a_flowmeter_8_sd_off_is_named_at_step_1_and_the_last_step_passes(tmp_path, capsys):
    sheet, survey = _flowmeter_off(tmp_path)
    out = tmp_path / "out"
    assert main(["circuit", str(sheet), str(survey), "-o", str(out), "--no-figures"]) == 0
    steps = pd.read_csv(out / "elimination.csv", keep_default_na=False)
    assert list(steps.columns) == ELIMINATION_COLUMNS
    assert steps.loc[0, "p_value"] < 0.05  # as reconciled, the global test rejects
    assert (steps.loc[1, "stream"], steps.loc[1, "kind"]) == ("middlings", "flow")
    assert float(steps.loc[1, "estimated_error"]) < 0  # measured - true: the meter reads low
    assert float(steps.iloc[-1]["p_value"]) > 0.05
    printed = capsys.readouterr().out
    assert "serial elimination proposes" in printed and "--exclude middlings:flow" in printed
    flows = pd.read_csv(out / "flows.csv").set_index("stream")
    assert flows.loc["middlings", "measured"] < flows.loc["middlings", "reconciled"]  # nothing applied silently


@pytest.mark.slow
def test_excluding_the_proposal_reconciles_as_the_compensation_step_said(tmp_path, capsys):
    sheet, survey = _flowmeter_off(tmp_path)
    balance = reconcile(sheet, survey)
    steps = balance.elimination_table()
    without = reconcile(sheet, survey, exclude=["middlings:flow"])
    assert without.dof == balance.dof - 1 and not without.rejected
    assert without.chi_square == pytest.approx(steps.iloc[-1]["chi_square"], rel=1e-3)  # compensating = leaving out
    assert "left out on request (exclude): middlings:flow" in without.report()
    out = tmp_path / "out"
    assert main(["circuit", str(sheet), str(survey), "-o", str(out), "--no-figures", "--exclude", "middlings:flow"]) == 0
    assert len(pd.read_csv(out / "elimination.csv")) == 1  # nothing left to propose
    assert "middlings flow" not in pd.read_csv(out / "adjustments.csv")["measurement"].tolist()


def test_a_survey_that_passes_gets_no_proposal():
    truth = grinding_circuit()
    balance = reconcile(truth.flowsheet, lab_survey(truth, np.random.default_rng(1), flows={"fresh_feed": 0.02}))
    assert not balance.rejected
    assert len(balance.elimination_table()) == 1 and "serial elimination" not in balance.report()


@pytest.mark.parametrize(
    "exclude, fragment",
    [
        ("nowhere:flow", "no stream 'nowhere'"),
        ("cyclone_feed:-7+3", "no size class '-7+3'"),
        ("cyclone_feed:flow", "which the survey does not measure"),
    ],
)
def test_an_exclusion_naming_no_measurement_is_refused(exclude, fragment):
    truth = grinding_circuit()
    survey = lab_survey(truth, np.random.default_rng(1))
    with pytest.raises(OptionError, match=re.escape(fragment)):
        reconcile(truth.flowsheet, survey, exclude=[exclude])


def test_excluding_one_class_leaves_the_analysis_open_and_the_command_line_names_the_option(tmp_path, capsys):
    truth = grinding_circuit()
    survey = lab_survey(truth, np.random.default_rng(1))
    balance = reconcile(truth.flowsheet, survey, exclude="cyclone_feed:-150+106")
    assert "cyclone_feed" not in balance.survey.closed_streams
    assert "cyclone_feed class -150+106" not in balance.adjustments_table()["measurement"].tolist()
    sheet, table = tmp_path / "sheet.csv", tmp_path / "survey.csv"
    truth.flowsheet.to_frame().to_csv(sheet, index=False)
    survey_table(simulate_survey(truth, np.random.default_rng(1))).to_csv(table, index=False)
    assert main(["circuit", str(sheet), str(table), "-o", str(tmp_path / "out"), "--exclude", "nowhere"]) == 2
    assert "--exclude names 'nowhere'" in capsys.readouterr().err


def test_the_nodal_test_points_at_the_class_balance_a_slip_breaks():
    truth = grinding_circuit()
    exact = ErrorModel(relative_error=1e-9, absolute_error=1e-9)
    table = survey_table(simulate_survey(truth, np.random.default_rng(0), errors=exact), decimals=None)
    clean = reconcile(truth.flowsheet, table, size_unit="um").nodal_tests_table()
    assert clean["nodal_test"].abs().max() < 1e-5  # exact data balance
    table.loc[(table["stream"] == "cyclone_feed") & (table["size_lower_um"] == 106), "retained_pct"] += 1.2
    tests = reconcile(truth.flowsheet, table, size_unit="um").nodal_tests_table()
    assert tests.loc[tests["nodal_test"].abs().idxmax(), "size_class"] == "-150+106"


def _benchmark():
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "circuit_error_model.py"
    spec = importlib.util.spec_from_file_location("circuit_error_model", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_on_lab_reported_surveys_the_reconciled_error_model_names_upward_slips_the_measured_one_misses():
    """A small run of benchmarks/circuit_error_model.py: 5-sd upward slips in the grinding circuit
    are never named first with the error model at the measured values (their sd grows with the
    slip), and are with the model at the reconciled values; the global test keeps its size."""
    bench = _benchmark()
    measured = bench.slip_study("grinding circuit", "measured", 1.0, 40, 11)["named_first"]
    reconciled = bench.slip_study("grinding circuit", "reconciled", 1.0, 40, 11)["named_first"]
    assert measured <= 0.03 and reconciled >= 0.05, (measured, reconciled)
    null = bench.null_study("grinding circuit", "reconciled", 80, 3)
    assert 0.01 <= null["chi_square_rejection_5pct"] <= 0.10 and 0.92 <= null["coverage_95"] <= 0.98


def test_what_each_measurement_is_worth_adds_up_to_each_results_variance():
    """worth.csv: the shifts per sd of every raw measurement error make up the delta-method
    variance of each result, the shares sum to 1, and a measurement no balance checks is just
    determined (redundancy 0) while the others are redundant (redundancy in 0..1)."""
    truth = grinding_circuit()
    balance = reconcile(truth.flowsheet, lab_survey(truth, np.random.default_rng(2), flows={"fresh_feed": 0.02}))
    table = balance.worth_table()
    load = table[table["result"] == "circulating load cyclone"]
    index = truth.flowsheet.stream_index
    gradient = np.zeros(balance.covariance.shape[0])
    n = balance.class_flows.shape[1]
    u, o = index["cyclone_underflow"], index["cyclone_overflow"]
    gradient[u * n : (u + 1) * n] = 1.0 / balance.flows[o]
    gradient[o * n : (o + 1) * n] = -balance.flows[u] / balance.flows[o] ** 2
    assert np.sqrt(np.sum(load["shift_per_sd"] ** 2)) == pytest.approx(
        np.sqrt(gradient @ balance.covariance @ gradient), rel=1e-9
    )
    assert load["result_value"].iloc[0] == pytest.approx(balance.flows[u] / balance.flows[o])
    assert table.groupby("result")["variance_share"].sum().to_numpy() == pytest.approx(1.0)
    fresh = table[(table["stream"] == "fresh_feed") & (table["kind"] == "share")]
    assert (fresh["solvability"] == "just determined").all() and (fresh["redundancy"] == 0).all()
    assert table.loc[table["solvability"] == "redundant", "redundancy"].between(0, 1).all()


@pytest.mark.parametrize("make, flows", [(grinding_circuit, {"fresh_feed": 0.02}), (example_plant, {"screen_feed": 0.02})])
def test_the_design_advice_predicts_the_sd_a_measurement_brings(make, flows):
    """design.csv: the top candidate and the best size analysis, added to the survey at their
    reconciled values with their stated errors and reconciled again, give the predicted sd of
    their quantity within 10 % (measured: within 0.1 %)."""
    from tromplab.circuit.design import DESIGN_COLUMNS, default_quantities, survey_with

    truth = make()
    balance = reconcile(truth.flowsheet, lab_survey(truth, np.random.default_rng(2), flows=flows))
    design = balance.design_table()
    assert list(design.columns) == DESIGN_COLUMNS and design["reduction"].is_monotonic_decreasing
    analyses = design[design["measurement"].isin(["solids flow", "size analysis"])]
    for _, row in analyses.drop_duplicates("measurement").iterrows():
        again = reconcile(truth.flowsheet, survey_with(balance, row["stream"], row["measurement"]))
        gradient = dict(default_quantities(again))[row["quantity"]]
        observed = np.sqrt(gradient @ again.covariance @ gradient)
        assert observed == pytest.approx(row["sd_after"], rel=0.10)
        assert observed < row["sd_before"]
    assert "the measurement that would help most" in balance.report()
