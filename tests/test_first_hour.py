"""The newcomer frictions of the first hour, each fixed and kept: a full disk or a folder
that cannot be written, a broken installation, the console's words (units, what a column is,
relative paths, wrapped lines), the fit report of an lmfit object, the overview of ties."""

import errno
import os
import re

import pandas as pd
import pytest

from tromplab.cli import main

from .conftest import DATASETS, TWO_EXPERIMENT_POINTS, write

FIT = ["--formulas", "plitt", "--no-figures", "--jobs", "1"]


# --- the file system, not tromplab ------------------------------------------------------------
@pytest.mark.parametrize(
    ("code", "words"),
    [(errno.ENOSPC, "No space left on device"), (errno.EACCES, "Permission denied"), (errno.EROFS, "Read-only")],
)
def test_a_full_disk_or_an_unwritable_folder_is_exit_1_naming_the_folder(tmp_path, monkeypatch, capsys, code, words):
    points = write(tmp_path, TWO_EXPERIMENT_POINTS)
    out = tmp_path / "out"
    assert main(["fit", str(points), "-o", str(out), *FIT]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if not p.name.startswith(".")}
    capsys.readouterr()

    def refused(self, path=None, *args, **kwargs):
        raise OSError(code, os.strerror(code), str(path))

    monkeypatch.setattr(pd.DataFrame, "to_csv", refused)
    assert main(["fit", str(points), "-o", str(out), *FIT]) == 1
    monkeypatch.undo()
    err = capsys.readouterr().err
    assert f"could not write in {out}: {words}" in err
    assert "the previous results there are intact" in err and "bug" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if not p.name.startswith(".")} == before


def test_another_os_error_is_still_an_internal_error(tmp_path, monkeypatch, capsys):
    points = write(tmp_path, TWO_EXPERIMENT_POINTS)

    def broken(self, path=None, *args, **kwargs):
        raise OSError(errno.EBADF, os.strerror(errno.EBADF))

    monkeypatch.setattr(pd.DataFrame, "to_csv", broken)
    assert main(["fit", str(points), "-o", str(tmp_path / "out"), *FIT]) == 70
    assert "internal error" in capsys.readouterr().err


# --- a broken installation ----------------------------------------------------------------------
@pytest.mark.parametrize(
    ("missing", "words"),
    [
        ("tromplab.curves.engine", "tromplab's module tromplab.curves.engine"),
        ("lmfit", "the package lmfit, which tromplab needs,"),
    ],
)
def test_an_import_error_says_the_installation_is_broken_and_how_to_reinstall(tmp_path, monkeypatch, capsys, missing, words):
    import tromplab.cli.fit

    def run(args):
        raise ModuleNotFoundError(f"No module named '{missing}'", name=missing)

    monkeypatch.setattr(tromplab.cli.fit, "_run_fit", run)
    points = write(tmp_path, TWO_EXPERIMENT_POINTS)
    parser_run = main(["fit", str(points), "-o", str(tmp_path / "out"), *FIT])
    err = capsys.readouterr().err
    assert parser_run == 70
    assert f"the installation is broken: {words} cannot be imported" in err
    assert "python -m pip install --force-reinstall tromplab" in err and "a bug in tromplab" not in err


# --- the circuit: a NaN assay, the error model at reconciled grades --------------------------
MINERALS_SHEET = DATASETS / "circuit_minerals_flowsheet.csv"
MINERALS_SURVEY = DATASETS / "circuit_minerals_survey.csv"


def test_the_assay_error_model_is_evaluated_at_grades_inside_0_to_1():
    """A reconciled grade outside 0..1 (seen: 56 and -76 where a class flow near 0 divides a
    component flow) or NaN made an assay's sd follow the solver's last digits."""
    import numpy as np

    from tromplab.circuit.assays import assays_at

    assays = pd.DataFrame(
        {"stream": ["a"] * 4, "class_index": [0, 1, 2, 3], "component": ["x"] * 4, "value": [0.1] * 4, "sd": [np.nan] * 4,
         "row": [2, 3, 4, 5], "relative": [0.05] * 4, "absolute": [0.0005] * 4}
    )  # fmt: skip
    grades = np.array([[[56.0, -76.0, np.nan, 0.3]]])
    sd = assays_at(assays, grades, {"a": 0}, ("x",))["sd"].to_numpy()
    np.testing.assert_allclose(sd, np.hypot(0.05 * np.array([1.0, 0.0, 0.0, 0.3]), 0.0005), rtol=1e-12)


