"""Outputs of ``tromplab fit``: the Excel workbook, --partition-to, the console table
following --rank-by and --ci, and a re-run that leaves exactly the current figures."""

import openpyxl
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.output.workbook import SHEETS

from .conftest import DATASETS, TWO_EXPERIMENT_POINTS, strip_unit, write

LAB = DATASETS / "double_deck_screen_decks_lab.csv"
POINTS = TWO_EXPERIMENT_POINTS


def sheet_frame(book, name) -> pd.DataFrame:
    rows = list(book[name].values)
    return pd.DataFrame(rows[1:], columns=[strip_unit(h) for h in rows[0]])


def assert_same_table(from_workbook: pd.DataFrame, from_csv: pd.DataFrame):
    assert list(from_workbook.columns) == list(from_csv.columns)
    for column in from_csv.columns:
        if pd.api.types.is_numeric_dtype(from_csv[column]) and not pd.api.types.is_bool_dtype(from_csv[column]):
            assert_allclose(
                pd.to_numeric(from_workbook[column]).to_numpy(dtype=float),
                from_csv[column].to_numpy(dtype=float),
                rtol=1e-12,
                equal_nan=True,
                err_msg=column,
            )
        else:
            expected = (
                from_csv[column].where(from_csv[column].notna(), None).astype(object).map(lambda v: v if v is None else str(v))
            )
            got = from_workbook[column].map(lambda v: None if v is None else str(v))
            assert list(got) == list(expected), column


def test_excel_workbook_holds_the_csv_tables_with_units_frozen_headers_and_figures(tmp_path):
    out = tmp_path / "out"
    assert (
        main(["fit", str(LAB), "-o", str(out), "--size-unit", "mm", "--excel", "--formulas", "plitt,lognormal,rosin_rammler"])
        == 0
    )
    book = openpyxl.load_workbook(out / "results.xlsx")
    assert book.sheetnames == [*SHEETS, "warnings", "figures"]  # neither deck's cut is bracketed: warnings.csv's rows
    said = sheet_frame(book, "warnings")
    assert list(said["code"]) == list(pd.read_csv(out / "warnings.csv")["code"]) == ["cut-not-bracketed"] * 2
    for name in SHEETS:
        assert book[name].freeze_panes == "A2", name
    fits_header = [cell.value for cell in book["fits"][1]]
    assert "d_cut [mm]" in fits_header and "eta [0..1]" in fits_header and "formula" in fits_header
    assert book["fits"]["E2"].number_format == "0.0000"  # d_cut
    for name in ("fits", "ranking", "averages"):
        csv = pd.read_csv(out / f"{name}.csv")
        workbook = sheet_frame(book, name)
        if name == "averages":
            assert list(workbook["unit"].drop_duplicates()) == ["mm", "0..1"]  # d_cut and Ep in mm, eta a share
            workbook = workbook.drop(columns="unit")
        assert_same_table(workbook, csv)
    balance = sheet_frame(book, "balance")
    assert set(balance["experiment"]) == {"deck_20mesh", "deck_65mesh"} and "balance_residual" in balance.columns
    points = sheet_frame(book, "points")
    assert {"size", "partition_fine", "feed_share", "used"} <= set(points.columns)
    figures = book["figures"]
    assert len(figures._images) == 2
    assert [
        figures.cell(row=r, column=1).value for r in range(1, figures.max_row + 1) if figures.cell(row=r, column=1).value
    ] == ["curves_deck_20mesh.png", "curves_deck_65mesh.png"]


def test_dash_o_xlsx_writes_only_the_workbook(tmp_path):
    target = tmp_path / "res" / "results.xlsx"
    assert main(["fit", str(write(tmp_path, POINTS)), "-o", str(target), "--formulas", "plitt,9"]) == 0
    assert sorted(p.name for p in target.parent.iterdir() if not p.name.startswith(".")) == ["results.xlsx"]  # .lock: see outputs
    book = openpyxl.load_workbook(target)
    assert book["balance"]["A1"].value.startswith("no mass balance")
    assert len(sheet_frame(book, "points")) == 12 and len(sheet_frame(book, "fits")) == 4
    assert len(book["figures"]._images) == 2


def test_a_failing_workbook_leaves_nothing_behind(tmp_path, monkeypatch):
    import tromplab.output.folder

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(tromplab.output.folder, "write_workbook", broken)
    out = tmp_path / "out"
    # a writer that breaks is a bug, not bad input: exit 70, and nothing is written
    assert main(["fit", str(write(tmp_path, POINTS)), "-o", str(out), "--excel", "--no-figures"]) == 70
    assert not (out / "fits.csv").exists() and not (out / "results.xlsx").exists()


