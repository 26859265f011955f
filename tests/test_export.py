"""Export to simulator conventions: each convention re-implemented here, independently of tromplab,
from its published form, must reproduce tromplab's fitted curve at the measured sizes within 1e-6."""

import math
import re

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose
from scipy import special

from tromplab.cli import main
from tromplab.curves.formulas import get_formula
from tromplab.errors import InputError
from tromplab.output.export import export_fits, read_fits

SIZES_UM = np.geomspace(15, 600, 13)
TRUTHS = {
    "lynch": (110.0, 2.5, {}),
    "whiten": (120.0, 3.0, {"bypass": 0.25, "fishhook": 0.4}),
    "rosin_rammler": (95.0, 1.8, {}),
    "rosin_rammler_bypass": (105.0, 2.2, {"bypass": 0.18}),
    "molerus_hoffmann": (100.0, 1.5, {}),
    "teipel_hennig": (130.0, 3.5, {"th_alpha": 2.0, "bypass": 0.1}),
    "normal": (140.0, 0.35, {}),
    "plitt": (90.0, 2.0, {}),
}


@pytest.fixture(scope="module")
def fits_dir(tmp_path_factory):
    """`tromplab fit` output for points drawn from each curve (one experiment per curve)."""
    folder, data = tmp_path_factory.mktemp("fits"), tmp_path_factory.mktemp("data")  # --outdir may not hold the input
    rng = np.random.default_rng(21)
    frames = []
    for name, (d_cut, shape, extras) in TRUTHS.items():
        phi = get_formula(name)(SIZES_UM, d_cut, shape, **extras) + rng.normal(0, 0.004, SIZES_UM.size)
        frames.append(pd.DataFrame({"experiment": f"run_{name}", "size": SIZES_UM, "partition_fine": np.clip(phi, 0, 1)}))
    pd.concat(frames).to_csv(data / "points.csv", index=False)
    formulas = ",".join(TRUTHS)
    assert main(["fit", str(data / "points.csv"), "-o", str(folder), "--formulas", formulas, "--no-figures"]) == 0
    return folder


def tromplab_curves(fits_dir):
    """Partition to fines of every successful fit in fits.csv, by tromplab, at the measured sizes."""
    return {
        (f.experiment, f.formula): get_formula(f.formula)(SIZES_UM, f.d_cut, f.shape, **f.extras) for f in read_fits(fits_dir)
    }


def whiten_overflow(d, row):
    """Napier-Munn et al. (1996): E_oa = C (1 + b b* x)(e^a - 1)/(e^(a b* x) + e^a - 2), x = d/d50c, to the overflow."""
    x = d / row.d50c
    a, b, bs = row.alpha, row.beta, row.beta_star
    return row.C * (1 + b * bs * x) * (np.exp(a) - 1) / (np.exp(a * bs * x) + np.exp(a) - 2)


def plitt_underflow(d, row):
    """Plitt (1976): Y = Rf + (1 - Rf)(1 - exp(-0.693 (d/d50c)^m)), Rf in percent, to the underflow."""
    rf = row.Rf_pct / 100
    return rf + (1 - rf) * (1 - np.exp(-0.693 * (d / row.d50c) ** row.m))


def dyssol_coarse(d_m, row):
    """Dyssol Screen unit, partition to the coarse product, sizes in metres (continuous Probability)."""
    if row.Model == "Plitt":
        return 1 - np.exp(-0.693 * (d_m / row.Xcut) ** row.Alpha)
    if row.Model == "Molerus & Hoffmann":
        return 1 / (1 + (row.Xcut / d_m) ** 2 * np.exp(row.Alpha * (1 - (d_m / row.Xcut) ** 2)))
    if row.Model == "Teipel & Hennig":
        x = d_m / row.Xcut
        return (1 - (1 + 3 * x ** ((x + row.Alpha) * row.Beta)) ** -0.5) * (1 - row.Offset) + row.Offset
    if row.Model == "Probability":
        return 0.5 * special.erfc(-(d_m - row.Mean) / (np.sqrt(2) * row.Deviation))
    raise AssertionError(row.Model)


CASES = {
    "whiten": (lambda row: whiten_overflow(SIZES_UM, row), {"lynch", "whiten"}),
    "plitt": (lambda row: 1 - plitt_underflow(SIZES_UM, row), {"rosin_rammler", "rosin_rammler_bypass"}),
    "dyssol": (
        lambda row: 1 - dyssol_coarse(SIZES_UM * 1e-6, row),
        {"rosin_rammler", "molerus_hoffmann", "teipel_hennig", "normal"},
    ),
}


