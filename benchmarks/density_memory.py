"""Peak memory and time of ``tromplab density fit`` on large tracer campaigns, streamed to disk
unit by unit, against the same command of a source tree before (``--before``), run in turn.

Each run is the whole command in a fresh process (start-up included), its figures the peak
resident set of its largest process (the main process; with ``--jobs 2`` a worker may be
larger) as the operating system counts it (``getrusage`` of a launcher process that runs only
that command), its CPU (user + system, workers included) and wall-clock seconds.  The
campaigns are ``density_speed.tracer_campaign(n)``: n simulated tests of 12 densities and 30
tracers.  The two folders of each pair are compared file by file (they must be identical).

    git archive e07e4cf tromplab | tar -x -C /tmp/before
    python benchmarks/density_memory.py --tests 1000 10000 --before /tmp/before [--options "--ci 0.95"] [--jobs 2]

Prints a table (and the load average before and after) and writes
benchmarks/output/density_memory.csv.
"""

import argparse
import filecmp
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from density_speed import tracer_campaign  # noqa: E402
from scaling import save_and_show  # noqa: E402
from trend_report_speed import FROM_SOURCE  # noqa: E402

#: Runs a command and prints its peak resident set (KiB, its largest process), CPU and wall seconds.
LAUNCHER = (
    "import resource, subprocess, sys, time; start = time.perf_counter(); subprocess.run(sys.argv[1:], check=True, "
    "capture_output=True); wall = time.perf_counter() - start; used = resource.getrusage(resource.RUSAGE_CHILDREN); "
    "print(used.ru_maxrss, used.ru_utime + used.ru_stime, wall)"
)


def run(path: Path, folder: Path, options: list[str], source: Path | None) -> dict:
    """Peak memory (MiB), CPU and wall seconds of one ``density fit`` run writing ``folder``."""
    command = [sys.executable, *(["-m", "tromplab"] if source is None else ["-c", FROM_SOURCE, str(source)])]
    command += ["density", "fit", str(path), "-o", str(folder), "-q", *options]
    found = subprocess.run([sys.executable, "-c", LAUNCHER, *command], check=True, capture_output=True, text=True)
    peak, cpu, wall = (float(value) for value in found.stdout.split())
    return {"peak_mib": peak / 1024, "cpu_s": cpu, "wall_s": wall}


def same_folders(one: Path, other: Path) -> bool:
    names = sorted(os.listdir(one))
    if names != sorted(os.listdir(other)):
        return False
    _, mismatch, errors = filecmp.cmpfiles(one, other, names, shallow=False)
    return not (mismatch or errors)


def measure(folder: Path, tests: int, options: list[str], before: Path | None, repeats: int) -> dict:
    path = folder / f"tracers_{tests}.csv"
    tracer_campaign(tests).to_csv(path, index=False)
    runs = {"now": [], "before": []}
    identical = True
    for _ in range(repeats):  # in turn, so that a change of the machine's load touches both
        runs["now"].append(run(path, folder / "now", options, None))
        if before is not None:
            runs["before"].append(run(path, folder / "before", options, before))
            identical &= same_folders(folder / "now", folder / "before")
    row = {"tests": tests, "options": " ".join(options)}
    for who, measured in runs.items():
        for figure in ("peak_mib", "cpu_s", "wall_s"):
            if measured:
                row[f"{who}_{figure}"] = statistics.median(run[figure] for run in measured)
    if before is not None:
        row["peak_now_over_before"] = row["now_peak_mib"] / row["before_peak_mib"]
        row["cpu_now_over_before"] = statistics.median(n["cpu_s"] / b["cpu_s"] for n, b in zip(runs["now"], runs["before"]))
        row["identical_files"] = identical
    return row


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, nargs="*", default=[1000, 10000], help="campaign sizes")
    parser.add_argument("--options", default="--figures none", help="options of the command (one string)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (--jobs)")
    parser.add_argument("--before", type=Path, default=None, help="a source tree of tromplab to compare with")
    parser.add_argument("--repeats", type=int, default=1, help="runs of each command, in turn")
    parser.add_argument("--output", type=Path, default=HERE / "output" / "density_memory.csv")
    args = parser.parse_args(argv)
    options = [*shlex.split(args.options), "--jobs", str(args.jobs)]
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        rows = [measure(Path(folder), tests, options, args.before, args.repeats) for tests in args.tests]
    return save_and_show(pd.DataFrame(rows), args.output, load_before)


if __name__ == "__main__":
    main()
