"""Which weighting of Tromp points gives the smallest error of the cut and Ep?

Simulated one-hydrocyclone surveys as a lab reports them (drawn from the error model, shares
clipped at 0, rounded to 0.01 %, read back through ``read_survey``:
:func:`tromplab.circuit.simulation.lab_survey`), reconciled, and fitted with each weighting:

- ``none``: every class alike (the lab path's default);
- ``feed-share``: the class's feed share;
- ``reconciled``: 1 / sd^2 of the reconciled partition (the circuit path before the weighting
  module: the delta-method sd of the reconciliation);
- ``error-model tau=...``: :func:`tromplab.loading.weights.partition_weights` with the
  partition floor tau (0: the error model alone).

The floor of the ``error-model`` weighting (:data:`tromplab.options.DEFAULT_PARTITION_FLOOR`)
is the one with the smallest worst ratio of its RMSE to the best weighting's over the truths,
formulas and the two indices (the ``regret`` table).

Truths: Plitt's corrected curve (the registry's ``rosin_rammler_bypass``, d50c 100 um, m 2.5)
without and with a bypass of 15 % to the coarse product, on eight classes (pan to +300 um) of
a Rosin-Rammler feed (d63 150 um, n 1); fitted with the formula of the truth and with Plitt's
curve without bypass (``plitt``: misspecified when there is a bypass, as a plant curve often
is for the formula fitted).  Reported: the root-mean-square relative error (%) of the fitted
cut d50 and Ep of the actual curve against the truth's, and the median share of the total
weight on the two heaviest classes.

Also the textbook hydrocyclone table of the tests (``tests/data/hydrocyclone_size_class_um.csv``)
as a one-node survey: the share of the weight on its two heaviest classes and the cut and Ep of
three formulas fitted with the former weights and with the default, against the unweighted
fit of the lab path.

Usage: ``OPENBLAS_NUM_THREADS=1 python benchmarks/circuit_weights.py --surveys 200 --seed 2026``
(``--surveys 0``: the textbook table only).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import time
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab import TrompPoints, curve_indices, fit_formula
from tromplab.circuit import read_flowsheet, reconcile
from tromplab.circuit.simulation import (
    CircuitTruth,
    classes_from_edges,
    lab_survey,
    plitt_partition_to_fines,
    rosin_rammler_shares,
)
from tromplab.loading.lab import read_lab
from tromplab.loading.weights import partition_weights, scaled_to_mean_one, weight_concentration

TEXTBOOK = Path(__file__).resolve().parent.parent / "tests" / "data" / "hydrocyclone_size_class_um.csv"

EDGES = [38, 53, 75, 106, 150, 212, 300]
D50C, SHAPE = 100.0, 2.5
FLOORS = (0.0, 0.01, 0.02, 0.03, 0.05, 0.1)
SHEET = pd.DataFrame(
    {
        "stream": ["feed", "overflow", "underflow"],
        "from": ["", "cyclone", "cyclone"],
        "to": ["cyclone", "", ""],
        "product": ["", "fine", "coarse"],
    }
)


def cyclone(bypass: float) -> CircuitTruth:
    """One hydrocyclone: its feed, overflow (fine) and underflow (coarse), eight classes."""
    classes = classes_from_edges(EDGES)
    phi = plitt_partition_to_fines(classes["size"], D50C, SHAPE, bypass=bypass)
    feed = 100.0 * rosin_rammler_shares(EDGES, 150.0, 1.0)
    flows = np.vstack([feed, feed * phi, feed * (1.0 - phi)])
    return CircuitTruth(flowsheet=read_flowsheet(SHEET), classes=classes, class_flows=flows, partitions={"cyclone": phi})


def weightings(part: pd.DataFrame) -> dict:
    """The weights of every weighting studied, for the partition table of one separator."""
    used = part["used"].to_numpy()
    phi, share = part["partition_fine"].to_numpy(), part["feed_share"].to_numpy()
    y = float(part["fine_yield"].iloc[0])
    sd = part["partition_sd"].to_numpy()
    found = {
        "none": None,
        "feed-share": partition_weights("feed-share", phi, share, y, used),
        "reconciled": scaled_to_mean_one(1.0 / np.maximum(sd, 1e-12) ** 2, used),
    }
    for floor in FLOORS:
        found[f"error-model tau={floor:g}"] = partition_weights("error-model", phi, share, y, used, floor=floor)
    return found


def study(n_surveys: int, seed: int) -> pd.DataFrame:
    rows = []
    for bypass, formulas in ((0.0, ("rosin_rammler", "plitt")), (0.15, ("rosin_rammler_bypass", "plitt"))):
        truth = cyclone(bypass)
        true = curve_indices("rosin_rammler_bypass", D50C, SHAPE, delta_max=600.0, bypass=bypass)
        rng = np.random.default_rng(seed)
        for _ in range(n_surveys):
            balance = reconcile(truth.flowsheet, lab_survey(truth, rng))
            part = balance.partition_table()
            used = part["used"].to_numpy()
            for name, weight in weightings(part).items():
                points = TrompPoints(
                    experiment="cyclone",
                    size=part["size"].to_numpy()[used],
                    partition_fine=part["partition_fine"].to_numpy()[used],
                    weight=None if weight is None else weight[used],
                )
                top_two = weight_concentration(weight).share if weight is not None else 2 / used.sum()
                for formula in formulas:
                    fit = fit_formula(points, formula, delta_max=600.0)
                    if not fit.success:
                        continue
                    rows.append(
                        {
                            "truth": f"bypass {bypass:g}",
                            "formula": formula,
                            "weighting": name,
                            "d50_error_pct": 100.0 * (fit.indices.d50 / true.d50 - 1.0),
                            "ep_error_pct": 100.0 * (fit.indices.ep / true.ep - 1.0),
                            "top_two_share": top_two,
                        }
                    )
    return pd.DataFrame(rows)


def summary(results: pd.DataFrame) -> pd.DataFrame:
    def rms(values):
        return float(np.sqrt(np.mean(np.square(values))))

    grouped = results.groupby(["truth", "formula", "weighting"], sort=False)
    return grouped.agg(
        fits=("d50_error_pct", "size"),
        d50_rmse_pct=("d50_error_pct", rms),
        d50_bias_pct=("d50_error_pct", "mean"),
        ep_rmse_pct=("ep_error_pct", rms),
        ep_bias_pct=("ep_error_pct", "mean"),
        top_two_median=("top_two_share", "median"),
    ).round(2)


def textbook() -> pd.DataFrame:
    """The textbook table: cut and Ep per formula, unweighted (lab path), former and default weights."""
    lab = pd.read_csv(TEXTBOOK, comment="#")
    survey = pd.concat(
        [
            pd.DataFrame({"stream": stream, "size_class_um": lab["size_class_um"], "retained_pct": lab[f"{stream}_pct"]})
            for stream in ("feed", "overflow", "underflow")
        ],
        ignore_index=True,
    )
    sheet = "stream,from,to,product\nfeed,,cyclone,\noverflow,cyclone,,fine\nunderflow,cyclone,,coarse\n"
    balance = reconcile(pd.read_csv(io.StringIO(sheet)), survey)
    (default,) = balance.to_points()
    part = balance.partition_table()
    former = scaled_to_mean_one(1.0 / part["partition_sd"].to_numpy() ** 2, part["used"].to_numpy())
    ordered = TrompPoints(experiment="cyclone", size=part["size"].to_numpy(), partition_fine=part["partition_fine"].to_numpy(),
                          weight=former)  # fmt: skip
    (unweighted,) = read_lab(TEXTBOOK)
    rows = []
    for formula in ("plitt", "rosin_rammler", "logistic"):
        fits = {
            "unweighted": fit_formula(unweighted.to_points(), formula),
            "former": fit_formula(dataclasses.replace(default, weight=ordered.weight), formula),
            "default": fit_formula(default, formula),
        }
        base = fits["unweighted"].indices
        for name, fit in fits.items():
            rows.append({"formula": formula, "weights": name, "d50_um": fit.indices.d50, "ep_um": fit.indices.ep,
                         "d50_change_pct": 100 * (fit.indices.d50 / base.d50 - 1),
                         "ep_change_pct": 100 * (fit.indices.ep / base.ep - 1)})  # fmt: skip
    print(
        "textbook table, share of the weight on the two heaviest classes: "
        f"former {weight_concentration(former).share:.2f}, default {weight_concentration(default.weight).share:.2f}"
    )
    return pd.DataFrame(rows).round(2)


def regret(table: pd.DataFrame) -> pd.DataFrame:
    """Per weighting, the RMSE of each (truth, formula, d50 or Ep) over the smallest RMSE any
    weighting reached there: the largest and the geometric mean of these ratios (1 = always
    the best), and the plain mean of the RMSEs."""
    cells = table[["d50_rmse_pct", "ep_rmse_pct"]].unstack("weighting")
    ratios = {}
    for column in ("d50_rmse_pct", "ep_rmse_pct"):
        block = cells[column]
        ratios[column] = block.div(block.min(axis=1), axis=0)
    ratio = pd.concat(ratios.values())
    rmse = pd.concat([cells["d50_rmse_pct"], cells["ep_rmse_pct"]])
    return pd.DataFrame(
        {
            "worst_ratio": ratio.max(),
            "geometric_mean_ratio": np.exp(np.log(ratio).mean()),
            "mean_rmse_pct": rmse.mean(),
        }
    ).round(3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--surveys", type=int, default=500)
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    started = time.perf_counter()
    with pd.option_context("display.width", 200):
        print(textbook().to_string(index=False), "\n")
    if args.surveys < 1:
        return
    results = study(args.surveys, args.seed)
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        table = summary(results)
        print(table.to_string())
        print("\nAgainst the best weighting of each truth, formula and index:")
        print(regret(table).to_string())
    print(f"\n{args.surveys} surveys per truth, seed {args.seed}, {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
