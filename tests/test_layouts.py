"""Input layouts as laboratories write them load without reshaping: size-class
strings, a pan written as 0, hydrocyclone stream names, units in column names, product
masses, representative sizes; and the partition uses both products (swap-symmetric)."""

import dataclasses
import warnings

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.errors import InputError
from tromplab.loading.lab import LabOptions, YieldWarning, read_experiments, read_lab
from tromplab.loading.points import read_points

from .conftest import DATASETS, ROOT

DATA = ROOT / "tests" / "data"
PARTITIONS = [0.02, 0.10, 0.35, 0.70, 0.92, 0.99]  # the curve the layout files were built from (coarse class first)
BOUNDS_UM = [(1168, np.nan), (589, 1168), (295, 589), (147, 295), (74, 147), (np.nan, 74)]
YIELD = 0.6156  # overflow yield of those files
SCREEN_460 = dict(
    kind="retained_frac", rename={"sieve_um": "size_um", "feed_cum": "feed", "coarse_cum": "coarse", "fine_cum": "fine"}
)


def test_size_class_strings_and_hydrocyclone_names_load_as_written():
    (balance,) = read_lab(DATA / "hydrocyclone_size_class_um.csv")
    classes = balance.classes
    assert_allclose(classes[["size_lower", "size_upper"]].to_numpy(), BOUNDS_UM)
    assert_allclose(classes["partition_fine"], PARTITIONS, atol=1e-6)
    assert balance.size_unit == "um" and balance.yield_source == "column overflow_yield"
    assert balance.fine_yield == pytest.approx(YIELD)
    assert balance.to_points().size_unit == "um"


def test_pan_written_as_zero_and_product_masses_in_mm():
    with warnings.catch_warnings():
        warnings.simplefilter("error", YieldWarning)
        (balance,) = read_lab(DATA / "pan_at_zero_masses_mm.csv")
    (in_um,) = read_lab(DATA / "hydrocyclone_size_class_um.csv")
    classes = balance.classes
    assert np.isnan(classes["size_lower"].iloc[-1])  # 0 = the pan, extended like a blank bound
    assert_allclose(classes["size"] * 1000, in_um.classes["size"], rtol=1e-9)  # same classes, mm vs um
    assert_allclose(classes["partition_fine"], PARTITIONS, atol=1e-6)
    assert balance.yield_source == "product masses" and balance.fine_yield == pytest.approx(YIELD, abs=1e-6)
    assert balance.size_unit == "mm"


def test_a_stated_yield_contradicting_the_product_masses_is_reported(capsys):
    path = DATA / "pan_at_zero_masses_mm.csv"
    with pytest.warns(
        YieldWarning, match=r"stated fine yield 0.5000 \(option fine_yield\) contradicts the product masses, which imply 0.6156"
    ):
        (balance,) = read_lab(path, LabOptions(fine_yield=0.5))
    assert balance.fine_yield == 0.5 and any("product masses" in note for note in balance.notes)
    assert main(["balance", str(path), "--fine-yield", "0.5"]) == 0
    assert "contradicts the product masses" in capsys.readouterr().err.replace("\n", " ")
    with warnings.catch_warnings():
        warnings.simplefilter("error", YieldWarning)  # a yield within 0.005 of the masses' is not a contradiction
        read_lab(path, LabOptions(fine_yield=0.618))


def test_class_strings_accept_the_pan_as_plus_zero_and_a_unicode_minus(tmp_path):
    path = tmp_path / "classes.csv"
    path.write_text("size_class_mm,feed_pct,fine_pct\n+2,30,5\n\u22122+1,30,25\n-1+0.5,25,40\n-0.5+0,15,30\n")
    (balance,) = read_lab(path, LabOptions(fine_yield=0.4))
    assert_allclose(balance.classes["size_lower"].to_numpy(), [2, 1, 0.5, np.nan])
    assert_allclose(balance.classes["size_upper"].to_numpy(), [np.nan, 2, 1, 0.5])
    assert balance.size_unit == "mm"


