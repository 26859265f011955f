"""``tromplab circuit`` and ``tromplab circuit design`` against their floors and the acceptance yardstick.

One run measures, side by side:

* the yardstick: bare ``lmfit.minimize`` fits of 100 synthetic experiments x 10 curves (the nine
  formulas of the paper and the first again, each from a generic start:
  ``fit_robustness.bare_lmfit``), in this process;
* ``tromplab circuit`` on the bundled example with a magnetite assay on the three cyclone
  streams, by class and one value per stream (``tests/data/circuit_reference/inputs``: the
  surveys of the reference outputs), elimination, design and worth included, figures off, as a
  whole command in a subprocess (start-up and imports count), and its floor: one dense weighted
  least-squares solve of the survey (``numpy.linalg.lstsq`` of the whitened Jacobian and
  residuals at the starting point, the work of one Gauss-Newton step), median of 20;
* ``tromplab circuit design`` of the bundled flowsheet without a survey (a whole command);
* the synthetic 30-node plant (``tromplab.circuit.simulation.large_plant``: ten grinding stages
  of sump, cyclone and mill; 20 classes), reconciled with its tables in this process, the
  solids alone and (``--minerals``) with the four minerals assayed on every stream, each
  against its floor: one weighted least-squares solve of the sparse path it takes (the LU of the
  augmented system and one step, ``tromplab.circuit.sparse_solve``), and the wall seconds of its
  stages: the rounds of the error model with the linearisation, the bounds (with the number of
  solves and steps they report), the tables.

It prints each wall time and CPU time (user and system: on a loaded machine the steadier
measure), their ratios to the yardstick's (the acceptance targets: ``circuit`` at most
0.3 each, ``circuit design`` at most 0.2) and to its floor, and the load average before and
after.

``--stages`` prints instead, for the two assayed example surveys, the CPU milliseconds of each
stage of ``tromplab circuit`` in this process (imports done; the fastest of ``--repeats`` runs):
reading the files, the reconciliation with its error model's rounds, the serial elimination, the
adjustments and their tests, the design table, the worth table, the other tables and the files.
With ``PYTHONPATH`` naming another checkout it measures that one, for a before and after.

    python benchmarks/circuit_speed.py
    python benchmarks/circuit_speed.py --repeats 3 --minerals
    python benchmarks/circuit_speed.py --stages --repeats 5
"""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

from tromplab._launch import BLAS_THREAD_VARIABLES

for _variable in BLAS_THREAD_VARIABLES:  # as the command sets them (tromplab._launch), before numpy loads
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
REFERENCE = ROOT / "tests" / "data" / "circuit_reference"
FLOWSHEET = ROOT / "datasets" / "circuit_example_flowsheet.csv"
SURVEYS = {"assay by class": REFERENCE / "inputs" / "assay_class.csv",
           "assay one value per stream": REFERENCE / "inputs" / "assay_stream.csv"}  # fmt: skip
TARGETS = {"circuit": 0.3, "circuit design": 0.2}
sys.path.insert(0, str(HERE))


def yardstick_seconds(experiments: int = 100, curves: int = 10) -> tuple[float, float]:
    """Bare lmfit fits of ``experiments`` synthetic experiments x ``curves`` curves: ``(wall, CPU)`` seconds."""
    from fit_robustness import bare_lmfit, synthetic

    from tromplab.curves.formulas import FORMULAS
    from tromplab.curves.measured import measured_efficiency

    data = [synthetic(seed) for seed in range(experiments)]
    start, cpu = time.perf_counter(), time.process_time()
    for points in data:
        efficiency = measured_efficiency(points)
        for k in range(curves):
            formula = FORMULAS[k % len(FORMULAS)]
            bare_lmfit(points, formula, {"measured_efficiency": efficiency} if formula.context_from_efficiency else {})
    return time.perf_counter() - start, time.process_time() - cpu


