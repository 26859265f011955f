"""Minerals by size: coverage and test size of the per-component reconciliation of tromplab.circuit.

The truth is the simulated magnetite circuit (tromplab.circuit.simulation.mineral_circuit): a
ball mill closed by a hydrocyclone treating magnetite (5 %, d50c 50 um), pyrite (3 %, 65 um)
and an unassayed gangue (95 um), every mineral on the registry's rosin_rammler_bypass curve
with a bypass of 0.25.  Each survey is drawn from the stated error model (size analyses of
every stream, per-class assays of both minerals, a 2 % belt scale on the fresh feed), written
as a measurement table with the shares and assays clipped at 0 and rounded to 0.01 % and read
back through tromplab.circuit.read_survey (simulation.lab_survey), then reconciled.  Counted:
the share of surveys the global chi-square test rejects at 5 %, the coverage of the 95 %
intervals of each mineral's reconciled partition (used classes) and of its recovery to the
overflow (logit intervals).

    OPENBLAS_NUM_THREADS=1 python benchmarks/circuit_components.py --surveys 1000

Results are printed and written to benchmarks/output/circuit_components.csv; docs/circuit.md
states them.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling import write_study_table  # noqa: E402

from tromplab.circuit.simulation import component_study, mineral_circuit

#: Which streams carry assays: all four, or the cyclone's three (the mill's new feed not assayed).
ASSAYED = {
    "every stream": None,
    "cyclone streams only": ("cyclone_feed", "cyclone_overflow", "cyclone_underflow"),
}


def study(name: str, n_surveys: int, seed: int) -> dict:
    truth = mineral_circuit()
    result = component_study(truth, n_surveys, np.random.default_rng(seed), flows={"fresh_feed": 0.02},
                             assayed=ASSAYED[name])  # fmt: skip
    return {"circuit": "magnetite circuit", "assayed": name, "surveys": n_surveys, "dof": result.dof,
            "chi_square_rejection_5pct": result.rejection_rate, "partition_coverage_95": result.coverage,
            "partitions_checked": result.checked, "recovery_coverage_95": result.recovery_coverage,
            "recoveries_checked": result.recovery_checked}  # fmt: skip


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--surveys", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--assayed", choices=list(ASSAYED), action="append", help="one configuration (default: all)")
    parser.add_argument("--output", type=Path, default=Path(__file__).resolve().parent / "output" / "circuit_components.csv")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    rows = []
    for k, name in enumerate(ASSAYED):
        if args.assayed and name not in args.assayed:
            continue
        rows.append(study(name, args.surveys, args.seed + k))
        print(rows[-1], flush=True)
    return write_study_table(pd.DataFrame(rows), args.output, start)


if __name__ == "__main__":
    main()
