"""Digests of the results folders ``tromplab fit`` writes, to show a refactoring changes no byte.

Runs ``tromplab fit`` on every bundled dataset it reads, in several configurations (the
defaults, ``--ci 0.95``, ``--extended``, ``--jobs 2``, ``--format parquet``, ``--dask local``,
``--excel``), and on a synthetic batch large enough to stream (``--figures none`` and
``auto``, one and two workers); records the SHA-256 of every file written and the console's
standard output, per run, in a JSON file.  ``--compare OLD.json`` then lists every file that
differs, is missing or is new, and exits 1 when any does.

    python benchmarks/fit_folders_digest.py --out before.json          # on the old code
    python benchmarks/fit_folders_digest.py --out after.json --compare before.json

A dataset the command refuses (a flowsheet, a washability table) is recorded with its exit
code, so a refusal that changes is caught too.  The runs take a few minutes on two cores.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import re
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from scaling import write_points  # noqa: E402

#: Configurations run on every bundled dataset: name -> extra options.
CONFIGURATIONS = {
    "default": [],
    "ci": ["--ci", "0.95"],
    "extended": ["--extended", "--rank-extended", "--partition-to", "coarse"],
    "jobs2": ["--jobs", "2", "--ci", "0.9", "--rank-by", "aicc"],
    "parquet": ["--format", "parquet", "--figures", "best"],
    "excel": ["--excel", "--alpha", "0.1", "--bootstrap", "20", "--seed", "3"],
}
#: Configurations run on :data:`ONCE_ON` only (a Dask cluster takes seconds to start).
ONCE_ON = "double_deck_screen_decks_lab.csv"
ONCE = {"dask": ["--dask", "local"], "single": ["--single-fits", "--formulas", "plitt,lognormal,3"]}
#: Configurations of the synthetic batch (streamed from 1,000 experiments).
LARGE = {
    "large-none": ["--figures", "none", "--jobs", "1"],
    "large-auto-jobs2": ["--figures", "auto", "--jobs", "2", "--ci", "0.95"],
    "large-memory": ["--figures", "none", "--format", "parquet", "--jobs", "2"],
}


def digest_file(path: Path) -> str:
    """The SHA-256 of a file; of a workbook, of its parts but the time it was written
    (``docProps/core.xml``), which differs from run to run."""
    if path.suffix != ".xlsx":
        return hashlib.sha256(path.read_bytes()).hexdigest()
    digest = hashlib.sha256()
    with zipfile.ZipFile(path) as book:
        for name in sorted(book.namelist()):
            if name != "docProps/core.xml":
                digest.update(name.encode() + b"\0" + book.read(name))
    return digest.hexdigest()


def digest_folder(folder: Path) -> dict[str, str]:
    """``{relative path: sha256}`` of every file under ``folder`` (or of ``folder``, a file)."""
    if folder.is_file():
        return {folder.name: digest_file(folder)}
    return {str(path.relative_to(folder)): digest_file(path) for path in sorted(folder.rglob("*")) if path.is_file()}


def run(input_path: Path, options: list[str], scratch: Path, command: tuple[str, ...] = ("fit",)) -> dict:
    """One ``tromplab fit`` run (or of another ``command``): its exit code, its standard output's
    digest and its files' digests."""
    outdir = scratch / "out"
    command = [sys.executable, "-m", "tromplab", *command, str(input_path), "-o", str(outdir), *options]
    done = subprocess.run(command, capture_output=True, text=True, cwd=scratch)  # no terminal: no progress bars
    stdout = done.stdout.replace(str(scratch), "SCRATCH")
    return {
        "exit": done.returncode,
        "stdout": hashlib.sha256(stdout.encode()).hexdigest(),
        "stderr_tail": done.stderr.replace(str(ROOT), "ROOT").strip().splitlines()[-1:] if done.returncode else [],
        "files": digest_folder(outdir) if outdir.exists() else {},
    }


def all_runs(large: int, only: re.Pattern, keep: Path | None = None) -> dict:
    datasets = sorted(p for p in (ROOT / "datasets").glob("*.csv"))
    runs = {}
    # the folders written are kept under ``keep`` when it is given (to compare their numbers), else removed
    if keep:
        keep.mkdir(parents=True, exist_ok=True)
    with contextlib.nullcontext(keep) if keep else tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        for dataset in datasets:
            configurations = {**CONFIGURATIONS, **(ONCE if dataset.name == ONCE_ON else {})}
            for name, options in configurations.items():
                if not only.search(f"{dataset.name} {name}"):
                    continue
                scratch = folder / f"{dataset.stem}-{name}"
                scratch.mkdir()
                runs[f"{dataset.name} {name}"] = run(dataset, options, scratch)
                print(f"{dataset.name} {name}: exit {runs[f'{dataset.name} {name}']['exit']}", flush=True)
        points = write_points(folder / "large_points.csv", large)
        for name, options in LARGE.items():
            if not only.search(name):
                continue
            scratch = folder / name
            scratch.mkdir()
            runs[name] = run(points, options, scratch)
            print(f"{name}: exit {runs[name]['exit']}", flush=True)
    return runs


def compare(old: dict, new: dict) -> list[str]:
    """Every difference between two digests, one line each."""
    lines = []
    for key in sorted(set(old) | set(new)):
        if key not in old or key not in new:
            lines.append(f"{key}: only in {'new' if key in new else 'old'}")
            continue
        a, b = old[key], new[key]
        for field in ("exit", "stdout", "stderr_tail"):
            if a[field] != b[field]:
                lines.append(f"{key}: {field} differs ({a[field]} -> {b[field]})")
        for name in sorted(set(a["files"]) | set(b["files"])):
            if a["files"].get(name) != b["files"].get(name):
                lines.append(f"{key}: {name} differs")
    return lines


def save_and_compare(runs: dict, out: Path, before: Path | None, only: re.Pattern) -> int:
    """Write the digests ``runs`` to ``out`` and, given the file ``before`` of the old code's, print
    every difference in the runs ``only`` matches; the exit code, 1 where anything differs."""
    out.write_text(json.dumps(runs, indent=1, sort_keys=True))
    print(f"{len(runs)} runs, {sum(len(r['files']) for r in runs.values())} files digested into {out}")
    if before is None:
        return 0
    old = {key: found for key, found in json.loads(before.read_text()).items() if only.search(key)}
    differences = compare(old, runs)
    print("\n".join(differences) or "byte-identical: every file and every console output")
    return 1 if differences else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="JSON file of the digests")
    parser.add_argument("--compare", type=Path, default=None, help="digests of the old code, compared with these")
    parser.add_argument("--large", type=int, default=1200, help="experiments of the streamed batch (default 1200)")
    parser.add_argument("--keep", type=Path, default=None, help="folder in which to keep the results folders written")
    parser.add_argument("--only", type=re.compile, default=re.compile(""), help="runs whose name matches this regex")
    args = parser.parse_args(argv)
    return save_and_compare(all_runs(args.large, args.only, args.keep), args.out, args.compare, args.only)


if __name__ == "__main__":
    sys.exit(main())
