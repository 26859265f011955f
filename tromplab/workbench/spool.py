"""A batch's results spooled to disk chunk by chunk: each worker writes the rows of
``fits.csv`` and ``averages.csv`` of its chunk as files (:func:`spool_chunk`) and sends back
only a small :class:`ChunkSummary`; the main process keeps the summaries
(:class:`Spool`) and at the end joins the files into the tables of the results folder.

The files go to a scratch folder beside the output folder, named as the output layer names
its staging folders (``.OUT.tmp-<pid>-<random>``), so a run that dies leaves nothing that
looks like a results folder and the next run into the same place removes it
(:func:`tromplab.output.outputs.clean_stale`).  On a Dask cluster whose workers cannot see
that folder, the workers send the files' content back in their summaries instead (gather
mode) and the main process writes them.
"""

from __future__ import annotations

import logging
import os
import pickle
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import pandas as pd
from scipy import stats

from ..curves.ranking import rank_formulas
from ..loading.points import TrompPoints
from ..loading.surveys import with_survey_columns
from ..output.csv_parts import csv_part, defended_frame, holds_carriage_return, write_csv
from ..output.outputs import check_output_folder
from .averages import _averages_table
from .worker import ChunkOptions, chunk_tables, fitted_chunk

# one logger for the batch layer: its lines read "tromplab.workbench: ..." whichever module makes them
logger = logging.getLogger(__package__)

#: The tables whose rows the workers write, chunk by chunk.
SPOOLED_TABLES = ("fits", "averages")
#: Columns of the fits table the overview figure reads (:func:`tromplab.output.plotting.plot_batch_overview`).
OVERVIEW_COLUMNS = ("experiment", "formula", "rank", "d_cut", "ep", "eta")


@dataclass(frozen=True)
class SpoolOptions:
    """What every worker of a spooled batch needs beside the :class:`ChunkOptions`: the scratch
    folder to write into (None: gather mode, the files travel back in the summaries) and the
    experiments whose rows the console shows (``head``)."""

    chunk: ChunkOptions
    scratch: str | None
    head: tuple[str, ...] = ()


class ChunkWork(NamedTuple):
    """One unit of work: the chunk's number (its files' order), its experiments and, for the last
    chunk only, the batch's failed experiments (``{experiment: reason}``) with their points."""

    number: int
    experiments: Sequence[TrompPoints]
    failures: dict | None = None
    failed_points: tuple = ()


class ChunkSummary(NamedTuple):
    """What a worker sends back from a spooled chunk: no fit, only what the run's summary needs.

    Attributes: ``number``; ``notes`` (``{experiment: notes}``); ``fits`` and ``successes``
    (counts); ``failed_fits`` (``(experiment, formula, message)`` of each failed fit);
    ``layouts`` (``{table: (columns, dtypes, rows, carriage_return)}`` of the written rows);
    ``ranking`` (:func:`~tromplab.curves.ranking.rank_formulas` of the chunk, None when no fit
    is ranked); ``best`` (:data:`OVERVIEW_COLUMNS` of each experiment's top-ranked fit);
    ``head`` (the completed rows and the ``fits.csv`` rows of the ``head`` experiments, or
    None); ``files`` (gather mode: ``{file name: bytes}``, else empty).
    """

    number: int
    notes: dict
    fits: int
    successes: int
    failed_fits: list
    layouts: dict
    ranking: pd.DataFrame | None
    best: pd.DataFrame
    head: tuple | None
    files: dict
    any_ranked: bool = False


def chunk_file(table: str, number: int, kind: str) -> str:
    """Name of the scratch file of ``table``'s rows of chunk ``number``: ``kind`` ``"csv"`` (the
    text) or ``"pkl"`` (the rows themselves, for a table whose chunks were typed differently)."""
    return f"{table}-{number:07d}.{kind}"


def spool_chunk(options: SpoolOptions, work: ChunkWork) -> ChunkSummary:
    """Fit a chunk, write its rows of ``fits.csv`` and ``averages.csv`` (text, and the rows
    pickled) into ``options.scratch`` and return its :class:`ChunkSummary`; in gather mode
    the files travel in the summary.  Runs on a worker."""
    chunk = work.experiments
    fits, notes, columns, rows = fitted_chunk(options.chunk, chunk)
    averaged, completed, view = chunk_tables(options.chunk, chunk, fits, columns, rows, work.failures, work.failed_points)
    tables = {"fits": view}
    if averaged:
        tables["averages"] = _averages_table(averaged)
    files, layouts = {}, {}
    for name, table in tables.items():
        if name == "averages":
            table = with_survey_columns(table, [*chunk, *options.chunk.survey_probe])
        part = csv_part(table)
        layouts[name] = (part.columns, part.dtypes, part.rows, holds_carriage_return(table))
        files[chunk_file(name, work.number, "csv")] = part.text.encode("utf-8")
        files[chunk_file(name, work.number, "pkl")] = pickle.dumps(table, protocol=pickle.HIGHEST_PROTOCOL)
    if options.scratch is not None:
        for name, content in files.items():
            Path(options.scratch, name).write_bytes(content)
        files = {}
    ranked = completed[completed["rank"].notna() & ~completed["experiment"].isin(list(work.failures or ()))]
    best = view[view["rank"] == 1].drop_duplicates("experiment")
    shown = completed["experiment"].isin(options.head)
    return ChunkSummary(
        work.number,
        notes,
        len(fits),
        sum(fit.success for fit in fits),
        [(fit.experiment, fit.formula.id, fit.fit.message) for fit in fits if not fit.success],
        layouts,
        rank_formulas(ranked, by=options.chunk.rank_by, key="formula") if len(ranked) else None,
        best.reindex(columns=list(OVERVIEW_COLUMNS)),
        (completed[shown], view[view["experiment"].isin(options.head)]) if shown.any() else None,
        files,
        bool(view["rank"].notna().any()),
    )


