"""``tromplab circuit FLOWSHEET MEASUREMENTS -o DIR [--fit]``: reconcile a plant survey, write
its tables, figures and the separators' Tromp points, and (``--fit``) fit them;
``tromplab circuit design FLOWSHEET [SURVEY] -o DIR``: rank the measurements one could add.

The library is :mod:`tromplab.circuit`; this module (under the command line's
:mod:`tromplab.cli.circuit`, which parses the options) reads the files, calls the library, fits the points through
:func:`tromplab.workbench.fit_experiments` and writes the output folder all-or-nothing
(:func:`tromplab.output.outputs.replace_folder`): bad input ends in an
:class:`~tromplab.errors.InputError` before anything is written.  :func:`run_circuit` and
:func:`run_design` are the Python faces of the commands, with the same option names.  The
library is imported when a command runs.
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import OptionError
from .options import (
    CIRCUIT_FIT_FORMULAS,
    DEFAULT_ALPHA,
    WEIGHTINGS,
)
from .output.outputs import check_output_folder, replace_folder
from .validation import check_choice

if TYPE_CHECKING:
    from .circuit import CircuitBalance, ErrorModel
    from .circuit.planning import DesignAdvice
    from .workbench import Workbench

#: The formulas fitted by ``--fit``: the nine of the paper (ranked) and the extended curves
#: with bypass and fish-hook (reported beside them, as ``tromplab fit --extended`` does).
FIT_FORMULAS = CIRCUIT_FIT_FORMULAS


@dataclass(frozen=True)
class CircuitRun:
    """What ``tromplab circuit`` did: the reconciled survey, the fits (with ``--fit``) and the files written."""

    balance: CircuitBalance
    bench: Workbench | None
    written: dict
    next_steps: tuple[str, ...] = ()
    #: The notes on the weights of ``points.csv`` (:func:`tromplab.loading.weights.weight_notes`).
    weight_notes: tuple[str, ...] = ()
    #: Every warning of the separators, as ``warnings.csv`` holds them (:func:`tromplab.circuit.outputs.balance_notices`).
    notices: tuple = ()


def fit_separators(
    balance: CircuitBalance, *, formulas=FIT_FORMULAS, alpha: float | None = None, weighting: str = "error-model"
) -> Workbench:
    """Fit, screen and rank the separation curves of every separator of a reconciled survey.

    Parameters
    ----------
    balance : CircuitBalance
        The reconciled survey; one experiment per separator node (and assayed component), its
        points weighted as ``weighting`` says (:meth:`CircuitBalance.to_points`).
    formulas : str or iterable, optional
        As for :func:`tromplab.workbench.fit_experiments` (default: the nine, ranked, and the
        extended curves, reported).
    alpha : float, optional
        Significance level of the Fisher screen (default: fit_experiments' default).
    weighting : {"error-model", "feed-share", "none"}
        The weights of the points (:func:`tromplab.loading.weights.partition_weights`; the
        option of the same name of ``tromplab fit`` on a lab table).

    Returns
    -------
    Workbench
    """
    from .workbench import fit_experiments

    options = {} if alpha is None else {"alpha": alpha}
    return fit_experiments(
        balance.to_points(weighting=weighting), formulas=formulas, size_unit=balance.survey.size_unit, **options
    )


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
    weighting: str = "error-model",
    progress=None,
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
    weighting : {"error-model", "feed-share", "none"}
        The weights of ``points.csv`` and of the fits (``--weighting``; default the error model).
    progress : callable, optional
        ``progress(done, total, label)`` at each stage (``"reconciliation: round k"``,
        ``"elimination: step k"``, ``"design: candidate i of n"``; :func:`~tromplab.circuit.reconciliation.reconcile`).

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
    and ``ranking.csv``; with per cent solids measured, ``water.csv``; with per-class assays,
    ``components.csv`` and ``partition.png`` (and a curve per separator and component in
    ``partition.csv``, ``points.csv`` and the fits).
    """
    from .circuit import read_flowsheet, read_survey, reconcile
    from .circuit.outputs import balance_next_steps, balance_notices, balance_outputs, balance_tables
    from .loading.weights import weight_notes

    weighting = check_choice(weighting, "weighting", choices=WEIGHTINGS)
    check_output_folder(outdir, inputs=[flowsheet, measurements])  # the inputs are checked as they are read
    sheet = read_flowsheet(flowsheet)
    survey = read_survey(measurements, sheet, errors=errors, size_unit=size_unit)
    if fit and not survey.n_classes:
        raise OptionError(
            "fit", "needs size analyses: the survey holds flows and per cent solids only (no partition curve to fit)"
        )
    balance = reconcile(sheet, survey, alpha=alpha, exclude=exclude, progress=progress)
    tables = balance_tables(balance, errors, weighting=weighting)
    bench = None
    if fit and balance.flowsheet.separators:
        bench = fit_separators(balance, weighting=weighting)
        tables["fits"], tables["ranking"] = bench.fits_table(), bench.ranking_table()
    steps = balance_next_steps(balance, tables)
    notices = balance_notices(tables, bench)  # warnings.csv, and the console's lines once per kind
    written = replace_folder(balance_outputs(balance, figures=figures, tables=tables, steps=steps, notices=notices), outdir)
    return CircuitRun(balance, bench, written, steps, tuple(weight_notes(tables["points"])), tuple(notices))


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
    progress=None,
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
    progress : callable, optional
        ``progress(done, total, label)`` at each stage (the reconciliation, then
        ``"design: candidate i of n"``).

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
    from .circuit.planning import design_advice

    check_output_folder(outdir, inputs=[flowsheet] + ([measurements] if measurements is not None else []))
    sheet = read_flowsheet(flowsheet)
    survey = None if measurements is None else read_survey(measurements, sheet, errors=errors, size_unit=size_unit)
    advice = design_advice(sheet, survey, quantity=quantity, sampled=sampled, flows=flows, errors=errors, alpha=alpha,
                           exclude=exclude, progress=progress)  # fmt: skip
    return DesignRun(advice, advice.save(outdir))


def console_report(run: CircuitRun, *, format_fits=None) -> str:
    """What ``tromplab circuit`` prints: the summary, the flows, the largest adjustments, the
    fits (with ``format_fits``, the fit command's table, else the best curve per separator),
    the next steps and the files (the warnings go to standard error, once per kind:
    :attr:`CircuitRun.notices`)."""
    balance = run.balance
    lines = [*map(_wrapped, balance.report().splitlines()), "", "Reconciled solids flows:"]
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
        lines += ["", "Next:", *(_wrapped(f"  {k}. {step}", indent="     ") for k, step in enumerate(run.next_steps, start=1))]
    lines += ["", "Wrote:", *(f"  {path}" for path in run.written.values())]
    return "\n".join(lines)


#: The console's width, as the fit tables are wrapped (tromplab.cli.printing).
CONSOLE_WIDTH = 98


def _wrapped(line: str, *, indent: str = "  ") -> str:
    """A summary line wrapped at :data:`CONSOLE_WIDTH`, its continuation indented (a line of a
    table, starting with spaces and fitting the width, is left as it is)."""
    if len(line) <= CONSOLE_WIDTH:
        return line
    kept = re.sub(r"(--[\w-]+) (?=\S)", "\\1\x00", line)  # an option stays on one line with its value
    filled = textwrap.fill(kept, width=CONSOLE_WIDTH, subsequent_indent=indent, break_on_hyphens=False, break_long_words=False)
    return filled.replace("\x00", " ")


def _fits_text(bench: Workbench, format_fits, size_unit: str) -> str:
    """The fits of the separators: the fit command's table when given, else the best curve of each."""
    fits = bench.fits_table()
    if format_fits is not None:
        verdicts = {experiment: bench.verdicts(experiment) for experiment in dict.fromkeys(fits["experiment"])}
        unit = f"sizes (d50, d50c) in {size_unit}" if size_unit else "sizes in the unit of the survey"
        return f"Partition curves of the separators, {unit}; every fit in fits.csv:\n" + format_fits(fits, verdicts)
    best = fits[fits["rank"] == 1][["experiment", "formula", "d_cut", "shape", "F", "adequate"]]
    return "Best-ranked curve per separator (every fit in fits.csv):\n" + best.to_string(index=False)
