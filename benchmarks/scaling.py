"""Benchmark: how tromplab scales with the number of experiments and workers.

For each batch size (default 1, 128, 1024, 10,000 seeded synthetic experiments of
``fit_robustness.synthetic``: curves of every formula, 8-12 sizes, noise 0.01-0.03) it
measures, in one run and on the same data:

* **fits**: ``fit_experiments`` (nine formulas: fits, F screen, indices, diagnostics) plus
  the fits and ranking tables, with 1 and 2 worker processes;
* **full**: the ``tromplab fit`` command (tables, model averages, figures ``auto``) with
  ``--jobs 1`` and ``--jobs 2``;
* **bare lmfit**: nine single-start ``lmfit.minimize`` fits per experiment from a generic
  start (d_cut = median size, shape = 1), as in ``fit_robustness.py`` - on all
  experiments up to ``--bare-limit``, above it on the first ``--bare-limit`` experiments
  and scaled linearly (it is linear in the number of experiments);
* the share of fits at the optimum for tromplab and for bare lmfit: within 1e-6
  (relative) of the lower of the two sums of squares;
* peak memory (largest resident set of the main process and of any worker), and the
  1 -> 2 worker speed-up;
* the CPU time of the main process and of the workers in the 2-worker fits, and from them
  the speed-up two *free* cores would give (Amdahl: the main process's work is serial, the
  workers' is shared by two): on a machine shared with other work the measured speed-up
  says more about the load than about tromplab.

Each tromplab measurement runs in a fresh process so that its peak memory is its own.
Usage: ``python benchmarks/scaling.py [--sizes 1,128,1024,10000] [--bare-limit 1024]``
(not part of the test suite; about 10 minutes on 2 cores with the defaults).
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from fit_robustness import bare_lmfit, synthetic  # noqa: E402

AT_OPTIMUM = 1e-6


def experiments(n):
    return [synthetic(seed) for seed in range(n)]


def write_points(path: Path, n: int) -> Path:
    """The ``n`` synthetic :func:`experiments` as one Tromp-points CSV (the input the command line reads)."""
    frames = [
        pd.DataFrame({"experiment": p.experiment, "size": p.size, "partition_fine": p.partition_fine}) for p in experiments(n)
    ]
    pd.concat(frames).to_csv(path, index=False)
    return path


def save_and_show(table: pd.DataFrame, output: Path, load_before: float, prefix: str = "") -> pd.DataFrame:
    """Write a benchmark's ``table`` to ``output`` and print it with the load average before and now."""
    output.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(output, index=False)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"{prefix}load average {load_before:.2f} before, {os.getloadavg()[0]:.2f} after; written to {output}")
    return table


def write_study_table(table: pd.DataFrame, output: Path, started: float, *, width: int = 200) -> pd.DataFrame:
    """Write a simulation study's ``table`` to ``output``, print it at four decimals and say how
    long the study took (``started`` from :func:`time.perf_counter`)."""
    output.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(output, index=False)
    with pd.option_context("display.width", width, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"\n{time.perf_counter() - started:.0f} s; written to {output}")
    return table


def _cpu_seconds(who):
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def _peak_mib(who):
    return resource.getrusage(who).ru_maxrss / 1024.0


def child_fits(n, workers, out):
    from tromplab.workbench import fit_experiments

    data = experiments(n)
    main_before, workers_before = _cpu_seconds(resource.RUSAGE_SELF), _cpu_seconds(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    bench = fit_experiments(data, jobs=workers)
    table = bench.fits_table()
    bench.ranking_table()
    seconds = time.perf_counter() - start
    main_cpu = _cpu_seconds(resource.RUSAGE_SELF) - main_before
    workers_cpu = _cpu_seconds(resource.RUSAGE_CHILDREN) - workers_before
    table[["experiment", "formula", "ssr"]].to_csv(out, index=False)
    print(
        json.dumps(
            {
                "seconds": seconds,
                "main_cpu_s": main_cpu,
                "workers_cpu_s": workers_cpu,
                "peak_main_mib": _peak_mib(resource.RUSAGE_SELF),
                "peak_worker_mib": _peak_mib(resource.RUSAGE_CHILDREN),
            }
        )
    )


def run_full(n, workers, folder):
    points = folder / f"points_{n}.csv"
    if not points.exists():
        pd.concat([p.to_frame() for p in experiments(n)]).to_csv(points, index=False)
    command = [
        sys.executable,
        "-c",
        "import sys, resource, json; from tromplab.cli import main; code = main(sys.argv[1:]); "
        "print(json.dumps({'peak_main_mib': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "
        "'peak_worker_mib': resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}), file=sys.stderr); "
        "sys.exit(code)",
        "fit",
        str(points),
        "-o",
        str(folder / f"out_{n}_{workers}"),
        "--jobs",
        str(workers),
    ]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    seconds = time.perf_counter() - start
    peaks = json.loads(done.stderr.strip().splitlines()[-1])
    return {"seconds": seconds, **peaks}


def run_fits(n, workers, folder):
    out = folder / f"ssr_{n}_{workers}.csv"
    command = [sys.executable, __file__, "--child", str(n), str(workers), str(out)]
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1]), pd.read_csv(out)


