"""Memory of the main process of ``tromplab fit`` on a points file read whole or in pieces.

For each number of experiments (``--sizes``) a points file is written (10 sizes per
experiment, a Plitt-like curve with noise) and fitted by ``fit_to_folder`` with its results
streamed to disk, in a fresh process per run: the file read whole (``read_experiments``,
what ``tromplab fit`` does below ``IN_PIECES_FROM_BYTES``) or in pieces
(``ExperimentsInPieces``).  Reported per run: the peak of the main process's Python
allocations (tracemalloc, numpy's arrays included), its peak resident set (``ru_maxrss``,
imports included) and the seconds (with tracemalloc on: slower than a plain run).

    python benchmarks/fit_in_pieces_memory.py --sizes 5000,20000 --jobs 2
"""

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd


def write_points(path: Path, experiments: int) -> Path:
    rng = np.random.default_rng(1)
    size = 10.0 * 2.0 ** np.arange(10) / 8
    cut = rng.uniform(5, 40, experiments)[:, None]
    partition = 1 / (1 + (size / cut) ** 3) + rng.normal(0, 0.01, (experiments, 10))
    frame = pd.DataFrame(
        {
            "experiment": np.repeat([f"survey {i:06d}" for i in range(experiments)], 10),
            "size": np.tile(size, experiments),
            "partition_fine": np.clip(partition, 0, 1).round(4).ravel(),
        }
    )
    frame.to_csv(path, index=False)
    return path


def one_run(path: str, mode: str, jobs: int, outdir: str) -> dict:
    from tromplab.loading.lab import read_experiments
    from tromplab.workbench import ExperimentsInPieces, fit_to_folder

    tracemalloc.start()
    started = time.perf_counter()
    experiments = ExperimentsInPieces(path) if mode == "pieces" else read_experiments(path)
    fit_to_folder(experiments, outdir, stream=True, formulas="plitt", figures="none", jobs=jobs)
    seconds = time.perf_counter() - started
    peak = tracemalloc.get_traced_memory()[1]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {"mode": mode, "python_peak_mib": peak / 2**20, "rss_peak_mib": rss / 2**20, "seconds": seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="5000,20000")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--one", nargs=3, help=argparse.SUPPRESS)  # path mode outdir: a run in this process
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_run(*args.one[:2], args.jobs, args.one[2])))
        return
    with tempfile.TemporaryDirectory() as folder:
        print("experiments  mode    python peak (MiB)  RSS peak (MiB)  seconds")
        for size in map(int, args.sizes.split(",")):
            path = write_points(Path(folder) / f"points_{size}.csv", size)
            for mode in ("whole", "pieces"):
                command = [
                    sys.executable,
                    __file__,
                    "--jobs",
                    str(args.jobs),
                    "--one",
                    str(path),
                    mode,
                    f"{folder}/out_{size}_{mode}",
                ]
                found = json.loads(subprocess.run(command, check=True, capture_output=True, text=True).stdout)
                print(
                    f"{size:>11,}  {mode:<6}  {found['python_peak_mib']:>17.1f}  {found['rss_peak_mib']:>14.1f}  {found['seconds']:>7.1f}"
                )


if __name__ == "__main__":
    main()
