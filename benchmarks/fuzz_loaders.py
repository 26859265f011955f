"""Structured fuzzing of the loaders: many drawn lab and Tromp-point tables, each mutated
twice (extreme or non-finite cells, blanks, swapped, dropped or misspelt columns, shuffled
or duplicated rows, unicode names, scaled sizes), written as CSV and read back.

Every table must either load with finite, positive, strictly increasing sizes and
partitions in [0, 1], or raise the project's ``InputError``; anything else is counted and
printed with the table that caused it.  The strategies are those of the test suite
(``tests/strategies.py``), which runs 30 examples per property; this runs more.

Usage: ``python benchmarks/fuzz_loaders.py [--examples 1500] [--seed 0]`` from the
repository root (not part of the test suite; last result in docs/reliability.md).
"""

import argparse
import collections
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from hypothesis import given, seed, settings

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests/strategies.py

from tests.strategies import lab_tables, mutated, points_tables, write_frame  # noqa: E402
from tromplab.errors import InputError  # noqa: E402
from tromplab.loading.lab import read_experiments  # noqa: E402
from tromplab.loading.points import read_points  # noqa: E402


def check(experiments) -> None:
    for points in experiments:
        assert np.all(np.isfinite(points.size)) and np.all(points.size > 0) and np.all(np.diff(points.size) > 0), points
        assert np.all((points.partition_fine >= 0) & (points.partition_fine <= 1)), points


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", type=int, default=1500, help="tables per kind (lab, points)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    folder = Path(tempfile.mkdtemp())
    counts = collections.Counter()

    def attempt(kind, frame, read):
        path = write_frame(frame, folder / "table.csv")
        try:
            check(read(path))
            counts[kind, "loaded"] += 1
        except InputError:
            counts[kind, "InputError"] += 1
        except Exception as error:  # anything else is a loader bug
            counts[kind, type(error).__name__] += 1
            print(f"{kind}: {type(error).__name__}: {error}\n{frame.to_csv(index=False)}", file=sys.stderr)

    @seed(args.seed)
    @settings(max_examples=args.examples, deadline=None, database=None)
    @given(case=lab_tables(), first=mutated(), second=mutated())
    def lab(case, first, second):
        attempt("lab", second(first(case.frame, case), case), lambda p: read_experiments(p)[0])

    @seed(args.seed)
    @settings(max_examples=args.examples, deadline=None, database=None)
    @given(case=points_tables(), first=mutated(), second=mutated())
    def points(case, first, second):
        attempt("points", second(first(case.frame, case), case), read_points)

    start = time.perf_counter()
    lab()
    points()
    for (kind, outcome), n in sorted(counts.items()):
        print(f"{kind:>6} {outcome:<12} {n}")
    print(f"{sum(counts.values())} tables in {time.perf_counter() - start:.0f} s")
    return 1 if any(outcome not in ("loaded", "InputError") for _, outcome in counts) else 0


if __name__ == "__main__":
    sys.exit(main())
