"""What a worker does with one chunk of experiments: the fits of every formula (batched
engine or single fits), their intervals, the data notes, the rows of the fits table and,
where asked, the model averages and the CSV text of both tables.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import pandas as pd

from ..curves.curve_fit import (
    CurveFit,
    FitOptions,
    as_failure_if_implausible,
    attach_diagnostics,
    attach_indices,
    attach_screens,
    failed_fit,
    fit_formula,
)
from ..curves.engine import fit_formula_batch, measured_start
from ..curves.formulas import is_batchable, select_formulas
from ..curves.measured import unbracketed_cut
from ..curves.screening import DEFAULT_ALPHA
from ..loading.points import TrompPoints
from ..loading.surveys import with_survey_columns
from ..output.csv_parts import CsvPart, csv_part
from ..statistics.uncertainty import interval_columns
from ..validation import FitSettings
from .averages import averaged_groups, averages_level, averages_of_chunk, averages_table
from .inputs import data_notes
from .tables import by_experiment, completed_fit_rows, fit_rows_frame, output_view

# one logger for the batch layer: its lines read "tromplab.workbench: ..." whichever module makes them
logger = logging.getLogger(__package__)


@dataclass(frozen=True)
class ChunkOptions:
    """What a worker needs for each chunk of a batch: the batch's :class:`~tromplab.validation.FitSettings`
    as they were checked, and what the batch adds to them.  Made by
    :func:`~tromplab.workbench.batch.prepared_batch`, completed by the fan-out with ``width``
    and ``tables_on_worker``, and read by :func:`work_on_chunk`.

    Attributes
    ----------
    settings : FitSettings
        The settings of the batch (``alpha``, ``ci``, the bootstrap's, ``partition_to``, ...).
    formulas : tuple of str
        Ids of the formulas to fit, in the batch's order (``settings.formulas`` resolved).
    ranked : tuple of str
        Ids of the formulas the ranking and the model averages cover.
    size_unit : str
        Unit of the sizes of the batch: the loader's when every experiment has the same one,
        else ``settings.size_unit``.
    width : int
        Points every chunk is padded to (the largest experiment of the batch), so that the
        fits do not depend on how the batch is cut.
    tables_on_worker : bool
        Also make the model averages (at ``ci``, else 0.95) and the CSV text of the chunk's
        rows of ``fits.csv`` and ``averages.csv`` (where there are workers; in one process
        the main process makes them when they are first asked for).
    failure_example : tuple of (str, str)
        One failed experiment of the batch with its reason (empty when none failed): the
        rows are typed as in the whole table, which ends with the failed experiments.
    survey_probe : tuple of TrompPoints
        Experiments of the batch holding its survey columns (``date``, ``survey``), so that
        every chunk's rows have the columns the whole table has.
    """

    settings: FitSettings
    formulas: tuple[str, ...]
    ranked: tuple[str, ...]
    size_unit: str
    width: int = 0
    tables_on_worker: bool = False
    failure_example: tuple[tuple[str, str], ...] = ()
    survey_probe: tuple[TrompPoints, ...] = ()

    def refit(self, experiments: Sequence[TrompPoints]) -> list[CurveFit]:
        """The fits of ``experiments`` as the batch's workers made them (same options, same padding)."""
        settings = self.settings
        return fit_chunk(experiments, formulas=self.formulas, alpha=settings.alpha, delta_max=settings.delta_max,
                         engine=settings.engine, size_unit=self.size_unit, width=self.width)  # fmt: skip


class FittedChunk(NamedTuple):
    """What :func:`work_on_chunk` sends back from one chunk: its fits, the data notes
    (``{experiment: notes}``), the interval columns (None without ``ci`` or ``bootstrap``),
    the rows of the fits before ranking, and with ``tables_on_worker`` the model averages
    (one table per chunk, in a list) and the CSV text of the tables
    (``{"fits": CsvPart, "averages": CsvPart}``)."""

    fits: list[CurveFit]
    notes: dict[str, tuple[str, ...]]
    intervals: pd.DataFrame | None
    rows: pd.DataFrame
    averages: list[pd.DataFrame] | None = None
    csv_parts: dict[str, CsvPart] | None = None


def fit_chunk(
    experiments: Sequence[TrompPoints], *, formulas, alpha, delta_max, engine=True, size_unit="", width=None
) -> list[CurveFit]:
    """Fits of ``formulas`` to ``experiments``, experiment by experiment in formula order.

    Batchable formulas go through the engine for all experiments at once, padded to
    ``width`` points; the others (and a formula whose batch raised) are fitted one by one.
    """
    per_formula = []
    measured = [measured_start(points) for points in experiments] if engine else None  # shared by the formulas
    shared = _shared_options(experiments, alpha, delta_max, size_unit) if engine else None
    for formula in select_formulas(formulas):
        batch = None
        if engine and is_batchable(formula):
            try:
                batch = fit_formula_batch(
                    experiments,
                    formula,
                    alpha=alpha,
                    delta_max=delta_max,
                    size_unit=size_unit,
                    width=width,
                    measured=measured,
                    options=shared,
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
    attach_screens(fits)
    reasons = {}  # unbracketed is a property of the points, which the formulas of an experiment share
    for fit in fits:
        if id(fit.points) not in reasons:
            reasons[id(fit.points)] = unbracketed_cut(fit.points)
        fit.__dict__["unbracketed"] = reasons[id(fit.points)]  # where functools.cached_property keeps it
    for fit in fits:
        derive(fit)
    return fits


def _shared_options(experiments, alpha, delta_max, size_unit) -> list[FitOptions] | None:
    """Each experiment's :class:`FitOptions`, made once for all its formulas; None where one
    cannot be made (each formula's batch then meets the error, and reports it per fit)."""
    try:
        return [
            FitOptions.for_points(
                points, alpha=DEFAULT_ALPHA if alpha is None else alpha, delta_max=delta_max, size_unit=size_unit
            )
            for points in experiments
        ]
    except ValueError:
        return None


def derive(fit: CurveFit) -> CurveFit:
    """Compute the cached screen, indices, diagnostics, break point and warnings of ``fit`` now.

    The chunk's worker does it, so that they travel back with the pickled fit instead of
    being computed one by one in the parent when the tables are built (the serial part
    that kept two workers from being twice as fast as one).
    """
    for name in ("screen", "indices", "diagnostics", "x_break", "warnings"):
        getattr(fit, name)
    return fit


def work_on_chunk(options: ChunkOptions, chunk: Sequence[TrompPoints]) -> FittedChunk:
    """What a worker makes of ``chunk`` (consecutive experiments of the batch) with ``options``:
    the fits, the data notes, the interval columns (with ``ci`` or ``bootstrap``), the rows of
    the fits table and, with ``tables_on_worker``, the model averages and the CSV text of both
    tables.  Each result depends on the chunk's own experiments only, so the tables are the
    same however the batch is cut."""
    fits, notes, columns, rows = fitted_chunk(options, chunk)
    if not options.tables_on_worker:
        return FittedChunk(fits, notes, columns, rows)
    averaged, _, view = chunk_tables(options, chunk, fits, columns, rows)
    # the text of the chunk's rows: 2.2 s of serial formatting at 10,000 experiments
    parts = {"fits": csv_part(view)}
    if averaged:
        parts["averages"] = csv_part(with_survey_columns(averages_table(averaged), [*chunk, *options.survey_probe]))
    return FittedChunk(fits, notes, columns, rows, averaged, parts)


def fitted_chunk(options: ChunkOptions, chunk: Sequence[TrompPoints]) -> tuple:
    """The fits of ``chunk``, its data notes, its interval columns (None without ``ci`` or
    ``bootstrap``) and the rows of its fits (:func:`fit_rows_frame`)."""
    # the notes on the points are made in the worker too: in the parent they were a serial
    # Spearman test per experiment (seconds at 10,000 experiments)
    settings = options.settings
    intervals = bool(settings.ci or settings.bootstrap)
    notes = {points.experiment: found for points in chunk if (found := data_notes(points, intervals=intervals))}
    fits = options.refit(chunk)
    columns = None
    if settings.ci or settings.bootstrap:
        columns = interval_columns(
            fits,
            level=settings.ci,
            n_bootstrap=settings.bootstrap,
            method=settings.bootstrap_method,
            seed=settings.seed,
            width=options.width,
        )
    rows = fit_rows_frame(fits)  # the rows of fits.csv too: a serial 40 us per fit in the main process
    return fits, notes, columns, rows


def chunk_tables(options: ChunkOptions, chunk, fits, columns, rows, failures=None, failed_points=()) -> tuple:
    """The model averages of a chunk (a list of one table, or empty), its completed rows
    (:func:`completed_rows`) and its rows of ``fits.csv`` (:func:`output_view` of the completed
    rows), in the types the whole table has.

    The batch's failed experiments come last in the whole table, and their empty cells turn
    its integer columns into floats: the rows are completed together with those of
    ``options.failure_example`` (one failed experiment of the batch), which are then left out;
    the last chunk of a batch is given all the batch's ``failures`` (``{experiment: reason}``)
    with their ``failed_points`` instead, and its rows end with theirs, as the whole table does.
    """
    level = averages_level(options.settings.ci)
    averaged = averages_of_chunk(level, averaged_groups(by_experiment(fits).values(), options.ranked))
    completed = completed_rows(options, rows.copy(), fits, failures)
    view = output_view(completed, columns, [*chunk, *options.survey_probe, *failed_points], options.settings.partition_to)
    if failures is None and options.failure_example:
        left_out = [name for name, _ in options.failure_example]
        completed = completed[~completed["experiment"].isin(left_out)]
        view = view[~view["experiment"].isin(left_out)]
    return averaged, completed, view


def completed_rows(options: ChunkOptions, rows: pd.DataFrame, fits, failures=None) -> pd.DataFrame:
    """:func:`completed_fit_rows` of a chunk's ``rows`` with the batch's settings and ``failures``
    (default: ``options.failure_example``, see :func:`chunk_tables`); ``rows`` is changed."""
    return completed_fit_rows(
        rows,
        fits,
        failures=dict(options.failure_example) if failures is None else failures,
        formulas=options.formulas,
        ranked=options.ranked,
        rank_by=options.settings.rank_by,
        water_recovery=options.settings.water_recovery,
    )


def _fit_guarded(points, formula, alpha, delta_max, size_unit="") -> CurveFit:
    size_unit = size_unit or getattr(points, "size_unit", "")  # the unit the loader read from the column name
    try:
        return fit_formula(points, formula, alpha=alpha, delta_max=delta_max, size_unit=size_unit)
    except Exception as error:  # a batch reports a broken fit instead of stopping
        return failed_fit(
            points, formula, f"{type(error).__name__}: {error}", alpha=alpha, delta_max=delta_max, size_unit=size_unit
        )
