"""A batch's results spooled to disk chunk by chunk: each worker writes the rows of
``fits.csv`` and ``averages.csv`` of its chunk as files (:func:`spool_chunk`) and sends back
only a small :class:`ChunkSummary`; the main process keeps the summaries
(:class:`Spool`) and at the end joins the files into the tables of the results folder.
``ranking.csv``, which has a column per experiment, is joined the same way, line by line
from the chunks' ranks (:class:`ChunkRanks`), which the main process keeps as small arrays
(:class:`BatchRanks`), as it keeps the overview figure's values (:class:`TopFits`): what it
holds per experiment is a few dozen bytes.

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
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy import stats

from ..curves.ranking import rank_formulas, top_ranked
from ..loading.points import TrompPoints
from ..loading.surveys import with_survey_columns
from ..output.csv_parts import csv_part, defended_frame, holds_carriage_return, write_csv
from ..output.outputs import staging_folder_beside
from .averages import averages_table
from .worker import ChunkOptions, chunk_tables, fitted_chunk

# one logger for the batch layer: its lines read "tromplab.workbench: ..." whichever module makes them
logger = logging.getLogger(__package__)

#: The tables whose rows the workers write, chunk by chunk.
SPOOLED_TABLES = ("fits", "averages")
#: Columns of the fits table the overview figure reads (:func:`tromplab.output.plotting.plot_batch_overview`).
OVERVIEW_COLUMNS = ("experiment", "formula", "rank", "d_cut", "ep", "eta", "tied")


@dataclass(frozen=True)
class SpoolOptions:
    """What every worker of a spooled batch needs beside the :class:`ChunkOptions`: the scratch
    folder to write into (None: gather mode, the files travel back in the summaries) and the
    experiments whose rows the console shows (``head``)."""

    chunk: ChunkOptions
    scratch: str | None
    head: tuple[str, ...] = ()


class ChunkWork(NamedTuple):
    """One unit of work: the chunk's number (its files' order), its experiments, for the last
    chunk only the batch's failed experiments (``{experiment: reason}``) with their points,
    and the position of its first experiment among the batch's fitted ones."""

    number: int
    experiments: Sequence[TrompPoints]
    failures: dict | None = None
    failed_points: tuple = ()
    start: int = 0


class ChunkRanks(NamedTuple):
    """A chunk's share of the batch's ranking (:func:`~tromplab.curves.ranking.rank_formulas`
    of its experiments), kept by the main process instead of the chunk's ranking table.

    Attributes: ``formulas`` (in the chunk table's order); ``ranks`` (formulas x ranked
    experiments, float32 where that holds them exactly, as ranks, multiples of 1/2, are);
    ``positions`` (each ranked experiment's position among the batch's fitted experiments);
    ``points`` (per formula); ``lines`` (``(offset, length)`` in bytes, in the chunk's
    ``ranking`` file, of its experiments' header cells, then of each formula's rank cells, as
    ``ranking.csv`` writes them); ``joinable`` (False when those texts cannot be joined into
    the file's lines: an experiment name holding a carriage return, whose file quotes every
    text, or an empty name).
    """

    formulas: tuple
    ranks: np.ndarray
    positions: np.ndarray
    points: np.ndarray
    lines: tuple
    joinable: bool


class TopFits(NamedTuple):
    """The values the overview figure shows of each experiment's top-ranked fit, for a chunk:
    ``formulas`` (ids), ``codes`` (each experiment's formula, an index into ``formulas``) and
    ``values`` (experiments x ``d_cut, ep, eta, tied``: ``tied`` formulas share the first place)."""

    formulas: tuple
    codes: np.ndarray
    values: np.ndarray

    @classmethod
    def of(cls, best: pd.DataFrame) -> TopFits:
        codes, formulas = pd.factorize(best["formula"])
        values = best.reindex(columns=list(OVERVIEW_COLUMNS[3:])).to_numpy(dtype=float)
        return cls(tuple(formulas), codes.astype(np.int8 if len(formulas) < 128 else np.int32), values)


class ChunkSummary(NamedTuple):
    """What a worker sends back from a spooled chunk: no fit, only what the run's summary needs.

    Attributes: ``number``; ``notes`` (``{experiment: notes}`` of the experiments that have
    any); ``fits`` and ``successes`` (counts); ``failed_fits`` (``(experiment, formula,
    message)`` of each failed fit); ``layouts`` (``{table: (columns, dtypes, rows,
    carriage_return)}`` of the written rows); ``ranks`` (:class:`ChunkRanks`, None when no fit
    is ranked); ``best`` (:class:`TopFits`); ``head`` (the completed rows and the ``fits.csv``
    rows of the ``head`` experiments, or None); ``files`` (gather mode: ``{file name:
    bytes}``, else empty).
    """

    number: int
    notes: dict
    fits: int
    successes: int
    failed_fits: list
    layouts: dict
    ranks: ChunkRanks | None
    best: TopFits | None
    head: tuple | None
    files: dict
    any_ranked: bool = False


