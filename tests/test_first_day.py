"""What a new user meets on the first day: the lmfit object of any fit, the two cuts told apart
on the console, no band where the intervals are withheld, the report's figures in their own
folder, helpful errors for a formula id and a column without a kind, a quick answer for a
missing file, and an HTML report that reads as a document."""

import json
import re
import subprocess
import sys

import lmfit
import matplotlib
import numpy as np
import pytest

import tromplab
from tromplab.cli import main
from tromplab.errors import InputError, OptionError
from tromplab.output.plotting import plot_tromp_fits

from .conftest import DATASETS, ROOT, write

matplotlib.use("Agg")

DECKS = DATASETS / "double_deck_screen_decks_lab.csv"
HYDROCYCLONE = ROOT / "tests" / "data" / "hydrocyclone_size_class_um.csv"
GAS_CYCLONE = ROOT / "tests" / "data" / "gas_cyclone_classes_above_cut_um.csv"


# --- the lmfit ModelResult of any fit ----------------------------------------------------------
@pytest.fixture(scope="module")
def batched():
    return tromplab.fit_experiments(tromplab.read_experiments(HYDROCYCLONE), extended=True)


def test_a_batched_fit_gives_an_lmfit_model_result_on_demand(batched):
    fit = batched.best_fit(batched.experiments[0])
    assert fit.fit.raw is None  # the batched engine keeps no lmfit object
    result = fit.model_result()
    assert isinstance(result, lmfit.model.ModelResult)
    for name in fit.fit.names:
        assert result.params[name].value == pytest.approx(fit.fit.values[name], rel=1e-6)
    assert result.chisqr == pytest.approx(fit.fit.ssr, rel=1e-9)
    sizes = np.geomspace(50, 2000, 7)
    np.testing.assert_allclose(result.eval(size=sizes), fit.predict(sizes), rtol=1e-6)
    band = result.eval_uncertainty(size=sizes, sigma=2)
    assert band.shape == sizes.shape and np.all(np.isfinite(band)) and np.all(band >= 0)
    assert "d_cut" in result.fit_report() and fit.formula.shape_name in result.fit_report()
    assert result.plot() is not None


@pytest.mark.parametrize("formula", ["shuvalov", "plitt_bypass", "whiten"])
def test_every_kind_of_formula_gives_one(batched, formula):
    (fit,) = [f for f in batched.fits if f.formula.id == formula]
    result = fit.model_result()
    assert result.chisqr == pytest.approx(fit.fit.ssr, rel=1e-6)
    np.testing.assert_allclose(result.best_fit, fit.predict(fit.points.size), rtol=1e-5, atol=1e-9)


def test_a_failed_fit_says_it_has_no_model_result():
    points = tromplab.TrompPoints("run", [10, 20, 40, 80], [0.9, 0.6, 0.3, 0.1])
    failed = tromplab.fit_formula(points, "plitt")
    failed = type(failed)(formula=failed.formula, points=points, fit=failed.fit.failed([], 4, "no optimum"))
    with pytest.raises(ValueError, match="has no lmfit result: no optimum"):
        failed.model_result()


# --- the console's cuts -----------------------------------------------------------------------
def test_the_console_tells_the_actual_cut_from_the_corrected_one(tmp_path, capsys):
    assert main(["fit", str(HYDROCYCLONE), "-o", str(tmp_path / "a"), "--extended", "--figures", "none"]) == 0
    out = capsys.readouterr().out
    header = next(line for line in out.splitlines() if line.lstrip().startswith("rank"))
    assert header.split()[3:5] == ["d50", "d50c"] and "d_cut" not in header.split()
    assert "d50: actual cut (partition 1/2) of every curve; d50c: corrected cut" in out
    whiten = next(line for line in out.splitlines() if " whiten " in line).split()
    assert float(whiten[3]) < float(whiten[4])  # bypass: the actual cut lies below the corrected one
    assert main(["fit", str(HYDROCYCLONE), "-o", str(tmp_path / "b"), "--figures", "none"]) == 0
    header = next(line for line in capsys.readouterr().out.splitlines() if line.lstrip().startswith("rank"))
    assert "d50" in header.split() and "d50c" not in header.split()  # the nine formulas: one cut


# --- no band where the intervals are withheld ---------------------------------------------------
def _bands(ax):
    return [c for c in ax.collections if type(c).__name__ in ("PolyCollection", "FillBetweenPolyCollection")]


def test_no_band_is_drawn_when_the_points_do_not_bracket_the_cut():
    bench = tromplab.fit_experiments(tromplab.read_experiments(GAS_CYCLONE), formulas=["plitt", "lognormal"])
    fits = bench.fits_of(bench.experiments[0])
    assert all(f.unbracketed for f in fits)
    ax = plot_tromp_fits(fits)
    assert _bands(ax) == []
    assert "no 95 % band: the points do not bracket the cut" in [t.get_text() for t in ax.get_legend().get_texts()]
    bracketed = tromplab.fit_experiments(tromplab.read_experiments(HYDROCYCLONE), formulas=["plitt"])
    assert len(_bands(plot_tromp_fits(bracketed.fits))) == 1


