"""Where a :class:`~tromplab.workbench.Workbench` reads its fits and their tables: one interface,
:class:`FitStore`, and its two implementations, :class:`FitsInMemory` (every fit held, the
tables made from them when first asked for) and :class:`FitsOnDisk` (a batch streamed to its
results folder by :func:`~tromplab.workbench.fit_to_folder`: the tables read back from the
folder, an experiment's fits made again when they are asked for).

The workbench asks the same questions of either and does not know which it holds; the answers
are the same tables (a streamed batch's read as a CSV reader types them).
"""

from __future__ import annotations

import functools
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import pandas as pd

from ..curves.curve_fit import CurveFit
from ..curves.ranking import rank_formulas
from ..errors import OptionError
from ..output.folder import write_results_folder
from ..output.outputs import replace_folder
from ..parallel import MAX_CHUNK_SIZE, map_on_workers
from .averages import averages_level
from .tables import by_experiment, completed_fit_rows, fit_row_settings, fit_rows_frame, output_view
from .worker import ChunkOptions, completed_rows

if TYPE_CHECKING:
    from .result import Workbench
    from .spool import BatchRanks


class FitStore(Protocol):
    """What a :class:`~tromplab.workbench.Workbench` asks of the place its fits are kept."""

    def experiments(self) -> list[str]:
        """The fitted experiments, in batch order."""

    def fits_of(self, experiment: str) -> list[CurveFit]:
        """The fits of ``experiment`` in formula order (none for an experiment not fitted)."""

    def fits_by_experiment(self) -> dict[str, list[CurveFit]]:
        """Every experiment's fits, in batch order."""

    def n_successful(self) -> int:
        """The number of successful fits."""

    def failed_fits(self) -> list[tuple[str, str, str | None]]:
        """``(experiment, formula id, message)`` of each failed fit, in batch order."""

    def fits_table(self, experiments: list[str] | None) -> pd.DataFrame:
        """The rows of ``fits.csv`` (of ``experiments`` only, when given), a table of its own."""

    def experiment_rows(self, experiment: str) -> pd.DataFrame:
        """The completed rows (those of the fits table before its view) holding ``experiment``'s."""

    def best_formula(self, experiment: str) -> str | None:
        """The formula of ``experiment``'s best fit (None when it has no ranked fit)."""

    def top_rows(self, experiment: str) -> pd.DataFrame | None:
        """The completed rows sharing ``experiment``'s top rank (None when it has no ranked fit)."""

    def ranking(self) -> pd.DataFrame | None:
        """:func:`~tromplab.curves.ranking.rank_formulas` of the batch (None when no fit is ranked)."""

    def standings(self, equations: dict) -> pd.DataFrame | None:
        """``equation, formula, points, place`` made without the table of every rank (None:
        the store keeps that table, from which the workbench takes them)."""

    def averages_read(self, level: float) -> pd.DataFrame | None:
        """The model averages at ``level`` where the store keeps them written (None: compute them)."""

    def save(self, bench: Workbench, directory, *, figures: str, format: str, excel: bool, reloadable: bool, jobs):
        """Write the results folder of ``bench``; ``{file name: path}``."""


def _best_formulas_of(table: pd.DataFrame) -> dict[str, str]:
    """The formula of each experiment's best fit in ``table`` (completed rows, see :meth:`Workbench.best_fit`)."""
    rows = table[table["success"] & table["rank"].notna()].sort_values(["rank", "ssr", "equation"], kind="stable")
    return dict(rows.drop_duplicates("experiment")[["experiment", "formula"]].itertuples(index=False))


