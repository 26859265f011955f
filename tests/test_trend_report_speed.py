"""`trend` and `report` without repeated work, with progress; `circuit` writes warnings.csv.

The outputs are those of the code before the speed-up (tests/data/trend_reference, written by
it); each shortcut is checked against the long way it replaces, to the last bit where the
arithmetic is the same.
"""

import io
import re
import sys

import numpy as np
import pandas as pd
import pytest
import scipy.optimize

from tromplab.cli import main
from tromplab.cli.startup import progress_bars
from tromplab.curves.formulas.paper import _plateau_eta, shuvalov_break
from tromplab.curves.intervals import interval_table
from tromplab.trend import control_chart_pngs, monitor_surveys, read_surveys, write_trend

from .conftest import DATASETS, ROOT

SERIES = DATASETS / "classifier_trend_surveys.csv"
REFERENCE = ROOT / "tests" / "data" / "trend_reference"
CIRCUIT = (DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv")


@pytest.fixture(scope="module")
def documented():
    """The trend of docs/trend.md (formula plitt_bypass), fitted once for the module."""
    return monitor_surveys(read_surveys(SERIES), formula="plitt_bypass")


def assert_same_table(found: pd.DataFrame, expected: pd.DataFrame) -> None:
    """Text and flags exactly, numbers to 1e-9 relative (the last bit of another CPU's arithmetic aside)."""
    assert list(found.columns) == list(expected.columns)
    for column in expected.columns:
        if pd.api.types.is_float_dtype(expected[column]):
            np.testing.assert_allclose(found[column], expected[column], rtol=1e-9, atol=0, err_msg=column)
        else:
            assert found[column].tolist() == expected[column].tolist(), column


@pytest.mark.parametrize(
    ("reference", "options"),
    [("plitt_bypass", ["--formula", "plitt_bypass", "--size-unit", "um"]), ("best", [])],
)
def test_trend_writes_the_tables_of_the_code_before_the_speed_up(tmp_path, capsys, reference, options):
    assert main(["trend", str(SERIES), "-o", str(tmp_path / "out"), *options]) == 0
    capsys.readouterr()
    for name in ("trend.csv", "trend_surveys.csv", "warnings.csv"):
        assert_same_table(pd.read_csv(tmp_path / "out" / name), pd.read_csv(REFERENCE / reference / name))


def test_each_chart_drawn_once_gives_the_bytes_of_drawing_it_for_each_resolution(documented):
    """control_chart_pngs lays a chart out once and saves it at 120 and 100 dpi: the bytes of a
    chart drawn afresh and saved by figure_png at each resolution (what the files and the
    report held before)."""
    from tromplab.output.plotting import figure_png, offscreen_axes, plot_control_chart

    charts = control_chart_pngs(documented, size_unit="um")
    assert list(charts) == ["d_cut", "ep", "eta", "bypass"]
    for quantity, (file_png, report_png) in charts.items():
        for dpi, found in ((120, file_png), (100, report_png)):
            fresh = figure_png(plot_control_chart(documented, quantity, size_unit="um", ax=offscreen_axes()), dpi=dpi)
            assert found == fresh, (quantity, dpi)


def test_the_trend_folder_holds_the_charts_drawn_once(tmp_path, documented, monkeypatch):
    """write_trend draws each chart once (four charts, not eight) and the report embeds the
    100-dpi picture of each."""
    import tromplab.trend as trend

    drawn = []
    real = trend.plot_control_chart

    def counted(result, quantity, **options):
        drawn.append(quantity)
        return real(result, quantity, **options)

    monkeypatch.setattr(trend, "plot_control_chart", counted)
    write_trend(documented, tmp_path, size_unit="um")
    assert drawn == ["d_cut", "ep", "eta", "bypass"]
    html = (tmp_path / "trend_report.html").read_text(encoding="utf-8")
    assert html.count("data:image/png;base64,") == 4


def test_the_break_point_of_formula_11_is_the_root_of_the_equation_as_written_before():
    """shuvalov_break solves the same equation with its constant parts computed once: the root
    the old form (_plateau_eta at each step) gives, to the last bit."""
    for kr in np.geomspace(0.3, 12.0, 23):
        for efficiency in np.linspace(0.505, 0.97, 19):
            try:
                found = shuvalov_break(float(kr), float(efficiency))
            except ValueError:
                continue
            if found == 0.0:
                continue
            before = scipy.optimize.brentq(
                lambda xa, kr=kr, efficiency=efficiency: _plateau_eta(kr, xa) - efficiency, 0.0, 1.0, xtol=1e-14
            )
            assert found == before, (kr, efficiency)


def test_the_report_searches_the_intervals_of_every_best_fit_at_once_with_the_same_result():
    from tromplab import fit_experiments, read_experiments
    from tromplab.output.report import _profiled_bests

    experiments, _ = read_experiments(SERIES)
    bench = fit_experiments(experiments[:8])
    bests = [bench.best_fit(name) for name in bench.experiments]
    profiled = _profiled_bests(bests, 0.9)
    assert len(profiled) == len(bests)
    for best in bests:
        alone = interval_table(best, level=0.9)
        pd.testing.assert_frame_equal(interval_table(best, level=0.9, profiled=profiled[id(best)]), alone, check_exact=True)


def test_the_report_formats_each_table_once_for_both_renderings(tmp_path, monkeypatch):
    import tromplab.output.report as report_module
    from tromplab import fit_experiments, read_experiments

    calls = []
    real = report_module.display_table
    monkeypatch.setattr(report_module, "display_table", lambda table: calls.append(id(table)) or real(table))
    experiments, balances = read_experiments(DATASETS / "air_classifier_lab_synthetic.csv")
    bench = fit_experiments(experiments)
    bench.write_report(tmp_path / "report.html", balances=balances)
    assert calls and len(calls) == len(set(calls))
    assert "| formula" in (tmp_path / "report.md").read_text(encoding="utf-8")


def _display_table_column_by_column(table: pd.DataFrame):
    """display_table as it was written before: each column inserted into the frame in turn,
    every column's texts counted."""
    from tromplab.output.display import NOTE_LENGTH, column_format

    shown = pd.DataFrame(index=table.index)
    notes = []
    for column in table.columns:
        values = table[column]
        if pd.api.types.is_float_dtype(values):
            formatter = column_format(column)
            shown[column] = [formatter(v) if np.isfinite(v) else "-" for v in values]
            continue
        text = values.map(lambda v: "-" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v))
        counts = text.value_counts()
        for repeated in [t for t, count in counts.items() if count > 1 and len(t) > NOTE_LENGTH]:
            notes.append(repeated)
            text = text.where(text != repeated, f"see note {len(notes)}")
        shown[column] = text
    return shown, [f"note {k}: {note}" for k, note in enumerate(notes, 1)]


