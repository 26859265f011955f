"""Which side do the plant's intervals miss on?  Percentile and bias-corrected percentile intervals on the same draws.

The bundled plant's devices are the truth (as in ``benchmarks/plant_coverage.py``). ``--plants`` simulated tracer
tests of every device are written to one CSV file and fitted at once as ``tromplab density fit`` does (each test is
fitted on its own; the batch only stacks the arithmetic); each simulated plant's curves, with their covariance, are
drawn as ``plant predict`` draws them (``tromplab.plant.draws.parameter_draws``), and its clean yield and ash - per
size fraction and blended - are computed for every draw with the definitions of ``tromplab.plant.products``. From
the same draws: the percentile interval ``plant predict`` reports and the bias-corrected percentile interval
(Efron & Tibshirani 1993, sec. 14.3, the BCa interval without acceleration), which was tried and not adopted
(docs/plant.md, Validation). Printed per
quantity: the coverage of each, the share of true values above and below each interval, the mean z0 of the draws,
how the fits' Wald standard deviations compare with the spread of the estimates, and the bias of the fitted
slopes.

Usage: ``python benchmarks/plant_interval_tails.py [--plants 1000] [--draws 1000] [--seed 11]`` (a few minutes).
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.special import ndtr, ndtri

from tromplab.density.covariance import covariance_table
from tromplab.density.results import fit_density
from tromplab.plant import read_plant, read_plant_washability
from tromplab.plant.draws import parameter_draws
from tromplab.plant.inputs import Device
from tromplab.plant.simulation import tracer_tests

DATASETS = Path(__file__).resolve().parent.parent / "datasets"


def _yield_and_ash(fractions, devices, parameters) -> dict:
    """Clean yield and ash of each size fraction and of the plant for every draw (tromplab.plant.products' definitions)."""
    values, plant_clean, plant_ash = {}, 0.0, 0.0
    for fraction, device, (rho50, scale) in zip(fractions, devices, parameters):
        washability = fraction.washability
        sinks = device.partition(washability.density[None, :], rho50[:, None], scale[:, None])
        clean = washability.mass_pct[None, :] * (1.0 - sinks)
        clean_mass, ash_mass = clean.sum(axis=1), clean @ washability.ash_pct
        values[(fraction.name, "clean_yield_pct")], values[(fraction.name, "clean_ash_pct")] = clean_mass, ash_mass / clean_mass
        plant_clean = plant_clean + fraction.feed_pct / 100 * clean_mass
        plant_ash = plant_ash + fraction.feed_pct / 100 * ash_mass
    values[("total", "clean_yield_pct")], values[("total", "clean_ash_pct")] = plant_clean, plant_ash / plant_clean
    return values


def _bias_corrected(draws: np.ndarray, estimate: float, ci: float) -> np.ndarray:
    """The bias-corrected percentile interval: the draws' quantiles Phi(2 z0 -/+ z), z0 = Phi^-1(share below the estimate)."""
    below = np.clip(np.mean(draws < estimate), 0.5 / draws.size, 1 - 0.5 / draws.size)
    z0, z = ndtri(below), ndtri((1 + ci) / 2)
    return np.quantile(draws, ndtr(np.array([2 * z0 - z, 2 * z0 + z])))


def _fitted_devices(truth, fits: pd.DataFrame, covariance: pd.DataFrame, plant: int) -> list[Device]:
    devices = []
    for device in truth:
        test = f"{device.size_fraction}_{plant}"
        row = fits.loc[test]
        matrix = covariance[covariance["test"] == test].set_index("parameter").loc[["rho50", "ep"], ["rho50", "ep"]]
        devices.append(Device(device.size_fraction, device.device, device.curve, float(row["rho50"]), "ep", float(row["ep"]),
                              matrix.to_numpy(float)))  # fmt: skip
    return devices


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plants", type=int, default=1000)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    fractions = read_plant_washability(DATASETS / "plant_washability_synthetic.csv")
    truth = read_plant(DATASETS / "plant_devices_synthetic.csv", fractions)
    exact = [(np.array([d.rho50]), np.array([d.scale])) for d in truth]  # each in its own scale (Ep, or I)
    true_values = {key: value[0] for key, value in _yield_and_ash(fractions, truth, exact).items()}
    rng = np.random.default_rng(args.seed)
    tests = [tracer_tests(truth, rng).assign(test=lambda t, k=k: t["test"] + f"_{k}") for k in range(args.plants)]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "tracers.csv"
        pd.concat(tests, ignore_index=True).to_csv(path, index=False)
        result = fit_density(path, curves="normal")
    fits, covariance = result.fits_table().set_index("test"), covariance_table(result.fits, sizes=False)
    rows = []
    for plant in range(args.plants):
        devices = _fitted_devices(truth, fits, covariance, plant)
        for key, values in _yield_and_ash(fractions, devices, parameter_draws(devices, args.draws, seed=plant)).items():
            estimate, draws, true = values[0], values[1:], true_values[key]
            plain = np.quantile(draws, [0.025, 0.975])  # as tromplab.plant.draws.percentile_interval
            corrected = _bias_corrected(draws, estimate, 0.95)
            rows.append({"size_fraction": key[0], "quantity": key[1], "z0": ndtri(np.clip(np.mean(draws < estimate), 1e-6, 1 - 1e-6)),
                         "plain_above": true > plain[1], "plain_below": true < plain[0],
                         "corrected_above": true > corrected[1], "corrected_below": true < corrected[0]})  # fmt: skip
    table = pd.DataFrame(rows).groupby(["size_fraction", "quantity"], sort=False).mean()
    for kind in ("plain", "corrected"):
        table[f"{kind}_coverage"] = 1 - table[f"{kind}_above"] - table[f"{kind}_below"]
    with pd.option_context("display.width", 200):
        print(table.to_string(float_format=lambda v: f"{v:.4f}"))
    for device in truth:
        mine = fits[fits.index.str.startswith(f"{device.size_fraction}_")]
        wald = covariance[covariance["test"].isin(mine.index)].set_index(["test", "parameter"])
        sd = {name: np.sqrt(wald.xs(name, level="parameter")[name]).mean() for name in ("rho50", "ep")}
        slope, true_slope = device.curve.form.scale / mine["ep"], device.curve.form.scale / float(device.ep_at(device.rho50))
        print(f"{device.size_fraction}: spread / mean Wald sd of rho50 {mine['rho50'].std() / sd['rho50']:.3f}, "
              f"of Ep {mine['ep'].std() / sd['ep']:.3f}; bias of the slope k/Ep {(slope.mean() - true_slope) / slope.std():+.3f} "
              "of its sd")  # fmt: skip
    print(f"{args.plants} plants, {args.draws} draws, seed {args.seed}: {time.perf_counter() - start:.0f} s")
    return table


if __name__ == "__main__":
    main()
