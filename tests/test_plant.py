"""tromplab.plant and ``tromplab plant predict``: a washing plant's products against independent computations.

Reference values: each is computed here again from the definitions (Wills & Finch 2016 ch. 11;
ISO 923) with a few lines of numpy and scipy.stats.norm, independently of the package, or by hand
(the numbers written out in the comments).
"""

from __future__ import annotations

import filecmp

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose
from scipy.stats import norm

from tromplab.cli import main
from tromplab.density import fit_density
from tromplab.errors import InputError, OptionError
from tromplab.plant import devices_from_fits, predict, read_plant_washability
from tromplab.plant.draws import parameter_draws
from tromplab.plant.inputs import Device
from tromplab.plant.products import composite_washability

from .conftest import DATASETS

WASH = DATASETS / "plant_washability_synthetic.csv"
DEVICES = DATASETS / "plant_devices_synthetic.csv"
TRACERS = DATASETS / "density_tracers_dmc_by_size_synthetic.csv"
Z75 = norm.ppf(0.75)


def _table(path) -> pd.DataFrame:
    return pd.read_csv(path, comment="#")


def _plant(rho50, ep, **extra) -> pd.DataFrame:
    names = ["50x12mm", "12x1mm", "1x0.15mm"]
    frame = pd.DataFrame({"size_fraction": names, "device": ["a", "b", "c"], "curve": "normal", "rho50": rho50, "ep": ep})
    return frame.assign(**extra)


def _direct(wash: pd.DataFrame, cuts: dict, eps: dict) -> dict:
    """Clean yield and ash of each size fraction and of the plant, from the definitions (normal curve, midpoints)."""
    out, plant_mass, plant_ash_mass = {}, 0.0, 0.0
    for name, rows in wash.groupby("size_fraction", sort=False):
        density = (rows["density_lower"] + rows["density_upper"]).to_numpy() / 2
        floats = 1 - norm.cdf(Z75 * (density - cuts[name]) / eps[name])
        mass = rows["mass_pct"].to_numpy() * 100 / rows["mass_pct"].sum()
        clean = float(np.sum(mass * floats))
        ash = float(np.sum(mass * floats * rows["ash_pct"]) / clean)
        out[name] = (clean, ash)
        share = rows["fraction_pct"].iloc[0] / 100
        plant_mass += share * clean
        plant_ash_mass += share * clean * ash
    out["total"] = (plant_mass, plant_ash_mass / plant_mass)
    return out


@pytest.mark.parametrize("cuts", [(1.45, 1.55, 1.7), (1.6, 1.6, 1.6), (1.38, 1.72, 1.95)])
def test_yield_and_ash_equal_a_direct_computation(cuts):
    wash = _table(WASH)
    eps = (0.02, 0.045, 0.12)
    products = predict(wash, _plant(list(cuts), list(eps))).products.set_index("size_fraction")
    names = ["50x12mm", "12x1mm", "1x0.15mm"]
    expected = _direct(wash, dict(zip(names, cuts)), dict(zip(names, eps)))
    for name, (clean, ash) in expected.items():
        assert_allclose(products.loc[name, ["clean_yield_pct", "clean_ash_pct"]].to_numpy(float), [clean, ash], rtol=1e-9)
    assert_allclose(products.loc["total", "feed_pct"], 100.0)
    # the ash balances: clean and reject ash mass is the feed's
    for name in names:
        row, rows = products.loc[name], wash[wash["size_fraction"] == name]
        feed_ash = float(np.sum(rows["mass_pct"] * rows["ash_pct"]) / 100)
        balance = row["clean_yield_pct"] * row["clean_ash_pct"] + (100 - row["clean_yield_pct"]) * row["reject_ash_pct"]
        assert_allclose(balance / 100, feed_ash, rtol=1e-9)


