"""Command-line fuzzing: mutated bundled tables and options run through ``tromplab.cli.main``.

Each run picks a command (``fit``, ``points``, ``balance``, ``rank``, ``trend``, ``sieve
identify``, ``layer fit``, ``pulp fit``, ``export``), one of the bundled files it reads
(``datasets/`` and ``tests/data/``), mutates the file's text (cells set to extreme,
non-finite or non-numeric values, lines dropped, duplicated or swapped, header names
swapped, misspelt or duplicated, the file cut short, NUL bytes, a byte-order mark, other
separators, scaled numbers, unicode names) and sometimes its options (out-of-range or
malformed values), then runs the command in-process with standard output and error
captured.  Each outcome is classified by exit code; a finding is any Python traceback,
exit 70 (internal error), an exception escaping ``main``, an exit code outside the
documented ones, or anything written by a run that ended in an error (exit 1 or 2).

Usage: ``python benchmarks/fuzz_cli.py [--minutes 5] [--runs N] [--seed 0]`` from the
repository root (last result in docs/reliability.md); ``tests/test_hostile_cli.py`` runs a
short seeded version.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import io
import random
import shutil
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tromplab.cli import main as tromplab_main  # noqa: E402

DATASETS = ROOT / "datasets"
TEST_DATA = ROOT / "tests" / "data"

#: Documented exit codes (README, docs/reliability.md).
EXIT_CODES = {0: "ok", 1: "bad input", 2: "usage", 3: "partial"}

#: Values put into cells: extremes, non-finite, empty, text, other scripts' digits.
CELL_VALUES = ["inf", "-inf", "nan", "NaN", "", " ", "0", "-0", "-1", "1e308", "1e-320", "5e-324", "1e999", "-1e300",
               "abc", "1,5", "0,95", "١٢", "１２", "12%", "1e", "--3", "0x10", "TRUE", "2024-03-05", "#N/A", "None",
               "\"", "'", "Проба 1", "🧪", "x" * 300, "$x_{50}^2$", "../evil", "a\tb"]  # fmt: skip
#: Values for options (each option gets one of these or its own good values).
OPTION_VALUES = ["0", "-1", "1", "2", "nan", "inf", "-inf", "1e9", "0.5", "abc", "", "1e-300", "99999999999999999999"]


@dataclass
class Command:
    """A command, the bundled files it reads and options it takes (good values first)."""

    argv: list[str]
    files: list[Path]
    options: dict[str, list[str]] = field(default_factory=dict)
    flags: list[str] = field(default_factory=list)
    output: str = "-o"
    output_is_file: bool = False


def commands() -> dict[str, Command]:
    points = [TEST_DATA / "points_size_um.csv"]
    lab = [
        DATASETS / "double_deck_screen_decks_lab.csv",
        TEST_DATA / "hydrocyclone_size_class_um.csv",
        TEST_DATA / "pan_at_zero_masses_mm.csv",
        TEST_DATA / "european_semicolon_decimal_comma.csv",
    ]
    lab_options = {"--fine-yield": ["0.4", "0.6"], "--sum-tolerance": ["5"], "--size-unit": ["um", "mm", "parsec"],
                   "--partition-from": ["products", "feed", "both"], "--min-feed-share": ["0", "0.01"]}  # fmt: skip
    fit_options = {"--formulas": ["3,7,11", "plitt,lognormal", "all", "12", "plitt,plitt"], "--alpha": ["0.05", "0.01"],
                   "--ci": ["0.95", "0.9"], "--bootstrap": ["0", "3"], "--seed": ["0", "7"], "--rank-by": ["F", "aicc", "x"],
                   "--partition-to": ["fine", "coarse", "middle"], "--delta-max": ["1000", "1e-9"], "--jobs": ["1"],
                   "--figures": ["none", "best"], **lab_options}  # fmt: skip
    return {
        "fit": Command(["fit"], points + lab, fit_options, ["--no-figures", "--single-fits", "--reconcile"]),
        "points": Command(["points"], lab + points, {**lab_options, "--partition-to": ["fine", "coarse"]}, output_is_file=True),
        "balance": Command(["balance"], lab, lab_options, output=""),
        "rank": Command(["rank"], [DATASETS / "shuvalov2018_table2_F.csv"], {"--alpha": ["0.05"]}, ["--computed-adequacy"]),
        "trend": Command(
            ["trend"],
            [DATASETS / "classifier_trend_surveys.csv"],
            {"--alpha": ["0.01"], "--baseline": ["8", "0"]},
            ["--no-figures"],
        ),  # fmt: skip
        "sieve identify": Command(["sieve", "identify"], [DATASETS / "sieve_identify_residues_example.csv"], output_is_file=True),
        "layer fit": Command(
            ["layer", "fit"], [DATASETS / "layer_extraction_example.csv"], {"--level": ["0.9"]}, output_is_file=True
        ),
        "pulp fit": Command(
            ["pulp", "fit"],
            [DATASETS / "pulp_screen_productivity_example.csv"],
            {"--fit": ["beta,lam", "r"]},
            output_is_file=True,
        ),  # fmt: skip
    }


# --- mutations of a file's text --------------------------------------------------------------
def _split(text: str):
    lines = text.split("\n")
    comments = [i for i, line in enumerate(lines) if line.startswith("#")]
    data = [i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")]
    return lines, comments, data


def _separator(line: str) -> str:
    return ";" if line.count(";") > line.count(",") else ","


def mutate(text: str, rng: random.Random) -> tuple[str, str]:
    """One random change to a table's text; returns the new text and the mutation's name."""
    lines, _, data = _split(text)
    if not data:
        return text, "none"
    header, rows = data[0], data[1:]
    sep = _separator(lines[header])
    kind = rng.choice(["cell", "cell", "cell", "drop_line", "duplicate_line", "swap_lines", "swap_header", "typo_header",
                       "duplicate_header", "drop_column", "truncate", "nul", "bom", "separator", "scale", "unicode_name",
                       "blank_lines", "extra_field", "empty"])  # fmt: skip
    if kind == "cell" and rows:
        row = rng.choice(rows)
        cells = lines[row].split(sep)
        cells[rng.randrange(len(cells))] = rng.choice(CELL_VALUES)
        lines[row] = sep.join(cells)
    elif kind == "drop_line" and rows:
        del lines[rng.choice(rows)]
    elif kind == "duplicate_line" and rows:
        row = rng.choice(rows)
        lines.insert(row, lines[row])
    elif kind == "swap_lines" and len(rows) > 1:
        a, b = rng.sample(rows, 2)
        lines[a], lines[b] = lines[b], lines[a]
    elif kind in ("swap_header", "typo_header", "duplicate_header", "drop_column"):
        names = lines[header].split(sep)
        i, j = rng.randrange(len(names)), rng.randrange(len(names))
        if kind == "swap_header":
            names[i], names[j] = names[j], names[i]
        elif kind == "typo_header":
            names[i] = names[i][:-1] + names[i][-1:] * 2 if names[i] else "x"
        elif kind == "duplicate_header":
            names[i] = names[j]
        else:
            for index in [header, *rows]:
                cells = lines[index].split(sep)
                if i < len(cells):
                    del cells[i]
                lines[index] = sep.join(cells)
            names = None
        if names is not None:
            lines[header] = sep.join(names)
    elif kind == "truncate":
        text = "\n".join(lines)
        return text[: rng.randrange(len(text) + 1)], kind
    elif kind == "nul":
        text = "\n".join(lines)
        at = rng.randrange(len(text) + 1)
        return text[:at] + "\0" + text[at:], kind
    elif kind == "bom":
        return "\ufeff" + "\n".join(lines), kind
    elif kind == "separator":
        other = rng.choice([";", "\t", "|", " "])
        return "\n".join(line.replace(sep, other) if i in data else line for i, line in enumerate(lines)), kind
    elif kind == "scale" and rows:
        factor = rng.choice([1e-300, 1e-12, 1e-3, 25.4, 1e6, 1e300])
        column = rng.randrange(len(lines[header].split(sep)))
        for row in rows:
            cells = lines[row].split(sep)
            try:
                cells[column] = repr(float(cells[column]) * factor)
            except (ValueError, IndexError):
                continue
            lines[row] = sep.join(cells)
    elif kind == "unicode_name" and rows:
        name = rng.choice(["Проба 1", "Образец 1", "試料-α", "🧪", "a/b", "..", "CON", "x" * 250, " ", "\u202e"])
        for row in rows:
            cells = lines[row].split(sep)
            cells[0] = name if rng.random() < 0.5 else cells[0]
            lines[row] = sep.join(cells)
    elif kind == "blank_lines":
        for row in sorted(rng.sample(rows, min(2, len(rows))), reverse=True):
            lines.insert(row, "")
    elif kind == "extra_field" and rows:
        row = rng.choice(rows)
        lines[row] += sep + rng.choice(CELL_VALUES)
    elif kind == "empty":
        return "", kind
    return "\n".join(lines), kind


# --- one run ---------------------------------------------------------------------------------
@dataclass
class Outcome:
    """What one run did."""

    command: str
    argv: list[str]
    mutations: list[str]
    code: int | None
    finding: str = ""
    stderr: str = ""

    @property
    def label(self) -> str:
        return self.finding or EXIT_CODES.get(self.code, f"exit {self.code}")


def run_once(rng: random.Random, folder: Path, available: dict[str, Command]) -> Outcome:
    name = rng.choice(sorted(available))
    command = available[name]
    source = rng.choice(command.files)
    text = source.read_text(encoding="utf-8")
    mutations = []
    for _ in range(rng.choice([0, 1, 1, 2, 3])):
        text, kind = mutate(text, rng)
        mutations.append(kind)
    run_folder = Path(tempfile.mkdtemp(dir=folder))
    suffix = rng.choice([source.suffix] * 9 + [".txt", ".tsv", ".xlsx", ".json", ""])
    path = run_folder / f"input{suffix}"
    path.write_bytes(text.encode("utf-8", errors="surrogatepass"))
    argv = [*command.argv, str(path)]
    output = run_folder / ("out.csv" if command.output_is_file else "out")
    if command.output:
        argv += [command.output, str(output)]
    for option, good in command.options.items():
        if rng.random() < 0.15:
            argv += [option, rng.choice(good)]
    if command.options and rng.random() < 0.25:  # one option with a value from the hostile list
        option = rng.choice(sorted(command.options))
        argv += [option, rng.choice(OPTION_VALUES)]
        mutations.append(option)
    for flag in command.flags:
        if rng.random() < 0.2:
            argv.append(flag)
    if name == "fit" and "--no-figures" not in argv and "--figures" not in argv:
        argv.append("--no-figures")  # figures take most of the time; a few runs draw them (--figures best)
    before = {p.name for p in run_folder.iterdir()}
    stdout, stderr = io.StringIO(), io.StringIO()
    outcome = Outcome(name, argv, mutations, None)
    try:
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            outcome.code = tromplab_main(argv)
    except BaseException as error:  # noqa: BLE001 - anything escaping main is a finding
        if isinstance(error, KeyboardInterrupt):
            raise
        outcome.finding = f"escaped {type(error).__name__}: {error}"
    outcome.stderr = stderr.getvalue()
    if not outcome.finding:
        if "Traceback" in outcome.stderr:
            outcome.finding = "traceback"
        elif outcome.code == 70:
            outcome.finding = "internal error (70)"
        elif outcome.code not in EXIT_CODES:
            outcome.finding = f"undocumented exit {outcome.code}"
        elif outcome.code in (1, 2) and {p.name for p in run_folder.iterdir()} != before:
            outcome.finding = "wrote on error"
    if not outcome.finding:
        shutil.rmtree(run_folder, ignore_errors=True)
    return outcome


def fuzz(*, seed: int = 0, runs: int | None = None, seconds: float | None = None, report=None) -> list[Outcome]:
    """Run ``runs`` mutated command lines (or as many as fit in ``seconds``); return the outcomes.

    Runs that found something keep their input folder (named in ``Outcome.argv``)."""
    rng = random.Random(seed)
    available = commands()
    folder = Path(tempfile.mkdtemp(prefix="tromplab-fuzz-cli-"))
    outcomes = []
    start = time.monotonic()
    while (runs is None or len(outcomes) < runs) and (seconds is None or time.monotonic() - start < seconds):
        outcome = run_once(rng, folder, available)
        outcomes.append(outcome)
        if outcome.finding and report is not None:
            report(outcome)
    if not any(o.finding for o in outcomes):
        shutil.rmtree(folder, ignore_errors=True)
    return outcomes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=5.0, help="how long to run (default 5)")
    parser.add_argument("--runs", type=int, default=None, help="stop after this many runs instead")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    def report(outcome: Outcome) -> None:
        last = outcome.stderr.strip().splitlines()[-1:] or [""]
        print(f"FINDING {outcome.label}: {' '.join(outcome.argv)} (mutations {outcome.mutations}): {last[0][:300]}", flush=True)

    start = time.perf_counter()
    outcomes = fuzz(seed=args.seed, runs=args.runs, seconds=None if args.runs else args.minutes * 60, report=report)
    minutes = (time.perf_counter() - start) / 60
    table = collections.Counter((o.command, o.label) for o in outcomes)
    for (command, label), n in sorted(table.items()):
        print(f"{command:>15}  {label:<24} {n}")
    findings = sum(1 for o in outcomes if o.finding)
    print(f"{len(outcomes)} runs in {minutes:.1f} min (seed {args.seed}): {findings} finding(s)")
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