def chunk_file(table: str, number: int, kind: str) -> str:
    """Name of the scratch file of ``table``'s rows of chunk ``number``: ``kind`` ``"csv"`` (the
    text) or ``"pkl"`` (the rows themselves, for a table whose chunks were typed differently)."""
    return f"{table}-{number:07d}.{kind}"


def chunk_ranks(ranking: pd.DataFrame, experiments: Sequence[str], start: int) -> tuple[ChunkRanks, bytes]:
    """The :class:`ChunkRanks` of a chunk's ``ranking`` (:func:`~tromplab.curves.ranking.rank_formulas`
    of the chunk, whose experiments are ``experiments``, the first at position ``start`` of the
    batch) and the content of its ``ranking`` file: the header cells of its experiment columns,
    then each formula's rank cells, as :func:`~tromplab.output.csv_parts.write_csv` formats
    them in the whole table (a float as numpy writes it, a missing rank empty)."""
    columns = ranking.drop(columns=["formula", "points", "place"])  # as the whole batch's join drops them
    values = columns.to_numpy(dtype=float)
    cells = values.astype(str)  # what DataFrame.to_csv writes of a float column
    cells[np.isnan(values)] = ""
    header = defended_frame(columns.iloc[:0]).to_csv(index=False)[: -len(os.linesep)]
    texts = [text.encode("utf-8") for text in (header, *(",".join(row) for row in cells))]
    offsets = np.cumsum([0, *(len(text) for text in texts)])
    compact = values.astype(np.float32)
    index = {name: position for position, name in enumerate(experiments)}
    ranks = ChunkRanks(
        tuple(ranking["formula"]),
        compact if np.array_equal(compact, values, equal_nan=True) else values,
        np.array([start + index[name] for name in columns.columns], dtype=np.int64),
        ranking["points"].to_numpy(dtype=float),
        tuple((int(offset), len(text)) for offset, text in zip(offsets, texts)),
        "" not in index and not holds_carriage_return(columns.iloc[:0]),
    )
    return ranks, b"".join(texts)


