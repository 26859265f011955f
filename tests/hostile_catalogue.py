"""The catalogue of the hostile-input battery (tests/test_hostile_battery.py): mutations of
good inputs and options, each with the outcome it must have.

A :class:`Case` is a command line run in-process (``tromplab.cli.main``) in an empty folder
holding its input files, or a call of the Python API.  ``expect`` is the set of allowed
outcomes: exit codes for the command line (0 done, 1 bad input, 2 usage, 3 partial: a result
failed and says so), exception names (``"OptionError"``, ``"InputError"``, ``"TypeError"``) or
``"ok"`` for the API.  ``words`` must appear in the message of a refusal.  The families and
their counts are listed in docs/reliability.md ("Hostile-input battery").

The loader files of tests/test_hostile_inputs.py (``TEXT_CASES``, ``FILE_CASES``) are one
family here, run through every command that reads a table instead of ``fit`` alone.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import dataclass, field

from tromplab.cli import build_parser

from .conftest import DATASETS, LAB_CLASS_HEADER, LAB_CLASS_ROWS
from .hostile_edges import last_edges
from .test_hostile_inputs import FILE_CASES, TEXT_CASES

SIZES = (10, 20, 40, 80, 160, 320)
CURVE = (0.97, 0.9, 0.7, 0.35, 0.1, 0.02)
OTHER = (0.99, 0.93, 0.75, 0.3, 0.08, 0.01)


@dataclass(frozen=True)
class Case:
    """One hostile input and the outcomes it may have.

    ``argv`` may hold ``{name}`` for the path of an input file of ``files`` (file name ->
    text, bytes or a function writing the path) and ``{tmp}`` for the folder of the run.
    ``call`` (API cases) takes that folder and returns anything; its exception's class
    name is the outcome.  ``check`` takes the folder of a run that ended in 0 or 3 and asserts
    what the case is about (names read back, no formula cell).  ``known`` names a finding not
    yet fixed: the case is expected to fail (strictly: it fails the battery once fixed, so the
    mark is removed).
    """

    family: str
    id: str
    expect: frozenset
    argv: tuple = ()
    files: dict = field(default_factory=dict)
    words: str = ""
    call: Callable | None = None
    slow: bool = False
    check: Callable | None = None
    known: str = ""


def case(family, id, expect, argv=(), files=None, words="", call=None, slow=False, check=None, known="") -> Case:
    expect = frozenset(expect if isinstance(expect, (set, frozenset, tuple, list)) else [expect])
    return Case(family, id, expect, tuple(argv), dict(files or {}), words, call, slow, check, known)


# --- good inputs --------------------------------------------------------------------------
def points_text(curves=None, *, header="experiment,size,partition_fine", rows=None) -> str:
    """Tromp points of experiments A and B (or ``curves``: name -> partitions at SIZES)."""
    curves = curves if curves is not None else {"A": CURVE, "B": OTHER}
    if rows is None:
        rows = [f"{name},{size},{p}" for name, curve in curves.items() for size, p in zip(SIZES, curve)]
    return header + "\n" + "\n".join(rows) + "\n"


LAB = LAB_CLASS_HEADER + "\n".join(LAB_CLASS_ROWS) + "\n"
FIT = ("fit", "{points.csv}", "-o", "{tmp}/out", "--formulas", "plitt,lognormal", "--no-figures", "--jobs", "1")


def _dataset(name: str) -> str:
    return (DATASETS / name).read_text(encoding="utf-8")


def _with_cell(text: str, row: int, column: str, value: str) -> str:
    """``text`` (CSV, comments above the header kept out) with one cell replaced."""
    lines = [line for line in text.splitlines() if not line.startswith("#")]
    header = lines[0].split(",")
    cells = lines[row + 1].split(",")
    cells[header.index(column)] = value
    lines[row + 1] = ",".join(cells)
    return "\n".join(lines) + "\n"


def _with_column(text: str, column: str, value: str) -> str:
    lines = text.rstrip("\n").split("\n")
    return "\n".join([lines[0] + "," + column, *(line + "," + value for line in lines[1:])]) + "\n"


# --- families -----------------------------------------------------------------------------
#: Commands and how each is given one input file named ``{input}`` (for loader files).
READERS = {
    "fit": ("fit", "{input}", "-o", "{tmp}/out", "--no-figures"),
    "compare": ("compare", "{input}"),
    "report": ("report", "{input}", "-o", "{tmp}/report.html"),
    "balance": ("balance", "{input}"),
    "points": ("points", "{input}", "-o", "{tmp}/pts.csv"),
    "trend": ("trend", "{input}", "-o", "{tmp}/trend", "--no-figures"),
    "rank": ("rank", "{input}", "-o", "{tmp}/rank"),
    "sieve identify": ("sieve", "identify", "{input}", "-o", "{tmp}/laws.csv"),
    "layer fit": ("layer", "fit", "{input}", "-o", "{tmp}/layer.csv"),
    "pulp fit": ("pulp", "fit", "{input}", "-o", "{tmp}/pulp.csv"),
    "circuit flowsheet": ("circuit", "{input}", "{survey.csv}", "-o", "{tmp}/circuit", "--no-figures"),
    "circuit survey": ("circuit", "{flowsheet.csv}", "{input}", "-o", "{tmp}/circuit", "--no-figures"),
}


#: Files of FILE_CASES refused for their cells, which a reader checks after its columns.
CONTENT_FILES = {"dates.xlsx", "duplicate.xlsx", "folder.csv"}


def loader_files() -> list[Case]:
    """Files no reader takes (tests/test_hostile_inputs.py FILE_CASES) through every reader."""
    cases = []
    circuit = {"survey.csv": _dataset("circuit_example_survey.csv"), "flowsheet.csv": _dataset("circuit_example_flowsheet.csv")}
    for name, make, words in FILE_CASES:
        for command, argv in READERS.items():
            files = {**circuit, name: make}
            argv_of = [a.replace("{input}", "{" + name + "}") for a in argv]
            named = words if command in ("fit", "compare", "report") or name not in CONTENT_FILES else name.split(".")[0]
            cases.append(case("loader files", f"{command}: {name}", 1, argv_of, files, named))
    return cases


def loader_texts() -> list[Case]:
    """Bad tables of tests/test_hostile_inputs.py TEXT_CASES through the other readers of
    points and lab tables (``compare``, ``report``; ``fit`` runs them there)."""
    cases = []
    for i, (text, options, words) in enumerate(TEXT_CASES):
        for command in ("compare", "report"):
            if command == "compare" and "--size-unit" in options:  # compare has no --size-unit
                continue
            argv = [a.replace("{input}", "{input.csv}") for a in READERS[command]] + list(options)
            cases.append(case("loader texts", f"{command}: {i:02d} {words[:50]}", 1, argv, {"input.csv": text}, words))
    return cases


#: Cell values and their outcome in each column of a points file (1: refused, 0: fitted).
VALUES = {
    "inf": (1, 1, 1),
    "-inf": (1, 1, 1),
    "nan": (1, 1, 1),
    "": (1, 1, 1),
    "abc": (1, 1, 1),
    "1e999": (1, 1, 1),
    "1+2j": (1, 1, 1),
    "0x10": (1, 1, 1),
    "TRUE": (1, 1, 1),
    "-1": (1, 1, 1),
    "0": (1, 0, 1),
    "1e308": (1, 1, 0),
    "1e-300": (1, 0, 0),
    "5e-324": (1, 0, 0),
    "1.5": (1, 1, 0),
    "-0.05": (1, 1, 1),
    "1e3": (1, 1, 0),
}


def values() -> list[Case]:
    """Extreme, non-finite and non-numeric cells in each numeric column of a points file."""
    good = points_text(
        header="experiment,size,partition_fine,weight",
        rows=[f"{n},{s},{p},1" for n, c in {"A": CURVE, "B": OTHER}.items() for s, p in zip(SIZES, c)],
    )
    cases = []
    for value, outcomes in VALUES.items():
        for column, expect in zip(("size", "partition_fine", "weight"), outcomes):
            if column == "size" and value in ("1.5", "1e3"):  # a size among 10..320: a duplicate or a wide span
                expect = 0
            text = _with_cell(good, 2, column, value)
            words = f"column '{column}'" if expect == 1 else ""
            cases.append(case("values", f"{column}={value or 'blank'}", expect, FIT, {"points.csv": text}, words))
    return cases


def columns() -> list[Case]:
    """Missing, duplicated, misspelt, reordered and extra columns of a points file."""
    rows = [f"{n},{s},{p}" for n, c in {"A": CURVE, "B": OTHER}.items() for s, p in zip(SIZES, c)]
    flipped = [f"{n},{s},{1 - p:.4g}" for n, c in {"A": CURVE, "B": OTHER}.items() for s, p in zip(SIZES, c)]
    single = [f"{s},{p}" for s, p in zip(SIZES, CURVE)]
    table = {
        "no size": ("experiment,partition_fine", [f"{n},{p}" for n, c in {"A": CURVE}.items() for p in c], 1, "size"),
        "no partition": ("experiment,size", [f"A,{s}" for s in SIZES], 1, "partition"),
        "no experiment": ("size,partition_fine", single, 0, ""),
        "partition to coarse": ("experiment,size,partition_coarse", flipped, 0, ""),
        "percentages": ("experiment,size,partition_fine_pct", [f"A,{s},{100 * p:g}" for s, p in zip(SIZES, CURVE)], 0, ""),
        "percentages unmarked": (
            "experiment,size,partition_fine",
            [f"A,{s},{100 * p:g}" for s, p in zip(SIZES, CURVE)],
            1,
            "partition 97",
        ),
        "columns reordered": (
            "partition_fine,experiment,size",
            [f"{p},{n},{s}" for n, c in {"A": CURVE}.items() for s, p in zip(SIZES, c)],
            0,
            "",
        ),
        "size in mm": ("experiment,size_mm,partition_fine", rows, 0, ""),
        "two partitions": ("experiment,size,partition_fine,partition_coarse", [r + ",0.5" for r in rows], 1, "partition"),
        "unknown column": ("experiment,size,partition_fine,colour", [r + ",red" for r in rows], 1, "colour"),
        "note column": ("experiment,size,partition_fine,note", [r + ",sampled by J" for r in rows], 0, ""),
        "header only": ("experiment,size,partition_fine", [], 1, ""),
        "upper-case header": ("EXPERIMENT,SIZE,PARTITION_FINE", rows, 1, "SIZE"),
        "spaces in header": (" experiment , size , partition_fine ", rows, 0, ""),
        "weight column": ("experiment,size,partition_fine,weight", [r + ",2" for r in rows], 0, ""),
        "used column": ("experiment,size,partition_fine,used", [r + ",true" for r in rows], 0, ""),
    }
    return [
        case("columns", name, expect, FIT, {"points.csv": header + "\n" + "\n".join(body) + "\n"}, words)
        for name, (header, body, expect, words) in table.items()
    ]


def rows() -> list[Case]:
    """Duplicated, reordered, too few and degenerate rows; experiments that fail beside good ones."""
    base = [f"{n},{s},{p}" for n, c in {"A": CURVE, "B": OTHER}.items() for s, p in zip(SIZES, c)]
    table = {
        "row duplicated": (base + base[:1], 1, "duplicate size"),
        "rows reversed": (base[::-1], 0, ""),
        "rows interleaved": (base[::2] + base[1::2], 0, ""),
        "one row": (base[:1], 1, ""),
        "two points": (base[:2], 1, ""),
        "three points": (base[:3], {0, 3}, ""),
        "an experiment of two points beside a good one": (base[:2] + base[6:], 3, ""),
        "a flat experiment beside a good one": ([f"F,{s},0.4" for s in SIZES] + base[6:], 3, ""),
        "only a flat experiment": ([f"F,{s},0.4" for s in SIZES], 1, "no formula could be fitted"),
        "a step curve": ([f"S,{s},{p}" for s, p in zip(SIZES, (1, 1, 1, 0, 0, 0))], {0, 3}, ""),
        "an increasing curve": ([f"U,{s},{p}" for s, p in zip(SIZES, CURVE[::-1])], {0, 3}, ""),
        "all ones": ([f"O,{s},1" for s in SIZES], 1, ""),
        "all zeros": ([f"Z,{s},0" for s in SIZES], 1, ""),
        "blank lines between rows": ([*base[:3], "", *base[3:]], 0, ""),
        "trailing separators": ([r + "," for r in base], {0, 1}, ""),
        "many experiments": ([f"E{k},{s},{p}" for k in range(40) for s, p in zip(SIZES, CURVE)], 0, ""),
    }
    return [
        case("rows", name, expect, FIT, {"points.csv": "experiment,size,partition_fine\n" + "\n".join(body) + "\n"}, words)
        for name, (body, expect, words) in table.items()
    ]


def encodings() -> list[Case]:
    """Byte-level variants of a good points file: marks, line ends, separators, decimal marks."""
    text = points_text()
    table = {
        "byte-order mark": ("points.csv", b"\xef\xbb\xbf" + text.encode(), 0),
        "CRLF line ends": ("points.csv", text.replace("\n", "\r\n").encode(), 0),
        "no final newline": ("points.csv", text.rstrip("\n").encode(), 0),
        "semicolons and decimal commas": ("points.csv", text.replace(",", ";").replace(".", ",").encode(), 0),
        "tabs in a .tsv": ("points.tsv", text.replace(",", "\t").encode(), 0),
        "tabs in a .csv": ("points.csv", text.replace(",", "\t").encode(), 0),
        "pipes": ("points.csv", text.replace(",", "|").encode(), 1),
        "latin-1 name": ("points.csv", text.replace("A,", "Probe \xe9,").encode("latin-1"), 1),
        "utf-16": ("points.csv", text.encode("utf-16"), 1),
        "utf-8 names in five scripts": ("points.csv", text.replace("A,", "Проба 試料 δείγμα नमूना,").encode(), 0),
        "a NUL byte": ("points.csv", text.replace("B,", "B\x00,", 1).encode(), 1),
        "comment above the header": ("points.csv", ("# lab 3, run 12\n" + text).encode(), 0),
        "text after the table": ("points.csv", (text + "end of table\n").encode(), 1),
    }
    cases = []
    for name, (file_name, content, expect) in table.items():
        argv = [a.replace("{points.csv}", "{" + file_name + "}") for a in FIT]
        cases.append(case("encodings", name, expect, argv, {file_name: content}))
    return cases


def names() -> list[Case]:
    """Experiment names a reader and the writers must keep apart and write safely."""
    table = {
        "path separators": ("../evil", "..\\evil"),
        "mathtext": ("$x_{50}^2$", "$\\frac{1}{0}$"),
        "case only": ("run", "RUN"),
        "quoted comma": ('"a,b"', "c"),
        "very long": ("x" * 300, "y" * 300),
        "emoji and spaces": ("run 🚀 1", "run  1"),
        "html": ("<script>alert(1)</script>", "<b>B</b>"),
        "markdown": ("| pipe |", "*star*"),
    }
    cases = []
    for name, (first, second) in table.items():
        text = points_text({first: CURVE, second: OTHER})
        cases.append(case("names", name, 0, FIT, {"points.csv": text}))
    return cases


def lab_tables() -> list[Case]:
    """Mutated lab tables through ``points`` and ``balance`` (and ``fit``)."""
    rows = list(LAB_CLASS_ROWS)

    def lab(*replace, header=LAB_CLASS_HEADER):
        lines = list(rows)
        for index, text in replace:
            lines[index] = text
        return header + "\n".join(lines) + "\n"

    table = {
        "good": (lab(), [], 0, ""),
        "reconciled": (lab(), ["--reconcile"], 0, ""),
        "yield given": (lab(), ["--fine-yield", "0.4"], 0, ""),
        "yield estimated over a given one": (lab(), ["--fine-yield", "0.4", "--estimate-yield"], 0, ""),
        "partition from the feed": (lab(), ["--partition-from", "feed"], 0, ""),
        "coarse yield": (lab(), ["--coarse-yield", "0.6"], 0, ""),
        "yield column 1.5": (_with_column(lab(), "fine_yield", "1.5"), [], 1, "fine_yield"),
        "yield column 0": (_with_column(lab(), "fine_yield", "0"), [], 1, "fine_yield"),
        "yield column NaN": (_with_column(lab(), "fine_yield", "nan"), [], {0, 1}, ""),
        "negative share": (lab((2, "200,400,-30,16.3,35.4")), [], 1, "feed_pct"),
        "share of 1e308": (lab((2, "200,400,1e308,16.3,35.4")), [], 1, ""),
        "NaN share": (lab((2, "200,400,nan,16.3,35.4")), [], 1, "feed_pct"),
        "complex share": (lab((2, "200,400,30+1j,16.3,35.4")), [], 1, "feed_pct"),
        "shares summing to 150": (lab((2, "200,400,80,16.3,35.4")), [], 1, ""),
        "bounds reversed": (lab((2, "400,200,30,16.3,35.4")), [], 1, ""),
        "overlapping classes": (lab((2, "150,400,30,16.3,35.4")), [], 1, ""),
        "two classes": (LAB_CLASS_HEADER + "\n".join(rows[:2]) + "\n", [], 1, "feed_pct"),
        "top size below the top class": (lab(), ["--top-size", "100"], 1, ""),
        "top size 1e250": (lab(), ["--top-size", "1e250"], {0, 1}, ""),
        "empty product": (
            lab(*[(i, ",".join(r.split(",")[:3]) + ",0," + r.split(",")[4]) for i, r in enumerate(rows)]),
            [],
            1,
            "",
        ),
    }
    cases = []
    for name, (text, options, expect, words) in table.items():
        for command in ("points", "balance"):
            argv = [a.replace("{input}", "{lab.csv}") for a in READERS[command]] + options
            cases.append(case("lab tables", f"{command}: {name}", expect, argv, {"lab.csv": text}, words))
    return cases


# --- options ------------------------------------------------------------------------------
#: A valid command line of each command path, to which one option is added.
TEMPLATES = {
    "fit": ["fit", "{points.csv}", "-o", "{tmp}/out"],
    "report": ["report", "{points.csv}", "-o", "{tmp}/r.html"],
    "compare": ["compare", "{points.csv}"],
    "trend": ["trend", "{points.csv}", "-o", "{tmp}/trend"],
    "points": ["points", "{lab.csv}", "-o", "{tmp}/p.csv"],
    "balance": ["balance", "{lab.csv}"],
    "rank": ["rank", "{points.csv}", "-o", "{tmp}/rank"],
    "sieve identify": ["sieve", "identify", "{points.csv}", "-o", "{tmp}/l.csv"],
    "sieve pg": ["sieve", "pg", "--hole", "2", "--length", "2.5", "--width", "1.5", "--cell-width", "3.2"],
    "sieve bin": ["sieve", "bin", "--decks", "4", "--length", "1.6", "--recovery", "0.9"],
    "layer simulate": ["layer", "simulate"],
    "layer fit": ["layer", "fit", "{points.csv}"],
    "pulp optimum": ["pulp", "optimum", "--frequency", "10"],
    "pulp fit": ["pulp", "fit", "{points.csv}"],
    "optimize": ["optimize"],
    "circuit": ["circuit", "{points.csv}", "{lab.csv}", "-o", "{tmp}/c"],
    "circuit design": ["circuit", "design", "{points.csv}", "-o", "{tmp}/cd"],
    "export": ["export", "{points.csv}", "-o", "{tmp}/e.csv"],
    "density fit": ["density", "fit", "{points.csv}", "-o", "{tmp}/d"],
    "density predict": ["density", "predict", "{points.csv}", "--rho50", "1.5", "--ep", "0.05", "-o", "{tmp}/pred.csv"],
    "plant predict": ["plant", "predict", "{points.csv}", "{lab.csv}", "-o", "{tmp}/plant"],
    "plant optimize": ["plant", "optimize", "{points.csv}", "{lab.csv}", "--target-ash", "10", "-o", "{tmp}/cuts"],
    "plant evaluate": ["plant", "evaluate", "{points.csv}", "-o", "{tmp}/evaluation"],
    "app": ["app", "--no-browser"],  # every case refused by the parser: no server starts
}


def numeric_options() -> list[tuple[str, argparse.Action]]:
    """(command path, action) of every option checked by a :func:`tromplab.validation.cli_type`."""
    found = []

    def walk(parser, path):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, (*path, name))
            elif action.option_strings and getattr(action.type, "range", None):
                found.append((" ".join(path), action))

    walk(build_parser(), ())
    return found


def _outside(action) -> list[tuple[str, str]]:
    """Texts outside the range of ``action`` (value, label), and nan, inf and text."""
    texts = [("nan", "nan"), ("inf", "inf"), ("abc", "text"), ("", "empty")]
    probe = action.type
    for value in ("-1", "0", "1.5", "1e300", "1e-300"):
        try:
            probe(value)
        except argparse.ArgumentTypeError:
            texts.append((value, value))
    return texts


def _inside(action) -> list[str]:
    """Boundary and typical texts the option takes."""
    accepted = []
    for value in ("0", "1e-300", "1e-6", "0.001", "0.5", "1", "2", "1000", "4096", "1e6", "1e250"):
        try:
            action.type(value)
        except argparse.ArgumentTypeError:
            continue
        accepted.append(value)
    return accepted


def option_ranges() -> list[Case]:
    """Every numeric option of every command outside its range: exit 2 naming it, nothing read."""
    cases = []
    for command, action in numeric_options():
        option = action.option_strings[-1]
        for text, label in _outside(action):
            argv = [*TEMPLATES[command], f"{option}={text}"]
            words = f"argument {'/'.join(action.option_strings)}: "
            cases.append(case("option ranges", f"{command} {option} {label}", 2, argv, {}, words))
    return cases


def option_boundaries() -> list[tuple[str, argparse.Action, str]]:
    """(command, action, text) of values inside the ranges: the parser takes each."""
    return [(command, action, text) for command, action in numeric_options() for text in _inside(action)]


def other_options() -> list[Case]:
    """Choices, unknown options and option combinations."""
    points = {"points.csv": points_text()}
    table = {
        "unknown option": (["fit", "{points.csv}", "--nope"], 2, "--nope"),
        "rank-by outside its choices": (["fit", "{points.csv}", "--rank-by", "R2"], 2, "--rank-by"),
        "unknown formula": (["fit", "{points.csv}", "--formulas", "nosuch"], 2, "--formulas"),
        "empty formula list": (["fit", "{points.csv}", "--formulas", ","], 2, "--formulas"),
        "figures outside its choices": (["fit", "{points.csv}", "--figures", "some"], 2, "--figures"),
        "experiment named twice": (["compare", "{points.csv}", "--experiments", "A,A"], 2, "--experiments"),
        "unknown experiment": (["compare", "{points.csv}", "--experiments", "A,Z"], 1, "Z"),
        "unknown shared parameter": (["compare", "{points.csv}", "--shared", "bypass"], 2, "--shared"),
        "delta-max beyond the data's span": ([*FIT, "--delta-max", "1e12"], 2, "--delta-max"),
        "delta-max at the data's span": ([*FIT, "--delta-max", "1e10"], 0, ""),
        "delta-max below the cut": ([*FIT, "--delta-max", "1e-3"], 0, ""),
        "bootstrap beyond the budget": (["fit", "{many.csv}", "--bootstrap", "100000"], 2, "--bootstrap"),
        "separator of two characters": ([*FIT, "--sep", ";;"], 1, "--sep"),
        "pulp fit of an unknown coefficient": (["pulp", "fit", "{pulp.csv}", "--fit", "beta,gamma"], 2, "--fit"),
        "pulp without frequency or pressure": (["pulp", "optimum"], 2, "--frequency"),
        "no pressure at all": (["pulp", "optimum", "--applied", "0"], 2, "--applied"),
        "speed-min above speed-max": (["optimize", "--speed-min", "0.3", "--speed-max", "0.2"], 2, "--speed-min"),
        "layer with one initial cell": (["layer", "simulate", "--initial", "0.5"], 2, "--initial"),
        "layer 2d + v0 above 1": (["layer", "simulate", "--diffusion", "0.6", "--segregation", "0.5"], 2, "--diffusion"),
    }
    many = points_text({f"E{k}": CURVE for k in range(40)})
    files = {**points, "many.csv": many, "pulp.csv": _dataset("pulp_screen_productivity_example.csv")}
    return [case("other options", name, expect, argv, files, words) for name, (argv, expect, words) in table.items()]


#: Options whose largest values cost minutes by design (capped in docs/reliability.md,
#: "Resource limits"): only their smallest value is a corner here.
COSTLY = {"--weights", "--steps", "--cells"}


def model_corners() -> list[Case]:
    """The model commands with each option at an end of its range: done (0), or a failure said
    in words (3), never a crash, a usage error or nan printed."""
    cases = []
    for command, action in numeric_options():
        if command not in ("sieve pg", "sieve bin", "layer simulate", "pulp optimum", "optimize"):
            continue
        option = action.option_strings[-1]
        inside = _inside(action) if option not in COSTLY else _inside(action)[:1]
        for text in dict.fromkeys(inside[:1] + inside[-1:]):
            # optimize sweeps three weights, not eleven: the same arithmetic at fewer points
            sweep = ["--weights", "3"] if command == "optimize" and option != "--weights" else []
            argv = [*TEMPLATES[command], *sweep, option, text]
            slow = command == "optimize"  # each run is a Pareto sweep of constrained optimisations (1-10 s)
            cases.append(case("model corners", f"{command} {option}={text}", {0, 2, 3}, argv, words="--", slow=slow))
    return cases


#: Cells of the model data that are valid values: an F of 1e308 (a perfect fit) is ranked first.
PLAUSIBLE_DATA = {("rank", "F", "1e308"), ("rank", "F_crit", "1e308")}


def model_data() -> list[Case]:
    """Data files of the model commands with one implausible cell: refused naming it."""
    sources = {
        "sieve identify": (
            "sieve_identify_residues_example.csv",
            ("relative_speed", "residue", "sieve_length", "cell_pitch", "length"),
        ),
        "layer fit": ("layer_extraction_example.csv", ("step", "extraction")),
        "pulp fit": ("pulp_screen_productivity_example.csv", ("applied_pressure", "frequency", "productivity")),
        "rank": ("shuvalov2018_table2_F.csv", ("F", "F_crit")),
    }
    cases = []
    for command, (dataset, columns) in sources.items():
        text = _dataset(dataset)
        argv = [a.replace("{input}", "{data.csv}") for a in READERS[command]]
        cases.append(case("model data", f"{command}: as published", 0, argv, {"data.csv": text}))
        for column in columns:
            for value in ("-1", "1e308", "nan", "abc"):
                expect = 0 if (command, column, value) in PLAUSIBLE_DATA else 1
                cases.append(
                    case(
                        "model data",
                        f"{command}: {column}={value}",
                        expect,
                        argv,
                        {"data.csv": _with_cell(text, 1, column, value)},
                        column,
                    )
                )
    return cases


def surveys() -> list[Case]:
    """Plant surveys for ``circuit``: the example and broken topologies."""
    flowsheet, survey = _dataset("circuit_example_flowsheet.csv"), _dataset("circuit_example_survey.csv")
    sheet_lines = [line for line in flowsheet.splitlines() if not line.startswith("#")]
    table = {
        "the example": (flowsheet, survey, 0),
        "a stream of the survey not in the flowsheet": (flowsheet, survey.replace("screen_feed,", "nowhere,"), 1),
        "a flowsheet stream without ends": ("\n".join(sheet_lines + ["loose,,,"]) + "\n", survey, 1),
        "a stream twice in the flowsheet": ("\n".join(sheet_lines + sheet_lines[1:2]) + "\n", survey, 1),
        "an empty survey": (flowsheet, "", 1),
        "a negative retained share": (flowsheet, survey.replace(",3.74,", ",-3.74,", 1), 1),
    }
    return [
        case(
            "surveys",
            name,
            expect,
            ["circuit", "{flowsheet.csv}", "{survey.csv}", "-o", "{tmp}/c", "--no-figures"],
            {"flowsheet.csv": f, "survey.csv": s},
            slow=True,
        )
        for name, (f, s, expect) in table.items()
    ]


#: Findings of the battery in tromplab/circuit left to its maintainers, marked as expected
#: failures (none open: a share of 1e308, which overflowed the share sum, is now refused).
CIRCUIT_FINDINGS: dict[str, str] = {}


def survey_shapes() -> list[Case]:
    """The survey shapes docs/circuit.md allows (the inputs of tests/test_circuit_survey_shapes.py)
    and their hostile variants through ``circuit``: flows, water and partitions written in their
    ranges, or a refusal naming the cause."""
    from .test_circuit_survey_shapes import CYCLONE, EXACT_SHARES, MILL_AND_CYCLONE

    solids = "stream,solids_flow,solids_flow_sd,pct_solids,pct_solids_sd\nfresh_feed,120,0,,\n"
    dilution = solids + "cyclone_feed,,,50,0\ncyclone_overflow,,,30,0\ncyclone_underflow,,,75,0\n"
    two_classes = "stream,size_lower_um,size_upper_um,retained_frac\n" + "".join(
        f"{s},100,,{a}\n{s},0,100,{1 - a}\n" for s, a in (("feed", 0.4), ("overflow", 0.1), ("underflow", 0.7))
    )
    blank = EXACT_SHARES.replace(",0,100,0\n", ",,,\n").replace(",0,,\n", ",,,\n")
    table = {
        "every measurement exact": (CYCLONE, EXACT_SHARES, [], 0, ""),
        "no redundancy": (CYCLONE, two_classes, [], 0, ""),
        "per cent solids and flows only": (MILL_AND_CYCLONE, dilution, [], 0, ""),
        "per cent solids only, with --fit": (MILL_AND_CYCLONE, dilution, ["--fit"], 2, "--fit needs size analyses"),
        "a NaN share": (CYCLONE, blank.replace("overflow,50,100,0.25", "overflow,50,100,NaN"), [], 0, ""),
        "a negative share": (CYCLONE, blank.replace("overflow,50,100,0.25", "overflow,50,100,-0.25"), [], 1, "retained_frac"),
        "a share of 1e308": (CYCLONE, blank.replace("overflow,50,100,0.25", "overflow,50,100,1e308"), [], 1, "retained"),
        "a complex share": (CYCLONE, blank.replace("overflow,50,100,0.25", "overflow,50,100,0.25+1j"), [], 1, "retained"),
        "per cent solids of 150": (MILL_AND_CYCLONE, dilution.replace(",,,50,0", ",,,150,0"), [], 1, "pct_solids"),
        "a negative flow": (MILL_AND_CYCLONE, dilution.replace("fresh_feed,120", "fresh_feed,-120"), [], 1, "solids_flow"),
        "a relative error of 1e6 in the table": (
            CYCLONE,
            "stream,size_lower_um,size_upper_um,retained_frac,relative_error\nfeed,100,,0.2,1e6\nfeed,0,100,0.8,\n"
            "overflow,100,,0.05,\noverflow,0,100,0.95,\n",
            [], 1, "relative_error",
        ),
        "a relative error of 1e6 as an option": (CYCLONE, blank, ["--relative-error", "1e6"], 2, "--relative-error"),
        "a stream measured but not in the flowsheet": (CYCLONE, blank.replace("underflow,", "underflw,"), [], 1, "underflw"),
        "excluding an unknown stream": (CYCLONE, blank, ["--exclude", "nowhere"], {1, 2}, "nowhere"),
    }  # fmt: skip
    cases = []
    for name, (sheet, survey, options, expect, words) in table.items():
        argv = ["circuit", "{sheet.csv}", "{survey.csv}", "-o", "{tmp}/c", "--no-figures", *options]
        known = CIRCUIT_FINDINGS.get(name, "")
        cases.append(case("survey shapes", name, expect, argv, {"sheet.csv": sheet, "survey.csv": survey}, words, known=known))
    return cases


def whole_commands() -> list[Case]:
    """The commands that take longest, on good and on hostile data, their outputs checked."""
    trend = _dataset("classifier_trend_surveys.csv")
    points = points_text()
    table = {
        "trend of the example": (["trend", "{surveys.csv}", "-o", "{tmp}/trend", "--no-figures"], {"surveys.csv": trend}, 0),
        "trend of three surveys": (
            ["trend", "{surveys.csv}", "-o", "{tmp}/trend", "--no-figures"],
            {"surveys.csv": "\n".join(trend.splitlines()[: 6 + 3 * 12]) + "\n"},
            1,
        ),
        "report of two experiments": (["report", "{points.csv}", "-o", "{tmp}/r.html", "--jobs", "1"], {"points.csv": points}, 0),
        "fit with intervals and a bootstrap": ([*FIT, "--ci", "0.9", "--bootstrap", "20"], {"points.csv": points}, 0),
        "fit of the extended curves": (
            ["fit", "{points.csv}", "-o", "{tmp}/out", "--extended", "--no-figures", "--jobs", "1"],
            {"points.csv": points},
            {0, 3},
        ),
        "circuit with fits": (
            ["circuit", "{flowsheet.csv}", "{survey.csv}", "-o", "{tmp}/c", "--fit", "--no-figures"],
            {"flowsheet.csv": _dataset("circuit_example_flowsheet.csv"), "survey.csv": _dataset("circuit_example_survey.csv")},
            {0, 3},
        ),
    }
    return [case("whole commands", name, expect, argv, files, slow=True) for name, (argv, files, expect) in table.items()]


def api_calls() -> list[Case]:
    """The Python entry points with hostile arguments: refused naming the argument, or done."""
    import numpy as np

    import tromplab
    from tromplab.loading.lab import partition_to_fines, reconcile

    points = [tromplab.TrompPoints("run", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])]
    other = tromplab.TrompPoints("other", [10, 20, 40, 80, 160], [0.99, 0.95, 0.6, 0.1, 0.01])

    def fit(**keywords):
        return lambda tmp: tromplab.fit_experiments(points, formulas=keywords.pop("formulas", ["plitt"]), **keywords)

    table = {
        "formulas=[]": (fit(formulas=[]), "OptionError", "formulas"),
        "jobs=-3": (fit(jobs=-3), "OptionError", "jobs"),
        "jobs=2.5": (fit(jobs=2.5), "OptionError", "jobs"),
        "alpha='0.05'": (fit(alpha="0.05"), "OptionError", "alpha"),
        "alpha=2": (fit(alpha=2), "OptionError", "alpha"),
        "alpha=nan": (fit(alpha=math.nan), "OptionError", "alpha"),
        "alpha=True": (fit(alpha=True), "OptionError", "alpha"),
        "ci=1": (fit(ci=1), "OptionError", "ci"),
        "bootstrap=-1": (fit(bootstrap=-1), "OptionError", "bootstrap"),
        "seed=-1": (fit(seed=-1), "OptionError", "seed"),
        "delta_max=1e300": (fit(delta_max=1e300), "OptionError", "delta_max"),
        "delta_max=-1": (fit(delta_max=-1), "OptionError", "delta_max"),
        "delta_max='5'": (fit(delta_max="5"), "OptionError", "delta_max"),
        "water_recovery=1": (fit(water_recovery=1), "OptionError", "water_recovery"),
        "rank_by='R2'": (fit(rank_by="R2"), "OptionError", "rank_by"),
        "partition_to='middle'": (fit(partition_to="middle"), "OptionError", "partition_to"),
        "good call": (fit(), "ok", ""),
        "points with complex partitions": (
            lambda tmp: tromplab.TrompPoints("r", [1, 2, 3], np.array([0.9, 0.5, 0.1]) + 1j),
            "InputError",
            "partition_fine",
        ),
        "ragged points": (lambda tmp: tromplab.TrompPoints("r", [[1, 2], [3]], [0.9, 0.5, 0.1]), "InputError", "size"),
        "points of text": (lambda tmp: tromplab.TrompPoints("r", ["a", "b", "c"], [0.9, 0.5, 0.1]), "InputError", "size"),
        "points with NaN": (
            lambda tmp: tromplab.TrompPoints("r", [1, 2, 3], [0.9, math.nan, 0.1]),
            "InputError",
            "partition_fine",
        ),
        "reconcile with a yield of 1.5": (
            lambda tmp: reconcile([0.5, 0.5], [0.6, 0.4], [0.4, 0.6], 1.5),
            "OptionError",
            "fine_yield",
        ),
        "reconcile with NaN shares": (lambda tmp: reconcile([0.5, math.nan], [0.6, 0.4], [0.4, 0.6], 0.5), "OptionError", "feed"),
        "partition with ragged shares": (
            lambda tmp: partition_to_fines([0.5, 0.5], [0.6], [0.4, 0.6], 0.5),
            "OptionError",
            "feed",
        ),
        "curve_indices with d_cut -1": (
            lambda tmp: tromplab.curve_indices("plitt", -1, 2, delta_max=100),
            "OptionError",
            "d_cut",
        ),
        "curve_indices with delta_max nan": (
            lambda tmp: tromplab.curve_indices("plitt", 10, 2, delta_max=math.nan),
            "OptionError",
            "delta_max",
        ),
        "fit_formula alpha='0.05'": (lambda tmp: tromplab.fit_formula(points[0], "plitt", alpha="0.05"), "OptionError", "alpha"),
        "shared_fit of one experiment twice": (
            lambda tmp: tromplab.shared_fit(points * 2, "plitt"),
            "InputError",
            "more than once",
        ),
        "shared_fit sharing bypass": (
            lambda tmp: tromplab.shared_fit([points[0], other], "plitt", shared="bypass"),
            "OptionError",
            "shared",
        ),
        "rank_formulas of text": (lambda tmp: tromplab.rank_formulas("F.csv"), "TypeError", "table must be a pandas DataFrame"),
        "write_report of None": (lambda tmp: tromplab.write_report(None, tmp / "r.html"), "TypeError", "Report"),
        "model_averages of None": (lambda tmp: tromplab.model_averages(None), "TypeError", "Workbench"),
        "LabOptions fine_yield='0.5'": (lambda tmp: tromplab.LabOptions(fine_yield="0.5"), "OptionError", "fine_yield"),
        "LabOptions top_size=1e300": (lambda tmp: tromplab.LabOptions(top_size=1e300), "OptionError", "top_size"),
    }
    return [case("api", name, outcome, call=call, words=words) for name, (call, outcome, words) in table.items()]


# --- names and writers ---------------------------------------------------------------------
def _csv_text(rows) -> str:
    import csv
    import io

    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    return buffer.getvalue()


def _no_formula_cells(folder: str, table: str = "", expected=()):
    """A check: no CSV or workbook cell under ``folder`` starts as a formula, and ``table``
    (when given) reads back with the experiment names ``expected``, in order."""

    def check(tmp):
        from tromplab.loading.tables import read_table

        from .test_formula_injection import assert_no_formula_cell_in_csv, assert_no_formula_cell_in_workbook

        for path in (tmp / folder).rglob("*.csv"):
            assert_no_formula_cell_in_csv(path)
        for path in (tmp / folder).rglob("*.xlsx"):
            assert_no_formula_cell_in_workbook(path)
        if table:
            assert list(dict.fromkeys(read_table(tmp / folder / table).experiment_labels())) == list(expected)

    return check


def names_as_text() -> list[Case]:
    """Every name of tests/hostile_names.py beside a plain one, and names that look alike:
    fitted, written to CSV and a workbook, and read back as written."""
    from .hostile_names import HOSTILE_NAMES, as_read

    argv = ["fit", "{points.csv}", "-o", "{tmp}/out", "--formulas", "plitt", "--no-figures", "--excel", "--jobs", "1"]
    pairs = [(name, "plain") for name, _ in HOSTILE_NAMES]
    pairs += [("01", "1"), ("007", "7"), ("1e3", "1000"), ("4E2", "400"), ("TRUE", "true"), ("NA", "N/A"), ("None", "null")]
    cases = []
    for first, second in pairs:
        rows = [["experiment", "size", "partition_fine"]]
        rows += [[name, str(size), str(p)] for name, curve in ((first, CURVE), (second, OTHER)) for size, p in zip(SIZES, curve)]
        check = _no_formula_cells("out", "fits.csv", [as_read(first), as_read(second)])
        cases.append(case("names as text", f"{first!r} and {second!r}", 0, argv, {"points.csv": _csv_text(rows)}, check=check))
    return cases


def formula_writers() -> list[Case]:
    """Names that start as a spreadsheet formula through the other writers: points (a lab
    table), rank, sieve identify and the report (slow); every CSV marked, names read back."""
    from .hostile_names import FORMULA_LIKE, as_read

    cases = []
    for name in FORMULA_LIKE:
        names = [as_read(name), "plain"]
        lab = [["experiment", *LAB_CLASS_HEADER.strip().split(",")]]
        lab += [[label, *row.split(",")] for label in (name, "plain") for row in LAB_CLASS_ROWS]
        argv = ["points", "{lab.csv}", "-o", "{tmp}/out/pts.csv"]
        cases.append(
            case(
                "formula writers",
                f"points: {name!r}",
                0,
                argv,
                {"lab.csv": _csv_text(lab)},
                check=_no_formula_cells("out", "pts.csv", names),
            )
        )
        ranks = [
            ["experiment", "equation", "F", "F_crit"],
            [name, 3, 5, 3],
            [name, 7, 4, 3],
            ["plain", 3, 6, 3],
            ["plain", 7, 2, 3],
        ]
        argv = ["rank", "{ranks.csv}", "-o", "{tmp}/out"]
        cases.append(
            case("formula writers", f"rank: {name!r}", 0, argv, {"ranks.csv": _csv_text(ranks)}, check=_no_formula_cells("out"))
        )
        argv = ["sieve", "identify", "{residues.csv}", "-o", "{tmp}/out/laws.csv"]
        cases.append(
            case(
                "formula writers",
                f"sieve identify: {name!r}",
                0,
                argv,
                {"residues.csv": _with_sieve_name(name)},
                check=_no_formula_cells("out"),
            )
        )
        points = _csv_text([["experiment", "size", "partition_fine"], *([name, s, p] for s, p in zip(SIZES, CURVE))])
        argv = ["report", "{points.csv}", "-o", "{tmp}/out/r.html", "--jobs", "1"]
        cases.append(
            case(
                "formula writers",
                f"report: {name!r}",
                0,
                argv,
                {"points.csv": points},
                check=_in_the_report(as_read(name)),
                slow=True,
            )
        )
    for prefix in ("=", "-", "@"):
        sheet = _renamed_streams(_dataset("circuit_example_flowsheet.csv"), prefix, ("stream", "from", "to"))
        survey = _renamed_streams(_dataset("circuit_example_survey.csv"), prefix, ("stream",))
        argv = ["circuit", "{sheet.csv}", "{survey.csv}", "-o", "{tmp}/out", "--no-figures"]
        files = {"sheet.csv": sheet, "survey.csv": survey}
        cases.append(case("formula writers", f"circuit: streams {prefix}name", 0, argv, files, check=_no_formula_cells("out")))
    return cases


def _renamed_streams(text: str, prefix: str, columns) -> str:
    """A circuit table (comments dropped) with ``prefix`` before every name in ``columns``."""
    import csv

    rows = list(csv.reader(line for line in text.splitlines() if not line.startswith("#")))
    where = [rows[0].index(column) for column in columns]
    for row in rows[1:]:
        for i in where:
            row[i] = prefix + row[i] if row[i] else row[i]
    return _csv_text(rows)


def _in_the_report(name: str):
    """A check: the HTML report shows ``name`` escaped, the Markdown report holds it."""

    def check(tmp):
        import html

        page = (tmp / "out" / "r.html").read_text(encoding="utf-8")
        assert html.escape(name) in page
        assert (tmp / "out" / "r.md").is_file()

    return check


def _with_sieve_name(name: str) -> str:
    lines = [line for line in _dataset("sieve_identify_residues_example.csv").splitlines() if not line.startswith("#")]
    return _csv_text([lines[0].split(","), *([name, *line.split(",")[1:]] for line in lines[1:])])


def catalogue() -> list[Case]:
    """Every case of the battery."""
    return [
        *loader_files(),
        *loader_texts(),
        *values(),
        *columns(),
        *rows(),
        *encodings(),
        *names(),
        *lab_tables(),
        *option_ranges(),
        *other_options(),
        *model_corners(),
        *model_data(),
        *surveys(),
        *survey_shapes(),
        *whole_commands(),
        *names_as_text(),
        *formula_writers(),
        *api_calls(),
        *last_edges(case),
    ]