def test_a_start_whose_predictions_are_not_finite_is_a_failure_not_an_exception():
    import numpy as np

    from tromplab.circuit import read_survey
    from tromplab.circuit.flowsheet import read_flowsheet
    from tromplab.circuit.problem import build_problem, solve

    sheet = read_flowsheet(MINERALS_SHEET)
    problem, _ = build_problem(sheet, read_survey(MINERALS_SURVEY, sheet))
    z, success, message = solve(problem, np.full(problem.m0.size, np.nan))
    assert not success and "not finite at the starting point" in message


def test_a_nan_assay_reconciles_alike_every_time(tmp_path):
    """A NaN in one assay cell is an assay not made: the survey reconciles, the same way in
    repeated runs (to the last digits OpenBLAS rounds by the arrays' alignment)."""
    import numpy as np

    from tromplab.circuit import read_survey, reconcile
    from tromplab.circuit.flowsheet import read_flowsheet

    lines = MINERALS_SURVEY.read_text(encoding="utf-8").splitlines()
    lines = [",".join(["NaN" if k == 4 else cell for k, cell in enumerate(line.split(","))])
             if line.startswith("cyclone_overflow,53.0,75.0") else line for line in lines]  # fmt: skip
    path = tmp_path / "survey.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    sheet = read_flowsheet(MINERALS_SHEET)
    runs = [reconcile(sheet, read_survey(path, sheet)) for _ in range(3)]
    assert all(run.success for run in runs)
    assert len(runs[0].survey.assays) == len(read_survey(MINERALS_SURVEY, sheet).assays) - 1
    for run in runs[1:]:
        np.testing.assert_allclose(run.class_flows, runs[0].class_flows, rtol=1e-8)
        assert abs(run.chi_square - runs[0].chi_square) < 1e-8 * runs[0].chi_square


# --- the overview of a large batch: experiments whose first place is tied ---------------------
def test_the_overview_shows_experiments_whose_first_place_is_tied_and_counts_them():
    import matplotlib

    matplotlib.use("Agg")
    from tromplab.output.plotting import offscreen_axes, plot_batch_overview

    fits = pd.DataFrame(
        {"experiment": ["A", "A", "B", "B", "C", "C"], "formula": ["plitt", "lognormal"] * 3,
         "rank": [1.5, 1.5, 1.0, 2.0, 2.0, 1.0], "d_cut": [10.0, 11, 20, 21, 30, 31], "ep": [1.0] * 6, "eta": [0.9] * 6}
    )  # fmt: skip
    axes = offscreen_axes(2, 2)
    plot_batch_overview(fits, axes=axes)
    figure = axes.ravel()[0].figure
    assert figure._suptitle.get_text() == "3 experiments (1 with formulas tied at the first place: the first of them shown above)"
    bars = dict(
        zip((label.get_text() for label in axes.ravel()[3].get_yticklabels()), (p.get_width() for p in axes.ravel()[3].patches))
    )
    assert bars == {"(tied first place)": 1, "lognormal": 1, "plitt": 1}
    cuts = [patch.get_x() for patch in axes.ravel()[0].patches if patch.get_height() > 0]
    assert min(cuts) == 10.0  # A, tied, is shown by plitt's cut


# --- the console's words -----------------------------------------------------------------------
def test_the_intervals_table_names_the_shape_parameter(tmp_path, capsys):
    points = write(tmp_path, TWO_EXPERIMENT_POINTS)
    assert (
        main(["fit", str(points), "-o", str(tmp_path / "out"), "--ci", "0.9", "--formulas", "plitt,lognormal", "--no-figures"])
        == 0
    )
    blocks = capsys.readouterr().out.split("  intervals:\n")[1:]
    assert len(blocks) == 2
    header, *rows = blocks[0].splitlines()
    assert header.split()[:2] == ["formula", "par"] and "shape low" in header
    assert {row.split()[0]: row.split()[1] for row in rows[:2]} == {"plitt": "ks", "lognormal": "kf"}


