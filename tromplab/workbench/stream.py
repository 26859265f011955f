"""Fit a batch and write its results folder in one go (:func:`fit_to_folder`, what ``tromplab
fit -o DIR`` does): a large batch streams its results to disk chunk by chunk, so the main
process holds no fit and its memory does not grow with the batch.

A streamed run's workers fit their chunks and write the chunks' rows of ``fits.csv`` and
``averages.csv`` (:mod:`~tromplab.workbench.spool`); the main process keeps the counts, the
failures, the ranks (``ranking.csv`` has a column per experiment), the console's rows and
the top-ranked fit of each experiment (the overview figure), then joins the files and swaps
the folder into place as a whole.  The files are byte for byte those of the in-memory path.
The :class:`~tromplab.workbench.Workbench` it returns reads its tables from the folder and
refits an experiment when its fits are asked for (:meth:`Workbench.fit`).
"""

from __future__ import annotations

import collections
import logging
import os
import threading
import time
from dataclasses import fields, replace

from ..options import AUTO_FIGURE_LIMIT
from ..output.folder import check_folder_options, write_streamed_folder
from ..parallel import chunk_size, chunks_of, dask_client, map_on_workers, streams, worker_count
from ..validation import FitSettings
from .batch import batch_inputs, batch_workbench, fit_prepared, prepared_batch
from .inputs import FittableInPieces
from .result import Workbench
from .spool import ChunkWork, Spool, SpoolOptions, spool_chunk
from .store import FitsOnDisk

# one logger for the batch layer: its lines read "tromplab.workbench: ..." whichever module makes them
logger = logging.getLogger(__package__)


def fit_to_folder(experiments, outdir, *, figures: str = "auto", format: str = "csv", excel: bool = False,
                  reloadable: bool = False, stream: bool | None = None, source=None, settings: FitSettings | None = None,
                  client=None, progress=None, **keywords):  # fmt: skip
    """Fit ``experiments`` as :func:`~tromplab.workbench.fit_experiments` does (its keywords) and
    write the results folder ``outdir`` as :meth:`Workbench.save` does (``figures``, ``format``,
    ``excel``, ``reloadable``): what ``tromplab fit INPUT -o OUTDIR`` does.

    Parameters
    ----------
    experiments, client, progress, keywords
        As for :func:`~tromplab.workbench.fit_experiments`; ``experiments`` also an
        :class:`~tromplab.workbench.ExperimentsInPieces` (a points file read in pieces),
        read once for its checks and census before anything is fitted or written, then, when
        the run streams, again chunk by chunk as the workers take the chunks: the main
        process holds a few chunks' points, never the batch's (else it is read whole).
    outdir : str or path-like
        The results folder, replaced as a whole when every file is written.
    figures, format, excel, reloadable
        As for :meth:`Workbench.save`.
    stream : bool, optional
        Stream the results to disk chunk by chunk (True), or keep every fit in memory and
        save them afterwards (False).  Default: stream from
        :data:`~tromplab.parallel.STREAM_THRESHOLD` fitted experiments.  Streaming needs CSV
        tables, no workbook, no reloadable batch and no per-experiment figures; otherwise the
        fits are kept in memory whatever ``stream`` says (the rule:
        :func:`tromplab.parallel.streams`).  The files are the same either way.
    settings : FitSettings, optional
        The settings of the fit as one record (what the command line passes), instead of
        the keywords of :func:`~tromplab.workbench.fit_experiments`.
    source : str or path-like, optional
        Named in the :class:`~tromplab.errors.InputError` raised, before anything is written,
        when no formula could be fitted to any experiment.

    Returns
    -------
    tuple
        The :class:`Workbench` (a streamed one reads its tables from ``outdir``) and
        ``{file name: path}`` of the written files.
    """
    check_folder_options(figures=figures, format=format)
    settings = _settings_of(settings, keywords)
    plan = prepared_batch(experiments, settings, in_pieces=True)
    tables_only = format == "csv" and not excel and not reloadable and str(outdir).lower()[-5:] != ".xlsx"
    if not streams(len(plan.fittable), tables_only=tables_only, figures=figures, stream=stream):
        if isinstance(plan.fittable, FittableInPieces):  # kept in memory: read whole after all
            plan = prepared_batch(experiments.read_whole(), settings)
        bench = fit_prepared(plan, client=client, progress=progress)
        bench.check_fitted(source or "")
        saved = bench.save(outdir, figures=figures, format=format, excel=excel, reloadable=reloadable, jobs=settings.jobs)
        return bench, saved
    with dask_client(scheduler=settings.scheduler, dask=settings.dask, client=client) as cluster, Spool(outdir) as spool:
        warming = _figure_modules_loading() if figures == "auto" and (cluster is not None or settings.jobs != 1) else None
        bench, store = _streamed_batch(plan, spool, cluster, outdir, progress)
        if warming is not None:
            warming.join()
        bench.check_fitted(source or "")
        started = time.perf_counter()
        tables = {
            "fits.csv": spool.table_writer("fits"),
            "ranking.csv": spool.ranking_writer(store.ranks, bench.equations, bench.ranking_table),
            "averages.csv": spool.table_writer("averages"),
        }
        written = write_streamed_folder(bench, outdir, tables, overview=spool.best_rows() if figures == "auto" else None)
        store.seconds["write the folder"] = time.perf_counter() - started
        store.written = tuple(written)
    return bench, written


def _settings_of(settings: FitSettings | None, keywords: dict) -> FitSettings:
    """``settings``, or the :class:`FitSettings` of the keywords of :func:`fit_experiments`; an
    unknown keyword, or keywords beside ``settings``, is a TypeError."""
    unknown = sorted(set(keywords) - {field.name for field in fields(FitSettings)})
    if unknown:
        raise TypeError(f"fit_to_folder() got unexpected keyword argument(s): {', '.join(unknown)}")
    if settings is None:
        return FitSettings(**keywords)
    if keywords:
        raise TypeError(f"fit_to_folder() takes settings or their keywords, not both: {', '.join(sorted(keywords))}")
    return settings