def test_an_ideal_separation_on_a_fraction_bound_gives_the_theoretical_yield_and_ash():
    wash = _table(WASH)
    for cuts in ((1.5, 1.5, 1.5), (1.4, 1.6, 1.8)):
        products = predict(wash, _plant(list(cuts), 1e-5)).products.set_index("size_fraction")
        for name, cut in zip(["50x12mm", "12x1mm", "1x0.15mm"], cuts):
            rows = wash[(wash["size_fraction"] == name) & (wash["density_upper"] <= cut + 1e-9)]  # the floats of the cut
            floats_yield = rows["mass_pct"].sum()  # the masses of each size fraction add up to 100
            floats_ash = float(np.sum(rows["mass_pct"] * rows["ash_pct"]) / floats_yield)
            row = products.loc[name]
            assert_allclose([row["clean_yield_pct"], row["clean_ash_pct"]], [floats_yield, floats_ash], atol=1e-6)
            assert_allclose(row["theoretical_yield_pct"], floats_yield, atol=1e-6)
            assert_allclose(row["organic_efficiency_pct"], 100.0, atol=1e-6)
            assert row["misplaced_floats_pct"] == pytest.approx(0, abs=1e-9)
            assert row["misplaced_sinks_pct"] == pytest.approx(0, abs=1e-9)
    # one cut for all: the plant's product is the whole feed's ideal floats, at 100 % organic efficiency
    products = predict(wash, _plant(1.5, 1e-5)).products.set_index("size_fraction")
    assert_allclose(products.loc["total", "organic_efficiency_pct"], 100.0, atol=1e-6)
    # Ep = 0 is the ideal separation itself, and Ep towards 0 tends to it
    ideal = predict(wash, _plant([1.4, 1.6, 1.8], 0.0)).products
    sharp = predict(wash, _plant([1.4, 1.6, 1.8], 1e-5)).products
    pd.testing.assert_frame_equal(ideal, sharp, atol=1e-9, rtol=0)
    # an ideal cut's uncertainty moves the yield only when the cut crosses a fraction's midpoint (where it is read)
    uncertain_cut = predict(wash, _plant([1.4, 1.6, 1.8], 0.0, rho50_sd=0.06), draws=400).products
    assert (uncertain_cut["clean_yield_pct_high"] > uncertain_cut["clean_yield_pct_low"]).all()
    narrow = predict(wash, _plant([1.4, 1.6, 1.8], 0.0, rho50_sd=0.01), draws=400).products  # 1.4 +/- 0.03 stays in 1.35-1.45
    assert_allclose(narrow["clean_yield_pct_high"], narrow["clean_yield_pct_low"], rtol=0, atol=0)


def test_theoretical_yield_inside_a_fraction_by_hand():
    # one size fraction: 60 % at ash 5, 20 % at 20, 20 % at 60; an ideal cut inside 1.4-1.6 taking t of it has
    # ash (60*5 + 20 t 20)/(60 + 20 t); ash 8.75 needs t = 1 (yield 80); ash 7 needs 300 + 400 t = 420 + 140 t, t = 6/13
    wash = pd.DataFrame({"size_fraction": "all", "fraction_pct": 100, "density_lower": [1.2, 1.4, 1.6],
                         "density_upper": [1.4, 1.6, 2.0], "mass_pct": [60, 20, 20], "ash_pct": [5, 20, 60]})  # fmt: skip
    (fraction,) = read_plant_washability(wash)
    assert_allclose(fraction.washability.theoretical_yield_pct(7.0), 60 + 20 * 6 / 13, rtol=1e-12)
    plant = pd.DataFrame({"size_fraction": ["all"], "device": ["bath"], "curve": ["normal"], "rho50": [1.5], "ep": [0.08]})
    row = predict(wash, plant).products.iloc[0]
    # the floats partition of the three midpoints 1.3, 1.5, 1.8 at rho50 1.5, Ep 0.08
    floats = 1 - norm.cdf(Z75 * (np.array([1.3, 1.5, 1.8]) - 1.5) / 0.08)
    clean = float(np.sum([60, 20, 20] * floats))
    ash = float(np.sum(np.array([60, 20, 20]) * floats * [5, 20, 60]) / clean)
    t = (ash * 60 - 300) / (400 - 20 * ash)  # the share of 1.4-1.6 an ideal cut at that ash takes
    assert_allclose(row["theoretical_yield_pct"], 60 + 20 * t, rtol=1e-10)
    assert_allclose(row["organic_efficiency_pct"], 100 * clean / (60 + 20 * t), rtol=1e-10)
    # misplaced: the floats of 1.5 (all of 1.2-1.4, half of 1.4-1.6) in the sinks, the rest in the floats
    sinks = 1 - floats
    assert_allclose(row["misplaced_floats_pct"], 60 * sinks[0] + 20 * sinks[1] * 0.5, rtol=1e-10)
    assert_allclose(row["misplaced_sinks_pct"], 20 * floats[1] * 0.5 + 20 * floats[2], rtol=1e-10)
    assert_allclose(row["near_gravity_pct"], 20.0, rtol=1e-12)  # 1.5 +/- 0.1 is the fraction 1.4-1.6, all of it


