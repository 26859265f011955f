"""``tromplab circuit FLOWSHEET MEASUREMENTS -o DIR [--fit]``: reconcile a plant survey, write
its tables, figures and the separators' Tromp points, and (``--fit``) fit them;
``tromplab circuit design FLOWSHEET [SURVEY] -o DIR``: rank the measurements one could add.

The library is :mod:`tromplab.circuit`; this module registers the two commands on the CLI's
parser, reads the files, calls the library, fits the points through
:func:`tromplab.workbench.fit_experiments` and writes the output folder all-or-nothing
(:func:`tromplab.output.outputs.replace_folder`): bad input ends in an
:class:`~tromplab.errors.InputError` before anything is written.  :func:`run_circuit` and
:func:`run_design` are the Python faces of the commands, with the same option names.  The
parser needs only the light modules imported here; the library is imported when a command runs.
"""

from __future__ import annotations

import argparse
import functools
import io
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import OptionError
from .options import (
    CIRCUIT_FIT_FORMULAS,
    DEFAULT_ABSOLUTE_ERROR,
    DEFAULT_ALPHA,
    DEFAULT_FLOW_RELATIVE_ERROR,
    DEFAULT_PCT_SOLIDS_SD,
    DEFAULT_RELATIVE_ERROR,
    ERROR_MODEL_POINTS,
)
from .output.outputs import check_output_folder, replace_folder
from .validation import (
    check_pct_solids_sd,
    check_positive_relative_error,
    check_probability,
    check_relative_error,
    check_share_sd,
    cli_type,
)

if TYPE_CHECKING:
    import pandas as pd

    from .circuit import CircuitBalance, ErrorModel
    from .circuit.planning import DesignAdvice
    from .workbench import Workbench

#: What the circuit commands import when they run (before they start, under the CLI's signal handling).
IMPORTS = (
    "tromplab.circuit",
    "tromplab.circuit.planning",
    "tromplab.workbench",
    "tromplab.output.csv_parts",
    "tromplab.output.plotting",
)
#: Exit code of the command line (tromplab.cli): done.
EXIT_OK = 0

#: The formulas fitted by ``--fit``: the nine of the paper (ranked) and the extended curves
#: with bypass and fish-hook (reported beside them, as ``tromplab fit --extended`` does).
FIT_FORMULAS = CIRCUIT_FIT_FORMULAS

_USAGE = (
    "tromplab circuit FLOWSHEET MEASUREMENTS [-o DIR] [--fit] [options]\n"
    "       tromplab circuit design FLOWSHEET [SURVEY] [-o DIR] [options]"
)


def add_circuit_command(commands, *, format_fits=None) -> argparse.ArgumentParser:
    """Register ``tromplab circuit`` and ``tromplab circuit design``; returns the circuit parser.

    ``format_fits`` is the fit command's console table (``tromplab.cli.format_fits``), passed in
    because this module sits below the CLI's in the layers; ``--fit`` prints its fits with it.
    """
    circuit = commands.add_parser(
        "circuit",
        usage=_USAGE,
        help="reconcile a plant survey over its flowsheet; partition curves of every separator; "
        "'circuit design': what to measure next (docs/circuit.md)",
    )
    circuit.add_argument("flowsheet", type=Path, help="flowsheet CSV: stream, from, to, product")
    circuit.add_argument("measurements", type=Path, help="survey CSV: stream, size classes, retained_pct [, solids_flow]")
    circuit.add_argument(
        "-o", "--outdir", type=Path, default=Path("results/circuit"), help="output folder (default: %(default)s)"
    )
    circuit.add_argument("--fit", action="store_true", help="also fit the nine formulas and the extended curves per separator")
    _add_survey_options(circuit)
    circuit.add_argument("--no-figures", action="store_true", help="do not draw the figures")
    _add_error_model_options(circuit)
    circuit.set_defaults(run=functools.partial(_run_circuit, format_fits=format_fits), imports=IMPORTS)
    sub = circuit.add_subparsers(
        dest="circuit_command", metavar="design", parser_class=type(circuit), required=False, prog=circuit.prog
    )
    design = sub.add_parser(
        "design",
        help="rank the measurements one could add (a flow, a size analysis, a repeat, a per cent solids) by the sd "
        "they would remove, from a survey taken or one simulated from the flowsheet",
        description="Write DIR/design.csv: every measurement one could add, with the predicted sd of each result "
        "named, ranked; with SURVEY at its reconciled values, without it at a survey simulated from the flowsheet.",
    )
    _add_design_options(design)
    _route_design(circuit, design)
    return circuit