def test_a_table_made_at_once_renders_as_the_table_made_column_by_column():
    """display_table builds its text table in one go, of Python strings: the HTML and Markdown
    of each of the report's kinds of table (numbers, p-values, shares, texts, long repeated notes,
    missing values, flags) are those of the table built column by column."""
    from tromplab.output.display import display_table
    from tromplab.output.report import _is_text, markdown_table

    long_note = "the fitted bypass differs from the water recovery by more than its interval"
    tables = [
        pd.DataFrame(
            {
                "experiment": ["a", "b", "c", "d"],
                "d_cut": [101.23456, np.nan, 3e-5, 12345678.0],
                "normality_p": [0.0123, 0.5, np.nan, 1.0],
                "eta": [0.81234, 0.7, 0.6, np.inf],
                "F": [1234.5678, 2.0, 0.0, -1.0],
                "note": [long_note, long_note, None, "short"],
                "other": [long_note + " too", "x", long_note + " too", long_note],
                "adequate": [True, False, True, True],
                "n": [12, 11, 10, 9],
            }
        ),
        pd.DataFrame({"d_cut": [1.0, 2.0], "text": ["a" * 40, "a" * 40]}),
        pd.DataFrame({"empty": pd.Series([], dtype=float)}),
    ]
    for table in tables:
        found, found_notes = display_table(table)
        before, before_notes = _display_table_column_by_column(table)
        assert found_notes == before_notes
        assert found.to_html(index=False, border=0) == before.to_html(index=False, border=0)
        text_columns = [c for c in table.columns if _is_text(table[c])]
        assert markdown_table(found, text_columns=text_columns) == markdown_table(before, text_columns=text_columns)


def test_trend_and_report_tell_their_progress_through_the_api(tmp_path, documented):
    from tromplab import fit_experiments, read_experiments

    told = []
    surveys = read_surveys(SERIES)
    monitor_surveys(surveys, formula="shuvalov", progress=lambda done, total, label: told.append((done, total, label)))
    tests = [t for t in told if t[2].startswith("tests: ")]
    assert tests[-1][0] == tests[-1][1] == 40  # 23 surveys against the previous one, 16 against the baseline, the baseline
    assert [d for d, _, _ in tests] == sorted(d for d, _, _ in tests)
    told.clear()
    documented.save(tmp_path / "trend", figures=True, progress=lambda done, total, label: told.append((done, total, label)))
    assert told[-1][:2] == (4, 4) and all(label.startswith("charts: ") for _, _, label in told)
    experiments, _ = read_experiments(SERIES)
    told.clear()
    fit_experiments(experiments[:7]).write_report(
        tmp_path / "r.html", progress=lambda done, total, label: told.append((done, total, label))
    )
    assert told[-1][:2] == (7, 7) and all(label.startswith("figures: ") for _, _, label in told)


