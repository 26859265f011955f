"""Intervals and trend at batch speed, each against its floor in the same run.

* ``fit --ci``: the whole command ``tromplab fit FILE --ci 0.95 --figures none --jobs J`` and
  the same without ``--ci``, against nine bare single-start lmfit fits per experiment
  (``fit_robustness.bare_lmfit``, measured on ``--bare-limit`` experiments and scaled);
* profile intervals: ``batched_profile_intervals`` against lmfit's ``conf_interval`` per fit
  (``ParameterFit.profile_intervals``) on the fits of ``--profile-experiments`` experiments;
* trend: ``monitor_surveys(..., formula="plitt")`` on ``--surveys`` simulated surveys, against
  the one-by-one floor of a single lmfit fit and one ``equality_test`` per survey (measured on
  100 surveys and scaled).

    python benchmarks/intervals_speed.py --experiments 1024 --jobs 2 --surveys 1000

Prints a table (and the load average before and after) and writes
benchmarks/output/intervals_speed.csv.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from scaling import experiments, run_bare, save_and_show, write_points  # noqa: E402

from tromplab.curves.curve_fit import fit_formula  # noqa: E402
from tromplab.curves.engine import fit_formula_batch  # noqa: E402
from tromplab.curves.formulas import FORMULAS  # noqa: E402
from tromplab.curves.intervals import batched_profile_intervals  # noqa: E402
from tromplab.trend import SeriesDesign, equality_test, monitor_surveys, simulate_surveys, surveys_from_frame  # noqa: E402


def _command_seconds(path: Path, folder: Path, jobs: int, *extra: str) -> float:
    start = time.perf_counter()
    command = [sys.executable, "-m", "tromplab", "fit", str(path), "-o", str(folder), "--figures", "none", "-q"]
    subprocess.run([*command, "--jobs", str(jobs), *extra], check=True, capture_output=True)
    return time.perf_counter() - start


def fit_with_intervals(n: int, jobs: int, bare_limit: int) -> list[dict]:
    with tempfile.TemporaryDirectory() as folder:
        path = write_points(Path(folder) / "points.csv", n)
        plain = _command_seconds(path, Path(folder) / "plain", jobs)
        with_ci = _command_seconds(path, Path(folder) / "ci", jobs, "--ci", "0.95")
    bare, _ = run_bare(n, bare_limit)
    return [
        {"measure": f"fit, {n} experiments, {jobs} worker(s)", "seconds": plain, "floor_seconds": bare},
        {"measure": f"fit --ci 0.95, {n} experiments, {jobs} worker(s)", "seconds": with_ci, "floor_seconds": bare},
    ]


def profiles(n: int) -> dict:
    fits = [fit for formula in FORMULAS for fit in fit_formula_batch(experiments(n), formula) if fit.success]
    start = time.perf_counter()
    batched_profile_intervals(fits)
    batched = time.perf_counter() - start
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for fit in fits:
            fit.with_lmfit().fit.profile_intervals(0.95)
    single = time.perf_counter() - start
    return {"measure": f"profile intervals of {len(fits)} fits", "seconds": batched, "floor_seconds": single}


def trend(n: int) -> dict:
    surveys = sorted(surveys_from_frame(simulate_surveys(SeriesDesign(n_surveys=n), seed=1)), key=lambda s: s.date)
    start = time.perf_counter()
    monitor_surveys(surveys, formula="plitt", baseline=8)
    batched = time.perf_counter() - start
    sample = surveys[:100]
    start = time.perf_counter()
    baseline = [s.points for s in sample[:8]]
    for survey in sample:
        fit_formula(survey.points, "plitt")
        equality_test(baseline, [survey.points], "plitt")
    one_by_one = (time.perf_counter() - start) * n / len(sample)
    return {"measure": f"trend, {n} surveys (plitt)", "seconds": batched, "floor_seconds": one_by_one}


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=1024)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--bare-limit", type=int, default=256)
    parser.add_argument("--profile-experiments", type=int, default=60)
    parser.add_argument("--surveys", type=int, default=1000)
    parser.add_argument("--output", type=Path, default=HERE / "output" / "intervals_speed.csv")
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    rows = fit_with_intervals(args.experiments, args.jobs, args.bare_limit)
    rows.append(profiles(args.profile_experiments))
    rows.append(trend(args.surveys))
    table = pd.DataFrame(rows)
    table["ratio_to_floor"] = table["seconds"] / table["floor_seconds"]
    return save_and_show(table, args.output, load_before)


if __name__ == "__main__":
    main()
