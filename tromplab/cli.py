"""Command-line interface: the parser of every command, their handlers and the shared start-up.

Commands (``tromplab COMMAND -h`` for each; the command-line reference of the docs is generated from this parser):
``formulas`` (the formula catalogue), ``fit`` (fit, screen and rank on points or lab tables),
``report`` (HTML and Markdown report), ``compare`` (did the sharpness or the cut change),
``export`` (parameters in a simulator's convention), ``trend`` (control charts over surveys),
``points`` and ``balance`` (lab table to Tromp points, mass balance), ``sieve identify | pg |
bin``, ``rank`` (F table to ranks), ``circuit`` (plant survey reconciled; its work is in
:mod:`tromplab.circuit_command`), and from :mod:`tromplab.model_commands` ``layer simulate |
fit``, ``pulp optimum | fit`` and ``optimize``, and ``density fit | predict`` (density partition of gravity separators; its work
is in :mod:`tromplab.density_command` and :mod:`tromplab.density_predict_command`). The console script enters through
:mod:`tromplab._launch`, which handles SIGINT and SIGTERM before numpy is imported.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import logging
import os
import re
import signal
import sys
import textwrap
import traceback
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from ._version import __version__
from .density_command import add_density_command
from .density_predict_command import add_predict_parser
from .errors import InputError, InputNote, OptionError, ResultError, YieldWarning
from .model_commands import add_model_commands
from .options import (
    AUTO_FIGURE_LIMIT,
    BOOTSTRAP_METHODS,
    DEFAULT_ABSOLUTE_ERROR,
    DEFAULT_ALPHA,
    DEFAULT_ASSAY_ABSOLUTE_ERROR,
    DEFAULT_ASSAY_RELATIVE_ERROR,
    DEFAULT_FLOW_RELATIVE_ERROR,
    DEFAULT_MARGIN,
    DEFAULT_MIN_FEED_SHARE,
    DEFAULT_PCT_SOLIDS_SD,
    DEFAULT_RELATIVE_ERROR,
    DEFAULT_SUM_TOLERANCE_PCT,
    ERROR_MODEL_POINTS,
    FIGURE_CHOICES,
    KINDS,
    PARTITION_METHODS,
    PARTITION_TO,
    RANK_BY,
    TABLE_FORMATS,
)
from .output.outputs import check_output_file, check_output_folder, forget_written, write_files, written_outputs
from .validation import (
    MAX_BOOTSTRAP,
    MAX_DECKS,
    MAX_JOBS,
    SIZE_LIMITS,
    check_assay_sd,
    check_bootstrap,
    check_count,
    check_pct_solids_sd,
    check_positive_relative_error,
    check_probability,
    check_range,
    check_relative_error,
    check_seed,
    check_share,
    check_share_sd,
    check_size,
    check_water_recovery,
    cli_type,
    state_ranges,
)

#: Lengths of ``sieve pg`` (any one unit): only their ratios matter, and within this range
#: their squares and ratios stay normal floating-point numbers.
SIEVE_LENGTHS = {"low": 1e-100, "high": 1e100}
#: Sieve length of ``sieve bin`` (any unit): the design scales with it; beyond this range the
#: normal approximation's root is no longer bracketed in floating point.
BIN_LENGTHS = {"low": 1e-6, "high": 1e6}

# Each command imports the modules it needs when it runs: building the parser takes only the
# light modules above, so --version, -h and a command that needs little (export) do not pay
# for scipy.stats, lmfit, matplotlib and statsmodels at start-up (nothing imports the CLI, so
# the imports inside the functions hide no cycle).
if TYPE_CHECKING:
    import pandas as pd

    from .loading.lab import LabOptions

TERMINAL_COLUMNS = ["rank", "equation", "formula", "d50", "shape_name", "shape", "F", "F_crit", "adequate", "eta", "ep"]
#: Said under an experiment's table when a curve with bypass is shown: the two cuts told apart.
CUT_LEGEND = "d50: actual cut (partition 1/2) of every curve; d50c: corrected cut (of the classified part) of a curve with bypass"


#: Exit codes (documented in the README and docs/reliability.md).
EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_PARTIAL, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 1, 2, 3, 70, 130
EXIT_TERMINATED = 143  # 128 + SIGTERM, as shells report a process ended by SIGTERM


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread so the same clean-up runs as for Ctrl-C."""


