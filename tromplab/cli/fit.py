"""``tromplab fit``: fit, screen and rank the formulas on Tromp points or lab tables, write
the results folder (or one workbook) and print the ranked fits."""

from __future__ import annotations

import textwrap
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

from ..notices import level_of
from ..options import AUTO_FIGURE_LIMIT, FIGURE_CHOICES, TABLE_FORMATS
from ..output.outputs import check_output_file, check_output_folder
from ..validation import FitSettings
from .option_groups import READERS, add_partition_to, add_scale_options, add_uncertainty_options, lab_options
from .printing import format_fits, print_notices, report_failures
from .startup import print_result, progress_bars, require

if TYPE_CHECKING:
    import pandas as pd


def add_fit(commands, groups) -> None:
    fit = commands.add_parser(
        "fit",
        parents=[groups["shared"], groups["lab"], groups["water"]],
        help="fit, screen and rank the formulas on Tromp points or lab data",
    )
    fit.add_argument(
        "-o",
        "--outdir",
        type=Path,
        default=Path("results"),
        help="output folder, replaced as a whole when the run succeeds (default: results), or a .xlsx "
        "file: then one Excel workbook holds every table and figure",
    )
    fit.add_argument(
        "--excel", action="store_true", help="also write the tables and figures as one workbook, results.xlsx, in the folder"
    )
    add_partition_to(fit)
    fit.add_argument(
        "--figures",
        choices=FIGURE_CHOICES,
        default="auto",
        help=f"per-experiment figures with every fit (all) or the top-ranked one (best); auto: all up to "
        f"{AUTO_FIGURE_LIMIT} experiments, then one overview figure (default auto)",
    )
    fit.add_argument("--no-figures", dest="figures", action="store_const", const="none", help="same as --figures none")
    fit.add_argument("--format", choices=TABLE_FORMATS, default="csv", help="format of the tables (parquet needs pyarrow)")
    add_scale_options(fit.add_argument_group("scale"))
    add_uncertainty_options(fit.add_argument_group("uncertainty"))
    fit.set_defaults(run=_run_fit, imports=(*READERS, "tromplab.workbench", "tromplab.statistics.hydrocyclone"))


def _run_fit(args) -> int:
    from ..loading.lab import read_experiments
    from ..loading.tables import check_input_file
    from ..workbench import ExperimentsInPieces, check_formula_selection, fit_to_folder

    check_formula_selection(args.formulas, args.extended)  # refused before the input is read
    check_input_file(args.input)
    if args.outdir.suffix.lower() == ".xlsx":
        check_output_file(args.outdir, inputs=[args.input], option="--outdir")
    else:
        check_output_folder(args.outdir, inputs=[args.input])
    if args.format == "parquet":
        require("pyarrow", "--format parquet", "pip install 'tromplab[dask]'")
    if reads_in_pieces(args):  # every row checked (the census) before anything is fitted or written
        experiments = ExperimentsInPieces(args.input, lab_options(args))
        experiments.census()
    else:
        experiments = read_experiments(args.input, lab_options(args))
    with progress_bars(quiet=args.quiet) as progress:
        bench, written = fit_to_folder(experiments, args.outdir, figures=args.figures, format=args.format, excel=args.excel,
                                       source=args.input, settings=FitSettings.from_options(args), progress=progress)  # fmt: skip
    _print_fits(bench, args)
    _print_written(list(written.values()), args.outdir)
    notices = bench.notices()
    total = len(bench.experiments) + len(bench.failures)
    print_notices(notices, total=total, quiet=args.quiet, verbose=args.verbose, intervals=bool(bench.ci or bench.bootstrap),
                  listed_in="the workbook's warnings sheet" if args.outdir.suffix.lower() == ".xlsx" else "warnings.csv")  # fmt: skip
    if args.quiet:
        print_result(result_line("tromplab fit", bench, notices, args.outdir))
    return report_failures(bench.failure_table())


def result_line(command: str, bench, notices, outdir) -> str:
    """What ``--quiet`` prints of a fit run: one line with the experiments, the failures, the
    warnings and where the results are."""
    total = len(bench.experiments) + len(bench.failures)
    failed = len(bench.failure_table())
    counted = f"{total} experiment(s) fitted" + (f", {failed} failure(s) (failures.csv)" if failed else "")
    levels = Counter(level_of(notice.code) for notice in notices)
    said = [f"{levels[level]} {level}(s)" for level in ("warning", "note") if levels[level]]
    if said:
        counted += f", {' and '.join(said)} ({'warnings sheet' if Path(outdir).suffix.lower() == '.xlsx' else 'warnings.csv'})"
    return f"{command}: {counted}; results in {outdir}"


