"""``tromplab report`` against ``tromplab fit`` of the same file (report <= 3 x the fit).

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
from scaling import save_and_show, write_points  # noqa: E402


def _command_seconds(arguments: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "tromplab", *arguments], check=True, capture_output=True)
    return time.perf_counter() - start


def report_against_fit(n: int, jobs: int) -> pd.DataFrame:
    with tempfile.TemporaryDirectory() as folder:
        path = write_points(Path(folder) / "points.csv", n)
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
    return save_and_show(report_against_fit(args.experiments, args.jobs), args.output, load_before)


if __name__ == "__main__":
    main()