def test_qualities_blend_by_mass_and_the_plant_by_feed_share():
    wash = _table(WASH)
    products = predict(wash, DEVICES, draws=0).products.set_index("size_fraction")
    shares = wash.groupby("size_fraction", sort=False)["fraction_pct"].first() / 100
    clean = products.loc[shares.index, "clean_yield_pct"]
    for quality in ("ash", "sulfur"):
        expected = np.sum(shares * clean * products.loc[shares.index, f"clean_{quality}_pct"]) / np.sum(shares * clean)
        assert_allclose(products.loc["total", f"clean_{quality}_pct"], expected, rtol=1e-12)
    assert_allclose(products.loc["total", "clean_yield_pct"], np.sum(shares * clean), rtol=1e-12)


def test_an_imperfection_device_is_the_ep_device_at_its_cut():
    wash = _table(WASH)
    by_ep = predict(wash, _plant([1.5, 1.6, 1.8], [0.02, 0.04, 0.8 * 0.2])).products
    plant = _plant([1.5, 1.6, 1.8], [0.02, 0.04, np.nan], imperfection=[np.nan, np.nan, 0.2])
    by_imperfection = predict(wash, plant).products
    pd.testing.assert_frame_equal(by_ep, by_imperfection, rtol=1e-12)


def test_composite_washability_adds_the_size_fractions_at_equal_density():
    fractions = read_plant_washability(WASH)
    whole = composite_washability(fractions)
    wash = _table(WASH)
    weighted = wash.assign(mass=wash["mass_pct"] * wash["fraction_pct"] / 100, ash_mass=lambda t: t["mass"] * t["ash_pct"])
    by_density = weighted.groupby("density_lower")[["mass", "ash_mass"]].sum()
    assert_allclose(whole.mass_pct, by_density["mass"].to_numpy(), rtol=1e-12)
    assert_allclose(whole.ash_pct, (by_density["ash_mass"] / by_density["mass"]).to_numpy(), rtol=1e-12)


# --- intervals ----------------------------------------------------------------------------------
def test_intervals_bracket_the_estimate_and_repeat_with_the_seed():
    first = predict(WASH, DEVICES, draws=400, seed=3).products
    again = predict(WASH, DEVICES, draws=400, seed=3).products
    pd.testing.assert_frame_equal(first, again)
    for column in ("clean_yield_pct", "clean_ash_pct", "organic_efficiency_pct", "clean_sulfur_pct"):
        assert (first[f"{column}_low"] <= first[column] + 1e-9).all() and (first[column] <= first[f"{column}_high"] + 1e-9).all()
        assert (first[f"{column}_high"] > first[f"{column}_low"]).all()
    assert (first.filter(like="_pct").drop(columns="feed_pct") >= 0).all().all()


def test_exact_curves_give_no_interval_columns():
    products = predict(WASH, _plant([1.5, 1.6, 1.8], 0.03)).products
    assert not [column for column in products.columns if column.endswith(("_low", "_high"))]


def test_draws_follow_the_stated_covariance():
    """Drawn through the linear predictor's coefficients, the draws of (rho50, Ep) have the stated covariance to
    first order: with small standard deviations the sample sds and correlation match it."""
    from tromplab.density.registry import get_density_curve

    covariance = np.array([[0.002**2, 0.6 * 0.002 * 0.0005], [0.6 * 0.002 * 0.0005, 0.0005**2]])
    for curve in ("normal", "logistic", "gompertz"):
        device = Device("x", "d", get_density_curve(curve), 1.5, "ep", 0.04, covariance)
        [(rho50, ep)] = parameter_draws([device], 40000, seed=2)
        assert_allclose([np.std(rho50[1:]), np.std(ep[1:])], [0.002, 0.0005], rtol=0.03)
        assert_allclose(np.corrcoef(rho50[1:], ep[1:])[0, 1], 0.6, atol=0.02)
        assert_allclose([np.mean(rho50[1:]), np.mean(ep[1:])], [1.5, 0.04], rtol=1e-3)
    # a device given by its imperfection: I = Ep / (rho50 - 1) drawn with its stated sd
    device = Device("x", "d", get_density_curve("normal"), 1.75, "imperfection", 0.2, np.diag([0.003**2, 0.004**2]))
    [(rho50, imperfection)] = parameter_draws([device], 40000, seed=3)
    assert_allclose([np.std(rho50[1:]), np.std(imperfection[1:])], [0.003, 0.004], rtol=0.03)


