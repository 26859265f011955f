"""Digests of the results folders ``tromplab density fit`` writes, to show a refactoring changes no byte.

The density counterpart of ``fit_folders_digest.py`` (whose digests and comparison it uses):
runs ``tromplab density fit`` on the bundled tracer table and on simulated inputs that reach
every path of the fits (40 binomial tracer tests, overdispersed beta-binomial tests, tests
whose tracers separate, float-sink analyses with and without the feed, partitions given
directly), in several configurations (the defaults, ``--ci 0.95``, ``--ci 0.9 --curves
plain``, ``--method least_squares``, ``--excel --report``), and records the SHA-256 of every
file written and of the console's standard output.

    python benchmarks/density_folders_digest.py --out before.json          # on the old code
    python benchmarks/density_folders_digest.py --out after.json --compare before.json

The simulated inputs are made with fixed seeds by ``tromplab.density.simulation`` of the code
that runs the script; a change there shows up as a difference of the inputs themselves
(their digests are recorded too, under ``inputs``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from density_speed import tracer_campaign  # noqa: E402
from fit_folders_digest import compare, digest_file  # noqa: E402
from fit_folders_digest import run as fit_run  # noqa: E402

from tromplab.density.simulation import beta_binomial_tracer_test, float_sink_table, simulate_tracer_test  # noqa: E402

#: Configurations run on every input: name -> options of ``tromplab density fit``.
CONFIGURATIONS = {
    "default": ["--figures", "none"],
    "ci": ["--ci", "0.95", "--figures", "none"],
    "plain-ci90": ["--ci", "0.9", "--curves", "plain", "--figures", "none"],
    "least-squares": ["--method", "least_squares", "--ci", "0.95", "--figures", "none"],
    "documents": ["--ci", "0.95", "--excel", "--report", "--figures", "best"],
}


def inputs(folder: Path) -> dict[str, Path]:
    """The tables the runs read: the bundled tracer table and simulated ones (fixed seeds)."""
    rng = np.random.default_rng(44)
    paths = {"bundled": ROOT / "datasets" / "density_tracers_dmc_by_size_synthetic.csv"}
    tables = {"campaign": tracer_campaign(40)}
    densities = np.round(np.linspace(1.35, 1.75, 9), 3)
    tables["overdispersed"] = pd.concat(
        [
            beta_binomial_tracer_test("normal", {"rho50": 1.55, "ep": 0.05}, densities, precision=4.0, rng=rng, test=f"od{i}")
            for i in range(6)
        ],
        ignore_index=True,
    )
    steps = pd.DataFrame({"test": "step", "density": [1.3, 1.4, 1.5, 1.6, 1.7], "placed": 20,
                          "sinks": [0, 0, 3, 20, 20], "floats": [20, 20, 17, 0, 0]})  # fmt: skip
    limits = simulate_tracer_test("logistic_limits", {"rho_c": 1.5, "ep_c": 0.04, "light_limit": 0.08, "heavy_limit": 0.9},
                                  np.round(np.linspace(1.3, 1.8, 11), 3), placed=60, rng=rng, test="limits")  # fmt: skip
    tables["mixed"] = pd.concat([steps, limits], ignore_index=True)
    bounds = [1.3, 1.4, 1.5, 1.6, 1.7, 1.8]
    feed = [30, 20, 12, 8, 6, 9, 15]
    params = {"rho50": 1.52, "ep": 0.06}
    with_feed = float_sink_table("normal", params, bounds, feed, test="fs")
    noisy = with_feed.copy()
    for column in ("feed_pct", "floats_pct", "sinks_pct"):  # analyses with errors: the joint fit has residuals
        noisy[column] = noisy[column] * np.exp(rng.normal(0.0, 0.03, len(noisy)))
    tables["float_sink_feed"] = noisy
    tables["float_sink"] = float_sink_table("gompertz", params, bounds, feed, test="fs", with_feed=False)
    partition = get_partitions(rng)
    tables["partition"] = partition
    for name, table in tables.items():
        paths[name] = folder / f"{name}.csv"
        table.to_csv(paths[name], index=False)
    return paths


def get_partitions(rng) -> pd.DataFrame:
    """Partitions to sinks given directly, with errors (the least-squares path on shares)."""
    density = np.round(np.linspace(1.3, 1.8, 8), 3)
    share = 1.0 / (1.0 + np.exp(-np.log(3.0) * (density - 1.55) / 0.05))
    share = np.clip(share + rng.normal(0.0, 0.02, density.size), 0.0, 1.0)
    return pd.DataFrame({"test": "given", "density": density, "partition_sinks": np.maximum.accumulate(share)})


def all_runs(only: re.Pattern, keep: Path | None = None) -> dict:
    runs = {}
    # the folders written are kept under ``keep`` when it is given (to compare their numbers), else removed
    if keep:
        keep.mkdir(parents=True, exist_ok=True)
    with contextlib.nullcontext(keep) if keep else tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        paths = inputs(folder)
        runs["inputs"] = {name: digest_file(path) for name, path in paths.items()}
        for name, path in paths.items():
            for configuration, options in CONFIGURATIONS.items():
                key = f"{name} {configuration}"
                if not only.search(key):
                    continue
                scratch = folder / f"{name}-{configuration}"
                scratch.mkdir()
                runs[key] = run(path, options, scratch)
                print(f"{key}: exit {runs[key]['exit']}", flush=True)
    return runs


def run(input_path: Path, options: list[str], scratch: Path) -> dict:
    """One ``tromplab density fit`` run (``fit_folders_digest.run`` with the command's name)."""
    return fit_run(input_path, options, scratch, command=("density", "fit"))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="JSON file of the digests")
    parser.add_argument("--compare", type=Path, default=None, help="digests of the old code, compared with these")
    parser.add_argument("--keep", type=Path, default=None, help="folder in which to keep the results folders written")
    parser.add_argument("--only", type=re.compile, default=re.compile(""), help="runs whose name matches this regex")
    args = parser.parse_args(argv)
    runs = all_runs(args.only, args.keep)
    args.out.write_text(json.dumps(runs, indent=1, sort_keys=True))
    print(
        f"{len(runs) - 1} runs, {sum(len(r['files']) for k, r in runs.items() if k != 'inputs')} files digested into {args.out}"
    )
    if args.compare is None:
        return 0
    old = json.loads(args.compare.read_text())
    differences = [f"inputs differ: {old.get('inputs')} -> {runs['inputs']}"] if old.get("inputs") != runs["inputs"] else []
    old = {key: value for key, value in old.items() if key != "inputs" and args.only.search(key)}
    differences += compare(old, {key: value for key, value in runs.items() if key != "inputs"})
    print("\n".join(differences) or "byte-identical: every file and every console output")
    return 1 if differences else 0


if __name__ == "__main__":
    sys.exit(main())
