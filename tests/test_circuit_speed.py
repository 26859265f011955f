"""The factor-once rewrite of ``tromplab circuit`` and ``circuit design`` (batch speed for every face) against the
implementation before it: every file of eight surveys equal to the stored outputs
(tests/data/circuit_reference, written by its make_reference.py), byte for byte where the
arithmetic is the same and otherwise to 1e-9 relative.  The outputs were those of commit ed84263
until the deterministic least squares replaced MINPACK's; make_reference.py says by how much
they moved then.
"""

import gzip
import importlib.util
import io
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

REFERENCE = Path(__file__).parent / "data" / "circuit_reference"
#: Relative agreement of a number computed by other arithmetic (low-rank updates, one
#: factorisation); a number near 0 agrees to this much of its column's scale, and of the unit
#: (a share's adjustment of 4e-10 is rounding of the bounded solution).
RELATIVE = 1e-9
#: The reference is reproducible to the last bit since the least squares are Gauss-Newton in
#: numpy (MINPACK's result depended on the heap's leftovers: ed84263's assayed surveys moved by
#: 1e-4 between runs); a tolerance is left for another machine's BLAS only.
SPREAD_OF_THE_REFERENCE: dict[str, float] = {}
UNBOUNDED_FILES = ("chi_square.csv", "degrees_of_freedom.csv")


def _reference_module():
    spec = importlib.util.spec_from_file_location("make_reference", REFERENCE / "make_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


MAKE = _reference_module()
CASES = [*MAKE.CIRCUIT_CASES, *MAKE.DESIGN_CASES]


def _text(path: Path) -> str:
    return gzip.decompress(path.read_bytes()).decode() if path.suffix == ".gz" else path.read_text()


def _design_order(table: pd.DataFrame, relative: float) -> pd.DataFrame:
    """``design.csv`` without its ranks, in an order that does not depend on the last bits of
    tied reductions: before the rewrite candidates of equal reduction (two that measure the
    same flow; a flow that only sets the scale) ranked by rounding; now in candidate order."""
    assert (table["rank"] == [str(k) for k in range(1, len(table) + 1)]).all()
    key = table.assign(tie=pd.to_numeric(table["reduction"]).round(9), n=pd.to_numeric(table["n_made_testable"]))
    key = key.sort_values(["tie", "n", "quantity", "stream", "measurement"], ascending=[False, False, True, True, True])
    if relative > 1e-6:  # reductions known to the reference's spread only: rows in candidate order
        key = key.sort_values(["stream", "measurement", "quantity"])
    return table.loc[key.index].drop(columns="rank").reset_index(drop=True)


def _assert_tables_agree(expected: str, actual: str, name: str, relative: float = RELATIVE) -> None:
    """Same columns, rows and text; numbers equal to :data:`RELATIVE` of themselves (or of the
    column's largest magnitude, for a number that is rounding around 0)."""
    left, right = (pd.read_csv(io.StringIO(text), keep_default_na=False, dtype=str) for text in (expected, actual))
    if name.endswith("design.csv"):
        left, right = _design_order(left, relative), _design_order(right, relative)
    assert list(left.columns) == list(right.columns), name
    assert left.shape == right.shape, name
    for column in left.columns:
        a = pd.to_numeric(left[column].replace("", "nan"), errors="coerce").to_numpy(float)
        b = pd.to_numeric(right[column].replace("", "nan"), errors="coerce").to_numpy(float)
        text = np.isnan(a) & (left[column] != "").to_numpy() & ~left[column].str.lower().isin(["nan", "inf", "-inf"]).to_numpy()
        if text.all() or (left[column] == right[column]).all():
            assert (left[column] == right[column]).all(), f"{name}: {column}"
            continue
        if not np.isfinite(relative):
            continue
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=f"{name}: {column}")
        scale = np.nanmax(np.abs(a), initial=0.0)
        np.testing.assert_allclose(b, a, rtol=relative, atol=relative * max(scale, 1.0), err_msg=f"{name}: {column}")


def _untied(summary: str) -> str:
    """A design summary without the names of the results in its candidate lines: two results
    of equal reduction (a separator's fine yield and its circulating load, one flow ratio) are a
    tie, whose order was the last bits of the two reductions before the rewrite."""
    return re.sub(r"sd of .+? \d\S* -> \d\S* \(", "sd of ... (", summary)


