"""``tromplab report`` (HTML and Markdown report of a fit run), ``tromplab compare`` (did
the sharpness or the cut change between experiments) and ``tromplab export`` (fitted
parameters in a simulator's convention)."""

from __future__ import annotations

import contextlib
import gc
import textwrap
from pathlib import Path

from ..errors import InputError, OptionError
from ..options import DEFAULT_MARGIN
from ..output.outputs import check_output_file, write_files
from ..validation import FitSettings, check_probability, check_share, cli_type
from .option_groups import READERS, add_jobs_option, add_partition_to, lab_options
from .printing import print_notices, report_failures
from .startup import print_result, progress_bars


def add_report(commands, groups) -> None:
    report = commands.add_parser(
        "report",
        parents=[groups["shared"], groups["lab"], groups["water"]],
        help="HTML and Markdown report: balance, ranked fits, uncertainties, figures",
    )
    report.add_argument(
        "-o", "--output", type=Path, default=Path("results/report.html"), help="HTML file (a .md twin is written beside it)"
    )
    report.add_argument(
        "--ci",
        type=cli_type(check_probability, "--ci"),
        default=0.95,
        metavar="LEVEL",
        help="level of the intervals (default 0.95)",
    )
    report.add_argument("--title", default="tromplab report", help="title of the report (default: tromplab report)")
    add_jobs_option(report.add_argument_group("scale"))
    add_partition_to(report)
    report.set_defaults(run=_run_report, imports=(*READERS, "tromplab.workbench"))


def _run_report(args) -> int:
    from ..loading.lab import read_experiments
    from ..loading.tables import check_input_file
    from ..workbench import check_formula_selection, fit_with_settings

    check_formula_selection(args.formulas, args.extended)  # refused before the input is read
    check_input_file(args.input)
    check_output_file(args.output, inputs=[args.input])
    experiments = read_experiments(args.input, lab_options(args))
    settings = FitSettings.from_options(args, ci=None)  # the report's --ci is the level of its tables, not interval columns
    with progress_bars(quiet=args.quiet, stages=("intervals", "figures")) as progress:
        bench = fit_with_settings(experiments, settings, progress=progress)
        bench.check_fitted(args.input)
        args.output.parent.mkdir(parents=True, exist_ok=True)
        written = bench.write_report(args.output, level=args.ci, title=args.title, jobs=args.jobs, progress=progress)
    print("Wrote:")
    for path in written.values():
        print(f"  {path}")
    notices, total = bench.notices(), len(bench.experiments) + len(bench.failures)
    # no file holds every one: the report details the first experiments and those flagged
    print_notices(notices, total=total, quiet=args.quiet, verbose=args.verbose, intervals=True, listed_in="")
    if args.quiet:
        print_result(
            f"tromplab report: {total} experiment(s) fitted, {len(notices)} warning(s) and note(s); report in {args.output}"
        )
    return report_failures(bench.failure_table(), listed_in="the report")


def add_compare(commands, groups) -> None:
    compare = commands.add_parser(
        "compare", parents=[groups["lab"]], help="did the sharpness (or the cut) change between experiments?"
    )
    compare.add_argument("input", type=Path, help="Tromp points or a lab table with two or more experiments")
    compare.add_argument("--formula", default="plitt", help="formula id or equation number (default plitt)")
    compare.add_argument("--shared", choices=("shape", "d_cut"), default="shape", help="parameter shared by the joint fit")
    compare.add_argument("--experiments", default=None, help="comma-separated experiments to compare (default: all)")
    compare.add_argument(
        "--margin",
        type=cli_type(check_share, "--margin"),
        default=DEFAULT_MARGIN,
        help="relative margin of practical equivalence: estimates closer than it are 'equal within the margin' "
        "whatever the F test says (default %(default)s)",
    )
    compare.set_defaults(run=_run_compare, imports=(*READERS, "tromplab.statistics.compare"))


