"""Benchmark: time and peak memory of ``tromplab fit`` against the number of experiments, on
one and two worker processes and on a Dask cluster of two workers, against bare lmfit.

For each batch size (default 1,000, 4,000, 10,000, 40,000 and 100,000 seeded synthetic
experiments of ``fit_robustness.synthetic``: curves of every formula, 8-12 sizes, noise
0.01-0.03) it runs the whole ``fit`` command (read the points file, fit the nine formulas,
write the results folder with its overview figure; ``tromplab.workbench.fit_to_folder``, as
the command line calls it) in a fresh process and measures:

* the wall-clock seconds, and the seconds per 1,000 experiments;
* the peak memory of the whole process tree: the resident sets of the main process, its
  worker processes and (for Dask) the scheduler and workers, summed and sampled every 50 ms
  (from ``/proc`` on Linux, else psutil; the table of parents read once per sample);
* the main process's own peak resident set (``VmHWM``; after reading the input, and at the
  end) and its growth per experiment (the slope of the straight line below, in KiB): what
  must stay flat for a batch of any size;
* where the main process's time goes (reading the file, preparing the chunks, waiting for
  the workers, keeping their summaries, joining them, writing the folder) and its CPU time
  against the workers': the serial part that keeps two workers from being twice as fast;
* bare lmfit: nine single-start ``lmfit.minimize`` fits per experiment from a generic start,
  on the first ``--bare-limit`` experiments and scaled linearly; the ratio to it carries over
  between machines better than a time does;
* whether the results folders of one worker, two workers and Dask are identical.

The time and the memory are extrapolated to 1,000,000 experiments by a straight line through
the sizes from 10,000 up (``a + b n``).  The input is read as ``tromplab fit`` reads a CSV of
1 MiB or more whose results stream, in pieces (``--input whole``: read whole first, as a
Python caller holding every experiment's points gives them).  Output: a CSV table and a figure (``--output``, its
``.png`` beside it).  ``--acceptance`` runs what the targets need (10,000 experiments on
1 and 2 workers and on Dask, 40,000 on 2 workers) and prints PASS or FAIL with the numbers:
40,000 experiments on two workers within 1 GiB for the whole tree and no slower per
experiment than 10,000; 1 -> 2 workers at least 1.8 x at 10,000 with identical outputs; the
Dask cluster (scheduler and workers started as separate processes, as ``dask scheduler`` and
``dask worker`` start them) no slower per core than two local workers, with identical outputs
(with ``--repeats``: the median of the paired differences, each Dask run less the local run
before it, at most 0).

``--repeats N`` runs each mode N times in turn and reports its median run (odd N: the
middle one), which is what a comparison of two modes at a few per cent should rest on.

Not part of the test suite: run it on a quiet machine (the timings of a shared machine say
more about its load than about tromplab).  ``python benchmarks/scaling.py --sizes 1000,4000
--no-dask`` takes a few minutes; the default sizes about an hour on two cores.
"""

import argparse
import contextlib
import filecmp
import importlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from fit_robustness import bare_lmfit, synthetic  # noqa: E402

AT_OPTIMUM = 1e-6
MIB = 1024.0 * 1024.0
#: Modes of a run: worker processes, or a Dask cluster of two single-threaded workers.
MODES = ("1 worker", "2 workers", "dask, 2 workers")
#: The main process's steps (``Workbench.store.seconds`` of a streamed batch, plus the reading of the file).
STEPS = ("read", "prepare", "wait for the workers", "keep the chunks' summaries", "join the summaries", "write the folder")


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


