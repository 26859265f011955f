"""What keeping a batch's results out of Python's cyclic garbage collections saves.

``tromplab.workbench`` calls ``gc.freeze()`` after each chunk's results arrive and around
each chunk's work, and ``gc.unfreeze()`` at the end of the batch.  This benchmark runs the
same batch (``fit_experiments`` on ``--experiments`` synthetic experiments, ``--jobs``
workers, then the tables) twice in fresh processes, alternating, as it is and with the
freezing turned into no-ops, and prints the wall time and the CPU time of the main process
and of its worker processes (``resource.getrusage``), with the load average.

    python benchmarks/gc_freeze.py --experiments 10000 --jobs 2 --runs 1
"""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

RUN = """
import gc, json, resource, sys, time
sys.path.insert(0, {here!r})
from scaling import experiments
import tromplab.workbench as workbench
if {without!r}:
    class _NoFreeze:  # as if the process had frozen objects of its own: the batch then freezes nothing
        freeze = unfreeze = staticmethod(lambda: None)
        get_freeze_count = staticmethod(lambda: 1)
    workbench.gc = _NoFreeze
points = experiments({n})
start = time.perf_counter()
bench = workbench.fit_experiments(points, jobs={jobs})
bench.fits_table(); bench.ranking_table(); bench.averages(jobs={jobs})
wall = time.perf_counter() - start
me, workers = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({{"wall": wall, "main_cpu": me.ru_utime + me.ru_stime, "workers_cpu": workers.ru_utime + workers.ru_stime}}))
"""


def run(n: int, jobs: int, without: bool) -> dict:
    code = RUN.format(here=str(HERE), n=n, jobs=jobs, without=without)
    result = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=2048)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--runs", type=int, default=2)
    args = parser.parse_args(argv)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    for _ in range(args.runs):
        for label, without in (("frozen (as shipped)", False), ("collected as usual", True)):
            found = run(args.experiments, args.jobs, without)
            print(
                f"{label:20s} wall {found['wall']:6.1f} s   main CPU {found['main_cpu']:5.1f} s   "
                f"workers CPU {found['workers_cpu']:5.1f} s"
            )
    print(f"{args.experiments} experiments, {args.jobs} worker(s); load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
