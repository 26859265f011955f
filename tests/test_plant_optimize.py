"""``tromplab plant optimize``: the cuts of the most clean coal at a contract ash, checked against a brute-force grid.

The grid search here evaluates the clean coal and ash mass of every size fraction at cut densities every
0.005 g/cm3 (normal curves through scipy.stats.norm, the partition read at the fraction midpoints), forms
every combination of cuts and keeps the best yield whose ash is at most the target: independent of the
package's optimiser.
"""

from __future__ import annotations

import filecmp

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose
from scipy.stats import norm

from tromplab.cli import main
from tromplab.errors import OptionError
from tromplab.plant import optimize, predict

from .conftest import DATASETS

WASH = DATASETS / "plant_washability_synthetic.csv"
DEVICES = DATASETS / "plant_devices_synthetic.csv"
Z75 = norm.ppf(0.75)
STEP = 0.005


def _grid_masses(wash: pd.DataFrame, name: str, cuts: np.ndarray, ep_of) -> tuple[np.ndarray, np.ndarray]:
    rows = wash[wash["size_fraction"] == name]
    density = ((rows["density_lower"] + rows["density_upper"]) / 2).to_numpy()
    floats = 1 - norm.cdf(Z75 * (density[None, :] - cuts[:, None]) / ep_of(cuts)[:, None])
    clean = rows["mass_pct"].to_numpy() * floats
    return clean.sum(axis=1), clean @ rows["ash_pct"].to_numpy()


def _brute_force(wash: pd.DataFrame, plant: pd.DataFrame, target: float) -> float:
    """The best plant yield over every combination of grid cuts whose clean-coal ash is at most ``target``."""
    shares = wash.groupby("size_fraction", sort=False)["fraction_pct"].first() / 100
    yields, ashes = np.zeros(1), np.zeros(1)
    for row in plant.itertuples():
        cuts = np.arange(row.rho50_min, row.rho50_max + 1e-9, STEP)
        if np.isfinite(getattr(row, "imperfection", np.nan)):
            ep_of = lambda c, i=row.imperfection: i * (c - 1)  # noqa: E731
        else:
            ep_of = lambda c, e=row.ep: np.full_like(c, e)  # noqa: E731
        clean, ash = _grid_masses(wash, row.size_fraction, cuts, ep_of)
        yields = (yields[:, None] + shares[row.size_fraction] * clean[None, :]).ravel()
        ashes = (ashes[:, None] + shares[row.size_fraction] * ash[None, :]).ravel()
    feasible = ashes <= target * yields
    return float(yields[feasible].max())


@pytest.mark.parametrize("target", [8.0, 10.0, 12.0])
def test_the_optimum_reaches_the_brute_force_grid_and_has_equal_incremental_ash(target):
    wash, plant = pd.read_csv(WASH, comment="#"), pd.read_csv(DEVICES, comment="#")
    result = optimize(WASH, DEVICES, target_ash_pct=target, draws=0)
    cuts = result.cuts.set_index("size_fraction")
    total = cuts.loc["total"]
    assert total["clean_yield_pct"] >= _brute_force(wash, plant, target) - 0.02
    assert total["clean_ash_pct"] <= target + 1e-3
    interior = cuts.drop(index="total")
    interior = interior[interior["bound"].fillna("") == ""]
    assert len(interior) >= 2
    assert np.ptp(interior["incremental_ash_pct"]) < 0.5
    # the products written with the cuts are plant predict's at those cuts
    at_cuts = predict(WASH, plant.assign(rho50=interior_and_bound_cuts(cuts)), draws=0).products.set_index("size_fraction")
    assert_allclose(at_cuts["clean_yield_pct"], cuts["clean_yield_pct"], rtol=1e-9)
    assert_allclose(result.prediction.products["clean_yield_pct"], cuts["clean_yield_pct"].to_numpy(), rtol=1e-9)


def interior_and_bound_cuts(cuts: pd.DataFrame) -> list:
    return cuts.drop(index="total")["rho50"].tolist()


def test_the_incremental_ash_is_the_derivative_of_ash_mass_by_clean_mass():
    """At each fraction's cut, dM/dY by a central difference of the direct computation (step 1e-4)."""
    wash = pd.read_csv(WASH, comment="#")
    cuts = optimize(WASH, DEVICES, target_ash_pct=10, draws=0).cuts.set_index("size_fraction")
    for name, ep in (("50x12mm", 0.025), ("12x1mm", 0.04)):
        cut = cuts.loc[name, "rho50"]
        clean, ash = _grid_masses(wash, name, np.array([cut - 1e-4, cut + 1e-4]), lambda c, e=ep: np.full_like(c, e))
        assert_allclose(cuts.loc[name, "incremental_ash_pct"], (ash[1] - ash[0]) / (clean[1] - clean[0]), rtol=1e-4)


def test_a_target_below_the_lowest_reachable_ash_is_refused_naming_it():
    with pytest.raises(OptionError, match=r"below the lowest clean-coal ash the plant reaches, 5\.4\d* %"):
        optimize(WASH, DEVICES, target_ash_pct=3, draws=0)