def _peak_resident_mib() -> float:
    """This process's peak resident set (MiB) since it started: ``VmHWM`` of ``/proc/self/status``
    on Linux, which a fresh program starts anew; ``ru_maxrss`` elsewhere, which Linux carries
    over an ``exec`` from the process that forked it (this benchmark's parent, which made the
    points of every experiment: its peak, not the child's, would be reported)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _tree_rss(roots) -> int:
    """Bytes resident in the processes ``roots`` (pids) and all their descendants: from
    ``/proc`` (Linux), else psutil.  The table of parents is read once per sample whatever the
    number of roots (1.2 ms of CPU): psutil's ``children(recursive=True)`` reads it for each
    root (3.5 ms a sample for the four roots of a Dask run against 0.9 ms for one, a load on
    the two cores that fell on the Dask runs alone)."""
    if Path("/proc/self/stat").exists():
        return _tree_rss_proc(roots)
    import psutil

    children = {}
    for process in psutil.process_iter(["ppid"]):
        children.setdefault(process.info["ppid"], []).append(process.pid)
    total, todo = 0, list(roots)
    while todo:
        pid = todo.pop()
        todo += children.get(pid, [])
        try:
            total += psutil.Process(pid).memory_info().rss
        except psutil.NoSuchProcess:
            continue
    return total


def _tree_rss_proc(roots) -> int:
    """:func:`_tree_rss` from ``/proc`` (Linux)."""
    children = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
                children.setdefault(int(fields[1]), []).append(int(entry.name))
            except (OSError, IndexError):
                continue
    total, todo = 0, list(roots)
    while todo:
        pid = todo.pop()
        todo += children.get(pid, [])
        try:
            resident_pages = int(Path(f"/proc/{pid}/statm").read_text().split()[1])
            total += resident_pages * os.sysconf("SC_PAGE_SIZE")
        except (OSError, IndexError, ValueError):
            continue
    return total


class TreeMemory:
    """The peak of :func:`_tree_rss` over ``roots``, sampled every ``interval`` seconds in a thread."""

    def __init__(self, roots, interval=0.05):
        self.roots, self.interval, self.peak = list(roots), interval, 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self):
        while not self._stop.is_set():
            self.peak = max(self.peak, _tree_rss(self.roots))
            self._stop.wait(self.interval)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        return False


def child_run(points, outdir, workers, scheduler, reading="pieces"):
    """In a fresh process: the whole ``fit`` command on ``points`` into ``outdir``, the file
    read in pieces (``reading`` ``"pieces"``, as ``tromplab fit`` reads a CSV of 1 MiB or more
    whose results stream) or whole (``"whole"``, what a caller holding the experiments does);
    prints JSON with the main process's steps and CPU time and the workers' CPU time."""
    from tromplab.loading.lab import read_experiments
    from tromplab.workbench import ExperimentsInPieces, FitsOnDisk, fit_to_folder

    main_before, workers_before = _cpu_seconds(resource.RUSAGE_SELF), _cpu_seconds(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    if reading == "pieces":  # as the command line does: the census checks every row before anything is fitted
        data = ExperimentsInPieces(points)
        data.census()
    else:
        data = read_experiments(points)
    read = time.perf_counter() - started
    peak_after_read = _peak_resident_mib()
    bench, _ = fit_to_folder(data, outdir, jobs=workers, scheduler=scheduler, source=points)
    seconds = time.perf_counter() - started
    steps = {"read": read, **getattr(bench.store, "seconds", {})}
    print(
        json.dumps(
            {
                "seconds_in_process": seconds,
                "streamed": isinstance(bench.store, FitsOnDisk),
                "main_cpu_s": _cpu_seconds(resource.RUSAGE_SELF) - main_before,
                "workers_cpu_s": _cpu_seconds(resource.RUSAGE_CHILDREN) - workers_before,
                "peak_main_mib": _peak_resident_mib(),
                "peak_main_after_read_mib": peak_after_read,
                "peak_one_worker_mib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
                **{f"main: {step}": steps.get(step, float("nan")) for step in STEPS},
            }
        )
    )


def run_fit(points: Path, outdir: Path, mode: str, cluster=None, reading: str = "pieces") -> dict:
    """The whole command in a fresh process, its process tree's peak memory sampled (with the
    Dask ``cluster``'s processes, whose memory is part of the run's)."""
    workers = 1 if mode == "1 worker" else 2
    scheduler = cluster.address if mode.startswith("dask") else ""
    command = [sys.executable, __file__, "--child", str(points), str(outdir), str(workers), scheduler, reading]
    started = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with TreeMemory([process.pid, *(cluster.pids if scheduler else [])]) as memory:
        out, err = process.communicate()
    seconds = time.perf_counter() - started
    if process.returncode != 0:
        raise RuntimeError(f"{mode} failed ({process.returncode}): {err[-2000:]}")
    return {"seconds": seconds, "peak_tree_mib": memory.peak / MIB, **json.loads(out.strip().splitlines()[-1])}


def dask_environment() -> dict:
    """``DASK_WORKER_CONFIG`` as the ``DASK_*`` environment variables Dask reads at start (the
    nanny's setting left out: the workers run without a nanny)."""
    from tromplab.workbench import DASK_WORKER_CONFIG

    return {
        "DASK_" + key.upper().replace(".", "__").replace("-", "_"): str(value)
        for key, value in DASK_WORKER_CONFIG.items()
        if not key.startswith("distributed.nanny.")
    }


class DaskCluster:
    """A scheduler and two single-threaded workers started as separate processes (``dask
    scheduler``, ``dask worker --no-nanny``: without the nanny's ``MALLOC_TRIM_THRESHOLD_``),
    as docs/performance.md recommends: the other settings of ``DASK_WORKER_CONFIG`` in
    ``DASK_*`` environment variables, and ``--preload`` of tromplab's worker module in the
    scheduler and the workers (imported when they start, as local workers inherit it from the
    forking process); stopped on leaving."""

    def __init__(self, folder: Path):
        self.folder, self.processes, self.address = folder, [], None

    def __enter__(self):
        scheduler_file = self.folder / "scheduler.json"
        self.log = open(self.folder / "cluster.log", "w")
        self._start("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(scheduler_file))
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        self.address = json.loads(scheduler_file.read_text())["address"]
        for _ in range(2):
            self._start("worker", "--scheduler-file", str(scheduler_file), "--nthreads", "1", "--no-nanny",
                        "--no-dashboard", "--host", "127.0.0.1")  # fmt: skip
        from distributed import Client

        with Client(self.address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
            # preloaded, the import is found done (local workers inherit it from the forking
            # process); without the preload the first run would pay it, about 1 s
            started = time.perf_counter()
            client.run(importlib.import_module, "tromplab.workbench.worker")
            self.warm_up_seconds = time.perf_counter() - started
        print(
            f"Dask cluster: tromplab's worker module found imported in its 2 workers in {self.warm_up_seconds:.2f} s"
            f" (preloaded; not timed in the runs); settings {dask_environment()}",
            flush=True,
        )
        return self

    def _start(self, *arguments):
        command = [sys.executable, "-m", "dask", *arguments]
        command += ["--preload", "tromplab.workbench.worker"]  # the scheduler unpickles the tasks' functions too
        environment = {**os.environ, **dask_environment()}
        self.processes.append(subprocess.Popen(command, stdout=self.log, stderr=subprocess.STDOUT, env=environment))

    @property
    def pids(self):
        return [process.pid for process in self.processes]

    def __exit__(self, *exc):
        for process in self.processes:
            process.terminate()
        for process in self.processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
        self.log.close()
        return False


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


def measure_size(n, modes, folder: Path, cluster, bare_limit, reading: str = "pieces", repeats: int = 1) -> list[dict]:
    """One row per mode for ``n`` experiments: the run's numbers, bare lmfit's and whether the
    results folder is the first mode's, file for file.  With ``repeats`` the modes run that
    many times in turn (1, 2, Dask, 1, 2, Dask, ...: a change of the machine's load touches
    every mode alike) and each row is the mode's median run, its times all listed."""
    points = folder / f"points_{n}.csv"
    if not points.exists():
        write_points(points, n)
    bare_seconds, bare = run_bare(n, bare_limit)
    runs = {mode: [] for mode in modes}
    for _ in range(repeats):
        for mode in modes:
            out = folder / f"out_{n}_{mode.replace(' ', '_').replace(',', '')}"
            runs[mode].append(run_fit(points, out, mode, cluster, reading))
            print(
                f"{n} experiments, {mode}: {runs[mode][-1]['seconds']:.1f} s, {runs[mode][-1]['peak_tree_mib']:.0f} MiB",
                flush=True,
            )
    rows, first = [], None
    for mode in modes:
        out = folder / f"out_{n}_{mode.replace(' ', '_').replace(',', '')}"
        measured = sorted(runs[mode], key=lambda run: run["seconds"])[(len(runs[mode]) - 1) // 2]
        row = {"experiments": n, "mode": mode, "input": reading, **measured, "bare_lmfit_s": bare_seconds}
        row["seconds_of_each_run"] = " ".join(f"{run['seconds']:.2f}" for run in runs[mode])
        row["s_per_1000_experiments"] = 1000 * measured["seconds"] / n
        row["against_bare_lmfit"] = measured["seconds"] / bare_seconds
        if first is None:
            first = out
            row.update(_at_optimum(out, bare))
        else:
            row["same_files_as_first_mode"] = _same_folders(first, out)
        rows.append(row)
    for row in rows:
        row["speedup_1_to_2_workers"] = _speedup(rows)
    return rows


def _at_optimum(out: Path, bare: pd.DataFrame) -> dict:
    """Share of fits at the optimum (within :data:`AT_OPTIMUM` of the lower sum of squares) for tromplab and bare lmfit."""
    both = pd.read_csv(out / "fits.csv", usecols=["experiment", "formula", "ssr"]).merge(bare, on=["experiment", "formula"])
    best = np.minimum(both["ssr"], both["bare_ssr"])
    return {
        "tromplab_at_optimum_pct": 100 * float(np.mean(both["ssr"] <= best * (1 + AT_OPTIMUM) + 1e-15)),
        "bare_at_optimum_pct": 100 * float(np.mean(both["bare_ssr"] <= best * (1 + AT_OPTIMUM) + 1e-15)),
    }


def _same_folders(left: Path, right: Path) -> bool:
    names = sorted(p.name for p in left.iterdir())
    if names != sorted(p.name for p in right.iterdir()):
        return False
    return all(filecmp.cmp(left / name, right / name, shallow=False) for name in names)


def _speedup(rows) -> float:
    seconds = {row["mode"]: row["seconds"] for row in rows}
    return seconds.get("1 worker", np.nan) / seconds.get("2 workers", np.nan)


def extrapolated(table: pd.DataFrame, target: int = 1_000_000) -> pd.DataFrame:
    """Seconds and peak memory of each mode at ``target`` experiments, from a straight line
    ``a + b n`` through the sizes from 10,000 up (none for a mode measured at fewer than two
    of them: below, the fixed costs and the load of the machine would steer the line)."""
    rows = []
    for mode, group in table.groupby("mode", sort=False):
        group = group[group["experiments"] >= 10_000]
        if len(group) < 2:
            continue
        n = group["experiments"].to_numpy(dtype=float)
        row = {"experiments": target, "mode": mode, "extrapolated": True}
        for column in ("seconds", "peak_tree_mib", "peak_main_mib"):
            slope, intercept = np.polyfit(n, group[column].to_numpy(dtype=float), 1)
            row[column] = intercept + slope * target
            if column == "peak_main_mib":
                row["main_growth_kib_per_experiment"] = slope * 1024
        row["s_per_1000_experiments"] = 1000 * row["seconds"] / target
        rows.append(row)
    return pd.DataFrame(rows)


def draw(table: pd.DataFrame, path: Path) -> None:
    """Seconds per 1,000 experiments and peak memory of the process tree against the number of
    experiments, per mode (dashed: to the extrapolation), with bare lmfit's time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (time_axes, memory_axes) = plt.subplots(1, 2, figsize=(10, 4))
    measured = table[~table["extrapolated"].astype(bool)]
    for mode, group in table.groupby("mode", sort=False):
        group = group.sort_values("experiments")
        own = measured[measured["mode"] == mode].sort_values("experiments")
        line = time_axes.plot(own["experiments"], own["s_per_1000_experiments"], "o-", label=mode)[0]
        time_axes.plot(group["experiments"], group["s_per_1000_experiments"], "--", color=line.get_color())
        memory_axes.plot(own["experiments"], own["peak_tree_mib"], "o-", color=line.get_color(), label=mode)
        memory_axes.plot(group["experiments"], group["peak_tree_mib"], "--", color=line.get_color())
    bare = measured.drop_duplicates("experiments")
    time_axes.plot(bare["experiments"], 1000 * bare["bare_lmfit_s"] / bare["experiments"], "k:", label="bare lmfit (9 fits)")
    memory_axes.axhline(1024, color="0.6", lw=0.8)
    for axes, label in ((time_axes, "seconds per 1,000 experiments"), (memory_axes, "peak memory of the process tree (MiB)")):
        axes.set_xscale("log")
        axes.set_xlabel("experiments (dashed: extrapolated)")
        axes.set_ylabel(label)
    time_axes.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def _paired_difference(row, baseline) -> tuple[float, str]:
    """The median of the differences in seconds between ``row``'s runs and ``baseline``'s,
    pair by pair (with ``--repeats``: the two modes ran in turn, so each pair met the same
    load of the machine), and the numbers in words; one run each: the one difference."""
    runs = [float(s) for s in str(row["seconds_of_each_run"]).split()]
    baseline_runs = [float(s) for s in str(baseline["seconds_of_each_run"]).split()]
    differences = np.subtract(runs, baseline_runs)
    words = (f"median {row['seconds']:.1f} s against {baseline['seconds']:.1f} s; paired differences "
             f"{' '.join(f'{d:+.1f}' for d in differences)} s, median {np.median(differences):+.2f} s, "
             f"faster in {int(np.sum(differences < 0))} of {len(differences)} pairs")  # fmt: skip
    return float(np.median(differences)), words


def acceptance(table: pd.DataFrame, small: int, large: int) -> bool:
    """Print PASS or FAIL, with the numbers, for each target; True when every one passes."""

    def row(n, mode):
        found = table[(table["experiments"] == n) & (table["mode"] == mode) & ~table["extrapolated"].astype(bool)]
        return found.iloc[0] if len(found) else None

    one, two, dask, big = row(small, "1 worker"), row(small, "2 workers"), row(small, "dask, 2 workers"), row(large, "2 workers")
    speedup = one["seconds"] / two["seconds"]
    checks = [
        (f"{large:,} experiments on 2 workers: process tree at most 1 GiB",
         big["peak_tree_mib"] <= 1024, f"{big['peak_tree_mib']:.0f} MiB"),
        (f"{large:,} experiments on 2 workers: time per experiment no worse than at {small:,}",
         big["s_per_1000_experiments"] <= two["s_per_1000_experiments"],
         f"{big['s_per_1000_experiments']:.2f} s against {two['s_per_1000_experiments']:.2f} s per 1,000 experiments"),
        (f"1 -> 2 workers at {small:,} experiments: at least 1.8 x, identical files",
         speedup >= 1.8 and bool(two["same_files_as_first_mode"]),
         f"{speedup:.2f} x; identical: {bool(two['same_files_as_first_mode'])}"),
    ]  # fmt: skip
    if dask is not None:
        identical = bool(dask["same_files_as_first_mode"])
        difference, numbers = _paired_difference(dask, two)
        checks.append((f"Dask (2 worker processes of their own) at {small:,}: no slower per core than 2 local workers, identical files",
                       difference <= 0 and identical, f"{numbers}; identical: {identical}"))  # fmt: skip
    print()
    for name, passed, numbers in checks:
        print(f"{'PASS' if passed else 'FAIL'}  {name}: {numbers}")
    steps = ", ".join(f"{step} {two[f'main: {step}']:.2f}" for step in STEPS)
    cpu = f"main process CPU {two['main_cpu_s']:.1f} s, workers CPU {two['workers_cpu_s']:.1f} s"
    print(f"\nwhere the main process's time goes at {small:,} experiments on 2 workers (s): {steps}; {cpu}")
    return all(passed for _, passed, _ in checks)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--sizes", help="experiments per run (default 1000,4000,10000,40000,100000; with --acceptance two sizes, 10000,40000)"
    )
    parser.add_argument("--bare-limit", type=int, default=512)
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask cluster")
    parser.add_argument(
        "--modes", default="1,2,dask", help="the modes to run: 1 (one worker), 2 (two workers), dask (default all)"
    )
    parser.add_argument("--acceptance", action="store_true", help="check the targets: PASS or FAIL with the numbers")
    parser.add_argument(
        "--repeats", type=int, default=1, help="runs of each mode, taken in turn; the table gives the median run (default 1)"
    )
    parser.add_argument("--output", type=Path, default=HERE / "output" / "scaling.csv")
    parser.add_argument(
        "--input",
        choices=("pieces", "whole"),
        default="pieces",
        help="read the points file in pieces, as tromplab fit reads a CSV of 1 MiB or more (default), or whole, "
        "as a Python caller holding the experiments gives them",
    )
    parser.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        points, outdir, workers, scheduler, reading = args.child
        return child_run(points, outdir, int(workers), scheduler or None, reading)
    default = "10000,40000" if args.acceptance else "1000,4000,10000,40000,100000"
    sizes = [int(s) for s in (args.sizes or default).split(",")]
    modes = [
        m for m in MODES if not (args.no_dask and m.startswith("dask")) and m.split(" ")[0].rstrip(",") in args.modes.split(",")
    ]
    load_before = os.getloadavg()[0]
    rows = []
    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        folder = Path(tmp)
        cluster = None if args.no_dask else stack.enter_context(DaskCluster(folder))
        for n in sizes:
            wanted = ["2 workers"] if args.acceptance and n == sizes[-1] else modes
            rows += measure_size(n, wanted, folder, cluster, args.bare_limit, args.input, args.repeats)
    table = pd.DataFrame(rows).assign(extrapolated=False)
    extra = extrapolated(table)
    table = table if extra.empty else pd.concat([table, extra], ignore_index=True)
    save_and_show(table, args.output, load_before)
    columns = ["experiments", "mode", "seconds", "s_per_1000_experiments", "peak_tree_mib", "peak_main_mib", "peak_main_after_read_mib",
               "main_growth_kib_per_experiment", "against_bare_lmfit",
               "speedup_1_to_2_workers", "main_cpu_s", "workers_cpu_s", *[f"main: {s}" for s in STEPS]]  # fmt: skip
    with pd.option_context("display.width", 250, "display.max_columns", 30):
        print(table[[c for c in columns if c in table.columns]].to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    draw(table, args.output.with_suffix(".png"))
    print(f"figure: {args.output.with_suffix('.png')}")
    if args.acceptance:
        return 0 if acceptance(table, sizes[0], sizes[-1]) else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
