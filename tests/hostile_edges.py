"""The last edges of the reliability campaign as cases of the hostile-input
battery (tests/hostile_catalogue.py, run by tests/test_hostile_battery.py): each ends in exit 1,
2 or 3 (or the API's exception) with its cause named, and no raw numpy warning (the suite's
filter turns a RuntimeWarning of tromplab into an error, which would end in exit 70).
"""

from __future__ import annotations

import math

#: Tracer counts of one test: 30 tracers at each of 7 densities (the partition to sinks rises).
DENSITIES = (1.40, 1.45, 1.50, 1.55, 1.60, 1.65, 1.70)
SINKS = (1, 3, 8, 15, 22, 27, 29)
#: A float-sink analysis of one test (tests/test_density_readers.py, FLOAT_SINK).
FLOAT_SINK = (
    "test,density_lower,density_upper,feed_pct,floats_pct,sinks_pct\n"
    "A,,1.3,30,42.0,2.0\nA,1.3,1.4,25,34.0,4.0\nA,1.4,1.5,15,16.0,12.7\nA,1.5,1.6,10,5.0,21.7\nA,1.6,,20,3.0,59.6\n"
)


def tracers(cell: tuple[int, str, str] | None = None) -> str:
    """The tracer table, with ``cell`` = (density index, column, text) replaced."""
    rows = [
        {"test": "t", "density": f"{d}", "placed": "30", "sinks": f"{s}", "floats": f"{30 - s}"} for d, s in zip(DENSITIES, SINKS)
    ]
    if cell is not None:
        index, column, text = cell
        rows[index][column] = text
    return "test,density,placed,sinks,floats\n" + "".join(",".join(row.values()) + "\n" for row in rows)


def falling_partition() -> str:
    """The partition to floats of the tracers, given as the partition to sinks."""
    return "test,density,partition_sinks\n" + "".join(f"t,{d},{1 - s / 30:.4f}\n" for d, s in zip(DENSITIES, SINKS))


def density_cases(case) -> list:
    """``density fit`` on hostile counts, partitions and options; the density API with hostile keywords."""
    fit = ("density", "fit", "{tracers.csv}", "-o", "{tmp}/d")
    table = {
        "a count of 20 digits": (tracers((2, "sinks", "1" + "0" * 19)), [], 1, "column 'sinks': count 1e+19 is more than"),
        "a count of 400 digits": (tracers((2, "sinks", "9" * 400)), [], 1, "column 'sinks': '999999999999...99999999 (400"),
        "placed = 1e308": (tracers((2, "placed", "1e308")), [], 1, "column 'placed': count 1e+308 is more than"),
        "--curves ''": (tracers(), ["--curves", ""], 2, "--curves names no curve"),
        "--curves ,": (tracers(), ["--curves", ","], 2, "--curves names no curve"),
        "a partition to sinks falling with density": (falling_partition(), [], 1, "looks like the partition to floats"),
        "--floats-yield 1e-308": (FLOAT_SINK, ["--floats-yield", "1e-308"], 2, "argument --floats-yield: must lie in [1e-09"),
        "--floats-yield 0.9999999999999": (FLOAT_SINK, ["--floats-yield", "0.9999999999999"], 2, "argument --floats-yield"),
    }
    cases = [
        case("last edges", f"density fit: {name}", expect, [*fit, *options], {"tracers.csv": text}, words)
        for name, (text, options, expect, words) in table.items()
    ]

    def density_fit(**keywords):
        def call(tmp):
            from tromplab.density import fit_density

            (tmp / "fs.csv").write_text(FLOAT_SINK, encoding="utf-8")
            return fit_density(tmp / "fs.csv", **keywords)

        return call

    api = {
        "fit_density(curves=[])": (density_fit(curves=[]), "OptionError", "curves names no curve"),
        "fit_density(curves='')": (density_fit(curves=""), "OptionError", "curves names no curve"),
        "fit_density(floats_yield='0.5')": (density_fit(floats_yield="0.5"), "OptionError", "floats_yield takes a number"),
        "fit_density(floats_yield=1e-308)": (density_fit(floats_yield=1e-308), "OptionError", "floats_yield must lie in"),
        "fit_density(floats_yield=math.nan)": (density_fit(floats_yield=math.nan), "OptionError", "floats_yield"),
        "fit_density(floats_yield=0.3)": (density_fit(floats_yield=0.3), "ok", ""),
    }
    return cases + [case("last edges", name, outcome, call=call, words=words) for name, (call, outcome, words) in api.items()]


def _empty_points(tmp):
    import tromplab

    return tromplab.TrompPoints("a", [], [])