def test_representative_sizes_replace_the_geometric_mean_where_given(tmp_path):
    frame = pd.read_csv(DATA / "hydrocyclone_size_class_um.csv", comment="#")
    frame["size_representative_um"] = [1500, 850, None, 200, 100, 40]
    frame.to_csv(tmp_path / "rep.csv", index=False)
    (balance,) = read_lab(tmp_path / "rep.csv")
    (plain,) = read_lab(DATA / "hydrocyclone_size_class_um.csv")
    expected = plain.classes["size"].to_numpy().copy()
    expected[[0, 1, 3, 4, 5]] = [1500, 850, 200, 100, 40]
    assert_allclose(balance.classes["size"], expected)


def test_size_unit_from_the_column_name_of_points_files(tmp_path):
    (points,) = read_points(DATA / "points_size_um.csv")
    assert points.size_unit == "um" and points.n == 4
    (same,) = read_points(DATA / "points_size_um.csv", size_unit="µm")  # the same unit spelt otherwise
    assert same.size_unit == "um"
    plain = tmp_path / "plain.csv"
    plain.write_text("size,partition_fine\n10,0.9\n20,0.5\n40,0.1\n")
    (fallback,) = read_points(plain, size_unit="mm")
    assert fallback.size_unit == "mm"
    experiments, _ = read_experiments(DATA / "hydrocyclone_size_class_um.csv")
    assert experiments[0].size_unit == "um"


def test_points_command_writes_the_unit_into_the_column_names(tmp_path, capsys):
    output = tmp_path / "points.csv"
    assert main(["points", str(DATA / "pan_at_zero_masses_mm.csv"), "-o", str(output)]) == 0
    assert {"size_mm", "size_lower_mm", "size_upper_mm"} <= set(pd.read_csv(output).columns)
    (points,) = read_points(output)
    assert points.size_unit == "mm"
    assert main(["fit", str(output), "--size-unit", "um", "-o", str(tmp_path / "fit"), "--no-figures"]) == 1
    assert "contradicts the column name 'size_mm'" in capsys.readouterr().err


def test_every_layout_fits_end_to_end_without_options(tmp_path):
    for name in ("hydrocyclone_size_class_um.csv", "pan_at_zero_masses_mm.csv", "european_semicolon_decimal_comma.csv"):
        extra = ["--fine-yield", str(YIELD)] if name.startswith("european") else []
        out = tmp_path / name
        assert main(["fit", str(DATA / name), "-o", str(out), "--no-figures", "--formulas", "plitt", *extra]) == 0
        fits = pd.read_csv(out / "fits.csv")
        assert fits["n"].iloc[0] == 6 and fits["success"].all()


def test_blank_cumulative_cells_are_reported_with_their_rows(capsys):
    (balance,) = read_lab(DATASETS / "screen_460um_cumulative_oversize.csv", LabOptions(coarse_yield=0.5, **SCREEN_460))
    notes = " ".join(balance.notes)
    assert "column 'fine': blank cell(s) at row 27 (coarse end) read as 0" in notes
    assert "column 'coarse': blank cell(s) at row 34 (fine end) read as 1" in notes
    argv = [
        "balance",
        str(DATASETS / "screen_460um_cumulative_oversize.csv"),
        "--coarse-yield",
        "0.5",
        "--kind",
        "retained_frac",
        "--rename",
        "sieve_um=size_um,feed_cum=feed,coarse_cum=coarse,fine_cum=fine",
    ]
    assert main(argv) == 0
    assert "blank cell(s) at row 27" in capsys.readouterr().err.replace("\n", " ")


def test_blank_per_class_cells_are_reported(tmp_path):
    path = tmp_path / "blank.csv"
    path.write_text("size_lower,size_upper,feed_pct,fine_pct\n400,,40,\n200,400,30,20\n100,200,20,50\n,100,10,30\n")
    (balance,) = read_lab(path, LabOptions(fine_yield=0.3))
    assert "column 'fine_pct': blank cell(s) at row 2 read as no material" in balance.notes


