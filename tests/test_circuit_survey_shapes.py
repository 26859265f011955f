"""Every survey shape that docs/circuit.md allows: nothing to adjust, no redundancy, no size
analysis (per cent solids and flows only), blank values, error models out of range, and
reconciled values held at their bound 0."""

import re

import numpy as np
import pandas as pd
import pytest

from tromplab.circuit import ErrorModel, reconcile
from tromplab.cli import main
from tromplab.errors import InputError, OptionError

from .conftest import write

CYCLONE = "stream,from,to,product\nfeed,,cyclone,\noverflow,cyclone,,fine\nunderflow,cyclone,,coarse\n"
MILL_AND_CYCLONE = (
    "stream,from,to,product\nfresh_feed,,mill,\ncyclone_feed,mill,cyclone,ground\n"
    "cyclone_overflow,cyclone,,fine\ncyclone_underflow,cyclone,mill,coarse\n"
)
EXACT_SHARES = """stream,size_lower_um,size_upper_um,retained_frac,retained_sd,solids_flow,solids_flow_sd
feed,100,,0.2,0,100,0
feed,50,100,0.3,0,,
feed,0,50,0.5,0,,
overflow,100,,0.05,0,,
overflow,50,100,0.25,0,,
overflow,0,50,0.7,0,,
underflow,100,,0.35,0,,
underflow,50,100,0.35,0,,
underflow,0,50,0.3,0,,
"""


def _run(*args) -> int:
    return main(["circuit", *map(str, args), "--no-figures"])


def test_a_survey_with_every_measurement_exact_writes_its_flows_and_empty_test_tables(tmp_path, capsys):
    out = tmp_path / "out"
    assert _run(write(tmp_path, CYCLONE, "sheet.csv"), write(tmp_path, EXACT_SHARES, "survey.csv"), "-o", out) == 0
    flows = pd.read_csv(out / "flows.csv").set_index("stream")["reconciled"]
    # 0.2 = 0.05 f + 0.35 (1 - f) in the top class: f = 0.5 of the feed to the overflow
    np.testing.assert_allclose(flows[["feed", "overflow", "underflow"]], [100.0, 50.0, 50.0], rtol=1e-12)
    for name in ("adjustments", "gross_errors"):
        table = pd.read_csv(out / f"{name}.csv")
        assert table.empty and "measurement_test" in table.columns
    assert pd.read_csv(out / "chi_square.csv")["verdict"].iloc[0] == "no redundancy: nothing to test"
    assert "every measurement is exact" in (out / "summary.txt").read_text()


def test_a_survey_without_redundancy_is_reconciled_and_says_there_is_nothing_to_test(tmp_path):
    two_classes = "stream,size_lower_um,size_upper_um,retained_frac\n" + "".join(
        f"{s},100,,{a}\n{s},0,100,{1 - a}\n" for s, a in (("feed", 0.4), ("overflow", 0.1), ("underflow", 0.7))
    )
    balance = reconcile(write(tmp_path, CYCLONE, "sheet.csv"), write(tmp_path, two_classes, "survey.csv"))
    assert balance.dof == 0 and np.isnan(balance.p_value) and not balance.rejected
    assert balance.flows[1] == pytest.approx(50.0, rel=1e-9)  # 0.4 = 0.1 f + 0.7 (1 - f): f = 1/2
    assert balance.gross_errors_table().empty and balance.adjustments_table()["measurement_test"].isna().all()


def _dilution(pct: float) -> float:
    """Mass of water per mass of solids of a pulp of ``pct`` per cent solids."""
    return (100.0 - pct) / pct


