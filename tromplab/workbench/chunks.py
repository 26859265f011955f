"""The fits of a batch chunk by chunk (:func:`fit_in_chunks`), on the fan-out of
:mod:`tromplab.parallel` (in process, on a process pool or on a Dask cluster), gathered in
order into one :class:`ChunkResults`.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Sequence
from dataclasses import replace
from typing import NamedTuple

import pandas as pd

from ..curves.curve_fit import CurveFit
from ..loading.points import TrompPoints
from ..output.csv_parts import CsvPart
from ..parallel import chunked, map_on_workers, worker_count
from .averages import averages_table
from .tables import fit_rows_frame
from .worker import ChunkOptions, FittedChunk, work_on_chunk

# one logger for the batch layer: its lines read "tromplab.workbench: ..." whichever module makes them
logger = logging.getLogger(__package__)


class ChunkResults(NamedTuple):
    """What :func:`fit_in_chunks` gathers: the fits, the data notes, the interval columns and
    the model averages (None when not asked for), the rows of the fits, and the workers' CSV
    text of the tables (``{"fits": [CsvPart, ...], "averages": [...]}``, None in one process)."""

    fits: list[CurveFit]
    notes: dict
    intervals: pd.DataFrame | None
    averages: pd.DataFrame | None
    rows: pd.DataFrame
    csv_parts: dict[str, list[CsvPart]] | None = None


def fit_in_chunks(fittable: Sequence[TrompPoints], options: ChunkOptions, *, jobs, client, progress) -> ChunkResults:
    """The fits, data notes, interval columns (with ``options.settings.ci`` or ``options.settings.bootstrap``) and
    model averages of ``fittable``, chunk by chunk in order, wherever the chunks run (the
    averages only where there are workers: in one process they are made when first asked
    for).  Where there are workers, each also formats its rows of ``fits.csv`` and
    ``averages.csv``, which the main process only joins.

    A chunk's intervals are made by the worker that fitted it, right after the fits: the fits
    do not travel to the main process and back again, and each fit's intervals (its bootstrap
    seed included) depend on that fit only, so the table is the same for any number of workers.
    ``progress`` hears of each chunk twice: its fits, then (labels ``"intervals: ..."``) its intervals.
    """
    chunks = chunked(fittable, workers=worker_count(jobs, client))
    options = replace(
        options,
        width=max((points.n for points in fittable), default=0),  # one padding for every chunk
        tables_on_worker=not (jobs == 1 and client is None),  # in one process they wait until asked for
    )
    n_formulas = len(options.formulas)
    logger.info(
        "fitting %d experiment(s) x %d formula(s) in %d chunk(s) of up to %d (%s)",
        len(fittable),
        n_formulas,
        len(chunks),
        len(chunks[0]) if chunks else 0,
        "on a Dask cluster" if client is not None else f"jobs={jobs or 'all cores'}",
    )
    fits: list[CurveFit] = []
    notes: dict = {}
    frames: list[pd.DataFrame] = []
    averaged: list[pd.DataFrame] = []
    rows: list[pd.DataFrame] = []
    parts: dict[str, list[CsvPart]] = {}
    for number, (chunk, done) in enumerate(zip(chunks, map_chunks(chunks, options, jobs=jobs, client=client)), 1):
        fits += done.fits
        rows.append(done.rows)
        for name, part in (done.csv_parts or {}).items():
            parts.setdefault(name, []).append(part)
        notes.update(done.notes)
        averaged += done.averages or []
        logger.debug(
            "chunk %d/%d fitted: %d fits, %d failed", number, len(chunks), len(done.fits), sum(not f.success for f in done.fits)
        )
        if progress is not None:
            progress(len(fits) // max(n_formulas, 1), len(fittable), chunk[-1].experiment)
        if done.intervals is not None:
            frames.append(done.intervals)
            if progress is not None:
                progress(len(fits) // max(n_formulas, 1), len(fittable), f"intervals: {chunk[-1].experiment}")
    return ChunkResults(
        fits,
        notes,
        pd.concat(frames, ignore_index=True) if frames else None,
        averages_table(averaged) if options.tables_on_worker else None,
        pd.concat(rows, ignore_index=True) if rows else fit_rows_frame([]),
        parts if options.tables_on_worker else None,
    )


def map_chunks(chunks, options: ChunkOptions, *, jobs, client) -> Iterator[FittedChunk]:
    """Yield what :func:`work_on_chunk` makes of each chunk, in order: in process, in a process pool, or on Dask."""
    yield from map_on_workers(work_on_chunk, chunks, options, jobs=jobs, client=client)
