"""The workbook writer and the partition views of tables."""

import openpyxl
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.output.views import partition_view
from tromplab.output.workbook import column_unit, header_with_unit, write_workbook

from .conftest import strip_unit


def test_partition_view_turns_partitions_and_the_slope_with_its_bounds():
    table = pd.DataFrame(
        {
            "d_cut": [50.0],
            "slope": [-0.6],
            "slope_low": [-0.8],
            "slope_high": [-0.5],
            "slope_stderr": [0.07],
            "partition_fine": [0.3],
            "partition_coarse": [0.7],
            "d25": [40.0],
        }
    )
    view = partition_view(table, "coarse")
    assert list(view.columns) == [
        "d_cut",
        "slope_coarse",
        "slope_coarse_low",
        "slope_coarse_high",
        "slope_coarse_stderr",
        "partition_coarse",
        "d25",
    ]
    assert_allclose(
        view.iloc[0][["slope_coarse", "slope_coarse_low", "slope_coarse_high", "slope_coarse_stderr"]].astype(float),
        [0.6, 0.5, 0.8, 0.07],
    )
    assert_allclose(view["partition_coarse"], [0.7])
    assert_allclose(view[["d_cut", "d25"]].to_numpy(), [[50.0, 40.0]])
    assert partition_view(table, "fine").equals(table)
    with pytest.raises(ValueError, match="'fine' or 'coarse'"):
        partition_view(table, "underflow")


def test_headers_carry_units_and_strip_back():
    assert header_with_unit("d_cut_boot_high", "um") == "d_cut_boot_high [um]"
    assert header_with_unit("ep", "") == "ep [size unit]"
    assert header_with_unit("weight_plitt") == "weight_plitt [0..1]" and header_with_unit("weight") == "weight"
    assert column_unit("F") == "-" and column_unit("experiment") == ""
    assert strip_unit(header_with_unit("d_cut", "mm")) == "d_cut" and strip_unit("formula") == "formula"  # the tests read back


def test_workbook_keeps_full_precision_and_leaves_missing_values_empty(tmp_path):
    table = pd.DataFrame({"experiment": ["A", "B"], "n": [6, 7], "d_cut": [1 / 3, float("nan")], "adequate": [True, False]})
    path = write_workbook(
        tmp_path / "book.xlsx", {"fits": table, "balance": pd.DataFrame()}, size_unit="mm", notes={"balance": "nothing here"}
    )
    book = openpyxl.load_workbook(path)
    sheet = book["fits"]
    assert [c.value for c in sheet[1]] == ["experiment", "n", "d_cut [mm]", "adequate"]
    assert sheet["C2"].value == pytest.approx(1 / 3, rel=1e-15) and sheet["C3"].value is None
    assert sheet["B2"].number_format == "0" and sheet["C2"].number_format == "0.0000"
    assert sheet["D2"].value is True and sheet.freeze_panes == "A2"
    assert book["balance"]["A1"].value == "nothing here"


def test_the_same_tables_give_the_same_workbook_bytes_whatever_the_clock(tmp_path, monkeypatch):
    import datetime
    import zipfile

    import openpyxl.writer.excel

    from tromplab.output.workbook import WORKBOOK_DATE

    tables = {"fits": pd.DataFrame({"experiment": ["a", "b"], "d_cut": [0.31, 0.42]})}
    write_workbook(tmp_path / "first.xlsx", tables)

    class LaterClock(datetime.datetime):  # openpyxl stamps the modification date with the clock at saving
        @classmethod
        def now(cls, tz=None):
            return datetime.datetime(2031, 7, 9, 13, 5, 7, tzinfo=tz)

    monkeypatch.setattr(openpyxl.writer.excel.datetime, "datetime", LaterClock)
    monkeypatch.setattr("time.time", lambda: 1_950_000_000.0)  # the zip parts' time stamps come from time.time
    write_workbook(tmp_path / "second.xlsx", tables)
    assert (tmp_path / "first.xlsx").read_bytes() == (tmp_path / "second.xlsx").read_bytes()
    with zipfile.ZipFile(tmp_path / "second.xlsx") as archive:
        assert {part.date_time for part in archive.infolist()} == {WORKBOOK_DATE.timetuple()[:6]}
    properties = openpyxl.load_workbook(tmp_path / "second.xlsx").properties
    assert properties.created == properties.modified == WORKBOOK_DATE