def command_seconds(arguments: list[str]) -> tuple[float, float]:
    """``(wall, CPU)`` seconds of ``python -m tromplab ARGUMENTS`` (start-up included; CPU: user
    and system of the child, the measure a loaded machine disturbs least)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "tromplab", *arguments], check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def floor_seconds(flowsheet, survey, repeats: int = 20) -> float:
    """One dense weighted least-squares solve of the survey: the whitened Jacobian and residuals
    at the starting point, solved by ``numpy.linalg.lstsq`` (median of ``repeats``)."""
    from tromplab.circuit.problem import build_problem, starting_point

    problem, _ = build_problem(flowsheet, survey)
    z = problem.N.T @ (starting_point(flowsheet, survey, problem) - problem.m0)
    J, residual = problem.whitened_jacobian(z), problem.whitened_residual(z)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        np.linalg.lstsq(J, residual, rcond=None)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def example_rows(folder: Path, yardstick: tuple[float, float], repeats: int) -> list[dict]:
    from tromplab.circuit import read_flowsheet, read_survey

    sheet = read_flowsheet(FLOWSHEET)
    rows = []
    for name, path in SURVEYS.items():
        seconds = min(
            command_seconds(["circuit", str(FLOWSHEET), str(path), "-o", str(folder / "c"), "--no-figures", "-q"])
            for _ in range(repeats)
        )  # fmt: skip (the fastest run by wall time, with its CPU)
        floor = floor_seconds(sheet, read_survey(path, sheet))
        rows.append(_row("circuit", f"bundled example, {name}", seconds, yardstick, floor))
    seconds = min(command_seconds(["circuit", "design", str(FLOWSHEET), "-o", str(folder / "d"), "-q"]) for _ in range(repeats))
    rows.append(_row("circuit design", "bundled flowsheet, no survey", seconds, yardstick, np.nan))
    return rows


def stage_rows(repeats: int) -> pd.DataFrame:
    """CPU milliseconds of each stage of ``tromplab circuit`` on the assayed example surveys, in
    this process (the fastest of ``repeats`` runs, every cache of an earlier run emptied)."""
    from tromplab.circuit import CircuitResult, problem, read_flowsheet, read_survey, reconcile
    from tromplab.circuit.outputs import balance_next_steps, balance_tables

    def stages(path: Path, folder: Path) -> dict[str, float]:
        getattr(problem, "_AFFINE_FORMS", {}).clear()  # the null spaces of the constraints, kept per process
        seconds, clock = {}, time.process_time()

        def lap(name: str) -> None:
            nonlocal clock
            seconds[name], clock = time.process_time() - clock, time.process_time()

        sheet = read_flowsheet(FLOWSHEET)
        survey = read_survey(path, sheet)
        lap("read")
        balance = reconcile(sheet, survey)
        lap("reconciliation")
        balance.elimination_table()
        lap("serial elimination")
        balance.adjustments_table()
        lap("adjustments and tests")
        balance.design_table()
        lap("design")
        balance.worth_table()
        lap("worth")
        tables = balance_tables(balance)
        lap("other tables")
        CircuitResult(balance, tables, next_steps=balance_next_steps(balance, tables)).save(folder, figures=False)
        lap("files")
        return {name: 1000.0 * value for name, value in seconds.items()}

    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name, path in SURVEYS.items():
            runs = pd.DataFrame([stages(path, Path(folder) / f"run{k}") for k in range(repeats)])
            rows.append({"survey": name, **runs.min().to_dict(), "total": runs.sum(axis=1).min()})
    return pd.DataFrame(rows)


def plant_rows(yardstick: tuple[float, float], minerals: bool) -> list[dict]:
    """The 30-node plant reconciled with every table (as ``circuit`` writes them), in this process."""
    from tromplab.circuit import reconcile
    from tromplab.circuit.outputs import balance_tables
    from tromplab.circuit.simulation import lab_survey, large_plant

    truth = large_plant(10, 20)
    rows = []
    for assayed in [False, True] if minerals else [False]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the truth's grade of an empty class is 0/0: not drawn
            survey = lab_survey(truth, np.random.default_rng(40), flows={"fresh_feed": 0.02},
                                **({} if assayed else {"assayed": ()}))  # fmt: skip
        stamps: list[tuple[float, str]] = []
        start, cpu = time.perf_counter(), time.process_time()
        balance = reconcile(truth.flowsheet, survey, progress=_stamped(stamps))
        reconciled = time.perf_counter()
        balance_tables(balance)
        seconds = time.perf_counter() - start, time.process_time() - cpu
        what = "30-node plant, 20 classes" + (", 4 minerals assayed on every stream" if assayed else ", solids only")
        row = _row("circuit (in process)", what, seconds, yardstick, sparse_floor_seconds(truth.flowsheet, survey))
        rows.append({**row, **_plant_stages(start, stamps, reconciled, seconds[0])})
    return rows


def _stamped(stamps: list[tuple[float, str]]):
    """A progress callback that keeps each stage's label with the moment it was reported."""
    return lambda done, total, label: stamps.append((time.perf_counter(), label))


