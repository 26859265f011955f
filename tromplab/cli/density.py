"""``tromplab density fit FILE -o DIR``: density partition curves of gravity separators.

The library is :mod:`tromplab.density`; this module registers the ``density`` command and
its sub-commands on the CLI's parser and runs them: read the table, fit, and write the
folder through :meth:`tromplab.density.results.DensityResult.save` (what the Python API
writes, byte for byte).  Bad input ends in an :class:`~tromplab.errors.InputError` before
anything is written.  The parser needs only the light modules imported here; the library
is imported when a sub-command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..options import AUTO_FIGURE_LIMIT, FIGURE_CHOICES
from ..output.outputs import check_output_folder
from ..validation import check_probability, check_yield, cli_type
from .option_groups import add_dask_options, add_jobs_option
from .printing import print_notices
from .startup import (  # done, and some tests without any fitted curve
    EXIT_OK,
    EXIT_PARTIAL,
    print_result,
    print_usage,
    progress_bars,
)

#: What ``density fit`` imports when it runs (imported before it starts, under the CLI's signal handling).
#: The fits of tracer counts need neither scipy.stats nor scipy.optimize nor statsmodels: those are
#: imported where a float-sink fit or a table by size needs them (a large share of the start-up).
FIT_IMPORTS = ("tromplab.density", "tromplab.loading.tables")


def add_density_command(commands) -> argparse.ArgumentParser:
    """Register ``tromplab density`` with its sub-commands; returns the sub-command parsers' holder.

    Other sub-commands (``predict``) are added to the returned ``density`` parser's
    sub-parsers, reachable as ``parser.density_commands``.
    """
    density = commands.add_parser(
        "density", help="density partition (Tromp curves by relative density) of dense-medium and gravity separators"
    )
    sub = density.add_subparsers(dest="density_command", metavar="SUBCOMMAND", parser_class=type(density))
    density.density_commands = sub
    _add_fit(sub)
    density.set_defaults(run=lambda args: print_usage(density))
    return density


def _add_fit(sub) -> None:
    fit = sub.add_parser(
        "fit",
        help="fit density curves to tracer counts, float-sink analyses or a partition (told apart by the columns)",
        description="Fit the density partition curves to every test (and size fraction) of FILE and write fits.csv, "
        "partition.csv, summary.txt and one figure per test into the output folder.",
    )
    fit.add_argument("file", type=Path, help="tracer table (test, density, placed, sinks, floats), float-sink table "
                     "(test, density_lower, density_upper, feed_pct, floats_pct, sinks_pct) or partition (density, partition_sinks)")  # fmt: skip
    fit.add_argument("-o", "--outdir", type=Path, default=Path("results/density"),
                     help="output folder, replaced as a whole when the run succeeds (default: results/density)")  # fmt: skip
    fit.add_argument("--ci", type=cli_type(check_probability, "--ci"), default=None, metavar="LEVEL",
                     help="add profile-likelihood intervals of rho50, Ep and the imperfection at this level")  # fmt: skip
    fit.add_argument("--curves", default="all", metavar="IDS",
                     help="curves to fit: ids (normal, logistic, gompertz, normal_limits, ...) or plain, limits, all (default all)")  # fmt: skip
    fit.add_argument("--method", choices=("binomial", "least_squares"), default=None,
                     help="binomial (tracer counts, the default for them) or least_squares on the shares (the spreadsheet way); "
                     "default for float-sink tables with a feed analysis: the joint fit of the three analyses")  # fmt: skip
    fit.add_argument("--floats-yield", type=cli_type(check_yield, "--floats-yield"), default=None, metavar="Y",
                     help="mass share of the feed to the floats (float-sink tables; estimated from three analyses when not given)")  # fmt: skip
    fit.add_argument("--excel", action="store_true",
                     help="also write the tables and figures as one workbook, results.xlsx, in the folder")  # fmt: skip
    fit.add_argument("--report", action="store_true",
                     help="also write report.html (figures embedded) and its Markdown twin report.md in the folder")  # fmt: skip
    fit.add_argument("--figures", choices=FIGURE_CHOICES, default="auto",
                     help="per-test figures with every fitted curve (all) or the best one (best); auto: all up to "
                     f"{AUTO_FIGURE_LIMIT} tests and size fractions, then one overview figure (default auto)")  # fmt: skip
    fit.add_argument("--no-figures", dest="figures", action="store_const", const="none", help="same as --figures none")
    add_jobs_option(fit)
    add_dask_options(fit)
    fit.add_argument("--sheet", default=None, help="Excel sheet (default: the first)")
    fit.add_argument("--sep", default=None, help="CSV field separator (detected when not given)")
    fit.add_argument("--decimal", default=None, help="CSV decimal mark (detected when not given)")
    fit.set_defaults(run=run_density_fit, imports=FIT_IMPORTS)


def run_density_fit(args) -> int:
    """Run ``tromplab density fit``: read, fit, write the folder, print the summary and the files written.

    A large campaign streams its results to the folder (:func:`tromplab.density.streamed.fit_density_to_folder`);
    the console then copies ``summary.txt`` and reads the notes back from ``warnings.csv``: the same words."""
    import sys

    from ..density.streamed import DensityFolder, fit_density_to_folder

    check_output_folder(args.outdir, inputs=[args.file])
    with progress_bars(quiet=args.quiet, unit="test", stages=("figures",)) as progress:
        result, written = fit_density_to_folder(
            args.file, args.outdir, figures=args.figures, excel=args.excel, report=args.report, ci=args.ci,
            curves=args.curves, method=args.method, floats_yield=args.floats_yield, sheet=args.sheet, sep=args.sep,
            decimal=args.decimal, jobs=args.jobs, scheduler=args.scheduler, dask=args.dask, progress=progress,
        )  # fmt: skip
    streamed = isinstance(result, DensityFolder)
    if streamed:
        sys.stdout.flush()
        result.write_report(sys.stdout)
    else:
        print(result.report())
    print("\nWrote:")
    for path in written.values():
        print(f"  {path}")
    tests = result.tests if streamed else len(result.samples)
    notices = result.notices()
    print_notices(notices, total=tests, quiet=args.quiet, verbose=args.verbose, noun="tests",
                  intervals=args.ci is not None)  # fmt: skip
    if args.quiet:
        count = result.notes if streamed else len(notices)
        said = f", {count} note(s) (warnings.csv)" if count else ""
        print_result(f"tromplab density fit: {tests} test(s) fitted{said}; results in {args.outdir}")
    unfitted = result.unfitted()
    if unfitted:
        print(f"\nno curve could be fitted to: {', '.join(unfitted)} (the reasons are in fits.csv)")
        return EXIT_PARTIAL
    return EXIT_OK