@pytest.mark.parametrize("case", CASES)
@pytest.mark.slow
def test_every_file_agrees_with_the_implementation_before_the_rewrite(case, tmp_path, monkeypatch):
    monkeypatch.chdir(REFERENCE)  # the inputs as the reference run named them (the summaries show them)
    assert MAKE.run(case, tmp_path / case) == 0
    expected = {path.name.removesuffix(".gz"): path for path in (REFERENCE / case).iterdir()}
    # warnings.csv came after the reference (the separators' warnings, tromplab.notices): checked by tests/test_trend_report_speed.py
    written = {path.name: path for path in (tmp_path / case).iterdir() if path.name != "warnings.csv"}
    assert set(written) == set(expected)
    identical = 0
    for name, path in expected.items():
        reference, current = _text(path), written[name].read_text()
        if name == ".tromplab-manifest":  # the folder's list of files names warnings.csv too
            current = current.replace("warnings.csv\n", "")
        if reference == current:
            identical += 1
        elif name.endswith(".csv"):
            tolerance = RELATIVE if name in UNBOUNDED_FILES else SPREAD_OF_THE_REFERENCE.get(case, RELATIVE)
            _assert_tables_agree(reference, current, f"{case}/{name}", tolerance)
        elif case.startswith("design"):
            assert _untied(current) == _untied(reference), f"{case}/{name}"
        else:
            assert current == reference, f"{case}/{name}"
    assert identical >= 1


@pytest.mark.parametrize("case", ["example", "water", "assay_class", "assay_stream", "design_simulated"])
@pytest.mark.slow
def test_the_updates_equal_fresh_pseudo_inverses(case, monkeypatch):
    """The reference path kept in the tests: every candidate of ``design.csv`` by a fresh
    pseudo-inverse of the stacked Jacobian (the implementation before the rewrite) against the
    low-rank updates, on one reconciled balance (so the solver's own spread plays no part)."""
    from tromplab.circuit import ErrorModel, reconcile
    from tromplab.circuit.design import CandidateUpdates, design_table
    from tromplab.circuit.planning import simulated_survey

    monkeypatch.chdir(REFERENCE)
    if case in MAKE.CIRCUIT_CASES:
        balance = reconcile(MAKE.FLOWSHEET, MAKE.CIRCUIT_CASES[case][0])
    else:
        from tromplab.circuit import read_flowsheet

        sheet = read_flowsheet(MAKE.FLOWSHEET)
        balance = reconcile(sheet, simulated_survey(sheet)[0])
    refactored = []
    original = CandidateUpdates._refactored

    def counted(self, E):
        refactored.append(E.shape[0])
        return original(self, E)

    monkeypatch.setattr(CandidateUpdates, "_refactored", counted)
    updated = design_table(balance, errors=ErrorModel())
    n_candidates = len(updated.drop_duplicates(["stream", "measurement"]))
    assert len(refactored) < n_candidates / 2  # the updates did the work
    monkeypatch.setattr(CandidateUpdates, "_within_seen", lambda self, E: False)
    fresh = design_table(balance, errors=ErrorModel())
    _assert_tables_agree(fresh.to_csv(index=False), updated.to_csv(index=False), f"{case}/design.csv")


def test_the_distribution_functions_are_scipy_stats_bit_for_bit():
    from scipy import stats

    from tromplab.statistics.distributions import chi2_ppf, chi2_sf, norm_isf, norm_sf

    statistics = np.array([0.0, 1e-3, 0.5, 13.7, 21.71797430220539, 400.0])
    for dof in (1, 2, 17, 21, 300):
        np.testing.assert_array_equal(chi2_sf(statistics, dof), stats.chi2.sf(statistics, dof))
        assert chi2_sf(13.7, dof) == stats.chi2.sf(13.7, dof)
        for alpha in (0.05, 0.01, 1e-6):
            assert chi2_ppf(1.0 - alpha, dof) == stats.chi2.ppf(1.0 - alpha, dof)
    values = np.array([-40.0, -3.79, -0.5, 0.0, 0.5, 3.44, 8.0, np.nan])
    np.testing.assert_array_equal(norm_sf(values), stats.norm.sf(values))
    levels = np.array([1e-12, 1e-4, 0.0025, 0.025, 0.5, 0.975])
    np.testing.assert_array_equal(norm_isf(levels), stats.norm.isf(levels))
    assert norm_isf(0.025) == stats.norm.isf(0.025)