def test_the_washability_draws_have_the_multinomial_variance():
    """Dirichlet(N m) draws of the density fractions' shares: mean m, variance m (1 - m) / (N + 1), adding up to 100,
    an empty fraction staying empty (the model of tromplab.plant.sampling)."""
    from tromplab.density.washability import washability_from_arrays
    from tromplab.plant.inputs import SizeFraction
    from tromplab.plant.sampling import washability_mass_draws

    mass = np.array([55.0, 25.0, 0.0, 20.0])
    fraction = SizeFraction(
        "f", 100.0, washability_from_arrays([1.3, 1.4, 1.5, 1.6], [1.4, 1.5, 1.6, 2.0], mass, [4, 15, 30, 70])
    )
    (drawn,) = washability_mass_draws([fraction], 300, 40000, seed=5)
    share = mass / 100
    assert_allclose(drawn[0], mass)
    assert_allclose(drawn[1:].mean(axis=0), mass, atol=0.05)
    assert_allclose(drawn[1:].var(axis=0)[[0, 1, 3]], (1e4 * share * (1 - share) / 301)[[0, 1, 3]], rtol=0.03)
    assert (drawn[:, 2] == 0).all()
    assert_allclose(drawn.sum(axis=1), 100.0, rtol=1e-12)


def test_the_washability_error_gives_the_interval_a_direct_computation_gives():
    """With exact curves, a size fraction's clean yield Y = sum m_i (1 - P_i) is linear in the masses, so under the
    Dirichlet(N m) model its standard deviation is sqrt(c' S c), S = (diag(m) - m m') / (N + 1) x 100^2 with
    c_i = 1 - P_i: the 95 % interval is Y -/+ 1.96 sd wide to within the draws' error (N = 3000, 20,000 draws)."""
    exact = _plant([1.5, 1.6, 1.8], 0.03)
    plain = predict(WASH, exact).products
    result = predict(WASH, exact, washability_particles=3000, draws=20000, seed=4)
    products = result.products.set_index("size_fraction")
    wash = _table(WASH)
    for name, rows in wash.groupby("size_fraction", sort=False):
        density = (rows["density_lower"] + rows["density_upper"]).to_numpy() / 2
        cut = {"50x12mm": 1.5, "12x1mm": 1.6, "1x0.15mm": 1.8}[name]
        floats = 1 - norm.cdf(Z75 * (density - cut) / 0.03)
        share = rows["mass_pct"].to_numpy() / rows["mass_pct"].sum()
        covariance = (np.diag(share) - np.outer(share, share)) / 3001 * 1e4
        sd = np.sqrt(floats @ covariance @ floats)
        row = products.loc[name]
        half_width = (row["clean_yield_pct_high"] - row["clean_yield_pct_low"]) / 2
        assert_allclose(half_width, 1.959964 * sd, rtol=0.03)  # 20,000 draws: the quantiles' own error is about 1 %
        assert row["clean_yield_pct_low"] < row["clean_yield_pct"] < row["clean_yield_pct_high"]
    # the estimates are those without the option; the note says what the intervals carry
    assert_allclose(result.products["clean_yield_pct"], plain["clean_yield_pct"], rtol=0, atol=0)
    assert "3,000 particles" in result.notes[0]