# --- the report's figures ------------------------------------------------------------------------
@pytest.mark.slow
def test_write_report_puts_the_markdown_figures_in_their_folder(tmp_path):
    bench = tromplab.fit_experiments(tromplab.read_experiments(HYDROCYCLONE), formulas=["plitt", "lognormal"])
    (tmp_path / "mine.png").write_bytes(b"not tromplab's")
    written = bench.write_report(tmp_path / "REPORT.html")
    figures = sorted((tmp_path / "REPORT_figures").glob("*.png"))
    assert figures and {f"REPORT_figures/{f.name}" for f in figures} <= set(written)
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["mine.png"]  # nothing beside the user's files
    markdown = (tmp_path / "REPORT.md").read_text()
    linked = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", markdown)
    assert linked and all((tmp_path / link).is_file() for link in linked)


# --- errors that help ----------------------------------------------------------------------------
def test_an_unknown_formula_suggests_the_closest_and_lists_every_id_and_group(capsys):
    with pytest.raises(OptionError) as refused:
        tromplab.fit_experiments(tromplab.read_experiments(HYDROCYCLONE), formulas=["plit"])
    message = str(refused.value)
    assert message.startswith("formulas names an unknown formula 'plit' (did you mean plitt?)")
    for group in ("paper:", "other:", "extended:"):
        assert group in message
    for formula in tromplab.ALL_FORMULAS:
        assert f"{formula.id} ({formula.equation})" in message
    assert main(["fit", str(HYDROCYCLONE), "--formulas", "lognorm"]) == 2
    assert "--formulas names an unknown formula 'lognorm' (did you mean lognormal" in capsys.readouterr().err


def test_a_column_without_a_kind_names_the_option_of_each_face(tmp_path, capsys):
    table = write(
        tmp_path, "size_lower,size_upper,feed,fine,coarse\n800,,5,0,9.2\n400,800,15,1,25.3\n200,400,80,99,65.5\n", "lab.csv"
    )
    with pytest.raises(InputError, match=r"declare it with kind='pct' \(or another of mass, pct"):
        tromplab.read_lab(table)
    assert main(["points", str(table), "-o", str(tmp_path / "points.csv")]) == 1
    assert "declare it with --kind pct (or another of mass, pct" in capsys.readouterr().err


# --- a missing file answers before the numerical libraries load ------------------------------------
_MISSING = """
import json, sys, time
start = time.perf_counter()
from tromplab._launch import main
sys.argv = ["tromplab", "fit", "nosuch.csv", "-o", "out"]
code = main()
print(json.dumps({"code": code, "seconds": time.perf_counter() - start, "modules": sorted(sys.modules)}))
"""


def test_a_missing_input_is_reported_before_the_numerical_libraries_load(tmp_path):
    done = subprocess.run([sys.executable, "-c", _MISSING], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    said = json.loads(done.stdout.splitlines()[-1])
    assert said["code"] == 1 and "tromplab fit: error: nosuch.csv: file not found" in done.stderr
    loaded = {name.split(".")[0] for name in said["modules"]}
    assert not loaded & {"pandas", "scipy", "lmfit", "matplotlib"}  # numpy only, for the parser
    assert "tromplab.workbench" not in said["modules"] and not (tmp_path / "out").exists()


# --- the HTML report reads as a document ---------------------------------------------------------------
@pytest.fixture(scope="module")
def report_html(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "report.html"
    assert main(["report", str(DECKS.resolve()), "-o", str(out), "--size-unit", "mm", "-q"]) == 0
    return out.read_text(encoding="utf-8")


def _section(html, name):
    return html.split(f'<section id="{name}">', 1)[1].split("</section>", 1)[0]


def test_warnings_of_one_kind_are_one_line_naming_the_fits(report_html):
    warnings = re.findall(r'<div class="warn">(.*?)</div>', _section(report_html, "summary"), flags=re.S)
    shapiro = [w for w in warnings if "Shapiro-Wilk" in w]
    assert len(shapiro) == 1 and "(15 fits)" in shapiro[0]
    assert shapiro[0].count("deck_20mesh:") == 1 and "molerus_hoffmann (0.0047)" in shapiro[0]


def test_a_note_repeated_on_every_row_is_said_once(report_html):
    parameters = _section(report_html, "parameters")
    assert parameters.count("the cut is not bracketed by the data") == 2  # once per experiment's table
    assert parameters.count("see note 1") == 16  # 8 quantities without an interval, 2 experiments
    assert '<p class="note">note 1: no interval: the cut is not bracketed' in parameters


def test_numbers_have_a_precision_per_column_and_the_input_its_file_name(report_html):
    assert f"Input: <code>{DECKS.name}</code>" in report_html and str(DECKS.parent) not in report_html
    balance = _section(report_html, "balance")
    assert "<td>0.0251</td>" in balance and "<td>0.1250</td>" in balance  # shares: four decimals
    assert "<td>-7.9e-06</td>" in balance  # balance residuals: two significant digits
    fits = _section(report_html, "fits")
    assert "<td>2.79</td>" in fits and "<td>22.08</td>" in fits  # F_crit, F: two decimals
    assert "<td>0.0038</td>" in fits  # a p-value: two significant digits


def test_wide_tables_fit_or_scroll_within_the_page(report_html):
    assert ".table-wrap { overflow-x: auto;" in report_html
    tables = re.findall(r"<table.*?</table>", report_html, flags=re.S)
    wrapped = re.findall(r'<div class="table-wrap"><table.*?</table></div>', report_html, flags=re.S)
    assert len(tables) == len(wrapped) > 0
    assert "<th>normality_<wbr>p</th>" in report_html  # long headers may break after an underscore
