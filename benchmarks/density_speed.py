"""``tromplab density fit`` at batch speed, each run against its floor measured in the same run.

* acceptance: the whole command ``tromplab density fit FILE --ci 0.95 --figures none``
  on 40 simulated tracer tests (12 densities, 30 tracers each), as a ratio to the yardstick:
  bare single-start lmfit fits of 100 synthetic experiments x 10 curves (the nine formulas,
  the first again; ``fit_robustness.bare_lmfit``).  The two are timed in turn ``--repeats``
  times and the median of the ratios printed (a change of the machine's load touches both);
* scaling: the command from 10 to 1,000 tests with the three plain curves
  (``--curves plain --figures none``, with and without ``--ci 0.95``) and with every curve
  and intervals, against the floor: statsmodels' binomial GLM of each test and plain curve,
  one ``GLM.fit`` at a time in this process (its import not counted).

    python benchmarks/density_speed.py --tests 10 100 1000 --repeats 3

The tracer tables are written through the same CSV reader a lab file goes through (the
command reads them).  Prints a table (and the load average before and after) and writes
benchmarks/output/density_speed.csv.
"""

import argparse
import itertools
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from fit_robustness import bare_lmfit  # noqa: E402
from scaling import experiments, save_and_show  # noqa: E402

from tromplab.curves.formulas import FORMULAS  # noqa: E402
from tromplab.curves.measured import measured_efficiency  # noqa: E402
from tromplab.density import read_density  # noqa: E402
from tromplab.density.simulation import simulate_tracer_test  # noqa: E402

DENSITIES_PER_TEST = 12
TRACERS_PER_DENSITY = 30


def tracer_campaign(tests: int, *, seed: int = 0) -> pd.DataFrame:
    """``tests`` simulated tracer tests of a dense-medium cyclone: a normal curve with rho50 in
    1.45-1.75 and Ep in 0.02-0.08 g/cm3, 12 densities spanning rho50 -/+ 3 Ep, 30 tracers placed
    per density and each recovered with probability 0.95."""
    rng = np.random.default_rng(seed)
    frames = []
    for number in range(tests):
        rho50, ep = rng.uniform(1.45, 1.75), rng.uniform(0.02, 0.08)
        densities = np.round(np.linspace(rho50 - 3 * ep, rho50 + 3 * ep, DENSITIES_PER_TEST), 3)
        frames.append(
            simulate_tracer_test(
                "normal",
                {"rho50": rho50, "ep": ep},
                densities,
                placed=TRACERS_PER_DENSITY,
                retrieval=0.95,
                rng=rng,
                test=f"t{number:04d}",
            )  # fmt: skip
        )
    return pd.concat(frames, ignore_index=True)


def yardstick_seconds() -> float:
    """Bare single-start lmfit fits of 100 synthetic experiments x 10 curves."""
    data = experiments(100)
    formulas = list(itertools.islice(itertools.cycle(FORMULAS), 10))
    start = time.perf_counter()
    for points in data:
        efficiency = measured_efficiency(points)
        for formula in formulas:
            bare_lmfit(points, formula, {"measured_efficiency": efficiency} if formula.context_from_efficiency else {})
    return time.perf_counter() - start


def command_seconds(path: Path, folder: Path, *options: str) -> float:
    command = [sys.executable, "-m", "tromplab", "density", "fit", str(path), "-o", str(folder), "-q", *options]
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - start


def statsmodels_floor_seconds(path: Path) -> float:
    """statsmodels' GLM of every test of ``path`` and every plain curve, one fit at a time."""
    import statsmodels.api as sm

    links = (sm.families.links.Probit, sm.families.links.Logit, sm.families.links.CLogLog)
    samples = read_density(path)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for sample in samples:
            used = sample.used
            k, n = used["sinks"].to_numpy(float), used["recovered"].to_numpy(float)
            exog = np.column_stack([np.ones(len(k)), used["density"].to_numpy(float)])
            for link in links:
                sm.GLM(np.column_stack([k, n - k]), exog, family=sm.families.Binomial(link=link())).fit()
    return time.perf_counter() - start


def acceptance(folder: Path, repeats: int) -> dict:
    path = folder / "tracers_40.csv"
    tracer_campaign(40).to_csv(path, index=False)
    ratios, commands, yardsticks = [], [], []
    for _ in range(repeats):
        yardsticks.append(yardstick_seconds())
        commands.append(command_seconds(path, folder / "out_40", "--ci", "0.95", "--figures", "none"))
        ratios.append(commands[-1] / yardsticks[-1])
    return {
        "measure": "density fit --ci 0.95 --figures none, 40 tests x 12 densities x 30 tracers",
        "seconds": statistics.median(commands),
        "floor": "bare lmfit, 100 experiments x 10 curves",
        "floor_seconds": statistics.median(yardsticks),
        "ratio": statistics.median(ratios),
        "runs": "; ".join(f"{c:.2f}/{y:.2f}" for c, y in zip(commands, yardsticks)),
    }


def scaling(folder: Path, tests: int) -> list[dict]:
    path = folder / f"tracers_{tests}.csv"
    tracer_campaign(tests, seed=tests).to_csv(path, index=False)
    floor = statsmodels_floor_seconds(path)
    rows = []
    for options in (("--curves", "plain"), ("--curves", "plain", "--ci", "0.95"), ("--ci", "0.95")):
        seconds = command_seconds(path, folder / f"out_{tests}", *options, "--figures", "none")
        rows.append({
            "measure": f"density fit {' '.join(options)} --figures none, {tests} tests",
            "seconds": seconds,
            "floor": "statsmodels GLM per test and plain curve",
            "floor_seconds": floor,
            "ratio": seconds / floor,
            "runs": "",
        })  # fmt: skip
    return rows


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, nargs="*", default=[10, 100, 1000], help="campaign sizes of the scaling rows")
    parser.add_argument("--repeats", type=int, default=3, help="turns of yardstick and command for the acceptance row")
    parser.add_argument("--output", type=Path, default=HERE / "output" / "density_speed.csv")
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        rows = [acceptance(Path(folder), args.repeats)]
        for tests in args.tests:
            rows += scaling(Path(folder), tests)
    return save_and_show(pd.DataFrame(rows), args.output, load_before)


if __name__ == "__main__":
    main()