def _add_survey_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--size-unit", default=None, help="unit of the sizes when the size columns carry none")
    parser.add_argument("--exclude", default="", metavar="STREAM[:WHAT],...",
                        help="leave measurements out: a stream, or STREAM:flow, STREAM:pct_solids, STREAM:CLASS "
                        "(e.g. cyclone_feed:-150+75); what the elimination proposes")  # fmt: skip


def _add_error_model_options(parser: argparse.ArgumentParser) -> None:
    errors = parser.add_argument_group("error model (where the survey table gives none)")
    errors.add_argument("--relative-error", type=cli_type(check_relative_error, "--relative-error"),
                        default=DEFAULT_RELATIVE_ERROR, help="relative error of a measured share, 0..1 (default %(default)s)")  # fmt: skip
    errors.add_argument("--absolute-error", type=cli_type(check_share_sd, "--absolute-error"), default=DEFAULT_ABSOLUTE_ERROR,
                        help="absolute error of a share, as a fraction of the stream, 0..0.5 (default %(default)s)")  # fmt: skip
    errors.add_argument("--flow-relative-error", type=cli_type(check_positive_relative_error, "--flow-relative-error"),
                        default=DEFAULT_FLOW_RELATIVE_ERROR,
                        help="relative error of a measured solids flow, (0, 1] (default %(default)s)")  # fmt: skip
    errors.add_argument("--pct-solids-sd", type=cli_type(check_pct_solids_sd, "--pct-solids-sd"), default=DEFAULT_PCT_SOLIDS_SD,
                        help="sd of a per cent solids, percentage points, (0, 50] (default %(default)s)")  # fmt: skip
    errors.add_argument("--error-model-at", choices=ERROR_MODEL_POINTS, default=ERROR_MODEL_POINTS[0],
                        help="evaluate the error model at the reconciled values (iterated) or at the measured ones "
                        "(default %(default)s)")  # fmt: skip
    tests = parser.add_argument_group("tests")
    tests.add_argument("--alpha", type=cli_type(check_probability, "--alpha"), default=DEFAULT_ALPHA,
                       help="level of the chi-square and measurement tests, in (0, 1) (default %(default)s)")  # fmt: skip


def _add_design_options(design: argparse.ArgumentParser) -> None:
    design.add_argument("flowsheet", type=Path, help="flowsheet CSV: stream, from, to, product")
    design.add_argument("measurements", type=Path, nargs="?", default=None, metavar="SURVEY",
                        help="survey CSV (as for 'tromplab circuit'); without it, a survey simulated from the flowsheet")  # fmt: skip
    design.add_argument("-o", "--outdir", type=Path, default=Path("results/circuit-design"),
                        help="output folder (default: %(default)s)")  # fmt: skip
    design.add_argument("--quantity", action="append", default=None, metavar="RESULT",
                        help="a result whose sd matters, repeatable: 'partition at cut', 'partition', 'fine yield', "
                        "'circulating load' (every separator) or one result as worth.csv names it "
                        "(default: each separator's partition at its cut and each circulating load)")  # fmt: skip
    design.add_argument("--sampled", default=None, metavar="STREAM,...",
                        help="without SURVEY: the streams with a size analysis (default: every stream)")  # fmt: skip
    design.add_argument("--flows", default=None, metavar="STREAM,...",
                        help="without SURVEY: the streams with a measured solids flow (default: none, flows relative to a feed of 100)")  # fmt: skip
    _add_survey_options(design)
    _add_error_model_options(design)
    design.set_defaults(run=_run_design, imports=IMPORTS)


def _route_design(circuit: argparse.ArgumentParser, design: argparse.ArgumentParser) -> None:
    """Parse ``circuit design ...`` with the design parser and ``circuit FLOWSHEET MEASUREMENTS``
    with the circuit parser.

    argparse cannot have both a sub-command and positional files on one parser (it would read
    ``design`` as the flowsheet), so the circuit parser sends a leading ``design`` to the
    sub-parser itself; the sub-parser stays registered so that help, the generated reference
    and the option names of messages know it.
    """
    parse_circuit = circuit.parse_known_args

    def parse_known_args(args=None, namespace=None):
        args = list(sys.argv[1:] if args is None else args)
        if args[:1] == ["design"]:
            namespace, rest = design.parse_known_args(args[1:], namespace)
            namespace.circuit_command = "design"
            return namespace, rest
        return parse_circuit(args, namespace)

    circuit.parse_known_args = parse_known_args


