"""``tromplab report`` against ``tromplab fit`` of the same file (issue 24, item 1: report <= 3 x the fit).

On ``--experiments`` synthetic experiments written to a CSV, one run times the two whole
commands in subprocesses, start-up included:

* ``tromplab fit FILE -o DIR --figures none --jobs J -q`` (the floor: the report fits the same);
* ``tromplab report FILE -o DIR/report.html --jobs J -q``;

and prints their times, the ratio, the size of the report and the load average before and
after.  The report shows every experiment up to ``REPORT_DETAIL_LIMIT`` and a condensed view
beyond, so the ratio should fall as the batch grows.

    python benchmarks/report_speed.py --experiments 200 --jobs 2
    python benchmarks/report_speed.py --experiments 10000 --jobs 2
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from scaling import experiments  # noqa: E402


def _command_seconds(arguments: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "tromplab", *arguments], check=True, capture_output=True)
    return time.perf_counter() - start


def report_against_fit(n: int, jobs: int) -> pd.DataFrame:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "points.csv"
        table = [
            pd.DataFrame({"experiment": p.experiment, "size": p.size, "partition_fine": p.partition_fine}) for p in experiments(n)
        ]
        pd.concat(table).to_csv(path, index=False)
        common = ["--jobs", str(jobs), "-q"]
        fit = _command_seconds(["fit", str(path), "-o", str(Path(folder) / "fit"), "--figures", "none", *common])
        report_path = Path(folder) / "report" / "report.html"
        report = _command_seconds(["report", str(path), "-o", str(report_path), *common])
        size_mb = report_path.stat().st_size / 1e6
    return pd.DataFrame(
        [{"experiments": n, "workers": jobs, "fit_s": fit, "report_s": report, "ratio": report / fit, "report_mb": size_mb}]
    )


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=200)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--output", type=Path, default=HERE / "output" / "report_speed.csv")
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    table = report_against_fit(args.experiments, args.jobs)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.output, index=False)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"load average {load_before:.2f} before, {os.getloadavg()[0]:.2f} after; written to {args.output}")
    return table


if __name__ == "__main__":
    main()