def _plant_stages(start: float, stamps: list[tuple[float, str]], reconciled: float, total: float) -> dict:
    """Wall seconds of the plant's stages from the reconciliation's progress stamps: the rounds of
    the error model with the linearisation after them (to the first report of the bounds), the
    bounds (``bounds_steps``: the solves that hold the negative flows, then the steps under the
    bounds), and the tables."""
    bounds = [moment for moment, label in stamps if label.startswith("reconciliation: bounds")]
    first_bound = bounds[0] if bounds else reconciled
    return {"rounds_s": first_bound - start, "bounds_s": reconciled - first_bound, "bounds_steps": len(bounds),
            "tables_s": start + total - reconciled}  # fmt: skip


def sparse_floor_seconds(flowsheet, survey, repeats: int = 5) -> float:
    """The floor of a large flowsheet, which takes the sparse path: one weighted least-squares
    solve through the sparse augmented system (``tromplab.circuit.sparse_factor.AugmentedFactor``:
    its LU and one step) at the starting point, median of ``repeats`` (the order of the LU and the
    directions no measurement sees found once, before)."""
    from tromplab.circuit import sparse_factor, sparse_solve

    problem, _ = sparse_solve.build_sparse_problem(flowsheet, survey)
    start = sparse_solve.sparse_solids_first_start if problem.n_components else sparse_solve.sparse_starting_point
    v = sparse_solve.projected_start(problem, start(flowsheet, survey, problem))
    J, residual = problem.W @ problem.jacobian(v), problem.W @ (problem.predict(v) - problem.y)
    sparse_factor.AugmentedFactor(J, problem.A)
    times = []
    for _ in range(repeats):
        begin = time.perf_counter()
        sparse_factor.AugmentedFactor(J, problem.A).step(residual)
        times.append(time.perf_counter() - begin)
    return float(np.median(times))


def _row(command: str, what: str, seconds: tuple[float, float], yardstick: tuple[float, float], floor: float) -> dict:
    """One line: wall and CPU seconds, their ratios to the yardstick's, the target, the floor."""
    target = TARGETS.get(command, np.nan)
    ratio, cpu_ratio = seconds[0] / yardstick[0], seconds[1] / yardstick[1]
    return {"command": command, "survey": what, "seconds": seconds[0], "cpu_s": seconds[1], "yardstick_s": yardstick[0],
            "ratio": ratio, "cpu_ratio": cpu_ratio, "target": target, "met": bool(ratio <= target) if np.isfinite(target) else None,
            "floor_s": floor, "against_floor": seconds[0] / floor if np.isfinite(floor) else np.nan}  # fmt: skip


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs of each command (the fastest counts)")
    parser.add_argument("--minerals", action="store_true", help="also the 30-node plant with four minerals assayed")
    parser.add_argument("--no-plant", action="store_true", help="leave the 30-node plant out")
    parser.add_argument("--output", type=Path, default=HERE / "output" / "circuit_speed.csv")
    parser.add_argument("--stages", action="store_true", help="CPU ms of each stage on the assayed example surveys, in process")
    args = parser.parse_args(argv)
    if args.stages:
        table = stage_rows(args.repeats)
        with pd.option_context("display.width", 200, "display.max_columns", 20):
            print(table.to_string(index=False, float_format=lambda v: f"{v:.1f}"))
        return table
    load_before = os.getloadavg()[0]
    yardstick = yardstick_seconds()
    with tempfile.TemporaryDirectory() as folder:
        rows = example_rows(Path(folder), yardstick, args.repeats)
    if not args.no_plant:
        rows += plant_rows(yardstick, args.minerals)
    table = pd.DataFrame(rows)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.output, index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"load average: {load_before:.2f} before, {os.getloadavg()[0]:.2f} after; {os.cpu_count()} cores")
    return table


if __name__ == "__main__":
    main()