def _streamed_batch(plan, spool: Spool, cluster, outdir, progress) -> tuple[Workbench, FitsOnDisk]:
    """Fit the chunks of ``plan`` on the workers, which write their rows into ``spool``; the
    streamed :class:`Workbench` of the batch and the store it reads its fits through."""
    seconds = {}
    started = time.perf_counter()
    fittable, failures = plan.fittable, plan.failures
    in_pieces = isinstance(fittable, FittableInPieces)
    scratch = str(spool.scratch) if _workers_see(cluster, spool.scratch) else None
    example = next(iter(failures.items()), None)
    options = replace(
        plan.options,
        width=fittable.census.width if in_pieces else max(points.n for points in fittable),  # one padding for every chunk
        tables_on_worker=True,
        failure_example=(example,) if example else (),
        survey_probe=fittable.census.survey_probe if in_pieces else _survey_probe(plan.experiments),
    )
    fitted = tuple(fittable.census.fitted if in_pieces else (points.experiment for points in fittable))
    size = chunk_size(len(fittable), workers=worker_count(plan.settings.jobs, cluster))
    n_chunks = -(-len(fittable) // size)
    logger.info(
        "fitting %d experiment(s) x %d formula(s) in %d chunk(s) of up to %d, streamed to %s (%s%s)",
        len(fittable), len(options.formulas), n_chunks, size, spool.scratch,
        "workers write the files" if scratch else "the files travel back: the workers cannot see the folder",
        "; the input read in pieces" if in_pieces else "",
    )  # fmt: skip
    head = (fitted + tuple(failures))[:AUTO_FIGURE_LIMIT]
    seconds["prepare"] = time.perf_counter() - started
    shapes: collections.deque = collections.deque()  # (experiments, last experiment) of each chunk handed out and not yet back
    done, waited, kept = 0, 0.0, 0.0
    mark = time.perf_counter()
    work = _chunk_work(plan, size, n_chunks, shapes)
    for summary in map_on_workers(
        spool_chunk, work, SpoolOptions(options, scratch, head), jobs=plan.settings.jobs, client=cluster, count=n_chunks
    ):
        now = time.perf_counter()
        waited += now - mark
        spool.keep(summary)
        length, last_experiment = shapes.popleft()
        done += length
        logger.debug("chunk %d/%d fitted: %d fits, %d failed", summary.number + 1, n_chunks, summary.fits,
                     summary.fits - summary.successes)  # fmt: skip
        if progress is not None:
            progress(done, len(fittable), last_experiment)
            if plan.settings.ci or plan.settings.bootstrap:
                progress(done, len(fittable), f"intervals: {last_experiment}")
        mark = time.perf_counter()
        kept += mark - now
    seconds.update({"wait for the workers": waited, "keep the chunks' summaries": kept})
    started = time.perf_counter()
    store = FitsOnDisk(
        folder=outdir, options=options, inputs=batch_inputs(plan), fitted=fitted,
        failed_fits_made=tuple(spool.failed_fits()), successes=sum(s.successes for s in spool.summaries),
        ranks=spool.ranks(fitted), head=spool.head(), seconds=seconds,
    )  # fmt: skip
    bench = batch_workbench(plan, store.fits, spool.notes(), None, store=store)
    seconds["join the summaries"] = time.perf_counter() - started
    return bench, store


def _chunk_work(plan, size: int, n_chunks: int, shapes: collections.deque):
    """The :class:`ChunkWork` of each chunk of ``size`` experiments of ``plan.fittable``, cut
    as they are taken (the file read on, for a batch read in pieces); the last one carries the
    failed experiments.  ``shapes`` hears each chunk's size and last experiment."""
    fittable, failures = plan.fittable, plan.failures
    if isinstance(fittable, FittableInPieces):
        failed_points = fittable.census.failed_points
    else:
        failed_points = tuple(points for points in plan.experiments if points.experiment in failures)
    for number, chunk in enumerate(chunks_of(fittable, size)):
        shapes.append((len(chunk), chunk[-1].experiment))
        last = number == n_chunks - 1
        yield ChunkWork(number, chunk, failures if last else None, failed_points if last else (), number * size)


def _figure_modules_loading() -> threading.Thread:
    """A thread importing matplotlib's figure and Agg modules (its font list included, about
    0.5 s), started while the workers fit: the overview is drawn after the last chunk, in the
    serial part of the run.  Nothing is drawn in it (matplotlib's fonts are not shared safely
    between threads); join it before drawing."""

    def load():
        import matplotlib.backends.backend_agg  # noqa: F401
        import matplotlib.figure  # noqa: F401

    thread = threading.Thread(target=load, name="tromplab-figure-modules", daemon=True)
    thread.start()
    return thread


def _workers_see(cluster, folder) -> bool:
    """Whether the chunks' workers can write into ``folder``: always for local processes; on a
    Dask cluster when every worker finds it (a folder shared by the machines, or one machine)."""
    if cluster is None:
        return True
    found = cluster.run(os.access, str(folder), os.W_OK)
    return bool(found) and all(found.values())


def _survey_probe(experiments) -> tuple:
    """The first experiment holding each survey column (``date``, ``survey``), for every chunk."""
    from ..loading.surveys import SURVEY_COLUMNS

    probe = {}
    for column in SURVEY_COLUMNS:
        holder = next((points for points in experiments if column in points.meta), None)
        if holder is not None:
            probe[holder.experiment] = holder
    return tuple(probe.values())
