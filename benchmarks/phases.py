"""Where the time of ``tromplab fit`` goes, phase by phase, against the bare-lmfit floor.

On ``--experiments`` synthetic experiments written to a CSV, one run measures with the Python
API (the calls ``tromplab fit`` makes):

* load: ``read_experiments`` of the file;
* fit: ``fit_experiments(..., jobs=J)`` (fits, screen, indices, diagnostics, tables' inputs);
* intervals: ``fit_experiments(..., ci=0.95)`` minus the fit alone;
* averages: ``Workbench.averages(jobs=J)`` (the model averages);
* write: ``Workbench.save(DIR, figures="none")`` (tables only);

then the whole command ``tromplab fit FILE --figures F --jobs J`` in a subprocess (its
start-up and shutdown included; ``--figures none`` unless asked, ``auto`` draws the overview),
its wall-clock seconds and its CPU seconds (user + system of the process tree, which a
machine shared with other work disturbs less), and the floor: nine bare single-start lmfit
fits per experiment (``fit_robustness.bare_lmfit``, measured on ``--bare-limit`` experiments
and scaled).  The load average is printed before and after.

    python benchmarks/phases.py --experiments 1024 --jobs 1 [--figures auto]
"""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from scaling import run_bare, save_and_show, write_points  # noqa: E402

from tromplab.loading.lab import read_experiments  # noqa: E402
from tromplab.workbench import fit_experiments  # noqa: E402


def _seconds(work) -> tuple[float, object]:
    start = time.perf_counter()
    result = work()
    return time.perf_counter() - start, result


def _children_cpu() -> float:
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


def phases(n: int, jobs: int, bare_limit: int, *, intervals: bool = True, figures: str = "none") -> pd.DataFrame:
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        path = write_points(Path(folder) / "points.csv", n)
        load, read = _seconds(lambda: read_experiments(path))
        fit, bench = _seconds(lambda: fit_experiments(read, jobs=jobs))
        with_ci, _ = _seconds(lambda: fit_experiments(read, jobs=jobs, ci=0.95)) if intervals else (float("nan"), None)
        averages, _ = _seconds(lambda: bench.averages(jobs=jobs))
        write, _ = _seconds(lambda: bench.save(Path(folder) / "out", figures="none"))
        command = [sys.executable, "-m", "tromplab", "fit", str(path), "-o", str(Path(folder) / "cmd"), "--figures", figures]
        cpu_before = _children_cpu()
        whole, _ = _seconds(lambda: subprocess.run([*command, "--jobs", str(jobs), "-q"], check=True, capture_output=True))
        whole_cpu = _children_cpu() - cpu_before
    bare, _ = run_bare(n, bare_limit)
    for phase, seconds in (("load", load), ("fit", fit), ("intervals (ci 0.95)", with_ci - fit), ("averages", averages),
                           ("write (tables)", write), (f"whole command (--figures {figures})", whole),
                           ("whole command, CPU (user + system)", whole_cpu), ("floor: 9 bare lmfit fits", bare)):  # fmt: skip
        rows.append({"phase": phase, "seconds": seconds, "ms_per_experiment": 1000 * seconds / n, "of_floor": seconds / bare})
    return pd.DataFrame(rows)


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=1024)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--bare-limit", type=int, default=256)
    parser.add_argument("--no-intervals", action="store_true", help="skip the ci phase (long at 10,000 experiments)")
    parser.add_argument("--figures", choices=("none", "auto"), default="none", help="of the whole command (auto: the overview)")
    parser.add_argument("--output", type=Path, default=HERE / "output" / "phases.csv")
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    table = phases(args.experiments, args.jobs, args.bare_limit, intervals=not args.no_intervals, figures=args.figures)
    return save_and_show(table, args.output, load_before, prefix=f"{args.experiments} experiments, {args.jobs} worker(s); ")


if __name__ == "__main__":
    main()
