"""Benchmark: the start-up cost of ``import tromplab`` (well under 0.3 s above a bare interpreter).

Starts fresh interpreters and reports the median wall time of each statement over ``--runs``
runs, and the difference to a bare ``python -c pass``:

- ``import tromplab``: the public names load lazily, so this imports almost nothing;
- ``import tromplab; tromplab.fit_experiments``: the first use of a name imports what it needs
  (numpy, pandas, scipy, lmfit), as ``import tromplab`` did up to 0.1;
- ``import tromplab._launch``: what the ``tromplab`` command imports before its signal handling
  is installed;
- ``import tromplab.cli``: the command line itself (no numpy: the parser is built from light
  modules and each command imports its implementation when it runs);
- ``import tromplab.circuit.planning``: what ``tromplab circuit design`` imports (numpy, pandas
  and the circuit's own modules; none of scipy's numerical modules);
- ``import numpy, pandas``: the floor of every command that reads a table.

Then ``python -X importtime -c "import tromplab"`` lists the modules with the largest
cumulative import time (``--top``; add ``--statement`` to profile another statement).
Usage: ``python benchmarks/import_time.py [--runs 9] [--top 12]`` (not part of the tests: timings
depend on the machine and its load).
"""

import argparse
import statistics
import subprocess
import sys
import time

STATEMENTS = (
    "pass",
    "import tromplab",
    "import tromplab; tromplab.fit_experiments",
    "import tromplab._launch",
    "import tromplab.cli",
    "import tromplab.circuit.planning",
    "import numpy, pandas",
)


def wall_time(statement: str) -> float:
    """Seconds from starting ``python -c statement`` to its exit."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", statement], check=True)
    return time.perf_counter() - start


def median_times(statements, runs: int) -> dict[str, float]:
    """Median wall time of each statement; the runs are interleaved so a change of load hits all alike."""
    times = {statement: [] for statement in statements}
    for _ in range(runs):
        for statement in statements:
            times[statement].append(wall_time(statement))
    return {statement: statistics.median(values) for statement, values in times.items()}


def import_offenders(statement: str, top: int) -> list[tuple[int, int, str]]:
    """``(cumulative us, self us, module)`` of the ``top`` slowest imports of ``-X importtime``."""
    done = subprocess.run([sys.executable, "-X", "importtime", "-c", statement], capture_output=True, text=True, check=True)
    rows = []
    for line in done.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        own, cumulative, module = (field.strip() for field in line.removeprefix("import time:").split("|"))
        rows.append((int(cumulative), int(own), module.strip()))
    return sorted(rows, reverse=True)[:top]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=9, help="interpreters started per statement (default 9)")
    parser.add_argument("--top", type=int, default=12, help="slowest imports listed (default 12)")
    parser.add_argument("--statement", default="import tromplab", help="statement profiled with -X importtime")
    args = parser.parse_args(argv)
    medians = median_times(STATEMENTS, args.runs)
    bare = medians["pass"]
    print(f"median of {args.runs} runs, {sys.executable}")
    for statement, seconds in medians.items():
        print(f"  {statement:45s} {seconds:7.3f} s   {seconds - bare:+7.3f} s above bare")
    print(f'\n-X importtime -c "{args.statement}": slowest {args.top} (cumulative, self, module)')
    for cumulative, own, module in import_offenders(args.statement, args.top):
        print(f"  {cumulative / 1e6:7.3f} s {own / 1e6:7.3f} s  {module}")


if __name__ == "__main__":
    main()