def _error_model(args) -> ErrorModel:
    from .circuit import ErrorModel

    return ErrorModel(relative_error=args.relative_error, absolute_error=args.absolute_error,
                      flow_relative_error=args.flow_relative_error, pct_solids_sd=args.pct_solids_sd,
                      evaluated_at=args.error_model_at)  # fmt: skip


def _run_circuit(args, *, format_fits=None) -> int:
    run = run_circuit(args.flowsheet, args.measurements, args.outdir, fit=args.fit, errors=_error_model(args), alpha=args.alpha,
                      size_unit=args.size_unit, figures=not args.no_figures, exclude=args.exclude)  # fmt: skip
    print(console_report(run, format_fits=format_fits))
    return EXIT_OK


def _run_design(args) -> int:
    run = run_design(args.flowsheet, args.measurements, args.outdir, quantity=args.quantity, sampled=args.sampled,
                     flows=args.flows, errors=_error_model(args), alpha=args.alpha, size_unit=args.size_unit,
                     exclude=args.exclude)  # fmt: skip
    print(run.advice.summary() + "\n\nWrote:\n" + "\n".join(f"  {path}" for path in run.written.values()))
    return EXIT_OK


@dataclass(frozen=True)
class CircuitRun:
    """What ``tromplab circuit`` did: the reconciled survey, the fits (with ``--fit``) and the files written."""

    balance: CircuitBalance
    bench: Workbench | None
    written: dict
    next_steps: tuple[str, ...] = ()


def fit_separators(balance: CircuitBalance, *, formulas=FIT_FORMULAS, alpha: float | None = None) -> Workbench:
    """Fit, screen and rank the separation curves of every separator of a reconciled survey.

    Parameters
    ----------
    balance : CircuitBalance
        The reconciled survey; one experiment per separator node, its points weighted by the
        precision of the reconciled partition (:meth:`CircuitBalance.to_points`).
    formulas : str or iterable, optional
        As for :func:`tromplab.workbench.fit_experiments` (default: the nine, ranked, and the
        extended curves, reported).
    alpha : float, optional
        Significance level of the Fisher screen (default: fit_experiments' default).

    Returns
    -------
    Workbench
    """
    from .workbench import fit_experiments

    options = {} if alpha is None else {"alpha": alpha}
    return fit_experiments(balance.to_points(), formulas=formulas, size_unit=balance.survey.size_unit, **options)