def test_density_predict_prints_the_paths_as_given(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    washability = DATASETS / "density_washability_synthetic.csv"
    argv = [
        "density",
        "predict",
        str(washability),
        "--rho50",
        "1.5",
        "--ep",
        "0.05",
        "-o",
        "sub/pred.csv",
        "--table",
        "sub/t.csv",
    ]
    assert main(argv) == 0
    wrote = capsys.readouterr().out.split("Wrote:\n")[1].split()
    assert wrote == [os.path.join("sub", "pred.csv"), os.path.join("sub", "t.csv")]


@pytest.mark.slow
def test_the_density_report_heads_its_fits_per_test(tmp_path):
    from tromplab.density import fit_density

    result = fit_density(DATASETS / "density_tracers_dmc_by_size_synthetic.csv", curves="normal")
    result.save(tmp_path / "d", report=True)
    page = (tmp_path / "d" / "report.html").read_text(encoding="utf-8")
    markdown = (tmp_path / "d" / "report.md").read_text(encoding="utf-8")
    assert "<h2>Ranked fits per test</h2>" in page and "## Ranked fits per test" in markdown
    assert "experiment" not in page.lower().split("<h1>")[1].split("<figure")[0].replace("experiments", "")


def test_the_circuit_summary_is_wrapped_as_the_fit_tables(tmp_path, capsys):
    sheet, survey = DATASETS / "circuit_minerals_flowsheet.csv", DATASETS / "circuit_minerals_survey.csv"
    assert main(["circuit", str(sheet), str(survey), "-o", str(tmp_path / "c"), "--no-figures"]) == 0
    out = capsys.readouterr().out
    summary = out.split("\nReconciled solids flows:")[0].splitlines()
    assert max(len(line) for line in summary) <= 98
    assert any(line.startswith("  ") for line in summary)  # a continuation
    assert "assays set aside (the class holds less than 0.1 % of its stream" in " ".join(" ".join(summary).split())


def test_the_bundled_minerals_survey_is_what_its_script_draws():
    """datasets/circuit_minerals_survey.csv = analysis/make_circuit_minerals_example.py's draw (seed 11)."""
    import numpy as np

    from tromplab.circuit.simulation import mineral_circuit, simulate_survey, survey_table

    drawn = survey_table(simulate_survey(mineral_circuit(), np.random.default_rng(11), flows={"fresh_feed": 0.02}))
    bundled = pd.read_csv(MINERALS_SURVEY, comment="#")
    pd.testing.assert_frame_equal(bundled, drawn, check_dtype=False)
    assert {"assay_magnetite_pct", "assay_pyrite_pct"} <= set(bundled.columns)


# --- the lmfit object of a fit: its report says whose numbers it gives -----------------------
@pytest.mark.parametrize("batched", [False, True])
def test_the_fit_report_states_the_fits_own_starts_and_evaluations(batched):
    import tromplab

    points = tromplab.TrompPoints("run", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])
    fit = (
        tromplab.fit_experiments([points], formulas=["plitt"]).best_fit("run")
        if batched
        else tromplab.fit_formula(points, "plitt")
    )
    report = fit.model_result().fit_report()
    assert fit.fit.nfev > 3 and fit.fit.n_starts >= 1
    assert (
        f"Model(plitt: tromplab's fit ({fit.fit.n_starts} start(s), {fit.fit.nfev} function evaluations), re-evaluated by "
        "lmfit from its optimum)" in report
    )
    assert f"# function evals   = {fit.fit.nfev}\n" in report


# --- the documentation site loads nothing from another host ------------------------------------
def _offline_checker():
    import importlib.util

    from .conftest import ROOT

    spec = importlib.util.spec_from_file_location("check_offline_site", ROOT / ".ci" / "check_offline_site.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_site_check_finds_the_gallery_timing_pages_remote_scripts(tmp_path):
    checker = _offline_checker()
    timing_page = (  # what sphinx-gallery 0.15-0.22 writes into sg_execution_times when it writes the page
        '<link href="https://cdn.datatables.net/1.13.6/css/dataTables.bootstrap5.min.css" rel="stylesheet" />\n'
        '<script src="https://code.jquery.com/jquery-3.7.0.js"></script>\n'
        '<script src="https://cdn.datatables.net/1.13.6/js/jquery.dataTables.min.js"></script>\n'
    )
    assert checker.remote_loads(timing_page) == [
        "https://cdn.datatables.net/1.13.6/css/dataTables.bootstrap5.min.css",
        "https://code.jquery.com/jquery-3.7.0.js",
        "https://cdn.datatables.net/1.13.6/js/jquery.dataTables.min.js",
    ]
    local = '<script src="_static/x.js"></script><img src="data:image/png;base64,AA"><a href="https://doi.org/x">doi</a>'
    assert checker.remote_loads(local) == []
    (tmp_path / "index.html").write_text(local, encoding="utf-8")
    assert checker.main(str(tmp_path)) == 0
    (tmp_path / "sg_execution_times.html").write_text(timing_page, encoding="utf-8")
    assert checker.main(str(tmp_path)) == 1


def test_the_gallery_writes_no_computation_times_page():
    from .conftest import ROOT

    text = (ROOT / "docs" / "conf.py").read_text(encoding="utf-8")
    assert re.search(r'"write_computation_times":\s*False', text)
    assert "python .ci/check_offline_site.py docs/_build/html" in (ROOT / ".ci" / "run").read_text(encoding="utf-8")
