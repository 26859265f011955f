"""``tromplab trend`` and ``tromplab report`` on the bundled datasets, against a yardstick timed in the same run.

Each whole command (start-up included) runs in a fresh process and is measured by the CPU
seconds of its process tree (its worker processes included) and by its wall-clock seconds;
the yardstick is the one ``benchmarks/density_speed.py`` uses: bare single-start lmfit fits of
100 synthetic experiments x 10 curves, in this process, measured the same two ways.  Command
and yardstick are timed in turn ``--repeats`` times and the median of the ratios printed, CPU
to CPU (``ratio``: what a loaded machine changes least) and wall to wall (``wall_ratio``).
Commands:

* ``trend`` of ``datasets/classifier_trend_surveys.csv`` (24 surveys): the ranking's best
  formula (formula (11), 40 joint fits one by one), the command of docs/trend.md
  (``--formula plitt_bypass``, four charts) and the same with ``--no-figures``;
* ``report`` of ``datasets/air_classifier_lab_synthetic.csv`` (4 experiments) and of the
  survey series (24 experiments, 20 shown with their figures), ``--jobs 1``; the series also
  as the command runs by default, its figures drawn by one worker process per core (CPU of
  the workers included; its wall-clock time is the one to read on a quiet machine).

``--before SOURCE`` also runs each command on another source tree of tromplab (for example
``git archive 52a2c1d tromplab | tar -x -C /tmp/before``, then ``--before /tmp/before``),
in turn with the current one, and prints the ratio of the two (CPU to CPU, ``before_over_now``,
and wall to wall, ``wall_before_over_now``).

    python benchmarks/trend_report_speed.py --repeats 3 [--before /tmp/before]

Prints a table (and the load average before and after) and writes
benchmarks/output/trend_report_speed.csv.
"""

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from density_speed import yardstick_seconds  # noqa: E402
from scaling import save_and_show  # noqa: E402

SERIES = ROOT / "datasets" / "classifier_trend_surveys.csv"
LAB = ROOT / "datasets" / "air_classifier_lab_synthetic.csv"
#: Measured commands: name -> (command, input, options).
COMMANDS = {
    "trend, best formula (11)": ("trend", SERIES, []),
    "trend --formula plitt_bypass": ("trend", SERIES, ["--formula", "plitt_bypass", "--size-unit", "um"]),
    "trend --formula plitt_bypass --no-figures": ("trend", SERIES, ["--formula", "plitt_bypass", "--no-figures"]),
    "report, 4 lab experiments": ("report", LAB, ["--jobs", "1"]),
    "report, 24 surveys": ("report", SERIES, ["--jobs", "1"]),
    "report, 24 surveys, all cores": ("report", SERIES, []),
}
#: Runs tromplab from the source tree given as the first argument, ahead of the editable install.
FROM_SOURCE = (
    "import runpy, sys; source = sys.argv.pop(1); "
    "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in getattr(f, '__module__', '')]; "
    "sys.path.insert(0, source); sys.argv[0] = 'tromplab'; runpy.run_module('tromplab', run_name='__main__')"
)


def command_seconds(arguments: list[str], source: Path | None = None) -> tuple[float, float]:
    """``(CPU seconds of the process tree, wall-clock seconds)`` of one ``tromplab`` run."""
    launcher = ["-m", "tromplab"] if source is None else ["-c", FROM_SOURCE, str(source)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, *launcher, *arguments, "-q"], check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def measure(name: str, folder: Path, repeats: int, before: Path | None) -> dict:
    command, path, options = COMMANDS[name]
    target = ["-o", str(folder / "out")] if command == "trend" else ["-o", str(folder / "report" / "report.html")]
    arguments = [command, str(path), *target, *options]
    rows = {key: [] for key in ("cpu", "wall", "yardstick", "ratio", "wall_ratio", "before_cpu", "speed_up", "wall_speed_up")}
    for _ in range(repeats):
        started = time.process_time()
        yardstick_wall = yardstick_seconds()
        rows["yardstick"].append(time.process_time() - started)
        cpu, wall = command_seconds(arguments)
        rows["cpu"].append(cpu)
        rows["wall"].append(wall)
        rows["ratio"].append(cpu / rows["yardstick"][-1])
        rows["wall_ratio"].append(wall / yardstick_wall)
        if before is not None:
            before_cpu, before_wall = command_seconds(arguments, before)
            rows["before_cpu"].append(before_cpu)
            rows["speed_up"].append(before_cpu / cpu)
            rows["wall_speed_up"].append(before_wall / wall)
    median = {key: statistics.median(values) if values else float("nan") for key, values in rows.items()}
    return {
        "command": name,
        "cpu_s": median["cpu"],
        "wall_s": median["wall"],
        "yardstick_cpu_s": median["yardstick"],
        "ratio": median["ratio"],
        "wall_ratio": median["wall_ratio"],
        "before_cpu_s": median["before_cpu"],
        "before_over_now": median["speed_up"],
        "wall_before_over_now": median["wall_speed_up"],
    }


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--before", type=Path, default=None, help="a source tree of tromplab to compare with")
    parser.add_argument("--only", default="", help="commands whose name holds this text")
    parser.add_argument("--output", type=Path, default=HERE / "output" / "trend_report_speed.csv")
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        rows = [measure(name, Path(folder), args.repeats, args.before) for name in COMMANDS if args.only in name]
    return save_and_show(pd.DataFrame(rows), args.output, load_before)


if __name__ == "__main__":
    main()