def run_circuit(
    flowsheet,
    measurements,
    outdir,
    *,
    fit: bool = False,
    errors: ErrorModel | None = None,
    alpha: float = DEFAULT_ALPHA,
    size_unit: str | None = None,
    figures: bool = True,
    exclude=(),
) -> CircuitRun:
    """Reconcile the survey and write ``outdir`` as a whole (nothing written on bad input).

    Parameters
    ----------
    flowsheet, measurements : path
        The flowsheet and the measurement table (CSV or .xlsx).
    outdir : path
        Output folder, replaced as a whole when everything is written.
    fit : bool
        Also fit the separators' partition curves (:func:`fit_separators`).
    errors : ErrorModel, optional
        Standard deviations where the table gives none (also those of the candidates of
        ``design.csv``).
    alpha : float
        Level of the chi-square and measurement tests.
    size_unit : str, optional
        Unit of the sizes when the size columns carry none.
    figures : bool
        Draw the three figures.
    exclude : iterable of str or str, optional
        Measurements left out (``STREAM``, ``STREAM:flow``, ``STREAM:pct_solids``,
        ``STREAM:CLASS``), as :func:`~tromplab.circuit.reconciliation.reconcile` takes them.

    Returns
    -------
    CircuitRun

    Notes
    -----
    Files: ``flows.csv``, ``distributions.csv``, ``adjustments.csv``, ``gross_errors.csv``,
    ``elimination.csv`` (serial elimination with compensation: a proposal), ``nodal_tests.csv``,
    ``worth.csv`` (each measurement's solvability, redundancy and influence on the results),
    ``observability.csv`` (every unmeasured quantity: observable or not, and what would make
    it so), ``design.csv`` (the measurements one could add, ranked by the predicted reduction
    of sds: what ``tromplab circuit design`` writes for the same survey), ``chi_square.csv``,
    ``degrees_of_freedom.csv``, ``partition.csv`` (with standard deviations), ``points.csv``
    (Tromp-points schema with weights, what ``tromplab fit`` reads), the flowsheet as read
    (``flowsheet.csv``), ``summary.txt`` (ending with the next steps); figures
    ``flowsheet.png``, ``adjustments.png``, ``distributions.png``; with ``fit`` ``fits.csv``
    and ``ranking.csv``; with per cent solids measured, ``water.csv``.
    """
    from .circuit import read_flowsheet, read_survey, reconcile

    check_output_folder(outdir, inputs=[flowsheet, measurements])  # the inputs are checked as they are read
    sheet = read_flowsheet(flowsheet)
    survey = read_survey(measurements, sheet, errors=errors, size_unit=size_unit)
    if fit and not survey.n_classes:
        raise OptionError(
            "fit", "needs size analyses: the survey holds flows and per cent solids only (no partition curve to fit)"
        )
    balance = reconcile(sheet, survey, alpha=alpha, exclude=exclude)
    tables = _circuit_tables(balance, errors)
    bench = None
    if fit and balance.flowsheet.separators:
        bench = fit_separators(balance)
        tables["fits"], tables["ranking"] = bench.fits_table(), bench.ranking_table()
    steps = tuple(_next_steps(balance, tables))
    summary = balance.summary() + "".join(f"\nnext: {step}" for step in steps) + "\n"
    kinds = ("flowsheet", "adjustments", "distributions") if balance.has_size_classes else ("flowsheet", "adjustments")
    pictures = {kind: _png(balance, kind) for kind in kinds} if figures else {}
    written = replace_folder(_outputs(tables, summary, pictures), outdir)
    return CircuitRun(balance, bench, written, steps)


def _circuit_tables(balance: CircuitBalance, errors: ErrorModel | None) -> dict[str, pd.DataFrame]:
    """The tables of ``tromplab circuit``, by file stem."""
    from .circuit.design import design_table, observability_table

    tables = {
        "flows": balance.flows_table(),
        "distributions": balance.distributions_table(),
        "adjustments": balance.adjustments_table(),
        "gross_errors": balance.gross_errors_table(),
        "elimination": balance.elimination_table(),
        "nodal_tests": balance.nodal_tests_table(),
        "worth": balance.worth_table(),
        "observability": observability_table(balance, errors),
        "design": design_table(balance, errors=errors),
        "chi_square": balance.chi_square_table(),
        "degrees_of_freedom": balance.degrees_of_freedom_table(),
        "partition": balance.partition_table(),
        "points": balance.points_table(),
        "flowsheet": balance.flowsheet.to_frame(),
    }
    if balance.balances_water:
        tables["water"] = balance.water_table()
    return tables


def _next_steps(balance: CircuitBalance, tables: dict) -> list[str]:
    from .circuit.planning import next_steps

    return next_steps(balance, observability=tables["observability"], design=tables["design"])


def _outputs(tables: dict, summary: str, pictures: dict) -> dict:
    """The writers of the output folder: one CSV per table, ``summary.txt`` and one PNG per figure."""
    from .output.csv_parts import write_csv

    outputs = {f"{name}.csv": (lambda path, table=table: write_csv(table, path)) for name, table in tables.items()}
    outputs["summary.txt"] = lambda path: path.write_text(summary, encoding="utf-8")
    for kind, png in pictures.items():
        outputs[f"{kind}.png"] = lambda path, png=png: path.write_bytes(png)
    return outputs


def _png(balance: CircuitBalance, kind: str) -> bytes:
    """Figure ``kind`` drawn on a figure made without pyplot (no backend chosen, no figure left open)."""
    from .circuit.plotting import figure_size
    from .output.plotting import offscreen_axes

    ax = offscreen_axes(figsize=figure_size(balance, kind))
    balance.plot(kind, ax=ax)
    buffer = io.BytesIO()
    ax.figure.savefig(buffer, format="png", dpi=120, bbox_inches="tight")
    return buffer.getvalue()


@dataclass(frozen=True)
class DesignRun:
    """What ``tromplab circuit design`` did: the advice and the files written."""

    advice: DesignAdvice
    written: dict


