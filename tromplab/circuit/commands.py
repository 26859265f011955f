"""The two commands of the circuit as Python functions: :func:`reconcile_circuit` (``tromplab
circuit FLOWSHEET MEASUREMENTS [--fit]``) returns a :class:`CircuitResult` whose ``save(DIR)``
writes the command's folder, :func:`design_circuit` (``tromplab circuit design FLOWSHEET
[SURVEY]``) returns a :class:`~tromplab.circuit.planning.DesignAdvice` whose ``save(DIR)`` writes
that command's folder, byte for byte what the command line writes (it calls them).

The inputs are read and checked as the functions start: bad input ends in an
:class:`~tromplab.errors.InputError` and nothing is written.  The fits of ``--fit`` go through
:func:`tromplab.workbench.fit_experiments` (:func:`fit_separators`).
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import pandas as pd

from ..errors import OptionError
from ..options import (
    CIRCUIT_FIT_FORMULAS,
    DEFAULT_ALPHA,
    WEIGHTINGS,
)
from ..output.outputs import replace_folder
from ..results_contract import ResultContract
from ..validation import check_choice

if TYPE_CHECKING:
    from ..workbench import Workbench
    from .measurements import ErrorModel
    from .planning import DesignAdvice
    from .reconciliation import CircuitBalance

#: The formulas fitted by ``--fit``: the nine of the paper (ranked) and the extended curves
#: with bypass and fish-hook (reported beside them, as ``tromplab fit --extended`` does).
FIT_FORMULAS = CIRCUIT_FIT_FORMULAS


@dataclass(frozen=True)
class CircuitResult(ResultContract):
    """What ``tromplab circuit`` makes of a survey: the reconciled balance, its tables, the fits
    of the separators (with ``fit``) and the next steps; :meth:`save` writes the command's folder.

    Attributes
    ----------
    balance : CircuitBalance
        The reconciled survey (tests, elimination, worth, design: its own methods).
    tables : dict
        Name (without ``.csv``) -> every table of the folder
        (:func:`~tromplab.circuit.outputs.balance_tables`, and ``fits`` and ``ranking`` with ``fit``).
    bench : Workbench or None
        The fits of the separators' partition curves (``fit``), else None.
    next_steps : tuple of str
        The one or two things to do next, as ``summary.txt`` ends.
    weight_notes : tuple of str
        The notes on the weights of ``points.csv`` (:func:`tromplab.loading.weights.weight_notes`).
    notices : tuple of Notice
        Every warning of the separators, as ``warnings.csv`` holds them
        (:func:`tromplab.circuit.outputs.balance_notices`).
    """

    balance: CircuitBalance
    tables: dict[str, pd.DataFrame] = field(repr=False)
    bench: Workbench | None = None
    next_steps: tuple[str, ...] = ()
    weight_notes: tuple[str, ...] = ()
    notices: tuple = ()

    def summary(self) -> pd.DataFrame:
        """One row per stream: measured and reconciled solids flow and its sd."""
        return self.balance.summary()

    def to_frame(self) -> pd.DataFrame:
        """The main table, ``flows.csv``."""
        return self.balance.to_frame()

    def _result_context(self) -> str:
        return self.balance._result_context()

    def save(self, outdir, *, figures: bool = True) -> dict:
        """Write what ``tromplab circuit FLOWSHEET MEASUREMENTS -o OUTDIR`` writes (``figures``:
        not ``--no-figures``), all or nothing.  Returns ``{file name: path}``.

        Files: ``flows.csv``, ``distributions.csv``, ``adjustments.csv``, ``gross_errors.csv``,
        ``elimination.csv`` (serial elimination with compensation: a proposal), ``nodal_tests.csv``,
        ``worth.csv`` (each measurement's solvability, redundancy and influence on the results),
        ``observability.csv`` (every unmeasured quantity: observable or not, and what would make
        it so), ``design.csv`` (the measurements one could add, ranked by the predicted reduction
        of sds: what ``tromplab circuit design`` writes for the same survey), ``chi_square.csv``,
        ``degrees_of_freedom.csv``, ``partition.csv`` (with standard deviations), ``points.csv``
        (Tromp-points schema with weights, what ``tromplab fit`` reads), the flowsheet as read
        (``flowsheet.csv``), ``summary.txt`` (ending with the next steps); figures
        ``flowsheet.png``, ``adjustments.png``, ``distributions.png``; with the fits ``fits.csv``
        and ``ranking.csv``; with per cent solids measured, ``water.csv``; with per-class assays,
        ``components.csv`` and ``partition.png`` (and a curve per separator and component in
        ``partition.csv``, ``points.csv`` and the fits).
        """
        from .outputs import balance_outputs

        outputs = balance_outputs(
            self.balance, figures=figures, tables=self.tables, steps=self.next_steps, notices=list(self.notices)
        )
        return replace_folder(outputs, outdir)


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
    from ..workbench import fit_experiments

    points, unit = balance.to_points(weighting=weighting), balance.survey.size_unit
    if alpha is None:  # fit_experiments' default
        return fit_experiments(points, formulas=formulas, size_unit=unit)
    return fit_experiments(points, formulas=formulas, size_unit=unit, alpha=alpha)


def reconcile_circuit(
    flowsheet,
    measurements,
    *,
    fit: bool = False,
    errors: ErrorModel | None = None,
    alpha: float = DEFAULT_ALPHA,
    size_unit: str | None = None,
    exclude=(),
    weighting: str = "error-model",
    progress=None,
) -> CircuitResult:
    """Reconcile the survey ``measurements`` over ``flowsheet`` (and fit its separators): what
    ``tromplab circuit FLOWSHEET MEASUREMENTS`` does, its options as keywords of the same names.

    Parameters
    ----------
    flowsheet, measurements : path
        The flowsheet and the measurement table (CSV or .xlsx).
    fit : bool
        Also fit the separators' partition curves (:func:`fit_separators`; ``--fit``).
    errors : ErrorModel, optional
        Standard deviations where the table gives none (also those of the candidates of
        ``design.csv``): the command's error-model options (``--relative-error``, ...) as one record.
    alpha : float
        Level of the chi-square and measurement tests.
    size_unit : str, optional
        Unit of the sizes when the size columns carry none.
    exclude : iterable of str or str, optional
        Measurements left out (``STREAM``, ``STREAM:flow``, ``STREAM:pct_solids``,
        ``STREAM:CLASS``), as :func:`~tromplab.circuit.reconciliation.reconcile` takes them.
    weighting : {"error-model", "feed-share", "none"}
        The weights of ``points.csv`` and of the fits (default the error model).
    progress : callable, optional
        ``progress(done, total, label)`` at each stage (``"reconciliation: round k"``, on a large
        flowsheet ``"reconciliation: bounds, N flows held"`` and ``"reconciliation: bounds, step K,
        N flows at 0"``, ``"elimination: step k"``,
        ``"design: candidate i of n"``; :func:`~tromplab.circuit.reconciliation.reconcile`).

    Returns
    -------
    CircuitResult
        Its ``save(outdir, figures=...)`` writes the command's folder.
    """
    from ..loading.weights import weight_notes
    from .flowsheet import read_flowsheet
    from .measurements import read_survey
    from .outputs import balance_next_steps, balance_notices, balance_tables
    from .reconciliation import reconcile

    weighting = check_choice(weighting, "weighting", choices=WEIGHTINGS)
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
    return CircuitResult(balance, tables, bench, steps, tuple(weight_notes(tables["points"])), tuple(notices))


def design_circuit(
    flowsheet,
    measurements=None,
    *,
    quantity=None,
    sampled=None,
    flows=None,
    errors: ErrorModel | None = None,
    alpha: float = DEFAULT_ALPHA,
    size_unit: str | None = None,
    exclude=(),
    progress=None,
) -> DesignAdvice:
    """Rank the measurements one could add to a survey: what ``tromplab circuit design
    FLOWSHEET [MEASUREMENTS]`` does, its options as keywords of the same names.

    Parameters
    ----------
    flowsheet : path
        The flowsheet.
    measurements : path, optional
        The survey taken; without it, a survey simulated from the flowsheet
        (:func:`~tromplab.circuit.planning.simulated_survey`, its assumptions written in
        ``summary.txt``).
    quantity, sampled, flows, errors, alpha, size_unit, exclude
        As for :func:`~tromplab.circuit.planning.design_advice` (``--quantity``,
        ``--sampled``, ``--flows``, the error model options, ``--alpha``, ``--size-unit``,
        ``--exclude``).
    progress : callable, optional
        ``progress(done, total, label)`` at each stage (the reconciliation, then
        ``"design: candidate i of n"``).

    Returns
    -------
    DesignAdvice
        Its ``save(outdir)`` writes the command's folder: ``design.csv`` (:data:`~tromplab.circuit.design.DESIGN_COLUMNS`),
    ``observability.csv``, ``summary.txt`` and, for a simulated survey,
    ``simulated_survey.csv`` (the survey as a measurement table, rounded as a lab prints it).
    """
    from .flowsheet import read_flowsheet
    from .measurements import read_survey
    from .planning import design_advice

    sheet = read_flowsheet(flowsheet)
    survey = None if measurements is None else read_survey(measurements, sheet, errors=errors, size_unit=size_unit)
    return design_advice(sheet, survey, quantity=quantity, sampled=sampled, flows=flows, errors=errors, alpha=alpha,
                         exclude=exclude, progress=progress)  # fmt: skip


def console_report(result: CircuitResult, written: dict, *, format_fits=None) -> str:
    """What ``tromplab circuit`` prints: the summary, the flows, the largest adjustments, the
    fits (with ``format_fits``, the fit command's table, else the best curve per separator),
    the next steps and the files (the warnings go to standard error, once per kind:
    :attr:`CircuitResult.notices`)."""
    balance = result.balance
    lines = [*map(_wrapped, balance.report().splitlines()), "", "Reconciled solids flows:"]
    flows = result.tables.get("flows", None)  # the table of flows.csv, made once
    flows = (balance.flows_table() if flows is None else flows)[["stream", "measured", "reconciled", "reconciled_sd"]]
    lines.append(flows.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    largest = balance.largest_adjustments(5)
    if len(largest):
        lines += ["", "Largest measurement tests (gross error: measured - true, as the balances estimate it):"]
        lines.append(largest[["measurement", "row", "measured", "reconciled", "gross_error", "measurement_test", "suspect"]].to_string(
            index=False, float_format=lambda v: f"{v:.4g}"))  # fmt: skip
    if result.bench is not None:
        lines += ["", _fits_text(result.bench, format_fits, balance.survey.size_unit)]
    if result.next_steps:
        lines += ["", "Next:", *(_wrapped(f"  {k}. {step}", indent="     ") for k, step in enumerate(result.next_steps, start=1))]
    lines += ["", "Wrote:", *(f"  {path}" for path in written.values())]
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