def _streamed_carriage_return(tmp):
    """A quoted name holding a carriage return, in a file of CRLF line ends, read in pieces as read whole."""
    from tromplab.loading.tables import read_table, read_table_in_pieces

    path = tmp / "cr.csv"
    path.write_bytes(b'experiment,size,partition_fine\r\n"a\rb",10,0.9\r\n"a\rb",20,0.5\r\nc,10,0.8\r\n')
    whole = read_table(path).frame["experiment"].tolist()
    pieces = [name for piece in read_table_in_pieces(path, piece_rows=1) for name in piece.frame["experiment"].tolist()]
    if not whole == pieces == ["a\rb", "a\rb", "c"]:
        raise AssertionError(f"read whole {whole!r}, in pieces {pieces!r}")


def reader_cases(case) -> list:
    """The readers: points without a point, a carriage return inside a quoted name read in pieces."""
    api = {
        "TrompPoints('a', [], [])": (_empty_points, "InputError", "column 'size': no points"),
        "a carriage return in a quoted name, read in pieces": (_streamed_carriage_return, "ok", ""),
    }
    return [case("last edges", name, outcome, call=call, words=words) for name, (call, outcome, words) in api.items()]


CYCLONE = "stream,from,to,product\nfeed,,cyclone,\noverflow,cyclone,,fine\nunderflow,cyclone,,coarse\n"
#: A cyclone survey whose shares are all given exact and do not balance (the feed is not
#: between its products in the coarse class).
EXACT_AND_CONTRADICTING = (
    "stream,size_lower_um,size_upper_um,retained_frac,retained_sd,solids_flow\nfeed,100,,0.2,0,100\nfeed,50,100,0.3,0,\n"
    "feed,0,50,0.5,0,\noverflow,100,,0.05,0,\noverflow,50,100,0.25,0,\noverflow,0,50,0.7,0,\nunderflow,100,,0.35,0,\n"
    "underflow,50,100,0.45,0,\nunderflow,0,50,0.2,0,\n"
)
ONE_OPEN_CLASS = (
    "stream,size_lower_um,size_upper_um,retained_frac,solids_flow\nfeed,100,,1,100\noverflow,100,,1,\nunderflow,100,,1,\n"
)
LAB = "size_lower,size_upper,feed_pct,fine_pct,coarse_pct\n800,,5,0,9.2\n400,800,15,1,25.3\n{row}\n100,200,25,31.8,16.7\n50,100,15,25.9,7.7\n10,50,10,25,5.7\n"
POINTS = "experiment,size,partition_fine\n" + "".join(
    f"A,{s},{p}\n" for s, p in zip((10, 20, 40, 80, 160), (0.97, 0.9, 0.6, 0.2, 0.05))
)


def _residues(rows_of_second: int) -> str:
    """The bundled residue table with the second fraction cut to ``rows_of_second`` regimes."""
    from .conftest import DATASETS

    lines = [
        line for line in (DATASETS / "sieve_identify_residues_example.csv").read_text().splitlines() if not line.startswith("#")
    ]
    second = [line for line in lines[1:] if ",2.0x1.5," in line]
    return "\n".join([lines[0], *(line for line in lines[1:] if ",2.0x1.5," not in line), *second[:rows_of_second]]) + "\n"


def _dataset(name: str) -> str:
    from .conftest import DATASETS

    return (DATASETS / name).read_text(encoding="utf-8")