def test_the_washability_error_widens_the_curves_intervals_and_the_command_takes_it(tmp_path, capsys):
    curves_only = predict(WASH, DEVICES, draws=500, seed=1).products
    both = predict(WASH, DEVICES, draws=500, seed=1, washability_particles=400).products
    width = lambda p: p["clean_yield_pct_high"] - p["clean_yield_pct_low"]  # noqa: E731
    assert (width(both) > width(curves_only)).all()
    assert main(["plant", "predict", str(WASH), str(DEVICES), "--draws", "500", "--seed", "1", "--washability-particles",
                 "400", "-o", str(tmp_path / "cli")]) == 0  # fmt: skip
    capsys.readouterr()
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "cli" / "products.csv"), pd.read_csv(tmp_path / "cli" / "products.csv"))
    predict(WASH, DEVICES, draws=500, seed=1, washability_particles=400).save(tmp_path / "api")
    assert filecmp.cmp(tmp_path / "cli" / "products.csv", tmp_path / "api" / "products.csv", shallow=False)
    with pytest.raises(OptionError, match="washability_particles must be a whole number >= 1"):
        predict(WASH, DEVICES, washability_particles=0)
    assert main(["plant", "predict", str(WASH), str(DEVICES), "--washability-particles", "0", "-o", str(tmp_path / "x")]) == 2
    assert "--washability-particles: must be a whole number >= 1" in capsys.readouterr().err


@pytest.mark.slow
def test_intervals_cover_the_true_plant_yield_and_ash():
    """Simulated tracer tests of the bundled devices (30 tracers per density, 90 % recovered, as a lab gives them),
    written as CSV, fitted, propagated: the 95 % intervals of the plant's clean yield and ash hold the truth in most
    simulations (a small version of benchmarks/plant_coverage.py)."""
    from tromplab.plant import read_plant
    from tromplab.plant.simulation import coverage_runs, coverage_table

    fractions = read_plant_washability(WASH)
    runs = coverage_runs(fractions, read_plant(DEVICES, fractions), simulations=40, draws=300, seed=7)
    table = coverage_table(runs).set_index(["size_fraction", "quantity"])
    # at a true coverage of 95 %, 40 simulations fall below 34 covered with probability 0.34 % (binomial)
    for quantity in ("clean_yield_pct", "clean_ash_pct"):
        assert table.loc[("total", quantity), "coverage"] * 40 >= 34, table
    assert (table["coverage"] * 40 >= 32).all(), table  # every fraction and quantity (P(X < 32) = 0.013 % at 95 %)
    # the truth is the plant the true curves make: not what the first simulation estimated
    assert (runs["estimate"] != runs["truth"]).any()


# --- inputs: messages naming file, row and column -------------------------------------------------------
def _bad_wash(tmp_path, change) -> str:
    frame = _table(WASH)
    change(frame)
    path = tmp_path / "wash.csv"
    frame.to_csv(path, index=False)
    return str(path)


@pytest.mark.parametrize(
    ("change", "row", "column", "words"),
    [
        (lambda t: t.__setitem__("fraction_pct", t["fraction_pct"].where(t.index != 3, 44)), 5, "fraction_pct", "differs"),
        (lambda t: t.__setitem__("ash_pct", t["ash_pct"].where(t.index != 4, 130)), 6, "ash_pct", "outside"),
        (lambda t: t.__setitem__("sulfur_pct", t["sulfur_pct"].where(t.index != 0, -1)), 2, "sulfur_pct", "outside"),
        (lambda t: t.__setitem__("density_lower", t["density_lower"].where(t.index != 2, 1.36)), 4, "density_lower", "gap"),
    ],
)
def test_bad_washability_is_refused_naming_row_and_column(tmp_path, change, row, column, words):
    path = _bad_wash(tmp_path, change)
    with pytest.raises(InputError, match=words) as caught:
        read_plant_washability(path)
    assert (caught.value.row, caught.value.column) == (row, column) and caught.value.source.endswith("wash.csv")


def test_size_fractions_must_add_up_to_the_feed(tmp_path):
    path = _bad_wash(tmp_path, lambda t: t.__setitem__("fraction_pct", t["fraction_pct"] * 0.9))
    with pytest.raises(InputError, match="add up to 90"):
        read_plant_washability(path)


