"""Full-size validation of tromplab.circuit: reconciliation and gross-error tests on simulated surveys.

For each simulated circuit of tromplab.circuit.simulation (the grinding circuit, the two-deck
screen and the bundled example plant), draws ``--surveys`` seeded surveys from the default
error model and reconciles each:

* closer to the truth: mean squared error of the reconciled against the measured shares;
* coverage: share of the 95 % intervals (reconciled value +/- 1.96 sd) of every reconciled
  share and flow holding the true value;
* chi-square test: share of surveys rejected at 5 %.

Gross errors: a 5-sd error planted in one of three product flowmeters (10 %; belt scale 1 %
on the feed) of the example plant, and 5-sd and 8-sd errors in one random share of one
random analysed stream of each circuit: how often the planted measurement is named first
(largest measurement test), and how often it is named first or among the
measurements the first is indistinguishable from.  Results are printed and written to
benchmarks/output/circuit_reconciliation.csv; docs/circuit.md states them.

    python benchmarks/circuit_reconciliation.py --surveys 1000
"""

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab.circuit import reconcile
from tromplab.circuit.simulation import example_plant, grinding_circuit, reconciliation_study, simulate_survey, two_deck_screen

CIRCUITS = {
    "grinding circuit": (grinding_circuit, {"fresh_feed": 0.02}),
    "two-deck screen": (two_deck_screen, {}),
    "example plant": (example_plant, {"screen_feed": 0.02}),
}
FLOWMETERS = {"screen_feed": 0.01, "oversize": 0.10, "middlings": 0.10, "cyclone_overflow": 0.10}


def null_study(name: str, n_surveys: int, seed: int) -> dict:
    make, flows = CIRCUITS[name]
    study = reconciliation_study(make(), n_surveys, np.random.default_rng(seed), flows=flows)
    return {
        "study": "no gross error",
        "circuit": name,
        "surveys": n_surveys,
        "dof": study.dof,
        "mse_reconciled_over_measured": study.reconciled_error / study.measured_error,
        "coverage_95": study.coverage,
        "chi_square_rejection_5pct": study.rejection_rate,
    }


def _named(balance, stream: str, klass: int) -> tuple[bool, bool]:
    table = balance.adjustments_table().dropna(subset=["measurement_test"])
    first = table.loc[table["measurement_test"].abs().idxmax()]
    planted = f"{stream} flow" if klass < 0 else None
    hit = first["stream"] == stream and first["class_index"] == klass
    if planted is None:
        match = table[(table["stream"] == stream) & (table["class_index"] == klass)]
        planted = match["measurement"].iloc[0] if len(match) else ""
    group = hit or planted in first["indistinguishable_from"].split("; ")
    return bool(hit), bool(group)


def flowmeter_study(n_surveys: int, seed: int, size: float = 5.0) -> dict:
    truth = example_plant()
    rng = np.random.default_rng(seed)
    hits = groups = 0
    for _ in range(n_surveys):
        stream = ("oversize", "middlings", "cyclone_overflow")[rng.integers(3)]
        balance = reconcile(
            truth.flowsheet, simulate_survey(truth, rng, flows=FLOWMETERS, gross=(stream, -1, size * rng.choice([-1, 1])))
        )
        hit, group = _named(balance, stream, -1)
        hits += hit
        groups += group
    return {"study": f"{size:g}-sd error in a product flowmeter (10 %)", "circuit": "example plant", "surveys": n_surveys,
            "named_first": hits / n_surveys, "named_first_or_indistinguishable": groups / n_surveys}  # fmt: skip


def share_study(name: str, n_surveys: int, seed: int, size: float) -> dict:
    make, flows = CIRCUITS[name]
    truth = make()
    rng = np.random.default_rng(seed)
    measured = [s for s in truth.flowsheet.stream_names if not s.endswith("_deck_undersize")]
    hits = groups = 0
    for _ in range(n_surveys):
        stream = measured[rng.integers(len(measured))]
        klass = int(rng.integers(len(truth.classes)))
        survey = simulate_survey(truth, rng, flows=flows, gross=(stream, klass, size * rng.choice([-1, 1])))
        hit, group = _named(reconcile(truth.flowsheet, survey), stream, klass)
        hits += hit
        groups += group
    return {"study": f"{size:g}-sd error in one random share", "circuit": name, "surveys": n_surveys,
            "named_first": hits / n_surveys, "named_first_or_indistinguishable": groups / n_surveys}  # fmt: skip


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--surveys", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--output", type=Path, default=Path(__file__).resolve().parent / "output" / "circuit_reconciliation.csv")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    rows = [null_study(name, args.surveys, args.seed + k) for k, name in enumerate(CIRCUITS)]
    rows.append(flowmeter_study(args.surveys, args.seed + 10))
    for k, name in enumerate(CIRCUITS):
        for size in (5.0, 8.0):
            rows.append(share_study(name, max(args.surveys // 2, 1), args.seed + 20 + k, size))
    table = pd.DataFrame(rows)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.output, index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"\n{time.perf_counter() - start:.0f} s; written to {args.output}")
    return table


if __name__ == "__main__":
    main()
