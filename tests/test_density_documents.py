"""The density fits' workbook and report: the command and the API write the same, names stay text."""

import numpy as np
import pandas as pd
import pytest
from openpyxl import load_workbook

from tromplab.cli import main
from tromplab.density import fit_density
from tromplab.density.documents import density_column_unit
from tromplab.density.simulation import STUDY_BOUNDS, STUDY_FEED_PCT, float_sink_table, noisy_analysis

from .conftest import DATASETS

TRACERS = DATASETS / "density_tracers_dmc_by_size_synthetic.csv"


def _by_size_tracers(tmp_path, names=("DMC <script>", "=1+1")):
    lines = [line for line in TRACERS.read_text().splitlines() if not line.startswith("#")]
    header, rows = lines[0], lines[1:]
    body = [row.replace("dmc_tracers", name, 1) for name in names for row in rows]
    path = tmp_path / "tracers.csv"
    path.write_text("\n".join([header, *body]) + "\n")
    return path


def _float_sink(tmp_path):
    rng = np.random.default_rng(4)
    table = float_sink_table("normal", {"rho50": 1.55, "ep": 0.05}, STUDY_BOUNDS, STUDY_FEED_PCT)
    for column in ("feed_pct", "floats_pct", "sinks_pct"):
        table[column] = noisy_analysis(table[column], rng)
    path = tmp_path / "float_sink.csv"
    table.to_csv(path, index=False)
    return path


@pytest.mark.parametrize(
    "make", [pytest.param(_by_size_tracers, marks=pytest.mark.slow), _float_sink], ids=["tracers_by_size", "float_sink"]
)
def test_command_and_api_write_the_same_workbook_report_and_csvs(tmp_path, make):
    path = make(tmp_path)
    options = ["--ci", "0.95", "--curves", "normal,logistic"]
    assert main(["density", "fit", str(path), "-o", str(tmp_path / "cli"), *options, "--excel", "--report"]) in (0, 3)
    fit_density(path, ci=0.95, curves="normal,logistic").save(tmp_path / "api", excel=True, report=True)
    fit_density(path, ci=0.95, curves="normal,logistic").save(tmp_path / "plain")
    cli = sorted(p.name for p in (tmp_path / "cli").iterdir())
    assert cli == sorted(p.name for p in (tmp_path / "api").iterdir())
    assert {"results.xlsx", "report.html", "report.md"} <= set(cli)
    plain = sorted(p.name for p in (tmp_path / "plain").iterdir())
    assert set(cli) - set(plain) == {"results.xlsx", "report.html", "report.md"}
    for name in cli:
        if name != "results.xlsx":  # a workbook's zip records the time it was written
            assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "api" / name).read_bytes(), name
    for name in plain:  # the workbook and report change none of the other files (the manifest lists them)
        if name.startswith("."):
            continue
        assert (tmp_path / "plain" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name


@pytest.mark.slow
def test_the_workbook_holds_the_csv_values_with_units_and_names_as_text(tmp_path):
    path = _by_size_tracers(tmp_path)
    fit_density(path, ci=0.95, curves="normal").save(tmp_path / "out", excel=True)
    book = load_workbook(tmp_path / "out" / "results.xlsx")
    assert book.sheetnames == ["fits", "partition", "by_size", "ep_trend", "figures"]
    fits = pd.read_csv(tmp_path / "out" / "fits.csv", keep_default_na=False, dtype={"test": str})
    sheet = book["fits"]
    headers = [cell.value for cell in sheet[1]]
    assert "rho50 [g/cm3]" in headers and "ep_low [g/cm3]" in headers and "imperfection [-]" in headers
    assert "size_lower [mm]" in headers
    rho50 = headers.index("rho50 [g/cm3]") + 1
    values = [sheet.cell(row=r, column=rho50).value for r in range(2, sheet.max_row + 1)]
    np.testing.assert_allclose(values, pd.to_numeric(fits["rho50"]).to_numpy(), rtol=1e-15)
    tests = [sheet.cell(row=r, column=1) for r in range(2, sheet.max_row + 1)]
    assert {cell.value for cell in tests} == {"DMC <script>", "=1+1"}
    formula_like = [cell for cell in tests if cell.value == "=1+1"]
    assert formula_like and all(cell.data_type == "s" and cell.quotePrefix for cell in formula_like)
    pngs = [p for p in (tmp_path / "out").iterdir() if p.suffix == ".png"]
    assert len(book["figures"]._images) == len(pngs) == 2 * 4 + 2  # a figure per test and size fraction, one by size per test


@pytest.mark.slow
def test_the_report_shows_fits_partition_and_figures_with_every_name_escaped(tmp_path):
    path = _by_size_tracers(tmp_path)
    result = fit_density(path, ci=0.95, curves="normal")
    result.save(tmp_path / "out", report=True)
    html = (tmp_path / "out" / "report.html").read_text()
    assert "<script>" not in html and "DMC &lt;script&gt;" in html
    for heading in ("Ranked fits per test", "Measured partition", "Indices by size fraction", "Figures"):
        assert heading in html
    best = result.fits_table().iloc[0]
    assert f"{best['rho50_low']:.4g}"[:5] in html
    assert html.count("<img ") == len([p for p in (tmp_path / "out").iterdir() if p.suffix == ".png"])
    markdown = (tmp_path / "out" / "report.md").read_text()
    links = [line.split("](")[1].rstrip(")").strip("<>") for line in markdown.splitlines() if line.startswith("![")]
    assert links and all((tmp_path / "out" / link).is_file() for link in links)
    assert "<script>" not in markdown


def test_density_column_units():
    assert density_column_unit("ep_high") == "g/cm3" and density_column_unit("density_lower") == "g/cm3"
    assert density_column_unit("light_limit") == "0..1" and density_column_unit("feed_ash_pct") == "%"
    assert density_column_unit("size_upper", "mm") == "mm" and density_column_unit("notes") == ""