def _run_compare(args) -> int:
    from ..curves.formulas import get_formula
    from ..loading.lab import read_experiments
    from ..loading.tables import check_input_file
    from ..statistics.compare import shared_fit

    check_input_file(args.input)
    experiments, _ = read_experiments(args.input, lab_options(args))
    if len(experiments) < 2:
        one = experiments[0].experiment
        why = (
            "the file has no 'experiment' column, so all its rows are one experiment named after the file"
            if one == Path(args.input).stem
            else f"the file holds only experiment '{one}'"
        )
        raise InputError(f"compare needs two experiments or more: {why}", source=str(args.input), column="experiment")
    if args.experiments:
        wanted = [e.strip() for e in args.experiments.split(",") if e.strip()]
        repeated = sorted({e for e in wanted if wanted.count(e) > 1})
        if repeated:
            raise OptionError("--experiments", f"names {', '.join(repeated)} more than once; compare distinct experiments")
        known = {p.experiment: p for p in experiments}
        missing = [e for e in wanted if e not in known]
        if missing:
            raise InputError(
                f"--experiments names unknown experiment(s) {', '.join(missing)}; the file has {', '.join(known)}",
                source=str(args.input),
            )
        experiments = [known[e] for e in wanted]
    try:
        formula = get_formula(args.formula)
    except KeyError as error:
        raise OptionError("--formula", f"names an {error.args[0]}") from None
    result = shared_fit(experiments, formula, shared=args.shared)
    print(result.table().to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    test = result.test
    print(f"\nExtra sum of squares: F = {test.F:.4g} on ({test.df_extra}, {test.df_full}) df, p = {test.p_value:.4g}")
    print(result.conclusion(margin=args.margin))
    return 0


def add_export(commands, groups) -> None:
    export = commands.add_parser(
        "export", help="write fitted parameters in a simulator's convention (whiten, plitt, dyssol, csv-long)"
    )
    export.add_argument("fits_dir", type=Path, help="output folder of 'tromplab fit' (or its fits.csv)")
    export.add_argument(
        "--to", required=True, choices=("whiten", "plitt", "dyssol", "csv-long"), help="target convention (docs/export.md)"
    )
    export.add_argument(
        "-o", "--output", type=Path, default=None, help="CSV to write (default: FITS_DIR/export_<convention>.csv)"
    )
    export.add_argument("--size-unit", default=None, help="unit of the fitted sizes: um, mm, cm or m (required by --to dyssol)")
    export.set_defaults(run=_run_export, imports=("tromplab.output.export",))


#: Rows of an export (and experiments per left-out formula) printed on the console; the file has all.
EXPORT_CONSOLE_ROWS = 40


def _run_export(args) -> int:
    from ..output.export import export_fits

    folder = args.fits_dir if args.fits_dir.is_dir() else args.fits_dir.parent
    output = args.output or folder / f"export_{args.to.replace('-', '_')}.csv"
    check_output_file(output, inputs=[] if args.fits_dir.is_dir() else [args.fits_dir])
    with _cycle_collection_paused():
        result = export_fits(args.fits_dir, args.to, size_unit=args.size_unit)
        written = write_files({output.name: result.write_csv}, output.parent or Path("."))
    shown = result.table.head(EXPORT_CONSOLE_ROWS)
    print(shown.to_string(index=False, float_format=lambda v: f"{v:.6g}", na_rep="-"))
    if len(result.table) > len(shown):
        print(f"... and {len(result.table) - len(shown)} more rows in the file")
    if result.skipped:
        left_out = {}
        for experiment, formula, _ in result.skipped:
            left_out.setdefault(formula, []).append(experiment)
        print(f"\nNot expressible in the {args.to} convention (left out; docs/export.md lists what maps to what):")
        for formula, experiments in left_out.items():
            named = ", ".join(experiments[:EXPORT_CONSOLE_ROWS])
            more = f" and {len(experiments) - EXPORT_CONSOLE_ROWS} more" if len(experiments) > EXPORT_CONSOLE_ROWS else ""
            print(textwrap.fill(f"{formula}: {named}{more}", width=98, initial_indent="  ", subsequent_indent="    "))
    print(f"\nWrote: {written[output.name]}")
    return 0


@contextlib.contextmanager
def _cycle_collection_paused():
    """Python's cycle collector off, then back as it was: an export makes hundreds of thousands of
    small records without cycles (90,000 fits, 180,000 rows of csv-long), which reference counting
    frees; the collector's passes over them and over the imported libraries took 0.15 s of a 1 s
    command."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
