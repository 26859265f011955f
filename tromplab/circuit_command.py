"""``tromplab circuit FLOWSHEET MEASUREMENTS -o DIR [--fit]``: reconcile a plant survey, write
its tables, figures and the separators' Tromp points, and (``--fit``) fit them.

The library is :mod:`tromplab.circuit`; this module only reads the two files, calls it,
fits the points through :func:`tromplab.workbench.fit_experiments` and writes the output
folder all-or-nothing (:func:`tromplab.output.outputs.replace_folder`): bad input ends in an
:class:`~tromplab.errors.InputError` before anything is written.
"""

from __future__ import annotations

import functools
import io
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
    from .circuit import CircuitBalance, ErrorModel
    from .workbench import Workbench

#: What the circuit commands import when they run (before they start, under the CLI's signal handling).
IMPORTS = ("tromplab.circuit", "tromplab.workbench", "tromplab.output.csv_parts", "tromplab.output.plotting")
#: Exit code of the command line (tromplab.cli): done.
EXIT_OK = 0

#: The formulas fitted by ``--fit``: the nine of the paper (ranked) and the extended curves
#: with bypass and fish-hook (reported beside them, as ``tromplab fit --extended`` does).
FIT_FORMULAS = CIRCUIT_FIT_FORMULAS


def add_circuit_command(commands, *, format_fits=None) -> None:
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
    errors.add_argument("--error-model-at", choices=ERROR_MODEL_POINTS, default=ERROR_MODEL_POINTS[0],
                        help="evaluate the error model at the reconciled values (iterated) or at the measured ones "
                        "(default %(default)s)")  # fmt: skip
    tests = circuit.add_argument_group("tests")
    tests.add_argument("--alpha", type=cli_type(check_probability, "--alpha"), default=DEFAULT_ALPHA,
                       help="level of the chi-square and measurement tests, in (0, 1) (default %(default)s)")  # fmt: skip
    circuit.set_defaults(run=functools.partial(_run_circuit, format_fits=format_fits), imports=IMPORTS)


def _run_circuit(args, *, format_fits=None) -> int:
    from .circuit import ErrorModel

    errors = ErrorModel(relative_error=args.relative_error, absolute_error=args.absolute_error,
                        flow_relative_error=args.flow_relative_error, pct_solids_sd=args.pct_solids_sd,
                        evaluated_at=args.error_model_at)  # fmt: skip
    run = run_circuit(args.flowsheet, args.measurements, args.outdir, fit=args.fit, errors=errors, alpha=args.alpha,
                      size_unit=args.size_unit, figures=not args.no_figures, exclude=args.exclude)  # fmt: skip
    print(console_report(run))
    return EXIT_OK


@dataclass(frozen=True)
class CircuitRun:
    """What ``tromplab circuit`` did: the reconciled survey, the fits (with ``--fit``) and the files written."""

    balance: CircuitBalance
    bench: Workbench | None
    written: dict


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
        Standard deviations where the table gives none.
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
    ``design.csv`` (the measurements one could add, ranked by the predicted reduction of sds),
    ``chi_square.csv``, ``degrees_of_freedom.csv``, ``partition.csv`` (with standard
    deviations), ``points.csv`` (Tromp-points schema with weights, what ``tromplab fit``
    reads), the flowsheet as read (``flowsheet.csv``), ``summary.txt``; figures
    ``flowsheet.png``, ``adjustments.png``, ``distributions.png``; with ``fit``
    ``fits.csv`` and ``ranking.csv``; with per cent solids measured, ``water.csv``.
    """
    from .circuit import read_flowsheet, read_survey, reconcile
    from .output.csv_parts import write_csv

    check_output_folder(outdir, inputs=[flowsheet, measurements])  # the inputs are checked as they are read
    sheet = read_flowsheet(flowsheet)
    survey = read_survey(measurements, sheet, errors=errors, size_unit=size_unit)
    if fit and not survey.n_classes:
        raise OptionError(
            "fit", "needs size analyses: the survey holds flows and per cent solids only (no partition curve to fit)"
        )
    balance = reconcile(sheet, survey, alpha=alpha, exclude=exclude)
    tables = {
        "flows": balance.flows_table(),
        "distributions": balance.distributions_table(),
        "adjustments": balance.adjustments_table(),
        "gross_errors": balance.gross_errors_table(),
        "elimination": balance.elimination_table(),
        "nodal_tests": balance.nodal_tests_table(),
        "worth": balance.worth_table(),
        "design": balance.design_table(),
        "chi_square": balance.chi_square_table(),
        "degrees_of_freedom": balance.degrees_of_freedom_table(),
        "partition": balance.partition_table(),
        "points": balance.points_table(),
        "flowsheet": sheet.to_frame(),
    }
    if balance.balances_water:
        tables["water"] = balance.water_table()
    bench = None
    if fit and balance.flowsheet.separators:
        bench = fit_separators(balance)
        tables["fits"] = bench.fits_table()
        tables["ranking"] = bench.ranking_table()
    outputs = {f"{name}.csv": (lambda path, table=table: write_csv(table, path)) for name, table in tables.items()}
    summary = balance.summary() + "\n"
    outputs["summary.txt"] = lambda path: path.write_text(summary, encoding="utf-8")
    if figures:
        for kind in ("flowsheet", "adjustments", "distributions") if balance.has_size_classes else ("flowsheet", "adjustments"):
            png = _png(balance, kind)
            outputs[f"{kind}.png"] = lambda path, png=png: path.write_bytes(png)
    written = replace_folder(outputs, outdir)
    return CircuitRun(balance, bench, written)


def _png(balance: CircuitBalance, kind: str) -> bytes:
    """Figure ``kind`` drawn on a figure made without pyplot (no backend chosen, no figure left open)."""
    from .circuit.plotting import figure_size
    from .output.plotting import offscreen_axes

    ax = offscreen_axes(figsize=figure_size(balance, kind))
    balance.plot(kind, ax=ax)
    buffer = io.BytesIO()
    ax.figure.savefig(buffer, format="png", dpi=120, bbox_inches="tight")
    return buffer.getvalue()


def console_report(run: CircuitRun) -> str:
    """What the command prints: the summary, the flows, the largest adjustments, the fits' ranking and the files."""
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
        fits = run.bench.fits_table()
        best = fits[fits["rank"] == 1][["experiment", "formula", "d_cut", "shape", "F", "adequate"]]
        lines += ["", "Best-ranked curve per separator (every fit in fits.csv):", best.to_string(index=False)]
    lines += ["", "Wrote:", *(f"  {path}" for path in run.written.values())]
    return "\n".join(lines)