def _top_rows_of(table: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The rows sharing each experiment's top rank in ``table`` (completed rows)."""
    rows = table[table["success"] & table["rank"].notna()]
    rows = rows[rows["rank"] == rows.groupby("experiment", sort=False)["rank"].transform("min")]
    return {experiment: group for experiment, group in rows.groupby("experiment", sort=False)}


class FitsInMemory:
    """The fits a :class:`~tromplab.workbench.Workbench` holds (``bench``), and the tables made
    from them, each once, when first asked for.  ``rows``: the rows of the fits as the workers
    made them (:func:`~tromplab.workbench.tables.fit_rows_frame`), None to make them here."""

    def __init__(self, bench: Workbench, rows: pd.DataFrame | None = None):
        self.bench, self._rows = bench, rows

    def experiments(self) -> list[str]:
        return list(self.fits_by_experiment())

    def fits_of(self, experiment: str) -> list[CurveFit]:
        return list(self.fits_by_experiment().get(experiment, []))

    def fits_by_experiment(self) -> dict[str, list[CurveFit]]:
        return self._grouped

    @cached_property
    def _grouped(self) -> dict[str, list[CurveFit]]:
        return by_experiment(self.bench.fits)

    def n_successful(self) -> int:
        return sum(fit.success for fit in self.bench.fits)

    def failed_fits(self) -> list[tuple[str, str, str | None]]:
        return [(fit.experiment, fit.formula.id, fit.fit.message) for fit in self.bench.fits if not fit.success]

    def fits_table(self, experiments: list[str] | None) -> pd.DataFrame:
        table = self.output_frame
        return (table if experiments is None else table[table["experiment"].isin(experiments)]).copy()

    @cached_property
    def output_frame(self) -> pd.DataFrame:
        """The whole fits table (:func:`output_view` of :attr:`completed`)."""
        bench = self.bench
        return output_view(self.completed, bench.intervals, bench.inputs, bench.partition_to)

    @cached_property
    def completed(self) -> pd.DataFrame:
        """The completed rows of every fit, built once: the ranking, the best fits, the console
        and the report all read them."""
        bench, made = self.bench, self._rows
        self._rows = None  # the workers' rows are completed in place
        settings = fit_row_settings(bench.formulas, bench.rank_extended, bench.rank_by, bench.water_recovery)
        return completed_fit_rows(
            fit_rows_frame(bench.fits) if made is None else made, bench.fits, **settings, failures=bench.failures
        )

    def experiment_rows(self, experiment: str) -> pd.DataFrame:
        return self.completed

    def best_formula(self, experiment: str) -> str | None:
        return self._best_formulas.get(experiment)

    @cached_property
    def _best_formulas(self) -> dict[str, str]:
        # one pass over the table instead of a scan per experiment
        return _best_formulas_of(self.completed)

    def top_rows(self, experiment: str) -> pd.DataFrame | None:
        return self._top_rows.get(experiment)

    @cached_property
    def _top_rows(self) -> dict[str, pd.DataFrame]:
        # grouped once: a scan of the whole table per experiment is quadratic in the batch
        return _top_rows_of(self.completed)

    def ranking(self) -> pd.DataFrame | None:
        table, bench = self.completed, self.bench
        table = table[~table["experiment"].isin(list(bench.failures)) & table["rank"].notna()]
        return None if table.empty else rank_formulas(table, by=bench.rank_by, key="formula")

    def standings(self, equations: dict) -> pd.DataFrame | None:
        return None

    def averages_read(self, level: float) -> pd.DataFrame | None:
        return None

    def save(self, bench: Workbench, directory, *, figures: str, format: str, excel: bool, reloadable: bool, jobs):
        map_work = functools.partial(map_on_workers, jobs=jobs or None, client=None)
        return write_results_folder(
            bench, directory, figures=figures, format=format, excel=excel, reloadable=reloadable, map_work=map_work
        )


#: How read_csv reads back exactly the floats the folder's CSV files hold: pandas 3 does by
#: default (and deprecates the argument), pandas 2 with its round-trip converter.
_EXACT_FLOATS = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}


