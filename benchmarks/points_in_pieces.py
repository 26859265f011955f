"""Memory and time of a points file read whole (``read_points``) and in pieces (``iter_experiments``).

A file of ``--rows`` rows (10 sizes per experiment) is written twice: experiments in
consecutive rows (the usual file) and in shuffled rows (each experiment's rows spread over
the file).  For each reading the peak of the Python allocations (``tracemalloc``) and the
time are measured; the pieces' reading consumes one experiment at a time and keeps none.
The first pass alone (the checks and the count of each experiment's rows) is timed too.

    python benchmarks/points_in_pieces.py --rows 200000 --piece-rows 10000
"""

import argparse
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab.loading.points import _index_experiments, iter_experiments, read_points
from tromplab.loading.tables import read_table_in_pieces


def write_points(path: Path, rows: int, *, shuffled: bool) -> Path:
    experiments = rows // 10
    frame = pd.DataFrame(
        {
            "experiment": np.repeat([f"survey {i:06d}" for i in range(experiments)], 10),
            "size": np.tile(10.0 * 2.0 ** np.arange(10), experiments),
            "partition_fine": np.clip(
                np.tile(np.linspace(0.98, 0.02, 10), experiments) + np.random.default_rng(1).normal(0, 0.005, experiments * 10),
                0.0,
                1.0,
            ),
        }
    )
    if shuffled:
        frame = frame.iloc[np.random.default_rng(2).permutation(len(frame))]
    frame.to_csv(path, index=False)
    return path


def measure(work) -> tuple[float, float]:
    """(seconds, peak MiB) of ``work()``."""
    tracemalloc.start()
    start = time.perf_counter()
    try:
        work()
        return time.perf_counter() - start, tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=200_000)
    parser.add_argument("--piece-rows", type=int, default=10_000)
    args = parser.parse_args(argv)
    results = []
    with tempfile.TemporaryDirectory() as folder:
        for shuffled in (False, True):
            path = write_points(Path(folder) / f"points{int(shuffled)}.csv", args.rows, shuffled=shuffled)
            order = "shuffled" if shuffled else "consecutive"
            seconds, peak = measure(lambda path=path: read_points(path))
            results.append({"rows": order, "reading": "whole (read_points)", "seconds": seconds, "peak_MiB": peak})
            seconds, peak = measure(lambda path=path: sum(1 for _ in iter_experiments(path, piece_rows=args.piece_rows)))
            results.append({"rows": order, "reading": f"pieces of {args.piece_rows:,}", "seconds": seconds, "peak_MiB": peak})
            seconds, peak = measure(
                lambda path=path: _index_experiments(read_table_in_pieces(path, piece_rows=args.piece_rows), None)
            )
            results.append({"rows": order, "reading": "  of which the first pass", "seconds": seconds, "peak_MiB": peak})
    table = pd.DataFrame(results)
    print(f"{args.rows:,} rows ({args.rows // 10:,} experiments), Python {sys.version.split()[0]}")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    return table


if __name__ == "__main__":
    main()