@pytest.mark.parametrize("feed, overflow, underflow", [(50.0, 30.0, 75.0), (62.0, 38.5, 78.0)])
def test_exact_per_cent_solids_of_a_mill_closed_by_a_cyclone_give_the_dilution_ratio_circulating_load(
    tmp_path, feed, overflow, underflow
):
    r"""Solids U + O = F and water U D_u + O D_o = F D_f around the cyclone give
    U / O = (D_o - D_f) / (D_f - D_u), the circulating load of the textbook dilution-ratio
    method; at steady state O is the fresh feed (the only product)."""
    survey = (
        "stream,solids_flow,solids_flow_sd,pct_solids,pct_solids_sd\n"
        f"fresh_feed,120,0,,\ncyclone_feed,,,{feed},0\ncyclone_overflow,,,{overflow},0\ncyclone_underflow,,,{underflow},0\n"
    )
    out = tmp_path / "out"
    assert _run(write(tmp_path, MILL_AND_CYCLONE, "sheet.csv"), write(tmp_path, survey, "survey.csv"), "-o", out) == 0
    flows = pd.read_csv(out / "flows.csv").set_index("stream")["reconciled"]
    load = (_dilution(overflow) - _dilution(feed)) / (_dilution(feed) - _dilution(underflow))
    assert flows["cyclone_underflow"] / flows["cyclone_overflow"] == pytest.approx(load, rel=1e-9)
    assert flows["cyclone_overflow"] == pytest.approx(120.0, rel=1e-9)
    water = pd.read_csv(out / "water.csv").set_index("stream")
    assert water.loc["cyclone_overflow", "water_flow"] == pytest.approx(120.0 * _dilution(overflow), rel=1e-9)
    assert pd.read_csv(out / "partition.csv").empty and pd.read_csv(out / "points.csv").empty
    assert "no size analysis" in (out / "summary.txt").read_text()


def test_fit_of_a_survey_without_size_analyses_is_refused_with_a_message(tmp_path, capsys):
    survey = "stream,solids_flow,pct_solids\nfresh_feed,100,\ncyclone_feed,,50\ncyclone_overflow,,30\ncyclone_underflow,,75\n"
    out = tmp_path / "out"
    code = _run(write(tmp_path, MILL_AND_CYCLONE, "sheet.csv"), write(tmp_path, survey, "survey.csv"), "-o", out, "--fit")
    assert code == 2 and not out.exists()
    assert "--fit needs size analyses" in capsys.readouterr().err


def test_a_blank_or_nan_share_is_reported_as_not_measured(tmp_path):
    table = (
        EXACT_SHARES.replace(",0,100,0\n", ",,,\n")
        .replace(",0,,\n", ",,,\n")
        .replace("overflow,50,100,0.25", "overflow,50,100,NaN")
    )
    balance = reconcile(write(tmp_path, CYCLONE, "sheet.csv"), write(tmp_path, table, "survey.csv"))
    assert "not measured (blank or NaN value in the table): overflow class -100+50 (row 6)" in balance.report()
    measured = balance.distributions_table().set_index(["stream", "size_lower"])["measured"]
    assert np.isnan(measured[("overflow", 50.0)])


def test_an_error_model_override_naming_an_unknown_stream_is_refused(tmp_path):
    with pytest.raises(OptionError, match="names 'overflw', not a solids stream"):
        reconcile(write(tmp_path, CYCLONE, "sheet.csv"), write(tmp_path, EXACT_SHARES, "survey.csv"),
                  errors=ErrorModel(streams={"overflw": (0.1, 0.002)}))  # fmt: skip


@pytest.mark.parametrize(
    "keywords, fragment",
    [
        ({"relative_error": 1e6}, "relative_error is at most 1"),
        ({"absolute_error": 2.0}, "absolute_error is at most 0.5"),
        ({"flow_relative_error": 0.0}, "flow_relative_error must be a positive"),
        ({"pct_solids_sd": 1e3}, "pct_solids_sd is at most 50"),
        ({"streams": {"feed": (1e6, 0.001)}}, "relative_error of stream 'feed' is at most 1"),
    ],
)
def test_an_implausible_error_model_is_named_as_the_cause(keywords, fragment):
    with pytest.raises(OptionError, match=fragment):
        ErrorModel(**keywords)