class _Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.mark.parametrize(
    "arguments",
    [
        ["trend", str(SERIES), "--formula", "plitt", "-o"],
        ["report", str(DATASETS / "air_classifier_lab_synthetic.csv"), "--jobs", "1", "-o"],
    ],
)
def test_progress_is_silent_when_standard_error_is_not_a_terminal(tmp_path, capsys, arguments):
    assert main([*arguments, str(tmp_path / ("r.html" if arguments[0] == "report" else "out"))]) == 0
    err = capsys.readouterr().err
    assert "%|" not in err and "it/s" not in err and "\r" not in err


def test_the_bars_of_trend_count_surveys_joint_fits_and_charts_on_a_terminal(tmp_path, monkeypatch):
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    with progress_bars(unit="survey", stages=("tests", "charts"), units={"tests": "fit", "charts": "chart"}) as progress:
        result = monitor_surveys(read_surveys(SERIES), formula="plitt", progress=progress)
        write_trend(result, tmp_path, progress=progress)
    shown = terminal.getvalue()
    assert re.search(r"fitting: 100%.*24/24.*survey", shown)
    assert re.search(r"tests: 100%.*40/40.*fit", shown)
    assert re.search(r"charts: 100%.*3/3.*chart", shown)
    with progress_bars(quiet=True) as progress:
        assert progress is None


# --- figures on a shared renderer, the report's figures across experiments first, collections -----
def _own_canvas_axes():
    """Axes of a figure on matplotlib's own canvas, laid out and saved on renderers of its own
    (what offscreen_axes gave before its renderer was shared)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(7.5, 5.0)).subplots()


def test_figures_on_the_shared_renderer_have_the_bytes_of_figures_drawn_on_their_own(documented):
    """Tromp curves, residuals and control charts drawn by offscreen_axes (one renderer shared,
    the texts measured once) give the bytes of each figure on a canvas of its own, at the
    report's 100 and the files' 120 dpi, also when all are made before any is drawn and drawn
    in the reverse order."""
    from tromplab import fit_experiments, read_experiments
    from tromplab.output.plotting import figure_png, offscreen_axes, plot_control_chart, plot_residuals, plot_tromp_fits

    experiments, _ = read_experiments(SERIES)
    bench = fit_experiments(experiments[:3])
    drawings = [
        *(
            lambda ax, e=e: plot_tromp_fits(bench.fits_of(e), best=bench.best_fit(e), ax=ax, size_unit="um")
            for e in bench.experiments
        ),
        *(lambda ax, e=e: plot_residuals(bench.fits_of(e), ax=ax, partition_to="coarse") for e in bench.experiments),
        *(lambda ax, q=q: plot_control_chart(documented, q, ax=ax, size_unit="um") for q in ("d_cut", "bypass")),
    ]
    for dpi in (100, 120):
        made = [draw(offscreen_axes()) for draw in drawings]
        shared = [figure_png(ax, dpi=dpi) for ax in reversed(made)][::-1]
        own = [figure_png(draw(_own_canvas_axes()), dpi=dpi) for draw in drawings]
        assert len(set(own)) == len(own) and shared == own, dpi


def test_offscreen_figures_share_a_renderer_per_size_and_thread():
    import threading

    from tromplab.output.plotting import offscreen_axes

    first, second = offscreen_axes().figure.canvas, offscreen_axes().figure.canvas
    assert first.get_renderer() is second.get_renderer()
    assert offscreen_axes(2, 2, figsize=(9, 6.5))[0, 0].figure.canvas.get_renderer() is not first.get_renderer()
    in_thread = []
    thread = threading.Thread(target=lambda: in_thread.append(offscreen_axes().figure.canvas.get_renderer()))
    thread.start()
    thread.join()
    assert in_thread[0] is not first.get_renderer()


def test_the_report_draws_its_figures_across_experiments_before_those_of_each_and_shows_them_after(monkeypatch):
    """The F heatmap and the ranking are drawn before the workers start on the experiments (they
    then find matplotlib imported), and placed after the experiments' figures as before."""
    import tromplab.output.report as report_module
    from tromplab import fit_experiments, read_experiments

    drawn = []
    for name in ("plot_f_heatmap", "plot_ranking", "experiment_figures"):
        real = getattr(report_module, name)
        monkeypatch.setattr(report_module, name, lambda *a, real=real, name=name, **k: drawn.append(name) or real(*a, **k))
    experiments, _ = read_experiments(SERIES)
    bench = fit_experiments(experiments[:5])
    report = report_module.build_report(bench, [], source="series")
    assert drawn == ["plot_f_heatmap", "plot_ranking"] + ["experiment_figures"] * 3  # 5 experiments, 2 at a time
    captions = [caption for _, _, caption in report.sections["figures"]]
    assert captions[:2] == [f"Tromp curve, experiment {bench.experiments[0]}", f"Residuals, experiment {bench.experiments[0]}"]
    assert captions[-2:] == ["Fisher's F across experiments and formulas", "Points and places across experiments"]
    assert len(captions) == 2 * 5 + 2


