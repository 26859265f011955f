"""Test sizes and detection rates of tromplab.circuit on surveys as a lab reports them.

Every survey is drawn from the stated error model (tromplab.circuit.simulation.simulate_survey),
written as a measurement table with the shares clipped at 0 and rounded to 0.01 % and read
back through tromplab.circuit.read_survey (simulation.lab_survey), then reconciled with the
error model evaluated at the measured values and at the reconciled values (iterated):

* no gross error: the share of surveys the global chi-square test rejects at 5 % (its size),
  the coverage of the 95 % intervals of the reconciled shares and flows, and the mean squared
  error of the reconciled against the measured shares;
* a 5-sd slip up or down in one class (holding at least 2 % of its stream) of one random
  analysed stream: the share of surveys in which that measurement has the largest
  measurement test (named first), by the sign of the slip.

    OPENBLAS_NUM_THREADS=1 python benchmarks/circuit_error_model.py --surveys 1000

Results are printed and written to benchmarks/output/circuit_error_model.csv; docs/circuit.md
states them.
"""

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab.circuit import ErrorModel, reconcile
from tromplab.circuit.simulation import example_plant, grinding_circuit, lab_survey, reconciliation_study, two_deck_screen

CIRCUITS = {
    "grinding circuit": (grinding_circuit, {"fresh_feed": 0.02}),
    "two-deck screen": (two_deck_screen, {}),
    "example plant": (example_plant, {"screen_feed": 0.02}),
}
POINTS = ("measured", "reconciled")


def null_study(name: str, at: str, n_surveys: int, seed: int) -> dict:
    make, flows = CIRCUITS[name]
    study = reconciliation_study(make(), n_surveys, np.random.default_rng(seed), flows=flows, errors=ErrorModel(evaluated_at=at))
    return {"study": "no gross error", "circuit": name, "error_model_at": at, "surveys": n_surveys, "dof": study.dof,
            "chi_square_rejection_5pct": study.rejection_rate, "coverage_95": study.coverage,
            "mse_reconciled_over_measured": study.reconciled_error / study.measured_error}  # fmt: skip


def slip_study(name: str, at: str, sign: float, n_surveys: int, seed: int, size: float = 5.0) -> dict:
    """How often a ``size``-sd slip (``sign`` up or down) in one random class is named first."""
    make, flows = CIRCUITS[name]
    truth = make()
    rng = np.random.default_rng(seed)
    streams = [s for s in truth.flowsheet.stream_names if not s.endswith("_deck_undersize")]
    candidates = [(s, k) for s in streams for k in range(len(truth.classes))
                  if truth.shares[truth.flowsheet.stream_index[s], k] >= 0.02]  # fmt: skip
    named = 0
    for _ in range(n_surveys):
        stream, klass = candidates[rng.integers(len(candidates))]
        survey = lab_survey(truth, rng, flows=flows, errors=ErrorModel(evaluated_at=at), gross=(stream, klass, size * sign))
        table = reconcile(truth.flowsheet, survey).adjustments_table().dropna(subset=["measurement_test"])
        first = table.loc[table["measurement_test"].abs().idxmax()]
        named += bool(first["stream"] == stream and first["class_index"] == klass)
    return {"study": f"{size:g}-sd slip {'up' if sign > 0 else 'down'} in one class", "circuit": name,
            "error_model_at": at, "surveys": n_surveys, "named_first": named / n_surveys}  # fmt: skip


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--surveys", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--output", type=Path, default=Path(__file__).resolve().parent / "output" / "circuit_error_model.csv")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    rows = []
    for k, name in enumerate(CIRCUITS):
        for at in POINTS:
            rows.append(null_study(name, at, args.surveys, args.seed + k))
            print(rows[-1], flush=True)
    for k, name in enumerate(("grinding circuit", "example plant")):
        for at in POINTS:
            for sign in (1.0, -1.0):
                rows.append(slip_study(name, at, sign, max(args.surveys // 2, 1), args.seed + 10 + k))
                print(rows[-1], flush=True)
    table = pd.DataFrame(rows)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.output, index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"\n{time.perf_counter() - start:.0f} s; written to {args.output}")
    return table


if __name__ == "__main__":
    main()