def test_implausible_errors_on_the_command_line_and_in_the_table_are_named(tmp_path, capsys):
    sheet, out = write(tmp_path, CYCLONE, "sheet.csv"), tmp_path / "out"
    survey = write(tmp_path, EXACT_SHARES.replace(",0,100,0\n", ",,,\n").replace(",0,,\n", ",,,\n"), "survey.csv")
    assert _run(sheet, survey, "-o", out, "--relative-error", "1e6") == 2
    assert "--relative-error: is at most 1" in capsys.readouterr().err
    rows = "stream,size_lower_um,size_upper_um,retained_frac,relative_error\nfeed,100,,0.2,1e6\nfeed,0,100,0.8,\n"
    assert _run(sheet, write(tmp_path, rows + "overflow,100,,0.05,\noverflow,0,100,0.95,\n", "rows.csv"), "-o", out) == 1
    assert "row 2, column 'relative_error': relative error 1e+06 is implausible" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "cyclone_feed, underflow, where",
    [
        (
            "70,80,,",
            ",,75,0",
            "row 3, column 'solids_flow_sd': solids flow sd 80 is implausible for a flow of 70: more than 100%",
        ),
        (",,50,60", ",,75,0", "row 3, column 'pct_solids_sd': per cent solids sd 60 is implausible: at most 50 percentage"),
        (",,50,0", ",,0,0", "row 5, column 'pct_solids': per cent solids 0 outside (0, 100]"),
        (",,50,0", ",,100.5,1", "row 5, column 'pct_solids': per cent solids 100.5 outside (0, 100]"),
    ],
)
def test_an_implausible_flow_or_per_cent_solids_names_its_row_and_column(tmp_path, cyclone_feed, underflow, where):
    survey = (
        "stream,solids_flow,solids_flow_sd,pct_solids,pct_solids_sd\n"
        f"fresh_feed,120,0,,\ncyclone_feed,{cyclone_feed}\ncyclone_overflow,,,30,0\ncyclone_underflow,{underflow}\n"
    )
    with pytest.raises(InputError, match=re.escape(where)):
        reconcile(write(tmp_path, MILL_AND_CYCLONE, "sheet.csv"), write(tmp_path, survey, "survey.csv"))


def _one_node(feed, fine, coarse) -> pd.DataFrame:
    bounds = {"size_lower_um": [400, 200, 100, 50, 0], "size_upper_um": [np.nan, 400, 200, 100, 50]}
    return pd.concat(
        [pd.DataFrame({"stream": s, **bounds, "retained_frac": v}) for s, v in
         (("feed", feed), ("overflow", fine), ("underflow", coarse))], ignore_index=True,
    )  # fmt: skip


def test_reconciled_shares_are_never_negative_and_partitions_stay_in_0_1(tmp_path):
    """An overflow measured empty in the top class that the balance would drive below 0: the
    class flow is held at 0, the shares close, and the partition stays at 0 with a flag."""
    sheet = pd.read_csv(write(tmp_path, CYCLONE, "sheet.csv"), keep_default_na=False)
    table = _one_node([0.05, 0.15, 0.3, 0.3, 0.2], [0.0, 0.05, 0.25, 0.35, 0.35], [0.20, 0.25, 0.35, 0.15, 0.05])
    balance = reconcile(sheet, table)
    assert balance.held_at_zero == [("overflow", 0)]
    assert balance.fitted[balance.at_bound[0]] < 0  # what the least squares without the bound gives
    assert balance.shares.min() >= 0.0 and balance.shares[1, 0] == 0.0
    np.testing.assert_allclose(balance.shares.sum(axis=1), 1.0, rtol=1e-12)
    feed, fine, coarse = balance.class_flows
    np.testing.assert_allclose(feed, fine + coarse, atol=1e-9)  # every class balances
    partition = balance.partition_table()
    assert partition["partition_fine"].between(0.0, 1.0).all()
    assert partition["partition_fine"].iloc[0] == 0.0 and "held at 0" in partition["flag"].iloc[0]
    assert "held at 0" in balance.report() and "overflow class +400" in balance.report()