def test_trend_keeps_older_objects_out_of_collections_and_gives_them_back(monkeypatch):
    import gc

    import tromplab.trend as trend

    during = []
    real = trend._trend_fits
    monkeypatch.setattr(trend, "_trend_fits", lambda *a: during.append(gc.get_freeze_count()) or real(*a))
    before = gc.get_freeze_count()
    first = monitor_surveys(read_surveys(SERIES), formula="plitt")
    assert during[0] > before and gc.get_freeze_count() == before
    gc.freeze()  # frozen by the caller: left as it is
    try:
        frozen = gc.get_freeze_count()
        again = monitor_surveys(read_surveys(SERIES), formula="plitt")
        # not frozen again nor given back (the frozen objects that died meanwhile are freed)
        assert during[1] <= frozen and gc.get_freeze_count() > 0.9 * frozen
    finally:
        gc.unfreeze()
    pd.testing.assert_frame_equal(again.table, first.table, check_exact=True)


# --- circuit: warnings.csv, the console once per kind, --quiet and -v ----------------------------
def test_circuit_writes_every_warning_to_warnings_csv_and_groups_them_on_the_console(tmp_path, capsys, monkeypatch):
    """The bundled example's cyclone has its weights on two classes (one warning, said in its
    own words); with --fit and a cut unbracketed at every separator, the kind is said once with
    its count; every occurrence is in warnings.csv, and -v prints each one."""
    from tromplab.notices import Notice
    from tromplab.workbench.result import Workbench

    monkeypatch.setattr(
        Workbench, "notices", lambda bench: [Notice(n, "the cut is not bracketed by the data (gap)") for n in bench.experiments]
    )
    folder = tmp_path / "circuit"
    assert main(["circuit", *map(str, CIRCUIT), "-o", str(folder), "--fit", "--no-figures"]) == 0
    captured = capsys.readouterr()
    err = " ".join(captured.err.split())
    assert "warning: 3 of 3 separators: the cut is not bracketed by the data" in err
    assert "warning (cyclone): 2 of 7 classes (150-300 um, 300-600 um) carry 52 % of the weight" in err
    assert "every one in warnings.csv" in err and "2 of 7 classes" not in captured.out
    listed = pd.read_csv(folder / "warnings.csv")
    assert listed["code"].tolist() == ["weight-concentrated", "cut-not-bracketed", "cut-not-bracketed", "cut-not-bracketed"]
    assert listed["separator"].tolist() == ["cyclone", "top_deck", "bottom_deck", "cyclone"]
    assert str(folder / "warnings.csv") in captured.out  # among the files written
    assert main(["circuit", *map(str, CIRCUIT), "-o", str(folder), "--fit", "--no-figures", "-v"]) == 0
    verbose = capsys.readouterr().err
    assert len(re.findall(r"^warning \((top_deck|bottom_deck|cyclone)\): the cut is not bracketed", verbose, re.M)) == 3


def test_circuit_quiet_prints_one_result_line_and_no_warning(tmp_path, capsys):
    folder = tmp_path / "circuit"
    assert main(["-q", "circuit", *map(str, CIRCUIT), "-o", str(folder), "--no-figures"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    (line,) = captured.out.splitlines()
    assert line.startswith("tromplab circuit: survey reconciled (") and "1 warning(s) (warnings.csv)" in line
    assert str(folder) in line
    assert len(pd.read_csv(folder / "warnings.csv")) == 1


def test_a_balance_saved_from_python_writes_the_same_warnings_csv(tmp_path, capsys):
    from tromplab.circuit import read_flowsheet, read_survey, reconcile

    sheet = read_flowsheet(CIRCUIT[0])
    balance = reconcile(sheet, read_survey(CIRCUIT[1], sheet))
    balance.save(tmp_path / "api", figures=False)
    assert main(["circuit", *map(str, CIRCUIT), "-o", str(tmp_path / "cli"), "--no-figures"]) == 0
    capsys.readouterr()
    assert (tmp_path / "api" / "warnings.csv").read_bytes() == (tmp_path / "cli" / "warnings.csv").read_bytes()