@pytest.mark.parametrize(
    ("plant", "column", "words"),
    [
        (_plant([1.5, 1.6, 1.7], 0.03).assign(curve=["normal", "erf", "normal"]), "curve", "unknown curve 'erf'"),
        (_plant([1.5, 1.6, 1.7], 0.03).assign(imperfection=0.1), "ep", "exactly one of ep and imperfection"),
        (_plant([1.5, 0.9, 1.7], 0.03), "rho50", "cut density above 1"),
        (_plant([1.5, 1.6, 1.7], [0.03, -0.01, 0.03]), "ep", "probable error in \\[0, 2\\]"),
        (
            _plant([1.5, 1.6, 1.7], 0.03).assign(size_fraction=["50x12mm", "12x1mm", "fines"]),
            "size_fraction",
            "not in the washability",
        ),
        (_plant([1.5, 1.6, 1.7], 0.03).assign(rho50_min=1.8, rho50_max=1.4), "rho50_min", "not below rho50_max"),
    ],
)
def test_bad_plant_rows_are_refused_naming_the_column(plant, column, words):
    with pytest.raises(InputError, match=words) as caught:
        predict(WASH, plant)
    assert caught.value.column == column and caught.value.row is not None


def test_a_size_fraction_without_a_device_is_refused():
    with pytest.raises(InputError, match="no device for the size fraction"):
        predict(WASH, _plant([1.5, 1.6, 1.7], 0.03).iloc[:2])


def test_options_are_checked_by_the_library():
    with pytest.raises(OptionError, match="exactly one"):
        predict(WASH)
    with pytest.raises(OptionError, match="draws"):
        predict(WASH, DEVICES, draws=-1)
    with pytest.raises(OptionError, match="ci"):
        predict(WASH, DEVICES, ci=1.5)


@pytest.mark.parametrize(
    "option, value, flag",
    [("sum_tolerance_pct", -1, "--sum-tolerance"), ("float_lower_density", 0, "--float-lower-density"),
     ("sink_upper_density", -2.5, "--sink-upper-density")],
)  # fmt: skip
def test_the_washability_options_are_checked_as_read_washability_and_the_command_check_them(
    option, value, flag, tmp_path, capsys
):
    from tromplab.density.washability import read_washability

    with pytest.raises(OptionError) as plant_error:
        read_plant_washability(WASH, **{option: value})
    with pytest.raises(OptionError) as density_error:
        read_washability(DATASETS / "density_washability_synthetic.csv", **{option: value})
    assert str(plant_error.value) == str(density_error.value)
    assert plant_error.value.option == option and plant_error.value.reason in str(plant_error.value)
    with pytest.raises(OptionError) as predict_error:
        predict(WASH, DEVICES, **{option: value})
    assert str(predict_error.value) == str(plant_error.value)
    assert main(["plant", "predict", str(WASH), str(DEVICES), flag, str(value), "-o", str(tmp_path / "out")]) == 2
    assert f"argument {flag}: {plant_error.value.reason}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_command_names_file_row_and_column_and_writes_nothing(tmp_path, capsys):
    plant = tmp_path / "plant.csv"
    _plant([1.5, 1.6, 1.7], 0.03).assign(curve=["normal", "erf", "normal"]).to_csv(plant, index=False)
    assert main(["plant", "predict", str(WASH), str(plant), "-o", str(tmp_path / "out")]) == 1
    assert "plant.csv, row 3, column 'curve'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    assert main(["plant", "predict", str(WASH), "-o", str(tmp_path / "out")]) == 2


# --- the two faces --------------------------------------------------------------------------------------
@pytest.mark.slow
def test_the_command_writes_what_the_api_saves(tmp_path, capsys):
    assert main(["plant", "predict", str(WASH), str(DEVICES), "--draws", "300", "--seed", "5", "-o", str(tmp_path / "cli")]) == 0
    capsys.readouterr()
    written = predict(WASH, DEVICES, draws=300, seed=5).save(tmp_path / "api")
    assert sorted(written) == sorted(p.name for p in (tmp_path / "cli").iterdir() if not p.name.startswith("."))
    for name in written:
        assert filecmp.cmp(tmp_path / "cli" / name, tmp_path / "api" / name, shallow=False), name


# --- curves from a density fit ----------------------------------------------------------------------------
def _tracer_fractions() -> list:
    rows = []
    for size, share in (("2-4 mm", 20), ("4-8 mm", 30), ("8-16 mm", 30), ("16-32 mm", 20)):
        for lower, upper, mass, ash in ((1.3, 1.45, 50, 4), (1.45, 1.55, 20, 14), (1.55, 1.65, 10, 28), (1.65, 2.2, 20, 70)):
            rows.append({"size_fraction": size, "fraction_pct": share, "density_lower": lower, "density_upper": upper,
                         "mass_pct": mass, "ash_pct": ash})  # fmt: skip
    return read_plant_washability(pd.DataFrame(rows))