def spool_chunk(options: SpoolOptions, work: ChunkWork) -> ChunkSummary:
    """Fit a chunk, write its rows of ``fits.csv`` and ``averages.csv`` (text, and the rows
    pickled) into ``options.scratch`` and return its :class:`ChunkSummary`; in gather mode
    the files travel in the summary.  Runs on a worker."""
    chunk = work.experiments
    fits, notes, columns, rows = fitted_chunk(options.chunk, chunk)
    averaged, completed, view = chunk_tables(options.chunk, chunk, fits, columns, rows, work.failures, work.failed_points)
    tables = {"fits": view}
    if averaged:
        tables["averages"] = averages_table(averaged)
    files, layouts = {}, {}
    for name, table in tables.items():
        if name == "averages":
            table = with_survey_columns(table, [*chunk, *options.chunk.survey_probe])
        part = csv_part(table)
        layouts[name] = (part.columns, part.dtypes, part.rows, holds_carriage_return(table))
        files[chunk_file(name, work.number, "csv")] = part.text.encode("utf-8")
        files[chunk_file(name, work.number, "pkl")] = pickle.dumps(table, protocol=pickle.HIGHEST_PROTOCOL)
    ranked = completed[completed["rank"].notna() & ~completed["experiment"].isin(list(work.failures or ()))]
    ranks = None
    if len(ranked):
        ranking = rank_formulas(ranked, by=options.chunk.settings.rank_by, key="formula")
        ranks, files[chunk_file("ranking", work.number, "csv")] = chunk_ranks(ranking, [p.experiment for p in chunk], work.start)
    if options.scratch is not None:
        for name, content in files.items():
            Path(options.scratch, name).write_bytes(content)
        files = {}
    shown = completed["experiment"].isin(options.head)
    return ChunkSummary(
        work.number,
        notes,
        len(fits),
        sum(fit.success for fit in fits),
        [(fit.experiment, fit.formula.id, fit.fit.message) for fit in fits if not fit.success],
        layouts,
        ranks,
        TopFits.of(top_ranked(view)),
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
        self.scratch = staging_folder_beside(outdir)
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
                write_csv(averages_table([]) if table == "averages" else pd.DataFrame(), path)
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

    def ranks(self, names: Sequence[str]) -> BatchRanks | None:
        """The :class:`BatchRanks` of the batch, whose fitted experiments are ``names``; None
        when no fit is ranked."""
        pieces = tuple(s.ranks for s in self.summaries if s.ranks is not None)
        return BatchRanks(pieces, names) if pieces else None

    def ranking_writer(self, ranks: BatchRanks | None, equations: dict, table):
        """Writer of ``ranking.csv``: the header and each formula's line joined from the
        chunks' ``ranking`` files (one line in memory at a time), the text
        :func:`~tromplab.output.csv_parts.write_csv` writes for the ranking table (rows by
        place, then equation, as :meth:`Workbench.ranking_table` sorts them; ``equations``:
        formula id -> equation), else, when a chunk's texts cannot be joined
        (:class:`ChunkRanks`), ``table()`` (that table) formatted whole."""
        if ranks is None:
            return lambda path: write_csv(table(), path)
        in_memory = self._ranking_in_memory(table)
        if not all(piece.joinable for piece in ranks.pieces):
            return in_memory
        ends = ranks.standings(equations)  # the rows of Workbench.ranking_table, in its order
        starts = defended_frame(ends[["equation", "formula"]]).to_csv(index=False).split(os.linesep)[:-1]
        tails = defended_frame(ends[["points", "place"]]).to_csv(index=False).split(os.linesep)[:-1]
        if holds_carriage_return(ends) or len(starts) != len(ends) + 1:  # a line break in a cell
            return in_memory

        def write(path):
            with open(path, "wb") as file:
                for start, formula, tail in zip(starts, [None, *ends["formula"]], tails):  # None: the header
                    file.write(start.encode("utf-8"))
                    for summary in self.summaries:
                        if summary.ranks is not None:
                            file.write(b"," + self._rank_cells(summary, formula))
                    file.write(f",{tail}{os.linesep}".encode())

        return write

    @staticmethod
    def _ranking_in_memory(table):
        def write(path):
            logger.info("an experiment's or formula's name cannot be joined as text: ranking.csv is formatted in memory")
            write_csv(table(), path)

        return write

    def _rank_cells(self, summary: ChunkSummary, formula: str | None) -> bytes:
        """The text of chunk ``summary``'s cells in the line of ``formula`` of the joined
        ranking (None: the header): empty cells for a formula the chunk ranked no fit of."""
        piece = summary.ranks
        if formula is not None and formula not in piece.formulas:
            return b"," * (len(piece.positions) - 1)
        offset, length = piece.lines[0 if formula is None else 1 + piece.formulas.index(formula)]
        with open(self.scratch / chunk_file("ranking", summary.number, "csv"), "rb") as file:
            file.seek(offset)
            return file.read(length)

    def best_rows(self) -> pd.DataFrame | None:
        """:data:`OVERVIEW_COLUMNS` of each experiment's top-ranked fit, in batch order, the
        experiments numbered (the overview counts them; their names are not needed); None
        when no fit is ranked (no overview figure is drawn then)."""
        if not any(s.any_ranked for s in self.summaries):
            return None
        tops = [s.best for s in self.summaries if s.best is not None]
        formulas = np.array([formula for top in tops for formula in top.formulas], dtype=object)
        first = np.cumsum([0, *(len(top.formulas) for top in tops)])
        codes = np.concatenate([np.zeros(0, dtype=np.int64), *(top.codes + base for top, base in zip(tops, first))])
        values = np.concatenate([np.zeros((0, len(OVERVIEW_COLUMNS) - 3)), *(top.values for top in tops)])
        columns = {"experiment": np.arange(len(codes)), "formula": formulas[codes], "rank": np.ones(len(codes))}
        return pd.DataFrame({**columns, **{column: values[:, i] for i, column in enumerate(OVERVIEW_COLUMNS[3:])}})

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


class BatchRanks:
    """The ranks of a streamed batch, kept as its chunks' :class:`ChunkRanks` (a few bytes per
    experiment) instead of a table with a column per experiment; :meth:`frame` makes that
    table when it is asked for.  ``names``: the batch's fitted experiments, in order."""

    def __init__(self, pieces: Sequence[ChunkRanks], names: Sequence[str]):
        self.pieces, self.names = tuple(pieces), names

    def formulas(self) -> list[str]:
        """The formulas, in the order of their first appearance in the chunks' rankings."""
        return list(dict.fromkeys(formula for piece in self.pieces for formula in piece.formulas))

    def points(self, order: Sequence[str]) -> np.ndarray:
        """Each formula's points in ``order``: the chunks' points added up (ranks are per
        experiment, so the sums of ranks and half ranks add up exactly)."""
        total = 0
        for piece in self.pieces:
            total = total + pd.Series(piece.points, index=list(piece.formulas)).reindex(order, fill_value=0.0)
        return total.to_numpy(dtype=float)

    def standings(self, equations: dict) -> pd.DataFrame:
        """Each formula's ``equation`` (``equations``: formula id -> equation), ``formula``,
        ``points`` and ``place``, made from the chunks' points without the ranks, in the order
        of :meth:`Workbench.ranking_table` (by place, then equation)."""
        order = self.formulas()
        table = pd.DataFrame({"formula": order, "points": self.points(order)})
        table["place"] = stats.rankdata(table["points"].to_numpy(), method="min").astype(int)
        table.insert(0, "equation", table["formula"].map(equations))
        return table.sort_values(["place", "equation"]).reset_index(drop=True)

    def frame(self) -> pd.DataFrame:
        """:func:`~tromplab.curves.ranking.rank_formulas` of the whole batch."""
        order = self.formulas()
        wide = pd.concat(
            [pd.DataFrame(piece.ranks.astype(float), index=list(piece.formulas),
                          columns=[str(self.names[position]) for position in piece.positions]).reindex(order)
             for piece in self.pieces],
            axis=1,
        )  # fmt: skip
        wide.index.name = "formula"
        wide["points"] = self.points(order)
        wide["place"] = stats.rankdata(wide["points"].to_numpy(), method="min").astype(int)
        return wide.reset_index()