@pytest.mark.parametrize("convention", list(CASES))
@pytest.mark.slow
def test_exported_curve_re_evaluated_in_the_target_convention_reproduces_the_fit(fits_dir, convention):
    evaluate, expected = CASES[convention]
    args = ["export", str(fits_dir), "--to", convention] + (["--size-unit", "um"] if convention == "dyssol" else [])
    assert main(args) == 0
    table = pd.read_csv(fits_dir / f"export_{convention}.csv")
    assert set(table["formula"]) == expected
    curves = tromplab_curves(fits_dir)
    for row in table.itertuples(index=False):
        assert_allclose(evaluate(row), curves[(row.experiment, row.formula)], atol=1e-6, rtol=0)


def test_units_cuts_and_bypass_of_each_convention(fits_dir):
    fits = {(f.experiment, f.formula): f for f in read_fits(fits_dir)}
    dyssol = export_fits(fits_dir, "dyssol", size_unit="um").table.set_index("formula")
    teipel = fits[("run_teipel_hennig", "teipel_hennig")]
    row = dyssol.loc["teipel_hennig"].loc[lambda t: t["experiment"] == "run_teipel_hennig"].iloc[0]
    assert_allclose(row["Xcut"], teipel.d_cut * 1e-6, rtol=1e-12)  # metres
    assert_allclose(row["Offset"], teipel.bypass, rtol=1e-12)  # a fraction
    plitt = export_fits(fits_dir, "plitt", size_unit="um").table.set_index("experiment").loc["run_rosin_rammler_bypass"]
    plitt = plitt[plitt["formula"] == "rosin_rammler_bypass"].iloc[0]
    fit = fits[("run_rosin_rammler_bypass", "rosin_rammler_bypass")]
    assert_allclose(plitt["Rf_pct"], 100 * fit.bypass, rtol=1e-12)  # percent
    assert_allclose(plitt["d50c_ln2"], fit.d_cut, rtol=1e-12)
    assert plitt["d50c"] < fit.d_cut  # 0.693 < ln 2 moves the printed cut down
    # the actual cut: (1 - Rf) exp(-ln2 x^m) = 1/2, finer than the corrected cut
    assert_allclose(plitt["d50"], fit.d_cut * (np.log(2 * (1 - fit.bypass)) / np.log(2)) ** (1 / fit.shape), rtol=1e-10)
    whiten = export_fits(fits_dir, "whiten").table
    row = whiten[(whiten["formula"] == "whiten") & (whiten["experiment"] == "run_whiten")].iloc[0]
    assert_allclose(row["C"] + row["Rf_pct"] / 100, 1.0, rtol=1e-12)
    assert_allclose(whiten_overflow(np.array([row["d50c"]]), row) / row["C"], 0.5, atol=1e-12)  # d50c is the corrected cut


def test_dyssol_probability_model_approaches_the_normal_curve_on_a_fine_grid(fits_dir):
    table = export_fits(fits_dir, "dyssol", size_unit="um").table
    row = table[(table["Model"] == "Probability") & (table["experiment"] == "run_normal")].iloc[0]
    grid = np.linspace(1e-9, row.Mean + 8 * row.Deviation, 20001)  # Dyssol: cumulative sum of the density over classes
    density = np.exp(-((grid - row.Mean) ** 2) / (2 * row.Deviation**2))
    discrete = np.cumsum(density) / density.sum()
    # Dyssol normalises over its grid, which starts at size 0: the normal's mass below 0 is the gap left
    mass_below_zero = 0.5 * special.erfc(row.Mean / (np.sqrt(2) * row.Deviation))
    assert np.max(np.abs(discrete - dyssol_coarse(grid, row))) < mass_below_zero + 1e-3


def test_csv_long_holds_every_parameter_with_its_unit(fits_dir):
    table = export_fits(fits_dir, "csv-long", size_unit="um").table
    whiten = table[(table["experiment"] == "run_whiten") & (table["formula"] == "whiten")].set_index("parameter")
    assert set(whiten.index) == {"d_cut", "alpha", "bypass", "fishhook", "beta_star"}
    assert whiten.loc["d_cut", "unit"] == "um" and whiten.loc["alpha", "unit"] == "-"
    n_params = {f.formula: 2 + len(f.extras) for f in read_fits(fits_dir)}
    assert len(table[table["formula"] == "plitt"]) == len(TRUTHS) * n_params["plitt"]


