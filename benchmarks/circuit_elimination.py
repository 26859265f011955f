"""Detection power and false alarms of the circuit's gross-error identification.

For each simulated circuit (the grinding circuit, the two-deck screen, the example plant),
each with several flowmeters, ``--surveys`` surveys without a gross error and ``--surveys``
with one planted gross error of ``--size`` sd (half of them in a flowmeter, half in one
class holding at least 2 % of an analysed stream; random sign), all as a lab reports them
(clipped at 0, rounded, read through read_survey; tromplab.circuit.simulation.lab_survey),
reconciled with the default error model (evaluated at the reconciled values):

* measurement test (the generalised likelihood ratio): the planted measurement has the
  largest test (named first), or is among those the first is indistinguishable from;
* serial elimination with compensation (elimination.csv): the planted measurement (or its
  group) is compensated at step 1, at any step, and the last step passes the global test;
* false alarms: without a gross error, the share of surveys in which serial elimination
  proposes anything (the global test's size) and the average number of measurements it
  names (AVTI); with one, the average number of other measurements it names.

    OPENBLAS_NUM_THREADS=1 python benchmarks/circuit_elimination.py --surveys 1000

(``--circuit NAME`` runs one circuit, seeded as in the full run, so the circuits can run side by side.)

Results are printed and written to benchmarks/output/circuit_elimination.csv; docs/circuit.md
states them.
"""

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab.circuit import reconcile
from tromplab.circuit.simulation import example_plant, grinding_circuit, lab_survey, two_deck_screen

#: Circuits and their flowmeters (relative sd): the first a belt scale, the others product meters.
CIRCUITS = {
    "grinding circuit": (grinding_circuit, {"fresh_feed": 0.02, "cyclone_overflow": 0.05}),
    "two-deck screen": (two_deck_screen, {"screen_feed": 0.01, "oversize": 0.05, "middlings": 0.05, "undersize": 0.05}),
    "example plant": (example_plant, {"screen_feed": 0.01, "oversize": 0.05, "middlings": 0.05, "cyclone_overflow": 0.05}),
}


def _names(steps: pd.DataFrame, measurement: str) -> tuple[bool, bool, int]:
    """(named at step 1, named at any step, number of other measurements named)."""
    named = steps.iloc[1:]
    hits = [measurement == r.measurement or measurement in str(r.indistinguishable_from).split("; ") for r in named.itertuples()]
    return bool(hits[:1] == [True]), any(hits), int(len(hits) - sum(hits))


def study(name: str, n_surveys: int, seed: int, size: float) -> list[dict]:
    make, flows = CIRCUITS[name]
    truth = make()
    rng = np.random.default_rng(seed)
    streams = [s for s in truth.flowsheet.stream_names if not s.endswith("_deck_undersize")]
    classes = [
        (s, k) for s in streams for k in range(len(truth.classes)) if truth.shares[truth.flowsheet.stream_index[s], k] >= 0.02
    ]
    meters = [s for s, relative in flows.items() if relative >= 0.05]
    null = {"proposes": 0, "named": 0}
    planted = {"first": 0, "group": 0, "step1": 0, "any": 0, "passes": 0, "others": 0}
    for _ in range(n_surveys):
        balance = reconcile(truth.flowsheet, lab_survey(truth, rng, flows=flows))
        steps = balance.elimination_table()
        null["proposes"] += len(steps) > 1
        null["named"] += len(steps) - 1
        sign = rng.choice([-1.0, 1.0])
        if rng.random() < 0.5:
            stream, klass = meters[rng.integers(len(meters))], -1
        else:
            stream, klass = classes[rng.integers(len(classes))]
        balance = reconcile(truth.flowsheet, lab_survey(truth, rng, flows=flows, gross=(stream, klass, size * sign)))
        table = balance.adjustments_table().dropna(subset=["measurement_test"])
        rows = table[(table["stream"] == stream) & (table["class_index"] == klass)]
        measurement = rows["measurement"].iloc[0] if len(rows) else ""
        first = table.loc[table["measurement_test"].abs().idxmax()] if len(table) else None
        if first is not None:
            planted["first"] += first["measurement"] == measurement
            planted["group"] += first["measurement"] == measurement or measurement in first["indistinguishable_from"].split("; ")
        steps = balance.elimination_table()
        step1, anywhere, others = _names(steps, measurement)
        planted["step1"] += step1
        planted["any"] += anywhere
        planted["passes"] += (
            len(steps) > 1 and np.isfinite(steps.iloc[-1]["p_value"]) and steps.iloc[-1]["p_value"] > balance.alpha
        )
        planted["others"] += others
    n = n_surveys
    return [
        {"circuit": name, "case": "no gross error", "surveys": n, "elimination_proposes": null["proposes"] / n,
         "avti_elimination": null["named"] / n},
        {"circuit": name, "case": f"{size:g}-sd gross error (flowmeter or one class)", "surveys": n,
         "measurement_test_named_first": planted["first"] / n, "measurement_test_first_or_group": planted["group"] / n,
         "elimination_step_1": planted["step1"] / n, "elimination_any_step": planted["any"] / n,
         "elimination_last_step_passes": planted["passes"] / n, "avti_elimination": planted["others"] / n},
    ]  # fmt: skip


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--surveys", type=int, default=1000)
    parser.add_argument("--size", type=float, default=8.0)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--circuit", choices=sorted(CIRCUITS), action="append", help="only these circuits (default: all)")
    parser.add_argument("--output", type=Path, default=Path(__file__).resolve().parent / "output" / "circuit_elimination.csv")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    rows = []
    for k, name in enumerate(CIRCUITS):
        if args.circuit and name not in args.circuit:
            continue
        rows += study(name, args.surveys, args.seed + k, args.size)
        print(rows[-2], rows[-1], sep="\n", flush=True)
    table = pd.DataFrame(rows)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.output, index=False)
    with pd.option_context("display.width", 250, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"\n{time.perf_counter() - start:.0f} s; written to {args.output}")
    return table


if __name__ == "__main__":
    main()