def run_bare(n, limit):
    from tromplab.curves.formulas import FORMULAS
    from tromplab.curves.measured import measured_efficiency

    data = experiments(min(n, limit))
    rows = []
    start = time.perf_counter()
    for points in data:
        efficiency = measured_efficiency(points)
        for formula in FORMULAS:
            context = {"measured_efficiency": efficiency} if formula.context_from_efficiency else {}
            rows.append(
                {"experiment": points.experiment, "formula": formula.id, "bare_ssr": bare_lmfit(points, formula, context)}
            )
    seconds = (time.perf_counter() - start) * n / len(data)
    return seconds, pd.DataFrame(rows)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="1,128,1024,10000")
    parser.add_argument("--bare-limit", type=int, default=1024)
    parser.add_argument("--no-full", action="store_true", help="skip the full-pipeline runs")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child_fits(int(args.child[0]), int(args.child[1]), args.child[2])
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for n in [int(s) for s in args.sizes.split(",")]:
            bare_seconds, bare = run_bare(n, args.bare_limit)
            row = {"experiments": n, "bare_lmfit_s": bare_seconds}
            for workers in (1, 2):
                measured, ssr = run_fits(n, workers, folder)
                row[f"fits_{workers}w_s"] = measured["seconds"]
                row[f"fits_{workers}w_peak_mib"] = max(measured["peak_main_mib"], measured["peak_worker_mib"])
                row[f"fits_{workers}w_main_cpu_s"] = measured["main_cpu_s"]
                row[f"fits_{workers}w_workers_cpu_s"] = measured["workers_cpu_s"]
                if not args.no_full:
                    full = run_full(n, workers, folder)
                    row[f"full_{workers}w_s"] = full["seconds"]
                    row[f"full_{workers}w_peak_mib"] = max(full["peak_main_mib"], full["peak_worker_mib"])
            both = ssr.merge(bare, on=["experiment", "formula"])
            best = np.minimum(both["ssr"], both["bare_ssr"])
            row["tromplab_at_optimum_pct"] = 100 * float(np.mean(both["ssr"] <= best * (1 + AT_OPTIMUM) + 1e-15))
            row["bare_at_optimum_pct"] = 100 * float(np.mean(both["bare_ssr"] <= best * (1 + AT_OPTIMUM) + 1e-15))
            row["fits_1w_vs_bare"] = row["fits_1w_s"] / bare_seconds
            row["fits_2w_vs_bare"] = row["fits_2w_s"] / bare_seconds
            row["speedup_fits_1_to_2"] = row["fits_1w_s"] / row["fits_2w_s"]
            row["speedup_fits_free_cores_bound"] = (row["fits_2w_main_cpu_s"] + row["fits_2w_workers_cpu_s"]) / (
                row["fits_2w_main_cpu_s"] + row["fits_2w_workers_cpu_s"] / 2
            )
            if not args.no_full:
                row["speedup_full_1_to_2"] = row["full_1w_s"] / row["full_2w_s"]
            rows.append(row)
            print(pd.DataFrame([row]).T.to_string(header=False, float_format=lambda v: f"{v:.3g}"), flush=True)
            print(flush=True)
    print(pd.DataFrame(rows).set_index("experiments").T.to_string(float_format=lambda v: f"{v:.3g}"))


if __name__ == "__main__":
    main()