def raise_terminated(signum, frame):
    """Signal handler: SIGTERM becomes :class:`Terminated`."""
    raise Terminated


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """Turn SIGTERM into :class:`Terminated` while the command runs (main thread only)."""
    try:
        previous = signal.signal(signal.SIGTERM, raise_terminated)
    except ValueError:  # not the main thread (main() called from a worker thread): leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv=None, *, on_start=None) -> int:
    """Run the command line; returns the exit code (0 done, 1 bad input, 2 usage,
    3 partial, 70 internal error, 130 interrupted by SIGINT, 143 terminated by SIGTERM).

    ``on_start`` (from :mod:`tromplab._launch`) is called when the command has imported its
    modules and starts its work: until then an interrupt ends the start-up at once.
    """
    parser = build_parser()
    forget_written()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # argparse stops on a usage error (2) or after --help/--version (0)
        return stop.code if isinstance(stop.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        return interrupted()
    if not hasattr(args, "run"):
        parser.print_help()
        return EXIT_USAGE
    path = [
        name
        for name in (args.command, *(getattr(args, f"{n}_command", None) for n in ("sieve", "layer", "pulp", "density")))
        if name
    ]
    command = " ".join(("tromplab", *path))
    own = _command_parser(parser, path)  # its options, not another command's, name the Python words
    try:
        _check_input_paths(args, own)  # before the imports: a missing file answers at once
        # a command imports its modules before it starts: an interrupt inside an import can stop
        # a module half-initialised (an ImportError, or Python's exit by SIGINT instead of 130)
        for module in getattr(args, "imports", ()):
            importlib.import_module(module)
        if on_start is not None:
            on_start()
        with _sigterm_as_interrupt(), warnings.catch_warnings(), _verbosity(args):
            warnings.simplefilter("ignore", YieldWarning)  # printed from the balance notes instead
            warnings.showwarning = _show_input_notes(warnings.showwarning)
            return args.run(args)
    except BrokenPipeError:  # output piped into head or less and closed early
        sys.stderr.close()
        return EXIT_OK
    except KeyboardInterrupt as interruption:
        return interrupted(interruption)
    except InputError as error:  # the project's own input, option and output errors
        if args.debug:
            traceback.print_exc()
        print(f"{command}: error: {_cli_message(error, own)}", file=sys.stderr)
        return EXIT_USAGE if isinstance(error, OptionError) else EXIT_INPUT
    except ResultError as error:  # a result outside its range is a failure, not a result
        print(f"{command}: failed: {_cli_words(str(error), own)}", file=sys.stderr)
        return EXIT_PARTIAL
    except Exception as error:  # anything else is a bug in tromplab: say so, do not dress it up as bad input
        if args.debug:
            raise
        print(
            f"{command}: internal error (a bug in tromplab, please report it): {type(error).__name__}: {error}\n"
            f"  run again with --debug for the traceback",
            file=sys.stderr,
        )
        return EXIT_INTERNAL


#: Positional arguments that name an input file, checked before a command imports its modules.
INPUT_FILE_ARGUMENTS = ("input", "data", "table", "flowsheet", "measurements")


def _check_input_paths(args, command_parser: argparse.ArgumentParser) -> None:
    """Every input file of the command exists and can be read (the loaders check it again).
    Only positional arguments are input files (an option such as ``--table`` may name an output)."""
    from .loading.paths import check_input_file

    positional = {action.dest for action in command_parser._actions if not action.option_strings}
    for name in INPUT_FILE_ARGUMENTS:
        path = getattr(args, name, None) if name in positional else None
        if isinstance(path, (str, os.PathLike)):
            check_input_file(path, option=name)


def interrupted(interruption=None) -> int:
    """Print the one-line message for an interrupted run; return 130 (SIGINT) or 143 (SIGTERM).

    The message says what is on disk: the previous outputs, or the new ones when the run was
    interrupted after it had put them in place (they are complete: a swap is one step)."""
    what = "terminated (SIGTERM)" if isinstance(interruption, Terminated) else "interrupted"
    written = written_outputs()
    if written:
        places = ", ".join(dict.fromkeys(str(path) for path in written))
        print(f"tromplab: {what} after the new results were written, complete, to {places}", file=sys.stderr)
    else:
        print(f"tromplab: {what}; the output folder was left as it was", file=sys.stderr)
    return EXIT_TERMINATED if isinstance(interruption, Terminated) else EXIT_INTERRUPTED


@contextlib.contextmanager
def _verbosity(args):
    """``--quiet`` silences the tables and progress on standard output and error (errors and
    warnings stay); ``-v`` adds the library's informational log lines."""
    handler = None
    library = logging.getLogger("tromplab")
    previous_level = library.level
    if args.verbose:  # a handler for this command only: main() may run many times in one process
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(name)s: %(message)s"))
        library.addHandler(handler)
        library.setLevel(logging.INFO if args.verbose == 1 else logging.DEBUG)
    try:
        if args.quiet:
            with open(os.devnull, "w") as sink, contextlib.redirect_stdout(sink):
                yield
        else:
            yield
    finally:
        if handler is not None:
            library.removeHandler(handler)
            library.setLevel(previous_level)


def _command_parser(parser: argparse.ArgumentParser, path) -> argparse.ArgumentParser:
    """The parser of the (sub)command ``path`` (``["sieve", "identify"]``) under ``parser``."""
    for name in path:
        actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction) and name in a.choices]
        if not actions:
            break
        parser = actions[0].choices[name]
    return parser


def _cli_message(error: InputError, parser: argparse.ArgumentParser) -> str:
    """The error in the command line's words: an option error of the library (``formulas``,
    ``bootstrap``) names the option as typed (``--formulas``), other Python names too."""
    if isinstance(error, OptionError) and not error.option.startswith("-"):
        flags = {action.dest: flag for action in _all_actions(parser) for flag in action.option_strings if flag.startswith("--")}
        flag = flags.get(error.option) or flags.get({"n_bootstrap": "bootstrap"}.get(error.option, ""))
        if flag:
            return f"{flag} {_cli_words(error.reason, parser)}"
    return _cli_words(str(error), parser)


def _cli_words(message: str, parser: argparse.ArgumentParser | None = None) -> str:
    """Replace Python argument names (``fine_yield``) by the CLI's options (``--fine-yield``)."""
    parser = parser or build_parser()
    for name, flag in _python_names_of_options(parser).items():
        if name in message:  # not inside quoted column names
            message = re.sub(rf"(?<![-\w'\"]){name}(?![\w'\"])", flag, message)
    for name, flag in _keywords_of_options(parser).items():  # kind='pct' -> --kind pct
        if f"{name}=" in message:
            message = re.sub(rf"(?<![-\w'\"]){name}=(['\"]?)([\w.,-]+)\1", rf"{flag} \2", message)
    return message


def _keywords_of_options(parser: argparse.ArgumentParser) -> dict[str, str]:
    """Every option's Python keyword (``kind``) and its flag (``--kind``)."""
    return {
        action.dest: flag
        for action in _all_actions(parser)
        for flag in action.option_strings
        if flag.startswith("--") and flag[2:].replace("-", "_") == action.dest
    }


def _python_names_of_options(parser: argparse.ArgumentParser) -> dict[str, str]:
    options = {"sum_tolerance_pct": "--sum-tolerance", "n_bootstrap": "--bootstrap"}  # Python names unlike the option
    for action in _all_actions(parser):
        for flag in action.option_strings:
            if flag.startswith("--") and "_" in action.dest:
                options[action.dest] = flag
    return options


def _all_actions(parser: argparse.ArgumentParser):
    for action in parser._actions:
        yield action
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _all_actions(sub)


def _global_options(*, in_subcommand: bool) -> argparse.ArgumentParser:
    """--quiet, -v and --debug, accepted before or after the command."""
    options = argparse.ArgumentParser(add_help=False)
    default = argparse.SUPPRESS if in_subcommand else None
    group = options.add_argument_group("general")
    group.add_argument("-q", "--quiet", action="store_true", default=default or False, help="print only errors and warnings")
    group.add_argument("-v", "--verbose", action="count", default=default or 0, help="more detail (repeat for more)")
    group.add_argument("--debug", action="store_true", default=default or False, help="show the Python traceback of an error")
    return options


def _fit_options_parser() -> argparse.ArgumentParser:
    """Options shared by ``fit`` and ``report``, declared once."""
    shared = argparse.ArgumentParser(add_help=False)
    shared.add_argument("input", type=Path, help="Tromp points or a lab table (CSV or .xlsx), told apart by their columns")
    shared.add_argument(
        "--alpha",
        type=cli_type(check_probability, "--alpha"),
        default=DEFAULT_ALPHA,
        help="significance level of the Fisher screen, in (0, 1) (default %(default)s)",
    )
    shared.add_argument(
        "--delta-max",
        type=cli_type(check_size, "--delta-max"),
        default=None,
        help="largest feed particle size for the misplacement eps, at most 1e9 times the smallest size of "
        "an experiment (default: largest size of the data)",
    )
    shared.add_argument(
        "--formulas",
        default=None,
        help="comma-separated ids or equation numbers; 'paper' = the nine, 'extended' = the bypass and "
        "fish-hook curves (default: the nine)",
    )
    shared.add_argument("--rank-by", choices=sorted(RANK_BY), default="F", help="criterion within an experiment")
    shared.add_argument("--size-unit", default="", help="unit of the sizes, for the figure labels")
    shared.add_argument(
        "--extended",
        action="store_true",
        help="also fit the curves with bypass and fish-hook (reported, kept out of the ranking)",
    )
    shared.add_argument("--rank-extended", action="store_true", help="rank the extended curves with the nine")
    return shared