@pytest.mark.slow
def test_a_circuit_run_without_figures_and_fits_imports_neither_matplotlib_lmfit_nor_scipy_stats():
    import subprocess
    import sys

    code = (
        "import sys; from tromplab.cli import main; "
        f"code = main(['circuit', {MAKE.FLOWSHEET!r}, {MAKE.SURVEY!r}, '-o', sys.argv[1], '--no-figures', '-q']); "
        "print(code, *sorted(m for m in ('matplotlib', 'lmfit', 'scipy.stats', 'statsmodels', 'networkx') if m in sys.modules))"
    )
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        done = subprocess.run([sys.executable, "-c", code, folder], cwd=REFERENCE, capture_output=True, text=True, check=True)
    assert done.stdout.splitlines()[-1].split() == ["0"]  # after the one-line result of -q


@pytest.mark.slow
def test_progress_reports_each_stage_to_the_python_api(tmp_path, monkeypatch):
    from tromplab.circuit import design_circuit, reconcile_circuit

    monkeypatch.chdir(REFERENCE)
    heard = []
    reconcile_circuit(MAKE.FLOWSHEET, "inputs/assay_stream.csv", progress=lambda *a: heard.append(a))
    stages = [label.split(": ")[0] for _, _, label in heard]
    assert stages[0] == "reconciliation" and {"elimination", "design"} <= set(stages)
    assert "reconciliation: round 2" in [label for _, _, label in heard]  # the error model's rounds
    design = [(done, total) for done, total, label in heard if label.startswith("design: ")]
    assert design[-1][0] == design[-1][1] == len(design)  # candidate i of n, each once
    assert all(label.startswith("elimination: step ") for _, _, label in heard if label.startswith("elimination"))
    heard.clear()
    design_circuit(MAKE.FLOWSHEET, progress=lambda *a: heard.append(a))
    assert heard[0][2] == "reconciliation: round 1" and heard[-1][2].startswith("design: candidate")


@pytest.mark.slow
def test_the_command_line_is_silent_on_stderr_without_a_terminal(tmp_path, monkeypatch, capsys):
    from tromplab.cli import main

    monkeypatch.chdir(REFERENCE)
    assert main(["circuit", MAKE.FLOWSHEET, "inputs/assay_stream.csv", "-o", str(tmp_path / "c"), "--no-figures"]) == 0
    assert main(["circuit", "design", MAKE.FLOWSHEET, "-o", str(tmp_path / "d")]) == 0
    err = capsys.readouterr().err  # no bar; the separators' warnings, once per kind, are all it holds
    assert "\r" not in err and "%|" not in err and "step" not in err, err


def test_the_stage_bars_draw_each_stage_on_a_terminal_and_nothing_with_quiet(monkeypatch):
    pytest.importorskip("tqdm")
    from tromplab.cli.startup import stage_bars

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    screen = Terminal()
    monkeypatch.setattr("sys.stderr", screen)
    monkeypatch.setenv("COLUMNS", "100")
    with stage_bars() as progress:
        for label in ("reconciliation: round 1", "reconciliation: round 2"):
            progress(0, 1, label)
        for k in (1, 2, 3):
            progress(k, 3, f"design: candidate {k} of 3")
    drawn = screen.getvalue()
    assert "reconciliation: round 2" in drawn and "design" in drawn and "3/3" in drawn and "candidate 3 of 3" in drawn
    with stage_bars(quiet=True) as progress:
        assert progress is None