def test_a_target_above_the_highest_cuts_leaves_them_at_their_bounds():
    cuts = optimize(WASH, DEVICES, target_ash_pct=40, draws=0).cuts
    assert (cuts["bound"].iloc[:-1] == "max").all() and np.isnan(cuts["incremental_ash_pct"].iloc[-1])


@pytest.mark.slow
def test_the_confidence_keeps_the_ash_within_the_target_with_that_probability():
    plain = optimize(WASH, DEVICES, target_ash_pct=10, draws=400, seed=1).cuts.iloc[-1]
    sure = optimize(WASH, DEVICES, target_ash_pct=10, confidence=0.9, draws=400, seed=1)
    total = sure.cuts.iloc[-1]
    assert total["target_met_probability"] >= 0.9 and plain["target_met_probability"] < 0.9
    assert total["clean_yield_pct"] < plain["clean_yield_pct"] and sure.design_ash_pct < 10
    with pytest.raises(OptionError, match="confidence"):
        optimize(WASH, DEVICES, target_ash_pct=10, confidence=0.9, draws=0)


@pytest.mark.slow
def test_the_command_writes_what_the_api_saves(tmp_path, capsys):
    command = ["plant", "optimize", str(WASH), str(DEVICES), "--target-ash", "10", "--draws", "200", "-o", str(tmp_path / "cli")]
    assert main(command) == 0
    capsys.readouterr()
    written = optimize(WASH, DEVICES, target_ash_pct=10, draws=200).save(tmp_path / "api")
    assert "cuts.csv" in written and "products.csv" in written
    assert sorted(written) == sorted(p.name for p in (tmp_path / "cli").iterdir() if not p.name.startswith("."))
    for name in written:
        assert filecmp.cmp(tmp_path / "cli" / name, tmp_path / "api" / name, shallow=False), name
    assert main(["plant", "optimize", str(WASH), str(DEVICES), "--target-ash", "3", "-o", str(tmp_path / "x")]) == 2
    assert "--target-ash 3 % is below the lowest" in capsys.readouterr().err


@pytest.mark.slow
def test_progress_is_one_bar_that_ends_full():
    for confidence in (None, 0.9):
        calls: list = []
        optimize(
            WASH,
            DEVICES,
            target_ash_pct=10,
            confidence=confidence,
            draws=200,
            progress=lambda *call, seen=calls: seen.append(call),
        )
        done = [call[0] for call in calls]
        assert done == sorted(done) and len({call[1] for call in calls}) == 1 and done[-1] == calls[-1][1]


@pytest.mark.parametrize("target", [9.0, 11.0])
def test_sharp_curves_keep_a_finite_equal_incremental_ash_and_reach_the_grid(target):
    """Ep 0.005 on fractions 0.05 to 0.6 wide: the marginal coal's ash is a ratio of derivatives of order 1e-30,
    computed in logarithms (the spec's formula, sum m a p' / sum m p', with norm.pdf weights rescaled here too)."""
    wash = pd.read_csv(WASH, comment="#")
    plant = pd.read_csv(DEVICES, comment="#").assign(ep=0.005, imperfection=np.nan, imperfection_sd=np.nan)
    cuts = optimize(WASH, plant, target_ash_pct=target, draws=0).cuts.set_index("size_fraction")
    assert cuts.loc["total", "clean_yield_pct"] >= _brute_force(wash, plant, target) - 0.02
    assert cuts.loc["total", "clean_ash_pct"] <= target + 1e-3
    for name in ("50x12mm", "12x1mm", "1x0.15mm"):
        rows = wash[wash["size_fraction"] == name]
        density = ((rows["density_lower"] + rows["density_upper"]) / 2).to_numpy()
        log_pdf = norm.logpdf(Z75 * (density - cuts.loc[name, "rho50"]) / 0.005)
        weight = rows["mass_pct"].to_numpy() * np.exp(log_pdf - log_pdf.max())
        assert_allclose(cuts.loc[name, "incremental_ash_pct"], np.sum(weight * rows["ash_pct"]) / np.sum(weight), rtol=1e-9)
    interior = cuts.drop(index="total")
    interior = interior[interior["bound"].fillna("") == ""]
    assert len(interior) >= 2 and np.ptp(interior["incremental_ash_pct"]) < 0.5


@pytest.mark.parametrize("curve", ["normal", "logistic", "gompertz"])
@pytest.mark.parametrize("scale", ["ep", "imperfection"])
def test_the_analytic_incremental_ash_equals_central_differences(curve, scale):
    from tromplab.plant import read_plant, read_plant_washability
    from tromplab.plant.optimization import CutResponse

    fractions = read_plant_washability(WASH)
    plant = pd.read_csv(DEVICES, comment="#").assign(curve=curve)
    if scale == "ep":
        plant = plant.assign(ep=0.06, imperfection=np.nan, imperfection_sd=np.nan)
    else:
        plant = plant.assign(ep=np.nan, ep_sd=np.nan, imperfection=0.1)
    devices = read_plant(plant, fractions)
    for fraction, device in zip(fractions, devices):
        response = CutResponse(fraction, device, np.zeros(1), np.array([device.scale]), 1.3, 2.0)
        for cut in (1.45, 1.6, 1.75):
            assert_allclose(response.incremental_ash(cut), response._incremental_ash_by_differences(cut), rtol=1e-5)