def test_a_class_with_feed_but_no_product_is_flagged_with_its_bounds(tmp_path, capsys):
    path = tmp_path / "empty.csv"
    path.write_text(
        "size_lower_um,size_upper_um,feed_pct,fine_pct,coarse_pct\n800,,5,0,0\n400,800,15,1,26\n"
        "200,400,30,16,38\n100,200,25,33,17\n50,100,15,25,13\n,50,10,25,6\n"
    )
    (balance,) = read_lab(path)
    first = balance.classes.iloc[0]
    assert not first["used"] and "neither product has any" in first["flag"]
    assert balance.left_out == [f"class 800-top um (row 2) left out: {first['flag']}"]
    assert main(["balance", str(path)]) == 0
    said = capsys.readouterr().err.replace("\n", " ")  # one line per experiment, the classes with their reasons
    assert "1 class(es) left out: 800-top um (the feed has material in this class but neither product has any: 1)" in said


def test_swapping_fine_and_coarse_gives_one_minus_the_partition():
    """The 460 um screen's balance does not close; the fine-over-feed partition is not symmetric."""
    swapped_rename = {"sieve_um": "size_um", "feed_cum": "feed", "coarse_cum": "fine", "fine_cum": "coarse"}
    differences = {}
    for method in ("products", "feed"):
        options = LabOptions(partition_from=method, **SCREEN_460)
        (direct,) = read_lab(DATASETS / "screen_460um_cumulative_oversize.csv", options)
        (swapped,) = read_lab(
            DATASETS / "screen_460um_cumulative_oversize.csv", dataclasses.replace(options, rename=swapped_rename)
        )
        assert swapped.fine_yield == pytest.approx(1 - direct.fine_yield, abs=1e-12)
        both = direct.classes["used"] & swapped.classes["used"]
        differences[method] = np.max(np.abs(direct.classes["partition_fine"][both] + swapped.classes["partition_fine"][both] - 1))
        assert direct.partition_method == method
    assert differences["products"] < 1e-12
    assert differences["feed"] > 0.05  # why "products" is the default


def test_a_pan_lower_size_of_zero_means_the_pan_rule():
    (default,) = read_lab(DATA / "hydrocyclone_size_class_um.csv")
    (zero,) = read_lab(DATA / "hydrocyclone_size_class_um.csv", LabOptions(pan_lower_size=0.0))
    assert_allclose(zero.classes["size"], default.classes["size"])
    assert zero.classes["size"].iloc[-1] == pytest.approx(74 / np.sqrt(147 / 74))  # the pan one class-ratio below 74 um


def test_the_balance_command_says_how_the_partition_was_computed(capsys):
    path = str(DATASETS / "screen_460um_cumulative_oversize.csv")
    rename = "sieve_um=size_um,feed_cum=feed,coarse_cum=coarse,fine_cum=fine"
    for option, said in (
        ([], "partition from both products, y b / (y b + (1 - y) c)"),
        (["--partition-from", "feed"], "partition from the fine stream over the measured feed, y b / a"),
        (["--reconcile"], "partition from the reconciled distributions"),
    ):
        assert main(["balance", path, "--kind", "retained_frac", "--rename", rename, *option]) == 0
        assert said in capsys.readouterr().out


def test_dataframes_get_the_same_layouts_and_column_checks():
    frame = pd.read_csv(DATA / "hydrocyclone_size_class_um.csv", comment="#")
    (balance,) = read_lab(frame)
    assert_allclose(balance.classes["partition_fine"], PARTITIONS, atol=1e-6)
    assert balance.size_unit == "um" and balance.classes["row"].tolist() == list(range(6))
    points = pd.DataFrame({"size_mm": [0.1, 0.2, 0.4], "partiton_fine": [0.9, 0.5, 0.1]})
    with pytest.raises(InputError, match=r"DataFrame: no partition column.*'partiton_fine' \(did you mean 'partition_fine'\?\)"):
        read_points(points)
    (loaded,) = read_points(points.rename(columns={"partiton_fine": "partition_fine"}))
    assert loaded.size_unit == "mm"
