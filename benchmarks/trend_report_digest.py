"""Digests of what ``tromplab trend`` and ``tromplab report`` write, to show a speed-up changes no byte.

Runs ``tromplab trend`` on the bundled survey series in several configurations (a chosen
formula with and without figures, the ranking's best formula, formula (11), which is fitted
one survey at a time, a date-range baseline) and ``tromplab report`` on every bundled
dataset it reads (the defaults and ``--ci 0.9``); records the SHA-256 of every file written
and of the console's standard output and standard error, per run, in a JSON file.
``--compare OLD.json`` lists every file that differs, is missing or is new, and exits 1 when
any does (the digest of a workbook leaves out its time stamp, as ``fit_folders_digest.py``).

    python benchmarks/trend_report_digest.py --out before.json          # on the old code
    python benchmarks/trend_report_digest.py --out after.json --compare before.json

The runs take about a minute on two cores.
"""

from __future__ import annotations

import argparse
import hashlib
import re
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from fit_folders_digest import digest_folder, save_and_compare  # noqa: E402

SERIES = ROOT / "datasets" / "classifier_trend_surveys.csv"
#: ``tromplab trend`` configurations on :data:`SERIES`: name -> options.
TREND = {
    "trend-documented": ["--formula", "plitt_bypass", "--size-unit", "um"],
    "trend-best": [],
    "trend-plitt-no-figures": ["--formula", "plitt", "--no-figures", "--alpha", "0.05", "--baseline", "6"],
    "trend-shuvalov": ["--formula", "shuvalov", "--baseline", "2025-01-06:2025-02-24"],
}
#: ``tromplab report`` configurations on every bundled dataset: name -> options.
REPORT = {"report-default": [], "report-ci": ["--ci", "0.9", "--title", "Digest"]}


def run(command: str, input_path: Path, options: list[str], scratch: Path) -> dict:
    """One run of ``command``: exit code, digests of standard output and error and of its files."""
    outdir = scratch / "out"
    target = ["-o", str(outdir)] if command == "trend" else ["-o", str(outdir / "report.html")]
    done = subprocess.run(  # no terminal: no progress bars
        [sys.executable, "-m", "tromplab", command, str(input_path), *target, *options],
        capture_output=True,
        text=True,
        cwd=scratch,
    )
    stdout, stderr = (text.replace(str(scratch), "SCRATCH").replace(str(ROOT), "ROOT") for text in (done.stdout, done.stderr))
    return {
        "exit": done.returncode,
        "stdout": hashlib.sha256(stdout.encode()).hexdigest(),
        "stderr_tail": [hashlib.sha256(stderr.encode()).hexdigest()],
        "files": digest_folder(outdir) if outdir.exists() else {},
    }


def all_runs(only: re.Pattern) -> dict:
    jobs = [("trend", SERIES, name, options) for name, options in TREND.items()]
    jobs += [
        ("report", dataset, name, options)
        for dataset in sorted((ROOT / "datasets").glob("*.csv"))
        for name, options in REPORT.items()
    ]
    runs = {}
    with tempfile.TemporaryDirectory() as folder:
        for command, dataset, name, options in jobs:
            key = f"{dataset.name} {name}"
            if not only.search(key):
                continue
            scratch = Path(folder) / f"{dataset.stem}-{name}"
            scratch.mkdir()
            runs[key] = run(command, dataset, options, scratch)
            print(f"{key}: exit {runs[key]['exit']}, {len(runs[key]['files'])} files", flush=True)
    return runs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="JSON file of the digests")
    parser.add_argument("--compare", type=Path, default=None, help="digests of the old code, compared with these")
    parser.add_argument("--only", type=re.compile, default=re.compile(""), help="runs whose name matches this regex")
    args = parser.parse_args(argv)
    return save_and_compare(all_runs(args.only), args.out, args.compare, args.only)


if __name__ == "__main__":
    sys.exit(main())