def run_design(
    flowsheet,
    measurements=None,
    outdir=Path("results/circuit-design"),
    *,
    quantity=None,
    sampled=None,
    flows=None,
    errors: ErrorModel | None = None,
    alpha: float = DEFAULT_ALPHA,
    size_unit: str | None = None,
    exclude=(),
) -> DesignRun:
    """Rank the measurements one could add to a survey and write ``outdir`` as a whole.

    Parameters
    ----------
    flowsheet : path
        The flowsheet.
    measurements : path, optional
        The survey taken; without it, a survey simulated from the flowsheet
        (:func:`~tromplab.circuit.planning.simulated_survey`, its assumptions written in
        ``summary.txt``).
    outdir : path
        Output folder, replaced as a whole when everything is written.
    quantity, sampled, flows, errors, alpha, size_unit, exclude
        As for :func:`~tromplab.circuit.planning.design_advice` (``--quantity``,
        ``--sampled``, ``--flows``, the error model options, ``--alpha``, ``--size-unit``,
        ``--exclude``).

    Returns
    -------
    DesignRun

    Notes
    -----
    Files: ``design.csv`` (:data:`~tromplab.circuit.design.DESIGN_COLUMNS`),
    ``observability.csv``, ``summary.txt`` and, for a simulated survey,
    ``simulated_survey.csv`` (the survey as a measurement table, rounded as a lab prints it).
    """
    from .circuit import read_flowsheet, read_survey
    from .circuit.design import observability_table
    from .circuit.planning import design_advice
    from .circuit.simulation import survey_table

    check_output_folder(outdir, inputs=[flowsheet] + ([measurements] if measurements is not None else []))
    sheet = read_flowsheet(flowsheet)
    survey = None if measurements is None else read_survey(measurements, sheet, errors=errors, size_unit=size_unit)
    advice = design_advice(sheet, survey, quantity=quantity, sampled=sampled, flows=flows, errors=errors, alpha=alpha,
                           exclude=exclude)  # fmt: skip
    tables = {"design": advice.table, "observability": observability_table(advice.balance, errors)}
    if advice.simulated:
        tables["simulated_survey"] = survey_table(advice.balance.survey)
    written = replace_folder(_outputs(tables, advice.summary() + "\n", {}), outdir)
    return DesignRun(advice, written)


def console_report(run: CircuitRun, *, format_fits=None) -> str:
    """What ``tromplab circuit`` prints: the summary, the flows, the largest adjustments, the
    fits (with ``format_fits``, the fit command's table, else the best curve per separator),
    the next steps and the files."""
    balance = run.balance
    lines = [balance.summary(), "", "Reconciled solids flows:"]
    flows = balance.flows_table()[["stream", "measured", "reconciled", "reconciled_sd"]]
    lines.append(flows.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    largest = balance.largest_adjustments(5)
    if len(largest):
        lines += ["", "Largest measurement tests (gross error: measured - true, as the balances estimate it):"]
        lines.append(largest[["measurement", "row", "measured", "reconciled", "gross_error", "measurement_test", "suspect"]].to_string(
            index=False, float_format=lambda v: f"{v:.4g}"))  # fmt: skip
    if run.bench is not None:
        lines += ["", _fits_text(run.bench, format_fits, balance.survey.size_unit)]
    if run.next_steps:
        lines += ["", "Next:", *(f"  {k}. {step}" for k, step in enumerate(run.next_steps, start=1))]
    lines += ["", "Wrote:", *(f"  {path}" for path in run.written.values())]
    return "\n".join(lines)


def _fits_text(bench: Workbench, format_fits, size_unit: str) -> str:
    """The fits of the separators: the fit command's table when given, else the best curve of each."""
    fits = bench.fits_table()
    if format_fits is not None:
        verdicts = {experiment: bench.verdicts(experiment) for experiment in dict.fromkeys(fits["experiment"])}
        unit = f"sizes (d50, d50c) in {size_unit}" if size_unit else "sizes in the unit of the survey"
        return f"Partition curves of the separators, {unit}; every fit in fits.csv:\n" + format_fits(fits, verdicts)
    best = fits[fits["rank"] == 1][["experiment", "formula", "d_cut", "shape", "F", "adequate"]]
    return "Best-ranked curve per separator (every fit in fits.csv):\n" + best.to_string(index=False)