def old_weak_messages(case) -> list:
    """The eight messages the campaign found weak, each now naming its cause; the other
    frictions of the command line met on the way (per cent in a column of shares, a one-row
    ``pulp fit``, ``pulp optimum`` at a pressure drop that underflows)."""
    circuit = ("circuit", "{sheet.csv}", "{data.csv}", "-o", "{tmp}/c", "--no-figures")
    points = ("points", "{data.csv}", "-o", "{tmp}/p.csv")
    fit = ("fit", "{data.csv}", "-o", "{tmp}/out", "--formulas", "plitt", "--no-figures", "--jobs", "1")
    sheet = {"sheet.csv": CYCLONE}
    table = {
        "compare of a file without an experiment column": (
            ("compare", "{data.csv}"), {"data.csv": POINTS.replace("experiment,", "").replace("A,", "")}, 1,
            "column 'experiment': compare needs two experiments or more: the file has no 'experiment' column",
        ),
        "a partition of 1.0000001": (fit, {"data.csv": POINTS.replace("0.97", "1.0000001")}, 1, "partition 1.0000001 outside 0..1"),
        "partitions in per cent in partition_fine": (
            fit, {"data.csv": POINTS.replace(",0.97", ",97").replace(",0.9\n", ",90\n")}, 1,
            "these look like percentages; name the column partition_fine_pct (0..100)",
        ),
        "retained_sd of 0 on shares that do not balance": (
            circuit, {**sheet, "data.csv": EXACT_AND_CONTRADICTING}, 1, "shares of feed (rows 2, 3, 4); shares of overflow",
        ),
        "a single open size class": (circuit, {**sheet, "data.csv": ONE_OPEN_CLASS}, 1, "row 2, column 'size_upper_um': the only size class, 100-top, is open"),
        "a NaN share in a sum check": (
            points, {"data.csv": LAB.format(row="200,400,nan,16.3,35.4")}, 1,
            "row 4, column 'feed_pct': the per-class shares sum to 70.00 %",
        ),
        "a one-row pulp fit file": (
            ("pulp", "fit", "{data.csv}"), {"data.csv": "applied_pressure,frequency,productivity\n0.25,5.0,3.2482\n"}, 1,
            "data.csv: 1 measurement(s) cannot determine the 2 coefficient(s) of --fit",
        ),
        "sieve identify of a fraction with one regime": (
            ("sieve", "identify", "{data.csv}", "-o", "{tmp}/laws.csv"), {"data.csv": _residues(1)}, 3, "",
        ),
        "a blank lower class bound inside the table": (
            points, {"data.csv": LAB.format(row=",400,30,16.3,35.4")}, 1, "row 4, column 'size_lower': the lower bound is blank",
        ),
        "a blank upper class bound inside the table": (
            points, {"data.csv": LAB.format(row="200,,30,16.3,35.4")}, 1, "size_upper",
        ),
        "circuit --absolute-error 0 with shares of 0": (
            (*circuit, "--absolute-error", "0"),
            {"sheet.csv": _dataset("circuit_example_flowsheet.csv"), "data.csv": _dataset("circuit_example_survey.csv")},
            2,
            "--absolute-error of 0 gives the share 0 of stream 'oversize' at row 30 a standard deviation of 0",
        ),
        "a relative and absolute error of 0 in the table on a share of 0": (
            circuit,
            {**sheet, "data.csv": "stream,size_lower_um,size_upper_um,retained_frac,relative_error,absolute_error,solids_flow\n"
             "feed,100,,0.2,,,100\nfeed,0,100,0.8,,,\noverflow,100,,0,0.05,0,\noverflow,0,100,1,,,\nunderflow,100,,0.4,,,\n"
             "underflow,0,100,0.6,,,\n"},
            1,
            "row 4, column 'absolute_error': the share 0 of stream 'overflow' at row 4 has a standard deviation of 0",
        ),
        "pulp optimum --applied 1e-308": (("pulp", "optimum", "--applied", "1e-308"), {}, 0, ""),
        "pulp optimum --frequency 1e-3 --applied 1e-308": (("pulp", "optimum", "--frequency", "0.001", "--applied", "1e-308"), {}, 0, ""),
    }  # fmt: skip
    return [case("last edges", name, expect, argv, files, words) for name, (argv, files, expect, words) in table.items()]


def _with_nan_assay(text: str, line_start: str, column: int) -> str:
    lines = text.splitlines()
    return (
        "\n".join(
            ",".join("NaN" if k == column else cell for k, cell in enumerate(line.split(",")))
            if line.startswith(line_start)
            else line
            for line in lines
        )
        + "\n"
    )


def assay_cases(case) -> list:
    """The bundled survey with per-class assays, one assay cell NaN (an assay not made): it
    reconciles (an exit 70 "Residuals are not finite" came and went with the solver's last
    digits), with and without the separators' fits."""
    sheet, survey = _dataset("circuit_minerals_flowsheet.csv"), _dataset("circuit_minerals_survey.csv")
    cases = []
    for where, (line_start, column) in {
        "cyclone feed": ("cyclone_feed,150.0,212.0", 4),
        "overflow": ("cyclone_overflow,53.0,75.0", 5),
    }.items():
        files = {"sheet.csv": sheet, "survey.csv": _with_nan_assay(survey, line_start, column)}
        for options in ([], ["--fit"]):
            argv = ["circuit", "{sheet.csv}", "{survey.csv}", "-o", "{tmp}/c", "--no-figures", *options]
            name = f"circuit: a NaN assay in the {where}{' with --fit' if options else ''}"
            cases.append(case("last edges", name, {0, 3} if options else 0, argv, files, slow=True))
    return cases


def last_edges(case) -> list:
    """Every case of this module; ``case`` is the catalogue's constructor."""
    return [*density_cases(case), *reader_cases(case), *old_weak_messages(case), *assay_cases(case)]