def reads_in_pieces(args) -> bool:
    """Whether ``tromplab fit`` reads its input in pieces: a CSV file (not a workbook's sheet)
    whose batch will stream by the one rule of :func:`tromplab.parallel.streams`, judged from
    the file's size before its experiments are counted (the files and the console are the same
    either way)."""
    from ..loading.tables import EXCEL_SUFFIXES
    from ..parallel import streams

    path = Path(args.input)
    if path.suffix.lower() in EXCEL_SUFFIXES or getattr(args, "sheet", None) is not None or not path.is_file():
        return False
    tables_only = args.format == "csv" and not args.excel and args.outdir.suffix.lower() != ".xlsx"
    return streams(None, tables_only=tables_only, figures=args.figures, input_bytes=path.stat().st_size)


def _print_fits(bench, args) -> None:
    """The console view of a fit run: data notes, the ranked fits of the first experiments
    with their verdicts, the water-recovery checks, failures and the ranking across experiments."""
    from ..statistics.hydrocyclone import water_recovery_statements

    if args.quiet:  # standard output goes nowhere: formatting the tables would be wasted (0.3 s at 1,024 experiments)
        return
    shown_experiments = [*bench.experiments, *bench.failures][:AUTO_FIGURE_LIMIT]  # the fits table's order
    many = len(bench.experiments) > AUTO_FIGURE_LIMIT  # a column per experiment would not be read, nor fit a line
    fits, ranking = bench.fits_table(experiments=shown_experiments), bench.ranking_table(per_experiment=not many)
    verdicts = {experiment: bench.verdicts(experiment) for experiment in shown_experiments}
    print(format_fits(fits[fits["experiment"].isin(shown_experiments)], verdicts, rank_by=args.rank_by))
    _print_nested_tests(fits[fits["experiment"].isin(shown_experiments)], alpha=bench.alpha)
    checks = [(e, s) for e in shown_experiments for s in water_recovery_statements(fits, e)]
    if args.water_recovery is not None and not checks:
        print(f"\nnote: no curve with bypass was fitted, so the water recovery {args.water_recovery:g} is compared with "
              "nothing (add --extended or --formulas plitt_bypass,...)")  # fmt: skip
    if checks:
        print(f"\nFitted bypass against the water recovery {args.water_recovery:g} (share of the feed water to the underflow):")
        for experiment, statement in checks:
            print(textwrap.fill(f"{experiment}, {statement}", width=98, initial_indent="  ", subsequent_indent="    "))
    if len(bench.experiments) > AUTO_FIGURE_LIMIT:
        print(f"\n... and {len(bench.experiments) - len(shown_experiments)} more experiments: every fit is in fits.{args.format}")
    if bench.failures:
        print("\nExperiments that could not be fitted:")
        for experiment, reason in bench.failures.items():
            print(f"  {experiment}: {reason}")
    if ranking.shape[0] and len(bench.experiments) > 1:
        print("\nRanking across experiments (points: rank sum, inadequate ranks counted twice):")
        print(ranking.to_string(index=False))
        if many:
            print(f"(the rank of each formula in each experiment is in ranking.{args.format})")


def _print_nested_tests(fits: pd.DataFrame, *, alpha: float) -> None:
    """One line per curve that nests another (``--extended``): is its extra term needed?"""
    if "nested_p" not in fits.columns:
        return
    tested = fits[fits["nested_p"].notna()]
    if tested.empty:
        return
    print(f"\nExtra terms needed? Nested F test of each extended curve against the curve it extends (alpha {alpha:g}):")
    for row in tested.itertuples(index=False):
        needed = "yes" if row.nested_p < alpha else "no"
        print(f"  {row.experiment}: {row.formula} against {row.nests}: F = {row.nested_F:.4g}, p = {row.nested_p:.3g}: {needed}")


def _print_written(paths: list, outdir) -> None:
    print("\nWrote:")
    for path in paths[: AUTO_FIGURE_LIMIT + 3]:
        print(f"  {path}")
    if len(paths) > AUTO_FIGURE_LIMIT + 3:
        print(f"  ... and {len(paths) - AUTO_FIGURE_LIMIT - 3} more files in {outdir}")