@pytest.mark.slow
def test_curves_from_a_density_fit_folder_carry_its_covariance(tmp_path, capsys):
    folder = tmp_path / "fit"
    assert main(["density", "fit", str(TRACERS), "--curves", "normal,logistic", "-o", str(folder)]) == 0
    capsys.readouterr()
    fractions = _tracer_fractions()
    devices = devices_from_fits(folder, fractions)
    fits = pd.read_csv(folder / "fits.csv")
    covariance = pd.read_csv(folder / "covariance.csv")
    for device in devices:
        best = fits[(fits["size_fraction"] == device.size_fraction) & (fits["rank"] == 1)].iloc[0]
        assert (device.curve.id, device.rho50, device.scale) == (best["curve"], best["rho50"], best["ep"])
        block = covariance[(covariance["size_fraction"] == device.size_fraction) & (covariance["curve"] == best["curve"])]
        assert_allclose(device.covariance, block[["rho50", "ep"]].to_numpy(), rtol=1e-12)
    # the folder and the result in memory give the same devices, and the prediction has intervals
    from_result = devices_from_fits(fit_density(TRACERS, curves="normal,logistic"), fractions)
    for one, other in zip(devices, from_result):
        assert_allclose(one.covariance, other.covariance, rtol=1e-9)
    products = predict(fractions, curves_from=folder, draws=200).products
    assert "clean_yield_pct_low" in products.columns and products["clean_yield_pct_low"].notna().all()


def test_the_fit_covariance_is_the_glm_covariance_by_the_delta_method():
    """For the normal curve fitted as a probit GLM, P = Phi(a + b rho): rho50 = -a/b and Ep = z75/b, so the
    covariance of (rho50, Ep) is J C J' with C the inverse of the GLM's observed information (statsmodels'
    analytic Hessian of the log-likelihood) and J = [[-1/b, a/b^2], [0, -z75/b^2]]."""
    import statsmodels.api as sm

    from tromplab.density.covariance import index_covariance

    result = fit_density(TRACERS, curves="normal")
    for fit in result.fits:
        used = fit.sample.used
        counts = np.column_stack([used["sinks"], used["recovered"] - used["sinks"]]).astype(float)
        probit = sm.families.Binomial(link=sm.families.links.Probit())
        model = sm.GLM(counts, sm.add_constant(used["density"].to_numpy(float)), family=probit)
        a, b = fit.raw.params
        jacobian = np.array([[-1 / b, a / b**2], [0.0, -Z75 / b**2]])
        observed = -np.linalg.inv(model.hessian(np.asarray(fit.raw.params), observed=True))
        expected = jacobian @ observed @ jacobian.T
        scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected)))  # the covariance relative to its variances
        assert_allclose(index_covariance(fit) / scale, expected / scale, atol=1e-4)


def _documented_plant_columns() -> set[str]:
    import re

    from .conftest import ROOT

    names = set()
    for line in (ROOT / "docs" / "plant.md").read_text(encoding="utf-8").splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0].startswith("`"):
            names |= set(re.findall(r"`([^`]+)`", cells[0]))
    return names


def test_every_written_column_is_documented(tmp_path):
    from tromplab.plant import optimize

    documented = _documented_plant_columns()
    prediction = predict(WASH, DEVICES, draws=50)
    optimum = optimize(WASH, DEVICES, target_ash_pct=10, draws=50)
    qualities = {f"{side}_{name}_pct" for name in prediction.qualities for side in ("clean", "reject")}
    assert qualities == {"clean_sulfur_pct", "reject_sulfur_pct"}
    assert {"clean_<name>_pct", "reject_<name>_pct", "<column>_low", "<column>_high"} <= documented
    from tromplab.plant import evaluate

    from .test_plant_evaluate import _test_table

    evaluation = evaluate(_test_table())
    for table in (prediction.products, prediction.devices_table(), optimum.cuts, evaluation.evaluation, evaluation.fractions):
        for column in table.columns:
            stem = column.removesuffix("_low").removesuffix("_high")
            assert column in documented or stem in documented or stem in qualities, f"{column} is not in docs/plant.md"
