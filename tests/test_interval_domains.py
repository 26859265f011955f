"""Every interval tromplab reports contains its estimate and stays inside the quantity's range
on the bundled double-deck data where eta > 1, negative Ep and a negative
lower limit of ks were seen, and on generated experiments with bypass, few points, sharp and
flat curves."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import tromplab
from tromplab.cli import main
from tromplab.loading.points import TrompPoints
from tromplab.statistics.uncertainty import AVERAGED_QUANTITIES, interval_table, model_average, quantity_domain

from .conftest import DATASETS


def _inside(domain, values) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return (values >= domain.lower) & (values <= domain.upper)


@pytest.mark.slow
def test_bundled_deck_intervals_stay_in_range_and_name_their_method(tmp_path):
    out = tmp_path / "out"
    assert main(["fit", str(DATASETS / "double_deck_screen_decks_lab.csv"), "-o", str(out), "--size-unit", "mm",
                 "--ci", "0.95", "--no-figures", "--quiet"]) == 0  # fmt: skip
    fits = pd.read_csv(out / "fits.csv")
    fits = fits[fits["success"]]
    # the decks' partitions jump across the cut between two sieves (no point between 0.25 and
    # 0.75): the quantities resting on the cut get no interval, and say so
    for quantity in ("d_cut", "ep", "imperfection", "d25", "d75"):
        assert fits[f"{quantity}_low"].isna().all() and (fits[f"{quantity}_method"] == "none").all(), quantity
    for quantity in ("eta", "epsilon", "slope"):
        low, high, value = fits[f"{quantity}_low"], fits[f"{quantity}_high"], fits[quantity]
        made = low.notna() & high.notna()
        assert made.any(), quantity
        domain = quantity_domain(quantity)
        assert _inside(domain, low[made]).all() and _inside(domain, high[made]).all(), quantity
        assert ((low[made] <= value[made]) & (value[made] <= high[made])).all(), quantity
        assert fits.loc[made, f"{quantity}_method"].notna().all(), quantity
    assert (fits["eta_high"] <= 1.0).all()  # was 1.027
    assert (fits.loc[fits["formula"] == "plitt", "shape_low"] > 0).all()  # was -22.4
    averages = pd.read_csv(out / "averages.csv")
    made = averages["low"].notna()
    assert (averages.loc[made, "low"] > 0).all() and (averages.loc[averages["quantity"] == "eta", "high"] < 1).all()
    assert averages["method"].notna().all() and (averages["akaike_share"] <= 1).all()


def _experiment(seed: int, formula: str, n: int, shape: float, bypass: float = 0.0):
    rng = np.random.default_rng(seed)
    size = np.geomspace(5, 500, n)
    extras = {"bypass": bypass} if bypass else {}
    phi = tromplab.get_formula(formula)(size, 60.0, shape, **extras) + rng.normal(0, 0.02, n)
    return TrompPoints(f"{formula}-{seed}", size, np.clip(phi, 0.0, 1.0))


CASES = [
    ("plitt", 10, 3.0, 0.0, "plitt"),  # ordinary
    ("plitt", 5, 3.0, 0.0, "plitt"),  # few points
    ("plitt", 10, 25.0, 0.0, "plitt"),  # steep
    ("plitt", 10, 0.6, 0.0, "plitt"),  # flat
    ("plitt_bypass", 10, 3.0, 0.25, "plitt_bypass"),  # bypass
    ("lognormal", 6, 0.4, 0.0, "molerus_hoffmann"),  # a formula whose shape was fitted negative before
]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("truth, n, shape, bypass, fitted", CASES, ids=[f"{c[0]}-n{c[1]}-k{c[2]}-b{c[3]}" for c in CASES])
def test_every_interval_contains_its_estimate_and_stays_in_range(seed, truth, n, shape, bypass, fitted):
    fit = tromplab.fit_formula(_experiment(seed, truth, n, shape, bypass), fitted)
    if not fit.success:
        pytest.skip("the fit failed; nothing to bound")
    table = interval_table(fit, level=0.95, profile=False)
    assert table["method"].notna().all()
    for row in table.itertuples(index=False):
        if not (np.isfinite(row.low) and np.isfinite(row.high)):
            continue
        domain = quantity_domain(row.quantity, fit.formula, x_max=_x_max(fit))
        assert row.low <= row.value <= row.high, row
        assert _inside(domain, [row.low, row.high]).all(), row


def _x_max(fit) -> float:
    return fit.options.delta_max / fit.fit.values["d_cut"]


CURVES = {"plitt": (0.5, 30.0), "rosin_rammler": (0.5, 20.0), "lognormal": (0.03, 1.5), "plitt_bypass": (0.5, 30.0)}


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    formula=st.sampled_from(sorted(CURVES)),
    shape_position=st.floats(0.0, 1.0),
    n=st.integers(4, 14),
    bypass=st.floats(0.02, 0.5),
    noise=st.sampled_from([0.0, 0.005, 0.02, 0.06]),
    seed=st.integers(0, 2**16),
    delta_max_factor=st.sampled_from([1.0, 4.0, 1000.0]),
)
@pytest.mark.slow
def test_property_every_interval_contains_its_estimate_and_stays_in_range(
    formula, shape_position, n, bypass, noise, seed, delta_max_factor
):
    """Over generated experiments (few to many points, flat to sharp curves, bypass, exact to
    noisy data, delta_max at and far beyond the largest size): every parameter and index
    interval contains its estimate and lies inside the quantity's range, epsilon's within
    [0, x_max - 1] of its own fit."""
    low_shape, high_shape = CURVES[formula]
    shape = float(np.exp(np.log(low_shape) + shape_position * np.log(high_shape / low_shape)))
    rng = np.random.default_rng(seed)
    size = np.geomspace(5.0, 500.0, n)
    extras = {"bypass": bypass} if formula.endswith("bypass") else {}
    phi = np.clip(tromplab.get_formula(formula)(size, 60.0, shape, **extras) + rng.normal(0.0, noise, n), 0.0, 1.0)
    points = TrompPoints("generated", size, phi)
    fit = tromplab.fit_formula(points, formula, delta_max=500.0 * delta_max_factor)
    if not fit.success:
        return
    table = interval_table(fit, level=0.95, profile=False)
    assert table["method"].notna().all() and (table["method"] != "").all()
    for row in table.itertuples(index=False):
        domain = quantity_domain(row.quantity, fit.formula, x_max=_x_max(fit))
        if np.isfinite(row.value):
            assert _inside(domain, [row.value]).all(), row
        if np.isfinite(row.low) and np.isfinite(row.high):
            assert row.low <= row.value <= row.high, row
            assert _inside(domain, [row.low, row.high]).all(), row
        else:
            assert row.flag, row  # an interval that could not be made says so


def test_a_parameter_the_fit_does_not_determine_raises_no_numpy_warning(recwarn):
    """Hypothesis's example: a sharp lognormal of four points, whose covariance has a negative
    diagonal; lmfit's sqrt of it gave ``RuntimeWarning: invalid value encountered in sqrt``,
    which reached the console. The stderr is NaN and the interval says so instead."""
    size = np.geomspace(5.0, 500.0, 4)
    phi = np.clip(tromplab.get_formula("lognormal")(size, 60.0, 0.03) + np.random.default_rng(1).normal(0.0, 0.005, 4), 0, 1)
    fit = tromplab.fit_formula(TrompPoints("generated", size, phi), "lognormal", delta_max=500.0)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in recwarn]
    if fit.success:
        table = interval_table(fit, level=0.95, profile=False)
        missing = ~(np.isfinite(table["low"]) & np.isfinite(table["high"]))
        assert table.loc[missing, "flag"].astype(bool).all()


def test_epsilon_interval_stays_below_x_max_minus_one():
    """A flat curve with delta_max just above the cut: epsilon is close to its upper end
    x_max - 1 and a log-scale interval would pass it."""
    size = np.geomspace(5.0, 500.0, 8)
    rng = np.random.default_rng(7)
    phi = np.clip(tromplab.get_formula("plitt")(size, 300.0, 0.6) + rng.normal(0.0, 0.03, size.size), 0.0, 1.0)
    fit = tromplab.fit_formula(TrompPoints("flat", size, phi), "plitt", delta_max=500.0)
    table = interval_table(fit, level=0.95, profile=False).set_index("quantity")
    x_max = _x_max(fit)
    low, value, high = table.loc["epsilon", ["low", "value", "high"]]
    assert table.loc["epsilon", "method"] == "delta-logit"
    assert 0.0 < low <= value <= high < x_max - 1.0
    assert quantity_domain("epsilon", x_max=x_max).upper == pytest.approx(x_max - 1.0)


def test_averages_leave_out_a_quantity_the_favoured_formulas_lack():
    """With 80 % bypass the actual curve never reaches 1/4, so the favoured
    bypass curve has no actual cut or Ep; averaging the formulas that do (0.0001 % of the
    weight) would report a number the data do not support."""
    size = np.geomspace(5, 500, 12)
    rng = np.random.default_rng(3)
    phi = tromplab.get_formula("plitt_bypass")(size, 60.0, 3.0, bypass=0.8) + rng.normal(0, 0.005, size.size)
    points = TrompPoints("hydrocyclone", size, np.clip(phi, 0.0, 1.0))
    fits = [tromplab.fit_formula(points, formula) for formula in ("plitt_bypass", "plitt", "lognormal")]
    table = tromplab.statistics.uncertainty.model_average(fits).set_index("quantity")
    for missing in ("d50", "ep"):
        assert np.isnan(table.loc[missing, "value"]) and table.loc[missing, "akaike_share"] < 0.5
        assert "not averaged" in table.loc[missing, "note"]
    for present in ("d50c", "ep_c", "eta"):
        assert np.isfinite(table.loc[present, "value"]) and table.loc[present, "akaike_share"] > 0.99
    assert abs(table.loc["d50c", "value"] - 60.0) < 6.0


AVERAGED_FORMULAS = ("plitt", "rosin_rammler", "lognormal", "plitt_bypass")


@pytest.mark.slow
@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    truth=st.sampled_from(sorted(CURVES)),
    shape_position=st.floats(0.0, 1.0),
    n=st.integers(4, 12),
    bypass=st.floats(0.02, 0.6),
    noise=st.sampled_from([0.0, 0.01, 0.03, 0.06]),
    seed=st.integers(0, 2**16),
    delta_max_factor=st.sampled_from([1.0, 1.5, 100.0]),
)
def test_property_every_model_average_interval_contains_its_average_and_stays_in_range(
    truth, shape_position, n, bypass, noise, seed, delta_max_factor
):
    """Model averages over four formulas (one with bypass) of generated experiments: every
    averaged quantity's interval contains the average and lies inside its range (epsilon
    within [0, x_max - 1] of the widest of its fits), its Akaike share is a share, and an
    average left without an interval says why."""
    low_shape, high_shape = CURVES[truth]
    shape = float(np.exp(np.log(low_shape) + shape_position * np.log(high_shape / low_shape)))
    rng = np.random.default_rng(seed)
    size = np.geomspace(5.0, 500.0, n)
    extras = {"bypass": bypass} if truth.endswith("bypass") else {}
    phi = np.clip(tromplab.get_formula(truth)(size, 60.0, shape, **extras) + rng.normal(0.0, noise, n), 0.0, 1.0)
    points = TrompPoints("generated", size, phi)
    fits = [tromplab.fit_formula(points, formula, delta_max=500.0 * delta_max_factor) for formula in AVERAGED_FORMULAS]
    good = [fit for fit in fits if fit.success]
    if not good:
        return
    quantities = (*AVERAGED_QUANTITIES, "imperfection", "epsilon", "bypass")
    table = model_average(fits, quantities=quantities, level=0.95)
    x_max = max(_x_max(fit) for fit in good)
    assert ((table["akaike_share"] >= 0) & (table["akaike_share"] <= 1)).all()  # held in [0, 1] by construction
    for row in table.itertuples(index=False):
        domain = quantity_domain(row.quantity, x_max=x_max)
        if not np.isfinite(row.value):
            assert row.note, row  # an empty average says why
            continue
        assert _inside(domain, [row.value]).all(), row
        if np.isfinite(row.low) and np.isfinite(row.high):
            assert row.low <= row.value <= row.high, row
            assert _inside(domain, [row.low, row.high]).all(), row
            assert row.method.startswith("akaike-"), row
        else:
            assert row.note, row
