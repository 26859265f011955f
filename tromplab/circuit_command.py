"""``tromplab circuit FLOWSHEET MEASUREMENTS -o DIR [--fit]``: reconcile a plant survey, write
its tables, figures and the separators' Tromp points, and (``--fit``) fit them.

The library is :mod:`tromplab.circuit`; this module only reads the two files, calls it,
fits the points through :func:`tromplab.workbench.fit_experiments` and writes the output
folder all-or-nothing (:func:`tromplab.output.outputs.replace_folder`): bad input ends in an
:class:`~tromplab.errors.InputError` before anything is written.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

from .circuit import CircuitBalance, ErrorModel, read_flowsheet, read_survey, reconcile
from .circuit.plotting import figure_size
from .errors import OptionError
from .options import CIRCUIT_FIT_FORMULAS, DEFAULT_ALPHA
from .output.csv_parts import write_csv
from .output.outputs import check_output_folder, replace_folder
from .output.plotting import offscreen_axes
from .workbench import Workbench, fit_experiments

#: The formulas fitted by ``--fit``: the nine of the paper (ranked) and the extended curves
#: with bypass and fish-hook (reported beside them, as ``tromplab fit --extended`` does).
FIT_FORMULAS = CIRCUIT_FIT_FORMULAS


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
    ``fits.csv`` and ``ranking.csv``; with per cent solids measured, ``water.csv``; with
    per-class assays, ``components.csv`` and ``partition.png`` (and a curve per separator and
    component in ``partition.csv``, ``points.csv`` and the fits).
    """
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
    if balance.survey.components:
        tables["components"] = balance.components_table()
    bench = None
    if fit and balance.flowsheet.separators:
        bench = fit_separators(balance)
        tables["fits"] = bench.fits_table()
        tables["ranking"] = bench.ranking_table()
    outputs = {f"{name}.csv": (lambda path, table=table: write_csv(table, path)) for name, table in tables.items()}
    summary = balance.summary() + "\n"
    outputs["summary.txt"] = lambda path: path.write_text(summary, encoding="utf-8")
    if figures:
        kinds = ("flowsheet", "adjustments", "distributions") if balance.has_size_classes else ("flowsheet", "adjustments")
        for kind in kinds + (("partition",) if balance.survey.components else ()):
            png = _png(balance, kind)
            outputs[f"{kind}.png"] = lambda path, png=png: path.write_bytes(png)
    written = replace_folder(outputs, outdir)
    return CircuitRun(balance, bench, written)


def _png(balance: CircuitBalance, kind: str) -> bytes:
    """Figure ``kind`` drawn on a figure made without pyplot (no backend chosen, no figure left open)."""
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