def test_export_refuses_bad_input_with_clear_messages(fits_dir, tmp_path, capsys):
    with pytest.raises(ValueError, match="size-unit"):
        export_fits(fits_dir, "dyssol")
    with pytest.raises(ValueError, match="unknown size unit 'inch'"):
        export_fits(fits_dir, "plitt", size_unit="inch")
    with pytest.raises(ValueError, match="unknown convention 'jksimmet'"):
        export_fits(fits_dir, "jksimmet")
    with pytest.raises(InputError, match="no fits.csv"):
        read_fits(tmp_path)
    broken = pd.read_csv(fits_dir / "fits.csv")
    broken.loc[broken["formula"] == "teipel_hennig", "extras"] = ""
    broken.to_csv(tmp_path / "fits.csv", index=False)
    with pytest.raises(InputError, match=r"row \d+, column 'extras': the fitted value of th_alpha is missing"):
        read_fits(tmp_path)
    assert main(["export", str(fits_dir), "--to", "dyssol"]) == 1
    assert "--size-unit" in capsys.readouterr().err
    assert main(["export", str(fits_dir), "--to", "whiten"]) == 0
    assert "Not expressible in the whiten convention" in capsys.readouterr().out
    assert ("run_plitt", "plitt", "no whiten equivalent of plitt") in export_fits(fits_dir, "whiten").skipped


@pytest.mark.parametrize(
    "model, params, formula",
    [
        ("Teipel & Hennig", {"Xcut": 0.002, "Alpha": 8.0, "Beta": 0.5, "Offset": 0.2}, "teipel_hennig"),
        ("Plitt", {"Xcut": 0.002, "Alpha": 8.0}, "rosin_rammler"),
        ("Molerus & Hoffmann", {"Xcut": 0.002, "Alpha": 8.0}, "molerus_hoffmann"),
    ],
)
def test_dyssol_default_screen_parameters_survive_a_fit_and_an_export(model, params, formula):
    """Dyssol's Screen defaults (Units/Screen/Screen.cpp: Xcut 0.002 m, Alpha 8, Beta 0.5, Offset 0.2):
    a curve drawn by Dyssol's expression is fitted by tromplab and exported back to the same numbers."""
    from tromplab.curves.curve_fit import fit_formula
    from tromplab.loading.points import TrompPoints
    from tromplab.output.export import FittedCurve

    sizes_um = np.geomspace(300, 8000, 16)
    row = pd.Series({"Model": model, "Beta": np.nan, "Offset": 0.0, **params})
    points = TrompPoints(model, sizes_um, 1 - dyssol_coarse(sizes_um * 1e-6, row))
    fit = fit_formula(points, formula)
    exported = export_fits([FittedCurve(model, formula, fit.d_cut, fit.shape, fit.extras)], "dyssol", size_unit="um").table.iloc[
        0
    ]
    assert exported["Model"] == model
    for name, value in params.items():
        assert_allclose(exported[name], value, rtol=1e-6, atol=1e-9)


@pytest.mark.slow
def test_a_large_export_prints_its_first_rows_and_writes_them_all(fits_dir, tmp_path, capsys):
    """90,000 fits on the console took 5 s of pandas formatting: the console shows the first
    40 rows (and 40 experiments per left-out formula), the file every row."""
    fits = pd.read_csv(fits_dir / "fits.csv")
    copies = pd.concat([fits.assign(experiment=fits["experiment"] + f"_{k}") for k in range(60)], ignore_index=True)
    copies.to_csv(tmp_path / "fits.csv", index=False)
    output = tmp_path / "long.csv"
    assert main(["export", str(tmp_path), "--to", "csv-long", "-o", str(output)]) == 0
    console = capsys.readouterr().out
    written = pd.read_csv(output)
    assert len(written) > 100 and f"... and {len(written) - 40} more rows in the file" in console
    assert main(["export", str(tmp_path), "--to", "plitt", "-o", str(tmp_path / "plitt.csv")]) == 0
    assert re.search(r"and \d+ more", capsys.readouterr().out)


def test_the_actual_cut_is_scipys_brentq_root_with_the_same_refusals():
    from scipy import optimize

    from tromplab.output.export import _actual_cut

    whiten, rosin_rammler = get_formula("whiten"), get_formula("rosin_rammler")
    rng = np.random.default_rng(24)
    curves = [
        lambda x, a=a, c=c, b=b: float(whiten.phi(x, a, bypass=c, fishhook=b))
        for a, c, b in rng.uniform(0, 1, (40, 3)) * [10, 0.4, 1]
    ]
    curves += [lambda x, m=m, c=c: float((1 - c) * rosin_rammler.phi(x, m)) for m, c in rng.uniform(0, 1, (40, 2)) * [30, 0.4]]
    curves.append(lambda x: float(whiten.phi(x, 3.0)))  # Lynch's curve: 1/2 at x = 1 exactly
    for curve in curves:
        found = _actual_cut(curve)
        high = 1.0
        while curve(high) > 0.5:
            high *= 2.0
        assert found == optimize.brentq(lambda x, curve=curve: curve(x) - 0.5, 1e-6, high, xtol=1e-14)
    assert _actual_cut(curves[-1]) == 1.0
    with pytest.raises(ValueError, match="The function value at x=1e-06 is NaN; solver cannot continue."):
        _actual_cut(lambda x: math.nan)  # scipy's brentq's words
    assert math.isnan(_actual_cut(lambda x: 0.4)) and math.isnan(_actual_cut(lambda x: 0.6))
    assert _actual_cut(lambda x: 1.0 - x / 4) == 2.0