@pytest.mark.slow
def test_a_large_flowsheet_reconciled_by_gauss_newton_and_sparse_products_equals_the_dense_path(monkeypatch):
    """From SPARSE_UNKNOWNS on, sparse products, the bounds' affine forms by projection and thin
    SVDs; below it, dense products and full SVDs (the former path; Gauss-Newton steps in both):
    on a 12-node plant of the same kind forced through both, the same balance."""
    import warnings

    from tromplab.circuit import problem, reconcile, reconciliation
    from tromplab.circuit.simulation import lab_survey, large_plant

    truth = large_plant(4, 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the truth's grade of an empty class is 0/0 (no assay drawn)
        survey = lab_survey(truth, np.random.default_rng(40), flows={"fresh_feed": 0.02}, assayed=())
    balances = {}
    for path, threshold in (("dense", 10**9), ("large", 10)):
        monkeypatch.setattr(problem, "SPARSE_UNKNOWNS", threshold)
        monkeypatch.setattr(reconciliation, "SPARSE_UNKNOWNS", threshold)
        balances[path] = reconcile(truth.flowsheet, survey)
    dense, large = balances["dense"], balances["large"]
    assert large.message.startswith("Gauss-Newton") and dense.message.startswith("Gauss-Newton")
    assert large.dof == dense.dof and large.at_bound == dense.at_bound
    assert large.chi_square == pytest.approx(dense.chi_square, rel=1e-8)
    np.testing.assert_allclose(large.flows, dense.flows, rtol=1e-8)
    np.testing.assert_allclose(large.flow_sd, dense.flow_sd, rtol=1e-7)
    np.testing.assert_allclose(large.share_sd, dense.share_sd, rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize("case", ["assay_class", "water"])
def test_the_error_model_on_arrays_is_the_survey_tables_bit_for_bit(case, monkeypatch):
    """The error model's rounds evaluate the sds on arrays (problem.SurveyErrors) and change the
    problem's covariance only (problem.with_errors): the same bits as the survey's own
    ``with_errors_at`` and a problem built anew from it."""
    from tromplab.circuit import read_flowsheet, read_survey, reconcile
    from tromplab.circuit.problem import SurveyErrors, build_problem, error_model_point, with_errors

    monkeypatch.chdir(REFERENCE)
    sheet = read_flowsheet(MAKE.FLOWSHEET)
    survey = read_survey(MAKE.CIRCUIT_CASES[case][0], sheet)
    balance = reconcile(sheet, survey)
    problem, _ = build_problem(sheet, survey)
    shares, flows, grades = error_model_point(problem, balance.fitted * 1.01)  # a point of no round
    sd, share_at = SurveyErrors(survey, sheet.stream_index).at(shares, flows, grades)
    evaluated = survey.with_errors_at(shares, flows, sheet.stream_index, grades)
    tables = (evaluated.shares, evaluated.flows, evaluated.pct_solids, evaluated.assays)
    np.testing.assert_array_equal(sd, np.concatenate([table["sd"].to_numpy(float) for table in tables]))
    np.testing.assert_array_equal(share_at, evaluated.shares["at"].to_numpy(float))
    quick, anew = with_errors(problem, SurveyErrors(survey, sheet.stream_index), sd, share_at), build_problem(sheet, evaluated)[0]
    for name in ("sd", "cov", "W", "effects", "y", "A", "b", "m0", "N"):
        np.testing.assert_array_equal(getattr(quick, name), getattr(anew, name), err_msg=name)


def test_the_elimination_steps_reconciled_from_the_step_before_equal_a_reconciliation_anew(monkeypatch):
    """A compensated survey of the serial elimination is reconciled from the solution of the step
    before, the error model's rounds by single Gauss-Newton steps, without the bounds: its global
    test and measurement tests are those of reconciling the survey anew, to 1e-9 relative (the
    tests of a measurement the balances barely check, to 1e-9 of the largest test)."""
    from tromplab.circuit import read_flowsheet, reconcile
    from tromplab.circuit.elimination import _compensated
    from tromplab.circuit.reconciliation import _reconciled_for_elimination

    monkeypatch.chdir(REFERENCE)
    sheet = read_flowsheet(MAKE.FLOWSHEET)
    balance = reconcile(sheet, "inputs/assay_stream.csv")
    assert balance.rejected
    table = balance.adjustments_table().dropna(subset=["measurement_test"])
    j = table["measurement_test"].abs().idxmax()
    survey = _compensated(balance, j, float(table.loc[j, "gross_error"]))
    warm, anew = _reconciled_for_elimination(balance, survey), reconcile(sheet, survey)
    assert warm.dof == anew.dof and warm.chi_square == pytest.approx(anew.chi_square, rel=1e-9)
    tests = {name: b._measurement_tests for name, b in (("warm", warm), ("anew", anew))}
    np.testing.assert_array_equal(tests["warm"].testable, tests["anew"].testable)
    scale = np.nanmax(np.abs(tests["anew"].statistic))
    np.testing.assert_allclose(tests["warm"].statistic, tests["anew"].statistic, rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(tests["warm"].estimate, tests["anew"].estimate, rtol=1e-9,
                               atol=1e-9 * np.nanmax(np.abs(tests["anew"].estimate)))  # fmt: skip