def _water_recovery_parser() -> argparse.ArgumentParser:
    """``--water-recovery`` of ``fit``, ``report`` and ``points``, declared once."""
    water = argparse.ArgumentParser(add_help=False)
    water.add_argument(
        "--water-recovery",
        type=cli_type(check_water_recovery, "--water-recovery"),
        default=None,
        metavar="RF",
        help="hydrocyclones: share of the feed water reporting to the underflow, in [0, 1); gives the "
        "Kelsall-corrected partition (points) and compares the fitted bypass with it (fit, report)",
    )
    return water


def _show_input_notes(show):
    """A ``warnings.showwarning`` that prints input notes (e.g. a detected CSV dialect) as one line."""

    def showwarning(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, InputNote):
            print(textwrap.fill(f"note: {message}", width=98, break_on_hyphens=False), file=sys.stderr)
        else:
            show(message, category, filename, lineno, file, line)

    return showwarning


#: The modules each command imports when it runs (its functions' own imports), imported by
#: main() before the command starts; the readers of lab tables import statsmodels, and with it
#: scipy, when they estimate a yield.
_READERS = ("tromplab.loading.lab", "tromplab.loading.tables", "scipy.stats")


def build_parser() -> argparse.ArgumentParser:
    """The ``tromplab`` parser: one builder per command, from the option groups declared once."""
    parser = _CommandParser(
        prog="tromplab",
        description="Fit, screen and rank separation (Tromp) curves.",
        parents=[_global_options(in_subcommand=False)],
        epilog="Exit codes: 0 done, 1 bad input (nothing written), 2 usage, 3 partial "
        "(failures listed in failures.csv), 70 internal error, 130 interrupted, 143 terminated.",
    )
    parser.add_argument("--version", action="version", version=f"tromplab {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_SubcommandParser)
    groups = {"lab": _lab_options_parser(), "shared": _fit_options_parser(), "water": _water_recovery_parser()}
    for add_command in (_add_formulas, _add_fit, _add_report, _add_compare, _add_export, _add_trend, _add_points, _add_balance):
        add_command(commands, groups)
    _add_sieve(commands)
    _add_rank(commands)
    add_model_commands(commands)  # layer, pulp, optimize
    _add_circuit_command(commands)
    density = add_density_command(commands)  # density fit (the sub-commands and their work are in density_command)
    add_predict_parser(density.density_commands)  # density predict (density_predict_command)
    state_ranges(parser)
    return parser


def _add_formulas(commands, groups) -> None:
    formulas = commands.add_parser(
        "formulas", help="list the separation-curve formulas (the nine of the paper, then the extended curves)"
    )
    formulas.set_defaults(run=_run_formulas, imports=("tromplab.curves.formulas", "pandas", "scipy.special", "scipy.optimize"))


def _add_fit(commands, groups) -> None:
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
    _add_partition_to(fit)
    fit.add_argument(
        "--figures",
        choices=FIGURE_CHOICES,
        default="auto",
        help=f"per-experiment figures with every fit (all) or the top-ranked one (best); auto: all up to "
        f"{AUTO_FIGURE_LIMIT} experiments, then one overview figure (default auto)",
    )
    fit.add_argument("--no-figures", dest="figures", action="store_const", const="none", help="same as --figures none")
    fit.add_argument("--format", choices=TABLE_FORMATS, default="csv", help="format of the tables (parquet needs pyarrow)")
    _add_scale_options(fit.add_argument_group("scale"))
    _add_uncertainty_options(fit.add_argument_group("uncertainty"))
    fit.set_defaults(run=_run_fit, imports=(*_READERS, "tromplab.workbench", "tromplab.statistics.hydrocyclone"))


def _add_jobs_option(group) -> None:
    group.add_argument(
        "--jobs",
        type=cli_type(check_count, "--jobs", minimum=0, maximum=MAX_JOBS),
        default=0,
        metavar="N",
        help="worker processes (default 0: all cores)",
    )


def _add_scale_options(scale) -> None:
    _add_jobs_option(scale)
    scale.add_argument("--scheduler", default=None, metavar="ADDRESS", help="run on this Dask scheduler (tcp://host:8786)")
    scale.add_argument("--dask", choices=("local",), default=None, help="run on a local Dask cluster")
    scale.add_argument(
        "--single-fits",
        action="store_true",
        help="fit one experiment and formula at a time with lmfit instead of the batched engine",
    )


def _add_uncertainty_options(uncertainty) -> None:
    uncertainty.add_argument(
        "--ci",
        type=cli_type(check_probability, "--ci"),
        default=None,
        metavar="LEVEL",
        help="add interval columns at this level (profile likelihood for parameters, delta method for indices)",
    )
    uncertainty.add_argument(
        "--bootstrap",
        type=cli_type(check_bootstrap, "--bootstrap"),
        default=0,
        metavar="N",
        help=f"add bootstrap percentile intervals from N resamples (at most {MAX_BOOTSTRAP:,})",
    )
    uncertainty.add_argument(
        "--bootstrap-method",
        choices=BOOTSTRAP_METHODS,
        default="residuals",
        help="resample the residuals of the fit or whole points (default: residuals)",
    )
    uncertainty.add_argument(
        "--seed",
        type=cli_type(check_seed, "--seed"),
        default=0,
        help="seed of the bootstrap, a whole number >= 0: the same seed gives the same intervals (default %(default)s)",
    )


def _add_report(commands, groups) -> None:
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
    _add_jobs_option(report.add_argument_group("scale"))
    _add_partition_to(report)
    report.set_defaults(run=_run_report, imports=(*_READERS, "tromplab.workbench"))


def _add_compare(commands, groups) -> None:
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
    compare.set_defaults(run=_run_compare, imports=(*_READERS, "tromplab.statistics.compare"))


def _add_export(commands, groups) -> None:
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


def _add_trend(commands, groups) -> None:
    trend = commands.add_parser(
        "trend", parents=[groups["lab"]], help="monitor a classifier over surveys: control charts and change flags"
    )
    trend.add_argument("input", type=Path, help="Tromp points or a lab table with a 'date' (or 'survey') column")
    trend.add_argument("-o", "--outdir", type=Path, default=Path("results/trend"), help="output folder (default: results/trend)")
    trend.add_argument("--formula", default=None, help="formula id (default: the best-ranked of the nine over all surveys)")
    trend.add_argument(
        "--baseline",
        default=None,
        help="baseline period: the first N surveys, or a date range FROM:TO (default: the first half, at most 8)",
    )
    trend.add_argument(
        "--alpha",
        type=cli_type(check_probability, "--alpha"),
        default=0.01,
        help="significance level of the change flags (default 0.01)",
    )
    trend.add_argument("--size-unit", default="", help="unit of the sizes, for the figure labels")
    trend.add_argument("--no-figures", action="store_true", help="do not draw figures")
    trend.set_defaults(run=_run_trend, imports=(*_READERS, "tromplab.trend"))


def _add_points(commands, groups) -> None:
    points = commands.add_parser(
        "points", parents=[groups["lab"], groups["water"]], help="turn a lab table into Tromp points with diagnostics"
    )
    points.add_argument("input", type=Path, help="lab table (CSV or .xlsx)")
    points.add_argument("-o", "--output", type=Path, required=True, help="Tromp points CSV to write")
    _add_partition_to(points)
    points.set_defaults(run=_run_points, imports=(*_READERS, "tromplab.output.views", "tromplab.output.csv_parts"))


def _add_balance(commands, groups) -> None:
    balance = commands.add_parser("balance", parents=[groups["lab"]], help="yield estimate and mass-balance table of a lab table")
    balance.add_argument("input", type=Path, help="lab table (CSV or .xlsx)")
    _add_partition_to(balance)
    balance.set_defaults(run=_run_balance, imports=(*_READERS, "tromplab.output.views"))


def _add_sieve(commands) -> None:
    sieve = commands.add_parser("sieve", help="sieve classifiers: identification, geometric probability, bin design")
    sieve_commands = sieve.add_subparsers(dest="sieve_command", metavar="SIEVE_COMMAND", required=True)
    identify = sieve_commands.add_parser("identify", help="identify Vk and sigma from residues at several speed regimes")
    identify.add_argument("data", type=Path, help="CSV: sieve, fraction, relative_speed, residue, sieve_length, cell_pitch, P_g")
    identify.add_argument(
        "-o",
        "--output",
        type=Path,
        default=Path("results/velocity_laws.csv"),
        help="CSV of the identified laws (default: results/velocity_laws.csv)",
    )
    identify.add_argument("--two-sided", action="store_true", help="two-sided velocity probability (random-walk paper)")
    identify.add_argument(
        "--level", type=cli_type(check_probability, "--level"), default=0.95, help="confidence level of the intervals, in (0, 1)"
    )
    identify.set_defaults(run=_run_sieve_identify, imports=("tromplab.classifiers.sieve", *_READERS, "tromplab.output.csv_parts"))
    _add_sieve_pg(sieve_commands)
    _add_sieve_bin(sieve_commands)


def _add_sieve_pg(sieve_commands) -> None:
    pg = sieve_commands.add_parser("pg", help="geometric probability of a particle passing a round hole")
    pg.add_argument("--hole", type=cli_type(check_range, "--hole", **SIEVE_LENGTHS), required=True, help="hole diameter D")
    pg.add_argument("--length", type=cli_type(check_range, "--length", **SIEVE_LENGTHS), required=True, help="particle length l")
    pg.add_argument(
        "--width",
        type=cli_type(check_range, "--width", **SIEVE_LENGTHS),
        required=True,
        help="particle width d (shape factor d/l)",
    )
    pg.add_argument(
        "--cell-width",
        type=cli_type(check_range, "--cell-width", **SIEVE_LENGTHS),
        required=True,
        help="cell width 2b across the transport direction",
    )
    pg.add_argument(
        "--method",
        choices=("auto", "closed", "quadrature"),
        default="auto",
        help="closed form, quadrature, or auto: the closed form where it is valid (default)",
    )
    pg.set_defaults(run=_run_sieve_pg, imports=("tromplab.classifiers.sieve",))


def _add_sieve_bin(sieve_commands) -> None:
    bin_ = sieve_commands.add_parser("bin", help="collecting-bin position on the bottom deck for a required recovery")
    bin_.add_argument(
        "--decks",
        type=cli_type(check_count, "--decks", maximum=MAX_DECKS),
        required=True,
        help=f"number of decks m, 1 to {MAX_DECKS}",
    )
    bin_.add_argument(
        "--length", type=cli_type(check_range, "--length", **BIN_LENGTHS), required=True, help="sieve length L (= x2)"
    )
    bin_.add_argument(
        "--recovery",
        type=cli_type(check_probability, "--recovery"),
        required=True,
        help="required recovery g* of the target fraction, in (0, 1)",
    )
    bin_.set_defaults(run=_run_sieve_bin, imports=("tromplab.classifiers.sieve",))


def _add_rank(commands) -> None:
    rank = commands.add_parser("rank", help="rank formulas from a table of F values (Table 2 -> Table 3)")
    rank.add_argument("table", type=Path, help="CSV with experiment, equation, F and n or F_crit [, adequate]")
    rank.add_argument(
        "-o", "--outdir", type=Path, default=Path("results"), help="output folder for ranking.csv (default: results)"
    )
    rank.add_argument(
        "--alpha",
        type=cli_type(check_probability, "--alpha"),
        default=DEFAULT_ALPHA,
        help="significance level for F_crit from n, in (0, 1)",
    )
    rank.add_argument("--computed-adequacy", action="store_true", help="ignore an 'adequate' column and use F > F_crit")
    rank.set_defaults(run=_run_rank, imports=("tromplab.curves.ranking", *_READERS, "tromplab.output.csv_parts"))


def _add_partition_to(parser) -> None:
    parser.add_argument(
        "--partition-to",
        choices=PARTITION_TO,
        default="fine",
        help="report the partition to the fine product (default) or to the coarse product (underflow, oversize)",
    )


class _CommandParser(argparse.ArgumentParser):
    """A usage error prints the error and where to look, not the whole usage block."""

    def error(self, message):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n  see '{self.prog} -h' for the options\n")


class _SubcommandParser(_CommandParser):
    """Every command accepts the global options after its name too (``tromplab fit -q ...``)."""

    def __init__(self, *args, **kwargs):
        kwargs["parents"] = [*kwargs.get("parents", []), _global_options(in_subcommand=True)]
        super().__init__(*args, **kwargs)


def _lab_options_parser() -> argparse.ArgumentParser:
    lab = argparse.ArgumentParser(add_help=False)
    group = lab.add_argument_group("lab data (schema: docs/lab_tables.md)")
    group.add_argument(
        "--kind",
        choices=KINDS,
        default=None,
        help="what plain feed/fine/coarse columns hold (not needed with suffixed column names)",
    )
    group.add_argument(
        "--fine-yield",
        type=cli_type(check_probability, "--fine-yield"),
        default=None,
        help="fine-product yield, fraction of the feed",
    )
    group.add_argument(
        "--coarse-yield",
        type=cli_type(check_probability, "--coarse-yield"),
        default=None,
        help="coarse-product yield, fraction of the feed",
    )
    group.add_argument("--estimate-yield", action="store_true", help="estimate the yield from three streams even if one is given")
    group.add_argument("--reconcile", action="store_true", help="adjust the three streams minimally so every class balances")
    group.add_argument(
        "--min-feed-share",
        type=cli_type(check_share, "--min-feed-share"),
        default=DEFAULT_MIN_FEED_SHARE,
        help="leave out classes with a smaller feed share (fraction; default %(default)s)",
    )
    group.add_argument(
        "--sum-tolerance",
        type=cli_type(check_range, "--sum-tolerance", low=0.0, high=100.0),
        default=DEFAULT_SUM_TOLERANCE_PCT,
        help="allowed deviation of per-class percentages from 100 (percentage points; default %(default)s)",
    )
    group.add_argument(
        "--top-size", type=cli_type(check_size, "--top-size"), default=None, help="upper bound of the open top class"
    )
    group.add_argument(
        "--pan-lower-size",
        type=cli_type(check_range, "--pan-lower-size", low=0.0, high=SIZE_LIMITS[1]),
        default=None,
        help="lower bound of the pan",
    )
    group.add_argument("--rename", default="", help="column renames OLD=NEW,OLD=NEW applied before reading")
    group.add_argument("--sheet", default=None, help="Excel sheet name (default: the first sheet)")
    group.add_argument(
        "--weight-by-feed-share",
        action="store_true",
        help="weight each point by its class's feed share (variance inversely proportional to it)",
    )
    group.add_argument(
        "--partition-from",
        choices=PARTITION_METHODS,
        default="products",
        help="with three streams: partition from both products y b/(y b + (1-y) c) (default; swapping fine "
        "and coarse gives 1 - partition) or from the fine stream over the measured feed y b/a",
    )
    group.add_argument("--sep", default=None, help="CSV field separator, e.g. ';' (default: detected from the header)")
    group.add_argument("--decimal", default=None, help="CSV decimal mark, e.g. ',' (default: '.', or ',' when detected)")
    return lab


def _lab_options(args) -> LabOptions:
    from .loading.lab import LabOptions

    rename = {}
    for pair in filter(None, (p.strip() for p in args.rename.split(","))):
        old, sep, new = pair.partition("=")
        if not sep or not old.strip() or not new.strip():
            raise OptionError("--rename", f"takes OLD=NEW pairs separated by commas, got {pair!r}")
        rename[old.strip()] = new.strip()
    return LabOptions(
        kind=args.kind,
        fine_yield=args.fine_yield,
        coarse_yield=args.coarse_yield,
        estimate_yield=args.estimate_yield,
        reconcile=args.reconcile,
        min_feed_share=args.min_feed_share,
        sum_tolerance_pct=args.sum_tolerance,
        top_size=args.top_size,
        pan_lower_size=args.pan_lower_size,
        rename=rename,
        sheet=args.sheet,
        weight_by_feed_share=args.weight_by_feed_share,
        partition_from=args.partition_from,
        size_unit=getattr(args, "size_unit", None) or None,
        sep=args.sep,
        decimal=args.decimal,
        water_recovery=getattr(args, "water_recovery", None),
    )


def _print_balance_notes(balances, *, listed_in: str = "") -> None:
    """The balance warnings, and one line per experiment for the classes left out (where
    the full list is, when it is written: ``listed_in``)."""
    for balance in balances:
        for note in balance.notes:
            print(textwrap.fill(f"warning ({balance.experiment}): {_cli_words(note)}", width=98), file=sys.stderr)
        if summary := balance.left_out_summary():
            where = f"; the list is in {listed_in}" if listed_in else ""
            print(textwrap.fill(f"note ({balance.experiment}): {summary}{where}", width=98), file=sys.stderr)


def _run_points(args) -> int:
    import pandas as pd

    from .loading.lab import read_lab
    from .loading.tables import check_input_file
    from .output.views import partition_view

    check_input_file(args.input)
    check_output_file(args.output, inputs=[args.input])
    balances = read_lab(args.input, _lab_options(args))
    table = pd.concat(
        [b.points_table(weight_by_feed_share=args.weight_by_feed_share, unit_in_names=True) for b in balances], ignore_index=True
    )
    table = partition_view(table, args.partition_to)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    from .output.csv_parts import write_csv

    written = write_files({args.output.name: lambda p: write_csv(table, p)}, args.output.parent)
    _print_balance_notes(balances)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
    print(f"\nWrote: {written[args.output.name]}")
    return 0


def _run_balance(args) -> int:
    from .loading.lab import PARTITION_METHOD_TEXT, read_lab
    from .loading.tables import check_input_file
    from .output.views import balance_view

    check_input_file(args.input)
    balances = read_lab(args.input, _lab_options(args))
    _print_balance_notes(balances)
    for balance in balances:
        estimate = balance.yield_estimate
        print(
            f"Experiment {balance.experiment}: fine yield {balance.fine_yield:.4f} ({balance.yield_source}); "
            f"partition from {PARTITION_METHOD_TEXT[balance.partition_method]}"
        )
        if estimate is not None:
            print(
                f"  least-squares estimate from the three streams: {estimate.value:.4f} +/- {estimate.stderr:.4f} "
                f"(standard error, {estimate.n_classes} classes); coarse yield {1 - estimate.value:.4f}"
            )
        table = balance_view(balance.classes, args.partition_to, adjusted=True)
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
        print()
    return 0


def _run_sieve_identify(args) -> int:
    from .classifiers.sieve import identify_from_table
    from .loading.tables import check_input_file, read_table
    from .output.csv_parts import write_csv

    check_input_file(args.data)
    check_output_file(args.output, inputs=[args.data])
    laws = identify_from_table(read_table(args.data), two_sided=args.two_sided, level=args.level)
    written = write_files({args.output.name: lambda p: write_csv(laws, p)}, args.output.parent)
    view = laws[["sieve", "fraction", "n_regimes", "v_k", "v_k_stderr", "sigma", "sigma_stderr", "success"]]
    print(view.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
    for sieve, fraction, message in laws.loc[~laws["success"].astype(bool), ["sieve", "fraction", "message"]].itertuples(
        index=False
    ):
        print(f"  not identified: sieve {sieve}, fraction {fraction}: {message}")
    print(f"\nWrote: {written[args.output.name]}")
    return 0


def _run_sieve_pg(args) -> int:
    from .classifiers.sieve import closed_form_valid, geometric_probability

    if args.width > args.length:
        raise OptionError(
            "--width", f"must not exceed --length ({args.width:g} > {args.length:g}): the shape factor d/l is at most 1"
        )
    value = geometric_probability(args.hole, args.length, args.width, args.cell_width / 2, method=args.method)
    if not 0.0 <= value <= 1.0:  # also nan
        raise ResultError(f"the geometric probability came out as {value!r}, outside 0..1")
    closed = closed_form_valid(args.hole, args.length, args.width, args.cell_width / 2)
    print(
        f"P_g = {value:.6f}  (D = {args.hole:g}, l = {args.length:g}, d = {args.width:g}, d/l = {args.width / args.length:.3g}, "
        f"2b = {args.cell_width:g}; closed form {'valid' if closed else 'not valid: quadrature'})"
    )
    return 0


def _run_sieve_bin(args) -> int:
    import numpy as np

    from .classifiers.sieve import design_bin, distance_moments

    failed = []
    for method in ("exact", "normal"):
        try:
            design = design_bin(args.decks, args.length, args.recovery, method=method)
        except ValueError as error:  # the root of the recovery equation is not bracketed
            failed.append(f"{method}: no bin position found ({error})")
            continue
        # the normal approximation places the bin by its own distribution: only the exact
        # method must reach the required recovery, both must place the bin on the deck
        exact_enough = method != "exact" or abs(design.recovery - args.recovery) < 1e-6
        if not (np.isfinite([design.c, design.x1, design.recovery]).all() and exact_enough and 0.0 <= design.x1 <= design.x2):
            failed.append(
                f"{method}: the bin position {design.x1:.4g} (deck length {design.x2:g}) gives a recovery of "
                f"{design.recovery:.4g}, not the required {args.recovery:.15g}"
            )
            continue
        print(
            f"{method:>6}: C = {design.c:.4f}, x1 = {design.x1:.4f}, x2 = {design.x2:.4g}, recovery in the bin = {design.recovery:.4f}"
        )
        if method == "exact":
            mean, variance = distance_moments(args.decks, design.c)
            moments = f"exact mean distance on deck {args.decks}: {mean:.4f}, standard deviation {np.sqrt(variance):.4f}"
    if len(failed) == 2:
        raise ResultError("; ".join(failed))
    if not failed[:1] or not failed[0].startswith("exact"):
        print(moments)
    if failed:
        raise ResultError(failed[0])
    return 0


def _run_formulas(args) -> int:
    from .curves.formulas import NAME_CLASHES, registry_table

    table = registry_table()
    for family, heading in (
        ("paper", "The nine formulas of Shuvalov et al. (2018)"),
        ("extended", "Extended curves (--extended)"),
        ("other", "Curves of other tools (--formulas other)"),
    ):
        print(f"{heading}:")
        for row in table[table["family"] == family].itertuples(index=False):
            extras = f", extras {row.extras}" if row.extras else ""
            print(
                textwrap.fill(
                    f"({row.equation}) {row.id}: phi = {row.formula}", width=98, initial_indent="  ", subsequent_indent="      "
                )
            )
            print(
                textwrap.fill(
                    f"shape {row.shape_name}{extras}; slope at the cut {row.slope_at_cut}",
                    width=98,
                    initial_indent="      ",
                    subsequent_indent="      ",
                )
            )
        print()
    print("Same name, different curve (docs/curves.md):")
    for clash in NAME_CLASHES:
        print(textwrap.fill(clash, width=98, initial_indent="  - ", subsequent_indent="    "))
    print()
    print("x = size / d_cut; phi = partition to the fine product. Corrections: docs/errata.md.")
    return 0


def _run_fit(args) -> int:
    from .loading.lab import read_experiments
    from .loading.tables import check_input_file
    from .workbench import check_formula_selection, fit_experiments

    formulas = check_formula_selection(args.formulas, args.extended)
    check_input_file(args.input)
    if args.outdir.suffix.lower() == ".xlsx":
        check_output_file(args.outdir, inputs=[args.input], option="--outdir")
    else:
        check_output_folder(args.outdir, inputs=[args.input])
    if args.format == "parquet":
        _require("pyarrow", "--format parquet", "pip install 'tromplab[dask]'")
    experiments = read_experiments(args.input, _lab_options(args))
    _print_balance_notes(experiments.balances, listed_in="left_out.csv")
    with _progress_bars(quiet=args.quiet) as progress:
        bench = fit_experiments(experiments, **_fit_keywords(args, formulas), progress=progress)
    bench.check_fitted(args.input)
    written = bench.save(args.outdir, figures=args.figures, format=args.format, excel=args.excel, jobs=args.jobs)
    _print_fits(bench, args)
    _print_written(list(written.values()), args.outdir)
    return _report_failures(bench.failure_table())


def _fit_keywords(args, formulas) -> dict:
    """The keywords of :func:`tromplab.fit_experiments` from the options of the same names."""
    return dict(
        formulas=formulas,
        alpha=args.alpha,
        delta_max=args.delta_max,
        rank_by=args.rank_by,
        rank_extended=args.rank_extended,
        size_unit=args.size_unit,
        water_recovery=args.water_recovery,
        partition_to=args.partition_to,
        ci=getattr(args, "ci", None),
        bootstrap=getattr(args, "bootstrap", 0),
        bootstrap_method=getattr(args, "bootstrap_method", "residuals"),
        seed=getattr(args, "seed", 0),
        jobs=getattr(args, "jobs", 1) or None,
        scheduler=getattr(args, "scheduler", None),
        dask=getattr(args, "dask", None),
        single_fits=getattr(args, "single_fits", False),
    )


def _print_fits(bench, args) -> None:
    """The console view of a fit run: data notes, the ranked fits of the first experiments
    with their verdicts, the water-recovery checks, failures and the ranking across experiments."""
    from .statistics.hydrocyclone import water_recovery_statements

    for experiment, notes in bench.notes.items():
        for note in notes:
            print(textwrap.fill(f"warning ({experiment}): {note}", width=98), file=sys.stderr)
    if args.quiet:  # standard output goes nowhere: formatting the tables would be wasted (0.3 s at 1,024 experiments)
        return
    fits, ranking = bench.fits_table(), bench.ranking_table()
    shown_experiments = list(dict.fromkeys(fits["experiment"]))[:AUTO_FIGURE_LIMIT]
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


def _report_failures(failures: pd.DataFrame, *, listed_in: str = "failures.csv") -> int:
    """Exit code 3 with the failures on standard error when some fits failed, else 0."""
    if failures.empty:
        return EXIT_OK
    print(f"tromplab: partial result: {len(failures)} experiment(s) or fit(s) failed (listed in {listed_in}):", file=sys.stderr)
    for row in failures.itertuples(index=False):
        what = f"{row.experiment} / {row.formula}" if row.formula else row.experiment
        print("  " + textwrap.shorten(f"{what}: {row.reason}", width=160), file=sys.stderr)
    return EXIT_PARTIAL


def _require(module: str, option: str, install: str) -> None:
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise InputError(f"{option} needs the package {module}: {install}")


class _progress_bars:
    """tqdm bars on standard error with rate and ETA, as one ``progress(done, total, label)``
    callback: a bar for the fits, then one for the intervals (labels ``"intervals: ..."``);
    silent when standard error is not a terminal, with --quiet, or without tqdm."""

    def __init__(self, *, quiet: bool = False):
        self.enabled = not quiet and sys.stderr.isatty()
        self.bar, self.stage = None, None

    def __enter__(self):
        if not self.enabled:
            return None
        try:
            from tqdm import tqdm
        except ImportError:
            from .workbench import print_progress

            return print_progress

        def update(done, total, label):
            stage = "intervals" if label.startswith("intervals: ") else "fitting"
            if total <= 1:
                return
            if stage != self.stage:
                self._close()
                self.bar = tqdm(
                    total=total, desc=stage, unit="fit" if stage == "intervals" else "exp", file=sys.stderr, dynamic_ncols=True
                )
                self.stage = stage
            self.bar.update(done - self.bar.n)

        return update

    def _close(self):
        if self.bar is not None:
            self.bar.close()

    def __exit__(self, *exc):
        self._close()
        return False


def _run_report(args) -> int:
    from .loading.lab import read_experiments
    from .loading.tables import check_input_file
    from .workbench import check_formula_selection, fit_experiments

    formulas = check_formula_selection(args.formulas, args.extended)
    check_input_file(args.input)
    check_output_file(args.output, inputs=[args.input])
    experiments = read_experiments(args.input, _lab_options(args))
    keywords = {**_fit_keywords(args, formulas), "ci": None}  # the report's --ci is the level of its tables, not interval columns
    with _progress_bars(quiet=args.quiet) as progress:
        bench = fit_experiments(experiments, **keywords, progress=progress)
    bench.check_fitted(args.input)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    written = bench.report(args.output, level=args.ci, title=args.title, jobs=args.jobs)
    print("Wrote:")
    for path in written.values():
        print(f"  {path}")
    return _report_failures(bench.failure_table(), listed_in="the report")


def _run_compare(args) -> int:
    from .curves.formulas import get_formula
    from .loading.lab import read_experiments
    from .loading.tables import check_input_file
    from .statistics.compare import shared_fit

    check_input_file(args.input)
    experiments, _ = read_experiments(args.input, _lab_options(args))
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


#: Rows of an export (and experiments per left-out formula) printed on the console; the file has all.
EXPORT_CONSOLE_ROWS = 40


def _run_export(args) -> int:
    from .output.export import export_fits

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


def _run_trend(args) -> int:
    from .loading.tables import check_input_file
    from .trend import monitor_surveys, read_surveys, write_trend

    check_input_file(args.input)
    check_output_folder(args.outdir, inputs=[args.input])
    surveys = read_surveys(args.input, _lab_options(args))
    result = monitor_surveys(surveys, formula=args.formula, baseline=args.baseline, alpha=args.alpha)
    written = write_trend(result, args.outdir, size_unit=args.size_unit, figures=not args.no_figures)
    print(result.summary())
    print("\nWrote:")
    for path in written.values():
        print(f"  {path}")
    return 0


def _run_rank(args) -> int:
    from .curves.ranking import rank_formulas, read_f_table
    from .loading.tables import check_input_file
    from .output.csv_parts import write_csv

    check_input_file(args.table)
    check_output_folder(args.outdir, inputs=[args.table])
    table = read_f_table(args.table, alpha=args.alpha, use_given_marks=not args.computed_adequacy)
    ranking = rank_formulas(table)
    written = write_files({"ranking.csv": lambda p: write_csv(ranking, p)}, args.outdir)
    print(ranking.to_string(index=False))
    print(f"\nWrote: {written['ranking.csv']}")
    return 0


#: Console words for the residual verdict (fits.csv column ``residuals``).
RESIDUAL_WORDS = {
    "random": "random",
    "exact": "exact",
    "systematic": "SYSTEMATIC",
    "not normal": "NOT NORMAL",
    "systematic, not normal": "SYST.+NOT NORM.",
}


def format_fits(fits: pd.DataFrame, verdicts: dict[str, list[str]] | None = None, *, rank_by: str = "F") -> str:
    """The ranked fits, one block per experiment, readable in a 100-column terminal.

    The criterion of the ranking is shown: ``F`` and ``F_crit`` when ranking by F,
    ``aicc`` (beside F) when ranking by AICc.  When the table has interval columns
    (``--ci``, else ``--bootstrap``), a second table per experiment gives the intervals
    of d_cut, the shape parameter and Ep.  ``verdicts`` (experiment -> statements,
    :meth:`Workbench.verdicts`) are printed under each table: indistinguishable formulas,
    shared ranks, adequate fits with systematic or non-normal residuals, extrapolated
    indices.  An adequate fit whose residuals fail a test is marked ``yes*`` in the
    adequacy column.
    """
    import numpy as np

    from .curves.diagnostics import RESIDUAL_WARNING
    from .curves.measured import CUT_WARNING

    columns = list(TERMINAL_COLUMNS)
    if rank_by == "aicc":
        columns[columns.index("F_crit")] = "aicc"
    kind = "" if "d_cut_low" in fits.columns else "_boot"  # --ci intervals, else the bootstrap's
    intervals = [
        f"{q}{kind}_{end}" for q in ("d_cut", "shape", "ep") for end in ("low", "high") if f"{q}{kind}_{end}" in fits.columns
    ]
    blocks = []
    for experiment, group in fits.groupby("experiment", sort=False):
        if not group["success"].any():
            continue  # experiments that could not be fitted are listed separately
        ordered = group.sort_values("rank", na_position="last")
        corrected = _has_bypass(ordered)
        shown = [*columns[:4], "d50c", *columns[4:]] if corrected else columns
        view = ordered[shown].copy()
        flagged = ordered["residuals"].fillna("").str.contains("systematic|not normal")
        view["adequate"] = np.where(ordered["adequate"], np.where(flagged, "yes*", "yes"), "NO")
        view.loc[~ordered["success"], "adequate"] = "failed"
        view["residuals"] = ordered["residuals"].map(RESIDUAL_WORDS).fillna("-")
        view = view.rename(columns={"equation": "eq", "shape_name": "par", "adequate": "adequ."})
        text = view.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-")
        n = int(group["n"].dropna().iloc[0]) if group["n"].notna().any() else 0
        ranked_by = "AICc (lowest first)" if rank_by == "aicc" else "F (highest first)"
        blocks.append(f"Experiment {experiment} (n = {n}), ranked by {ranked_by}:\n{text}")
        if corrected:
            blocks.append(textwrap.fill(CUT_LEGEND, width=98, initial_indent="  ", subsequent_indent="    "))
        for statement in (verdicts or {}).get(experiment, []):
            blocks.append(textwrap.fill(statement, width=98, initial_indent="  ! ", subsequent_indent="    "))
        if intervals:
            cut = "d50c" if corrected else "d50"  # the fitted cut parameter: the actual cut of the nine formulas
            bounds = ordered[["formula", "d_cut", *intervals]].rename(
                columns=lambda c, cut=cut: re.sub(r"^d_cut", cut, re.sub(r"(_boot)?_(low|high)$", r" \2", c))
            )
            title = "  intervals:" if kind == "" else "  bootstrap intervals:"
            blocks.append(f"{title}\n" + bounds.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
        for formula, success, message, warned in group[["formula", "success", "message", "warnings"]].itertuples(index=False):
            note = warned if success else f"fit failed: {message}"
            if success and isinstance(
                note, str
            ):  # residual and cut warnings are stated once per experiment (verdicts, data notes)
                note = "; ".join(w for w in note.split("; ") if not w.startswith((RESIDUAL_WARNING, CUT_WARNING)))
            if isinstance(note, str) and note:
                blocks.append(textwrap.fill(f"note {formula}: {note}", width=98, initial_indent="  ", subsequent_indent="    "))
    return "\n".join(blocks)


def _has_bypass(fits: pd.DataFrame) -> bool:
    """Whether some fit of the table is a curve with bypass (its d50c differs from its d50)."""
    return bool("bypass" in fits.columns and fits["bypass"].notna().any())


def _add_circuit_command(commands) -> None:
    """``tromplab circuit FLOWSHEET MEASUREMENTS -o DIR [--fit]`` (the work is in circuit_command)."""
    circuit = commands.add_parser(
        "circuit", help="reconcile a plant survey over its flowsheet; partition curves of every separator (docs/circuit.md)"
    )
    circuit.add_argument("flowsheet", type=Path, help="flowsheet CSV: stream, from, to, product")
    circuit.add_argument("measurements", type=Path, help="survey CSV: stream, size classes, retained_pct [, solids_flow]")
    circuit.add_argument(
        "-o", "--outdir", type=Path, default=Path("results/circuit"), help="output folder (default: %(default)s)"
    )
    circuit.add_argument("--fit", action="store_true", help="also fit the nine formulas and the extended curves per separator")
    circuit.add_argument("--size-unit", default=None, help="unit of the sizes when the size columns carry none")
    circuit.add_argument("--no-figures", action="store_true", help="do not draw the figures")
    circuit.add_argument("--exclude", default="", metavar="STREAM[:WHAT],...",
                         help="leave measurements out: a stream, or STREAM:flow, STREAM:pct_solids, STREAM:CLASS "
                         "(e.g. cyclone_feed:-150+75); what the elimination proposes")  # fmt: skip
    errors = circuit.add_argument_group("error model (where the survey table gives none)")
    errors.add_argument("--relative-error", type=cli_type(check_relative_error, "--relative-error"),
                        default=DEFAULT_RELATIVE_ERROR, help="relative error of a measured share, 0..1 (default %(default)s)")  # fmt: skip
    errors.add_argument("--absolute-error", type=cli_type(check_share_sd, "--absolute-error"), default=DEFAULT_ABSOLUTE_ERROR,
                        help="absolute error of a share, as a fraction of the stream, 0..0.5 (default %(default)s)")  # fmt: skip
    errors.add_argument("--flow-relative-error", type=cli_type(check_positive_relative_error, "--flow-relative-error"),
                        default=DEFAULT_FLOW_RELATIVE_ERROR,
                        help="relative error of a measured solids flow, (0, 1] (default %(default)s)")  # fmt: skip
    errors.add_argument("--pct-solids-sd", type=cli_type(check_pct_solids_sd, "--pct-solids-sd"), default=DEFAULT_PCT_SOLIDS_SD,
                        help="sd of a per cent solids, percentage points, (0, 50] (default %(default)s)")  # fmt: skip
    errors.add_argument("--assay-relative-error", type=cli_type(check_relative_error, "--assay-relative-error"),
                        default=DEFAULT_ASSAY_RELATIVE_ERROR,
                        help="relative error of a per-class assay, 0..1 (default %(default)s)")  # fmt: skip
    errors.add_argument("--assay-absolute-error", type=cli_type(check_assay_sd, "--assay-absolute-error"),
                        default=DEFAULT_ASSAY_ABSOLUTE_ERROR,
                        help="absolute error of an assay, as a fraction of the class's solids, 0..0.5 (default %(default)s)")  # fmt: skip
    errors.add_argument("--error-model-at", choices=ERROR_MODEL_POINTS, default=ERROR_MODEL_POINTS[0],
                        help="evaluate the error model at the reconciled values (iterated) or at the measured ones "
                        "(default %(default)s)")  # fmt: skip
    tests = circuit.add_argument_group("tests")
    tests.add_argument("--alpha", type=cli_type(check_probability, "--alpha"), default=DEFAULT_ALPHA,
                       help="level of the chi-square and measurement tests, in (0, 1) (default %(default)s)")  # fmt: skip
    circuit.set_defaults(run=_run_circuit, imports=("tromplab.circuit", "tromplab.circuit_command"))


def _run_circuit(args) -> int:
    from .circuit import ErrorModel
    from .circuit_command import console_report, run_circuit

    errors = ErrorModel(relative_error=args.relative_error, absolute_error=args.absolute_error,
                        flow_relative_error=args.flow_relative_error, pct_solids_sd=args.pct_solids_sd,
                        evaluated_at=args.error_model_at, assay_relative_error=args.assay_relative_error,
                        assay_absolute_error=args.assay_absolute_error)  # fmt: skip
    run = run_circuit(args.flowsheet, args.measurements, args.outdir, fit=args.fit, errors=errors, alpha=args.alpha,
                      size_unit=args.size_unit, figures=not args.no_figures, exclude=args.exclude)  # fmt: skip
    print(console_report(run))
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