@dataclass
class FitsOnDisk:
    """A streamed batch (:func:`~tromplab.workbench.fit_to_folder`): what it keeps in memory
    instead of its fits.

    Attributes
    ----------
    folder : Path
        The results folder holding the batch's tables.
    options : ChunkOptions
        The options its chunks were fitted with (to fit an experiment again).
    inputs : sequence of TrompPoints
        The points of the batch (an :class:`~tromplab.workbench.ExperimentsInPieces` read on
        demand), from which an experiment is fitted again.
    fitted : tuple of str
        The fitted experiments, in batch order.
    failed_fits : tuple
        ``(experiment, formula, message)`` of each failed fit.
    successes : int
        The count of successful fits.
    ranks : BatchRanks or None
        The ranks kept per chunk (:class:`~tromplab.workbench.spool.BatchRanks`, a few bytes per
        experiment; None when nothing is ranked), made into the ranking table when it is
        first asked for.
    head : tuple or None
        The console's rows: the completed rows and the ``fits.csv`` rows of the first experiments.
    seconds : dict
        The main process's seconds per step.
    written : tuple of str
        The names of the written files.
    """

    folder: Path
    options: ChunkOptions
    inputs: Sequence
    fitted: tuple[str, ...]
    failed_fits_made: tuple
    successes: int
    ranks: BatchRanks | None
    head: tuple | None
    seconds: dict
    written: tuple[str, ...] = ()
    refitted: dict = field(default_factory=dict, repr=False)

    @cached_property
    def fitted_set(self) -> frozenset:
        return frozenset(self.fitted)

    def experiments(self) -> list[str]:
        return list(self.fitted)

    def fits_of(self, experiment: str) -> list[CurveFit]:
        """The fits of ``experiment`` made again from its points with the batch's options and
        padding, which gives the fits the worker made (an experiment's fits depend on its own
        points only); the last 64 experiments' are kept."""
        if experiment not in self.refitted:
            found = None
            if experiment in self.fitted_set:
                found = next((p for p in self.inputs if p.experiment == experiment), None)
            if len(self.refitted) >= 64:
                self.refitted.clear()
            self.refitted[experiment] = self.options.refit([found]) if found is not None else []
        return list(self.refitted[experiment])

    @cached_property
    def fits(self) -> RebuiltFits:
        """Every fit, in batch order, made again when read."""
        return RebuiltFits(self)

    def fits_by_experiment(self) -> dict[str, list[CurveFit]]:
        return self._grouped

    @cached_property
    def _grouped(self) -> dict[str, list[CurveFit]]:
        return by_experiment(self.fits)  # every experiment fitted again

    def n_successful(self) -> int:
        return self.successes

    def failed_fits(self) -> list[tuple[str, str, str | None]]:
        return list(self.failed_fits_made)

    def fits_table(self, experiments: list[str] | None) -> pd.DataFrame:
        """Read from the folder's ``fits.csv`` (the types a CSV reader gives), except the rows
        of the console's experiments, which are kept as they were made."""
        if experiments is not None and self.head is not None and set(experiments) <= set(self.head[1]["experiment"]):
            table = self.head[1]
            return table[table["experiment"].isin(experiments)].copy()
        return self.read_table("fits", experiments)

    def experiment_rows(self, experiment: str) -> pd.DataFrame:
        """Kept for the console's experiments, else made again from the refitted experiment."""
        if self.head is not None and experiment in set(self.head[0]["experiment"]):
            rows = self.head[0]
            return rows[rows["experiment"] == experiment]
        fits = self.fits_of(experiment)
        rows = completed_rows(self.options, fit_rows_frame(fits), fits)
        return rows[rows["experiment"] == experiment]

    def best_formula(self, experiment: str) -> str | None:
        return _best_formulas_of(self.experiment_rows(experiment)).get(experiment)

    def top_rows(self, experiment: str) -> pd.DataFrame | None:
        return _top_rows_of(self.experiment_rows(experiment)).get(experiment)

    def ranking(self) -> pd.DataFrame | None:
        return None if self.ranks is None else self.ranks.frame()

    def standings(self, equations: dict) -> pd.DataFrame | None:
        return None if self.ranks is None else self.ranks.standings(equations)

    def averages_read(self, level: float) -> pd.DataFrame | None:
        return self.read_table("averages") if level == averages_level(self.options.settings.ci) else None

    def read_table(self, table: str, experiments=None) -> pd.DataFrame:
        """``table`` (``"fits"`` or ``"averages"``) read from the folder's CSV file (floats as
        written, exactly), only the rows of ``experiments`` when given."""
        path = Path(self.folder) / f"{table}.csv"
        try:
            if experiments is None:
                return pd.read_csv(path, **_EXACT_FLOATS)
            wanted = set(experiments)
            pieces = pd.read_csv(path, chunksize=100_000, **_EXACT_FLOATS)
            return pd.concat([piece[piece["experiment"].isin(wanted)] for piece in pieces], ignore_index=True)
        except pd.errors.EmptyDataError:
            return pd.DataFrame()

    def save(self, bench: Workbench, directory, *, figures: str, format: str, excel: bool, reloadable: bool, jobs):
        """The files of the folder copied (figures as the run drew them; none with
        ``figures="none"``).  What needs the fits in memory is refused with an
        :class:`~tromplab.errors.OptionError`."""
        for option, refused in (("format", format != "csv"), ("excel", excel), ("reloadable", reloadable),
                                ("figures", figures in ("all", "best"))):  # fmt: skip
            if refused or str(directory).lower().endswith(".xlsx"):
                raise OptionError(
                    option if refused else "directory",
                    "needs the fits in memory, which a streamed batch does not keep: fit again with stream=False",
                )
        source = Path(self.folder)
        names = [name for name in self.written if figures != "none" or not name.endswith(".png")]
        return replace_folder({name: functools.partial(_copy_into, source / name) for name in names}, directory)

    def __getstate__(self) -> dict:
        # the refitted experiments are a cache, made again when asked for
        return {**self.__dict__, "refitted": {}}


class RebuiltFits(Sequence):
    """The fits of a streamed batch in batch order, each experiment refitted when read
    (:meth:`ChunkOptions.refit`, a chunk of experiments at a time when iterated)."""

    def __init__(self, store: FitsOnDisk):
        self._store = store

    def __len__(self) -> int:
        return len(self._store.fitted) * len(self._store.options.formulas)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        index = index + len(self) if index < 0 else index
        if not 0 <= index < len(self):
            raise IndexError("fit index out of range")
        per_experiment = len(self._store.options.formulas)
        return self._store.fits_of(self._store.fitted[index // per_experiment])[index % per_experiment]

    def __iter__(self):
        store = self._store
        points = {p.experiment: p for p in store.inputs}
        for start in range(0, len(store.fitted), MAX_CHUNK_SIZE):
            yield from store.options.refit([points[name] for name in store.fitted[start : start + MAX_CHUNK_SIZE]])

    def __repr__(self) -> str:
        return f"<{len(self)} fits of a streamed batch, refitted when read>"


def _copy_into(source: Path, target: Path) -> None:
    """Copy the file ``source`` to ``target`` (a writer of :func:`replace_folder`)."""
    shutil.copyfile(source, target)