class Spool:
    """The main process's side of a spooled batch: the scratch folder beside ``outdir``, the
    summaries of the chunks in order, and the writers of the joined tables.

    Use as a context manager: the scratch folder is removed on leaving, whatever happened.
    """

    def __init__(self, outdir):
        outdir = check_output_folder(outdir)
        parent = outdir.absolute().parent
        parent.mkdir(parents=True, exist_ok=True)
        # named as a staging folder: clean_stale removes it when this process has died
        self.scratch = Path(tempfile.mkdtemp(dir=parent, prefix=f".{outdir.name}.tmp-{os.getpid()}-"))
        self.summaries: list[ChunkSummary] = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        shutil.rmtree(self.scratch, ignore_errors=True)
        return False

    def keep(self, summary: ChunkSummary) -> None:
        """Keep a chunk's summary; write the files it carries (gather mode)."""
        for name, content in summary.files.items():
            (self.scratch / name).write_bytes(content)
        self.summaries.append(summary._replace(files={}))

    def table_writer(self, table: str):
        """Writer of ``fits.csv`` or ``averages.csv`` (``table``) from the chunks' files: the
        header and the texts one after another when every chunk's rows were typed alike
        (the text is then what :func:`~tromplab.output.csv_parts.write_csv` writes for the
        whole table), else the whole table joined from the pickled rows and formatted."""
        numbers = [s.number for s in self.summaries if table in s.layouts]
        layouts = {s.layouts[table][:2] for s in self.summaries if table in s.layouts}
        quoted = any(s.layouts[table][3] for s in self.summaries if table in s.layouts)

        def write(path):
            if not numbers:
                write_csv(_averages_table([]) if table == "averages" else pd.DataFrame(), path)
            elif len(layouts) == 1 and not quoted:
                columns = next(iter(layouts))[0]
                with open(path, "wb") as file:
                    file.write(defended_frame(pd.DataFrame(columns=list(columns))).to_csv(index=False).encode("utf-8"))
                    for number in numbers:
                        with open(self.scratch / chunk_file(table, number, "csv"), "rb") as part:
                            shutil.copyfileobj(part, file)
            else:
                logger.info("the chunks' rows of %s.csv were typed differently: the table is joined in memory", table)
                frames = [pd.read_pickle(self.scratch / chunk_file(table, number, "pkl")) for number in numbers]
                write_csv(pd.concat(frames, ignore_index=True), path)

        return write

    def ranking(self) -> pd.DataFrame | None:
        """:func:`~tromplab.curves.ranking.rank_formulas` of the whole batch from the chunks'
        rankings (ranks are per experiment; the points, sums of ranks and half ranks, add up
        exactly); None when no fit is ranked."""
        pieces = [s.ranking for s in self.summaries if s.ranking is not None]
        if not pieces:
            return None
        order = list(dict.fromkeys(formula for piece in pieces for formula in piece["formula"]))
        indexed = [piece.set_index("formula") for piece in pieces]
        wide = pd.concat([piece.drop(columns=["points", "place"]).reindex(order) for piece in indexed], axis=1)
        wide.index.name = "formula"
        wide["points"] = sum(piece["points"].reindex(order, fill_value=0.0) for piece in indexed)
        wide["place"] = stats.rankdata(wide["points"].to_numpy(), method="min").astype(int)
        return wide.reset_index()

    def best_rows(self) -> pd.DataFrame | None:
        """:data:`OVERVIEW_COLUMNS` of each experiment's top-ranked fit, in batch order; None
        when no fit is ranked (no overview figure is drawn then)."""
        if not any(s.any_ranked for s in self.summaries):
            return None
        return pd.concat([s.best for s in self.summaries], ignore_index=True)

    def head(self) -> tuple[pd.DataFrame, pd.DataFrame] | None:
        """The completed rows and the ``fits.csv`` rows of the console's experiments."""
        found = [s.head for s in self.summaries if s.head is not None]
        if not found:
            return None
        return pd.concat([h[0] for h in found]), pd.concat([h[1] for h in found])

    def failed_fits(self) -> list:
        return [failed for s in self.summaries for failed in s.failed_fits]

    def notes(self) -> dict:
        return {experiment: notes for s in self.summaries for experiment, notes in s.notes.items()}