FITS_HEADER = "experiment,formula,d_cut,shape_name,shape,bypass,fishhook,success,extras\n"
UNKNOWN = "unknown formula {}; give an id, an equation number or a group (paper, other, extended). paper: molerus (3)"


@pytest.mark.parametrize(
    "rows, error",
    [
        # the fits are read a formula at a time: the error is still the first row's, in the file's order
        ("a,lynch,100,kl,3,,,True,\nb,lynch,,kl,3,,,True,\nc,nonsense,1,k,1,,,True,\n",
         "row 3, column 'd_cut': a successful fit with a missing parameter value"),
        ("a,lynch,100,kl,3,,,True,\nc,nonsense,1,k,1,,,True,\nb,lynch,,kl,3,,,True,\n",
         "row 3, column 'formula': " + UNKNOWN.format("'nonsense'")),
        ("a,lynch,100,kl,3,,,True,\nb,,1,k,1,,,True,\n", "row 3, column 'formula': " + UNKNOWN.format("nan")),
        ("a,teipel_hennig,100,k,3,0.1,,True,th_alpha=2\nb,teipel_hennig,100,k,3,0.1,,True,bypass=0.1\n",
         "row 3, column 'extras': the fitted value of th_alpha is missing (expected 'th_alpha=VALUE')"),
        ("a,teipel_hennig,100,k,3,0.1,,True,th_alpha=inf\n", "row 2, column 'd_cut': a successful fit with a missing parameter value"),
        # within a row: the missing text value before the missing number
        ("a,teipel_hennig,100,k,,0.1,,True,\n",
         "row 2, column 'extras': the fitted value of th_alpha is missing (expected 'th_alpha=VALUE')"),
        ("a,whiten,100,a,3,0.1,,True,\n", "row 2, column 'd_cut': a successful fit with a missing parameter value"),
        ("a,lynch,100,kl,3,,,True,\nb,lynch,100,kl,3,,,maybe,\n", "row 3, column 'success': 'maybe' is not a yes/no mark"),
    ],
)  # fmt: skip
def test_a_broken_fits_table_is_refused_at_its_first_row_at_fault(tmp_path, rows, error):
    (tmp_path / "fits.csv").write_text(FITS_HEADER + rows, encoding="utf-8")
    with pytest.raises(InputError) as refused:
        read_fits(tmp_path)
    assert str(refused.value).startswith(f"{tmp_path / 'fits.csv'}, {error}")


def test_fits_of_several_formulas_are_read_in_the_files_order(tmp_path):
    rows = (
        "a,teipel_hennig,100,k,3,0.1,,True,th_alpha=2; bypass=0.1\n"
        "x,nonsense,,k,,,,False,\n"  # failed fits are not read
        "b,(6),100,kl,3,,,1,\n"
        "c,whiten,80,a,2,0.2,0.3,Y,\n"
        "d,7,90,ks,2.5,,,yes,\n"
    )
    (tmp_path / "fits.csv").write_text(FITS_HEADER + rows, encoding="utf-8")
    assert [(f.experiment, f.formula, f.d_cut, f.shape, f.extras) for f in read_fits(tmp_path)] == [
        ("a", "teipel_hennig", 100.0, 3.0, {"th_alpha": 2.0, "bypass": 0.1}),
        ("b", "lynch", 100.0, 3.0, {}),
        ("c", "whiten", 80.0, 2.0, {"bypass": 0.2, "fishhook": 0.3}),
        ("d", "plitt", 90.0, 2.5, {}),
    ]


def test_the_export_command_leaves_the_cycle_collector_as_it_found_it(fits_dir, tmp_path, capsys):
    import gc

    assert gc.isenabled()
    assert main(["export", str(fits_dir), "--to", "whiten", "-o", str(tmp_path / "w.csv")]) == 0
    assert gc.isenabled()
    assert main(["export", str(tmp_path), "--to", "whiten"]) == 1  # no fits.csv: refused inside the pause
    assert gc.isenabled()
    gc.disable()
    try:
        assert main(["export", str(fits_dir), "--to", "plitt", "-o", str(tmp_path / "p.csv")]) == 0
        assert not gc.isenabled()
    finally:
        gc.enable()
