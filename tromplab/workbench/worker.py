"""What a worker does with one chunk of experiments: the fits of every formula (batched
engine or single fits), their intervals, the data notes, the rows of the fits table and,
where asked, the model averages and the CSV text of both tables.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from ..curves.curve_fit import CurveFit, as_failure_if_implausible, attach_diagnostics, attach_indices, failed_fit, fit_formula
from ..curves.engine import fit_formula_batch, measured_start
from ..curves.formulas import is_batchable, select_formulas
from ..curves.measured import unbracketed_cut
from ..loading.points import TrompPoints
from ..loading.surveys import with_survey_columns
from ..output.csv_parts import csv_part
from ..statistics.uncertainty import interval_columns
from .averages import _averaged_groups, _averages_of_chunk, _averages_table
from .inputs import data_notes
from .tables import by_experiment, completed_fit_rows, fit_rows_frame, output_view

# one logger for the batch layer: its lines read "tromplab.workbench: ..." whichever module makes them
logger = logging.getLogger(__package__)


def fit_chunk(
    experiments: Sequence[TrompPoints], *, formulas, alpha, delta_max, engine=True, size_unit="", width=None
) -> list[CurveFit]:
    """Fits of ``formulas`` to ``experiments``, experiment by experiment in formula order.

    Batchable formulas go through the engine for all experiments at once, padded to
    ``width`` points; the others (and a formula whose batch raised) are fitted one by one.
    """
    per_formula = []
    measured = [measured_start(points) for points in experiments] if engine else None  # shared by the formulas
    for formula in select_formulas(formulas):
        batch = None
        if engine and is_batchable(formula):
            try:
                batch = fit_formula_batch(
                    experiments, formula, alpha=alpha, delta_max=delta_max, size_unit=size_unit, width=width, measured=measured
                )
            except Exception as error:  # a broken batch falls back to single fits, which report per fit
                logger.warning(
                    "batched engine failed on formula %s for %d experiment(s) (%s: %s); fitting them one at a time instead",
                    formula.id,
                    len(experiments),
                    type(error).__name__,
                    error,
                )
        per_formula.append(batch or [_fit_guarded(points, formula, alpha, delta_max, size_unit) for points in experiments])
    fits = [fits[i] for i in range(len(experiments)) for fits in per_formula]
    attach_indices(fits)
    fits = [as_failure_if_implausible(fit) for fit in fits]  # a result out of its range is a failure
    attach_diagnostics(fits)
    reasons = {}  # unbracketed is a property of the points, which the formulas of an experiment share
    for fit in fits:
        if id(fit.points) not in reasons:
            reasons[id(fit.points)] = unbracketed_cut(fit.points)
        fit.__dict__["unbracketed"] = reasons[id(fit.points)]  # where functools.cached_property keeps it
    for fit in fits:
        derive(fit)
    return fits


def derive(fit: CurveFit) -> CurveFit:
    """Compute the cached screen, indices, diagnostics, break point and warnings of ``fit`` now.

    The chunk's worker does it, so that they travel back with the pickled fit instead of
    being computed one by one in the parent when the tables are built (the serial part
    that kept two workers from being twice as fast as one).
    """
    for name in ("screen", "indices", "diagnostics", "x_break", "warnings"):
        getattr(fit, name)
    return fit


def _fit_chunk_star(options, chunk):
    # the notes on the points are made in the worker too: in the parent they were a serial
    # Spearman test per experiment (seconds at 10,000 experiments)
    notes = {points.experiment: found for points in chunk if (found := data_notes(points))}
    options = dict(options)
    intervals, averages, tables = options.pop("intervals", None), options.pop("averages", None), options.pop("tables", None)
    fits = fit_chunk(chunk, **options)
    columns = interval_columns(fits, **intervals, width=options["width"]) if intervals else None
    rows = fit_rows_frame(fits)  # the rows of fits.csv too: a serial 40 us per fit in the main process
    averaged = None
    if averages is not None:
        level, ranked = averages
        averaged = _averages_of_chunk(level, _averaged_groups(by_experiment(fits).values(), ranked))
    parts = None
    if tables is not None:  # the text of the chunk's rows: 2.2 s of serial formatting at 10,000 experiments
        tables = dict(tables)
        partition_to = tables.pop("partition_to")
        parts = {
            "fits": csv_part(
                output_view(completed_fit_rows(rows.copy(), fits, failures={}, **tables), columns, chunk, partition_to)
            )
        }
        if averaged:
            parts["averages"] = csv_part(with_survey_columns(_averages_table(averaged), chunk))
    return fits, notes, columns, averaged, rows, parts


def _fit_guarded(points, formula, alpha, delta_max, size_unit="") -> CurveFit:
    size_unit = size_unit or getattr(points, "size_unit", "")  # the unit the loader read from the column name
    try:
        return fit_formula(points, formula, alpha=alpha, delta_max=delta_max, size_unit=size_unit)
    except Exception as error:  # a batch reports a broken fit instead of stopping
        return failed_fit(
            points, formula, f"{type(error).__name__}: {error}", alpha=alpha, delta_max=delta_max, size_unit=size_unit
        )