def test_partition_to_coarse_turns_tables_and_figures(tmp_path, capsys):
    fine, coarse = tmp_path / "fine", tmp_path / "coarse"
    assert main(["fit", str(LAB), "-o", str(fine), "--formulas", "plitt", "--no-figures", "--excel"]) == 0
    assert (
        main(["fit", str(LAB), "-o", str(coarse), "--formulas", "plitt", "--no-figures", "--excel", "--partition-to", "coarse"])
        == 0
    )
    as_fine, as_coarse = pd.read_csv(fine / "fits.csv"), pd.read_csv(coarse / "fits.csv")
    assert "slope" not in as_coarse.columns
    assert_allclose(as_coarse["slope_coarse"], -as_fine["slope"])
    assert (as_coarse["slope_coarse"] > 0).all()
    assert_allclose(as_coarse["d_cut"], as_fine["d_cut"])
    points_fine = sheet_frame(openpyxl.load_workbook(fine / "results.xlsx"), "points")
    points_coarse = sheet_frame(openpyxl.load_workbook(coarse / "results.xlsx"), "points")
    assert "partition_fine" not in points_coarse.columns
    assert_allclose(points_coarse["partition_coarse"], 1 - points_fine["partition_fine"])
    capsys.readouterr()
    assert main(["points", str(LAB), "-o", str(tmp_path / "p.csv"), "--partition-to", "coarse"]) == 0
    written = pd.read_csv(tmp_path / "p.csv")
    assert_allclose(written["partition_coarse"], 1 - points_fine["partition_fine"])
    assert main(["balance", str(LAB), "--partition-to", "coarse"]) == 0
    assert "partition_coarse" in capsys.readouterr().out
    assert main(["fit", str(LAB), "--partition-to", "oversize"]) == 2  # usage error


def test_console_table_follows_rank_by_and_shows_intervals(tmp_path, capsys):
    points = write(tmp_path, POINTS)
    assert main(["fit", str(points), "-o", str(tmp_path / "f"), "--no-figures", "--formulas", "paper"]) == 0
    by_f = capsys.readouterr().out
    assert "ranked by F" in by_f and "F_crit" in by_f.splitlines()[1] and "aicc" not in by_f
    assert (
        main(
            [
                "fit",
                str(points),
                "-o",
                str(tmp_path / "a"),
                "--no-figures",
                "--rank-by",
                "aicc",
                "--ci",
                "0.9",
                "--formulas",
                "plitt,lognormal,rosin_rammler,molerus",
            ]
        )
        == 0
    )
    by_aicc = capsys.readouterr().out
    lines = by_aicc.splitlines()
    header = lines[1].split()
    assert "ranked by AICc" in lines[0] and "aicc" in header and "F_crit" not in header
    fits = pd.read_csv(tmp_path / "a" / "fits.csv")
    first_of_a = fits[fits["experiment"] == "A"].sort_values("rank")
    assert (first_of_a["aicc"].diff().dropna() >= -1e-9).all()  # rank 1 has the lowest AICc
    shown = [line.split()[2] for line in lines[2:6]]
    assert shown == list(first_of_a["formula"])
    assert "intervals:" in by_aicc and "d50 low" in by_aicc  # the nine formulas: the fitted cut is the actual one
    plitt = fits[(fits["experiment"] == "A") & (fits["formula"] == "plitt")].iloc[0]
    interval_line = next(line for line in lines[lines.index("  intervals:") :] if line.split()[0] == "plitt")
    assert f"{plitt['d_cut_low']:.4g}" in interval_line and f"{plitt['d_cut_high']:.4g}" in interval_line
    assert max(len(line) for line in lines if not line.startswith("  /")) <= 100
    assert main(["fit", str(points), "-o", str(tmp_path / "b"), "--no-figures", "--formulas", "plitt", "--bootstrap", "20"]) == 0
    lines = capsys.readouterr().out.splitlines()
    boot = pd.read_csv(tmp_path / "b" / "fits.csv").iloc[0]
    row = lines[lines.index("  bootstrap intervals:") + 2].split()
    # formula, par (the shape parameter's name), d50, then its interval
    assert row[:2] == ["plitt", "ks"] and row[3:5] == [f"{boot['d_cut_boot_low']:.4g}", f"{boot['d_cut_boot_high']:.4g}"]


def test_rerun_into_the_same_folder_leaves_exactly_the_current_figures(tmp_path):
    out = tmp_path / "out"
    assert main(["fit", str(write(tmp_path, POINTS)), "-o", str(out), "--formulas", "plitt"]) == 0
    assert sorted(p.name for p in out.glob("*.png")) == ["curves_A.png", "curves_B.png"]
    (out / "notes.txt").write_text("mine")
    only_c = "experiment,size,partition_fine\n" + "\n".join(
        f"C,{s},{p}" for s, p in zip((10, 20, 40, 80, 160, 320), (0.97, 0.9, 0.7, 0.35, 0.1, 0.02))
    )
    assert main(["fit", str(write(tmp_path, only_c, "c.csv")), "-o", str(out), "--formulas", "plitt"]) == 0
    assert sorted(p.name for p in out.glob("*.png")) == ["curves_C.png"]
    assert (out / "notes.txt").read_text() == "mine"  # files that are not ours stay
    assert set(pd.read_csv(out / "fits.csv")["experiment"]) == {"C"}
    assert main(["fit", str(out.parent / "c.csv"), "-o", str(out), "--formulas", "plitt", "--no-figures"]) == 0
    assert list(out.glob("*.png")) == []


@pytest.mark.slow
def test_report_reads_the_partition_to_the_coarse_product(tmp_path):
    output = tmp_path / "report.html"
    assert main(["report", str(LAB), "-o", str(output), "--formulas", "plitt", "--partition-to", "coarse"]) == 0
    markdown = (tmp_path / "report.md").read_text()
    assert "partition_coarse" in markdown and "partition_fine" not in markdown
