"""The result of a batch: :class:`Workbench` (every fit with its fits, ranking and averages
tables, figures, report and results folder), :func:`load` of a saved batch, and
:func:`model_averages` of a batch spread over workers.
"""

from __future__ import annotations

import functools
import logging
import os
import shutil
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import pandas as pd

from ..curves.curve_fit import CurveFit
from ..curves.formulas import Formula
from ..curves.ranking import fit_verdicts, rank_formulas
from ..errors import InputError, OptionError, expect_kind
from ..loading.lab import MassBalance
from ..loading.points import TrompPoints
from ..loading.surveys import with_survey_columns
from ..output.csv_parts import CsvPart
from ..output.folder import write_results_folder
from ..output.outputs import replace_folder
from ..output.plotting import plot_tromp_fits
from ..output.report import build_report, write_report
from ..output.results import experiment_summary, load_workbench, summary_text, workbench_html, workbench_repr
from ..results_contract import ResultContract
from ..validation import MAX_JOBS, FitSettings, check_count, check_optional, check_probability
from .averages import _averaged_groups, _averages_of_chunk, _averages_table, averages_level
from .fanout import MAX_CHUNK_SIZE, ChunkResults, _map_work, _worker_count, chunked
from .tables import by_experiment, completed_fit_rows, fit_row_settings, fit_rows_frame, output_view, ranked_among
from .worker import ChunkOptions, completed_rows

# one logger for the batch layer: its lines read "tromplab.workbench: ..." whichever module makes them
logger = logging.getLogger(__package__)


#: The settings a :class:`Workbench` offers as attributes (its fields of their own before they were one record).
_SETTINGS_READ = ("rank_by", "alpha", "rank_extended", "water_recovery", "ci", "bootstrap", "bootstrap_method", "seed",
                  "partition_to")  # fmt: skip


def _from_settings(name: str) -> property:
    """A read-only attribute of a :class:`Workbench`: the field ``name`` of its ``settings``."""
    return property(
        lambda bench: getattr(bench.settings, name), doc=f"``settings.{name}`` (:class:`~tromplab.validation.FitSettings`)."
    )


@dataclass(frozen=True)
class Workbench(ResultContract):
    """All fits of a batch with their tables.

    Made by :func:`tromplab.fit_experiments` (or :func:`tromplab.load`).  :meth:`summary`
    has one row per experiment (its top-ranked fit), :meth:`to_frame` is ``fits.csv``,
    :meth:`report` the text, :meth:`write_report` the HTML report, :meth:`save` the folder
    ``tromplab fit`` writes.

    A batch streamed to disk (:func:`~tromplab.workbench.fit_to_folder`, from
    :data:`~tromplab.workbench.STREAM_THRESHOLD` experiments) keeps no fit: its ``fits`` is a
    sequence that refits the experiments when read, its tables come from its results folder,
    and :meth:`fit` refits one experiment (docs/performance.md, "Large batches").

    Attributes
    ----------
    fits : tuple of CurveFit
        Every fit, experiment by experiment in batch order.
    failures : dict
        Experiment -> why it could not be fitted at all.
    formulas : tuple of Formula
        The formulas fitted.
    notes : dict
        Experiment -> notes on its data (classes left out, inferred columns).
    settings : FitSettings
        The settings the batch was fitted with (:class:`tromplab.validation.FitSettings`);
        the attributes ``rank_by`` to ``partition_to`` below read them.
    rank_by : str
        The criterion of the ranking (``"F"``, ``"aicc"``, ...).
    alpha : float
        Significance level of the Fisher screen.
    rank_extended : bool
        Whether the extended curves are ranked with the paper's nine.
    water_recovery : float or None
        Water split to the underflow, compared with the fitted bypass (hydrocyclones).
    ci : float or None
        Level of the intervals in the fits table (None: no intervals).
    bootstrap : int
        Bootstrap resamples per fit (0: none).
    bootstrap_method : str
        ``"residuals"`` or ``"cases"``.
    seed : int
        Seed of the bootstrap.
    partition_to : str
        ``"fine"`` or ``"coarse"``: the product the tables' partition refers to.
    size_unit : str
        Unit of the sizes ("" when unknown): the loader's when every experiment has the same
        one, else ``settings.size_unit``.
    inputs : tuple of TrompPoints
        The points of every experiment, as fitted.
    balances : tuple of MassBalance
        The lab balances the points came from (empty for points input).
    intervals : pandas.DataFrame or None
        The interval columns of the fits table (None without ``ci`` or ``bootstrap``).
    ranked_formulas : tuple of Formula
        The formulas the ranking covers.
    experiments : list of str
        The experiments, in batch order.
    n_successful : int
        The number of successful fits (of a streamed batch too, without refitting).
    """

    fits: tuple[CurveFit, ...]
    failures: dict[str, str] = field(default_factory=dict)
    formulas: tuple[Formula, ...] = ()
    notes: dict[str, tuple[str, ...]] = field(default_factory=dict)
    settings: FitSettings = field(default_factory=FitSettings)
    size_unit: str = ""
    inputs: tuple[TrompPoints, ...] = field(default=(), repr=False)
    balances: tuple[MassBalance, ...] = field(default=(), repr=False)
    intervals: pd.DataFrame | None = field(default=None, repr=False, compare=False)

    # the settings the batch was fitted with, read from its record
    rank_by = _from_settings("rank_by")
    alpha = _from_settings("alpha")
    rank_extended = _from_settings("rank_extended")
    water_recovery = _from_settings("water_recovery")
    ci = _from_settings("ci")
    bootstrap = _from_settings("bootstrap")
    bootstrap_method = _from_settings("bootstrap_method")
    seed = _from_settings("seed")
    partition_to = _from_settings("partition_to")

    def __setstate__(self, state: dict) -> None:
        state = dict(state)
        if "settings" not in state:  # pickled when the settings were fields of their own
            state["settings"] = FitSettings(**{name: state.pop(name) for name in _SETTINGS_READ if name in state})
        super().__setstate__(state)

    def fits_table(self, experiments=None) -> pd.DataFrame:
        """The table ``fits.csv`` holds: one row per experiment and formula (columns
        :data:`FIT_COLUMNS`; with a ``water_recovery`` also ``water_recovery`` and
        ``water_recovery_check``, the fitted bypass compared with it, see
        :mod:`tromplab.statistics.hydrocyclone`), with the interval columns when the batch
        was fitted with ``ci`` or ``bootstrap``, read as partition to ``partition_to``
        (:func:`tromplab.output.views.partition_view`); only the rows of ``experiments``
        (names) when given.

        A streamed batch (:func:`~tromplab.workbench.fit_to_folder`) reads the table from
        its folder's ``fits.csv`` (the types a CSV reader gives), except the rows of the
        first experiments, which it keeps as they were made."""
        run = self._spooled
        wanted = None if experiments is None else list(experiments)
        if run is None:
            table = self._output_frame
        elif wanted is not None and run.head is not None and set(wanted) <= set(run.head[1]["experiment"]):
            table = run.head[1]
        else:
            return run.read_table("fits", wanted)
        return (table if wanted is None else table[table["experiment"].isin(wanted)]).copy()

    @cached_property
    def _output_frame(self) -> pd.DataFrame:
        return output_view(self._fits_frame, self.intervals, self.inputs, self.partition_to)

    @cached_property
    def _fits_frame(self) -> pd.DataFrame:
        # built once: the ranking, the best fits, the CLI and the report all read it; the rows
        # of the fits were made by the workers that fitted them (_keep_fit_rows) where there were
        made = self.__dict__.pop("_fit_rows", None)
        settings = fit_row_settings(self.formulas, self.rank_extended, self.rank_by, self.water_recovery)
        return completed_fit_rows(
            fit_rows_frame(self.fits) if made is None else made, self.fits, **settings, failures=self.failures
        )

    @property
    def ranked_formulas(self) -> tuple[Formula, ...]:
        """The formulas the ranking covers: the paper's nine unless extended curves are ranked too."""
        return ranked_among(self.formulas, self.rank_extended)

    def best_fit(self, experiment: str) -> CurveFit | None:
        """The top-ranked successful fit of an experiment; among fits sharing the top rank
        (indistinguishable by the tie rule) the one with the lowest sum of squares."""
        best = (self._best_formulas if self._spooled is None else _best_formulas_of(self._rows_of(experiment))).get(experiment)
        if best is None:
            return None
        return next(f for f in self.fits_of(experiment) if f.formula.id == best)

    @cached_property
    def _best_formulas(self) -> dict[str, str]:
        # one pass over the table instead of a scan per experiment
        return _best_formulas_of(self._fits_frame)

    def top_ranked(self, experiment: str) -> pd.DataFrame:
        """Rows of the fits table that share the top rank of ``experiment`` (several when tied)."""
        table = self._fits_frame if self._spooled is None else self._rows_of(experiment)
        top = (self._top_rows if self._spooled is None else _top_rows_of(table)).get(experiment)
        return table.iloc[0:0] if top is None else top

    @cached_property
    def _top_rows(self) -> dict[str, pd.DataFrame]:
        # grouped once: a scan of the whole table per experiment is quadratic in the batch
        return _top_rows_of(self._fits_frame)

    def ranking_table(self, *, per_experiment: bool = True) -> pd.DataFrame:
        """Ranks per experiment, points and place per formula (failed experiments left out);
        with ``per_experiment=False`` only the equation, formula, points and place, which a
        streamed batch makes from its chunks' points without the table of every rank."""
        if per_experiment or self._spooled is None or self._spooled.ranks is None:
            table = self._ranking_frame
            return (table if per_experiment else table[["equation", "formula", "points", "place"]]).copy()
        return self._spooled.ranks.standings(self._equations)

    @property
    def _equations(self) -> dict:
        """Formula id -> equation number, of the batch's formulas."""
        return {formula.id: formula.equation for formula in self.formulas}

    @cached_property
    def _ranking_frame(self) -> pd.DataFrame:
        # built once: the results folder, the console and the report all read it
        if self._spooled is not None:
            ranking = self._spooled.ranking
        else:
            table = self._fits_frame
            table = table[~table["experiment"].isin(list(self.failures)) & table["rank"].notna()]
            ranking = None if table.empty else rank_formulas(table, by=self.rank_by, key="formula")
        if ranking is None:
            return pd.DataFrame(columns=["equation", "formula", "points", "place"])
        ranking = ranking.copy()
        ranking.insert(0, "equation", ranking["formula"].map(self._equations))
        return ranking.sort_values(["place", "equation"]).reset_index(drop=True)

    def verdicts(self, experiment: str) -> list[str]:
        """Plain-language statements on the fits of an experiment (:func:`tromplab.curves.ranking.fit_verdicts`)."""
        table = self._fits_frame if self._spooled is None else self._rows_of(experiment)
        fits = self.fits_of(experiment)
        sizes = (float(fits[0].points.size.min()), float(fits[0].points.size.max())) if fits else None
        return fit_verdicts(table[table["experiment"] == experiment], by=self.rank_by, measured_sizes=sizes)

    def fits_of(self, experiment: str) -> list[CurveFit]:
        """The fits of ``experiment`` in formula order (none for an experiment not fitted); a
        streamed batch refits the experiment (:meth:`fit`)."""
        if self._spooled is not None:
            return list(self._refitted(experiment))
        return list(self.fits_by_experiment().get(experiment, []))

    def fit(self, experiment: str, formula: str) -> CurveFit:
        """The fit of ``formula`` (its id) to ``experiment``.

        A streamed batch (:func:`~tromplab.workbench.fit_to_folder`) keeps no fit in memory:
        it fits the experiment again from its points with the batch's options and padding,
        which gives the fit the worker made (the fits of an experiment depend on its own
        points only).  Raises KeyError for an experiment or formula the batch did not fit.
        """
        for found in self.fits_of(experiment):
            if found.formula.id == formula:
                return found
        if experiment not in self.experiments:
            raise KeyError(f"no fitted experiment {experiment!r}")
        raise KeyError(f"no fit of formula {formula!r} in this batch; formulas: {', '.join(f.id for f in self.formulas)}")

    @property
    def n_successful(self) -> int:
        """The number of successful fits."""
        run = self._spooled
        return run.successes if run is not None else sum(fit.success for fit in self.fits)

    def fits_by_experiment(self) -> dict[str, list[CurveFit]]:
        """The fits grouped by experiment, in batch order."""
        return self._by_experiment

    @cached_property
    def _by_experiment(self) -> dict[str, list[CurveFit]]:
        return by_experiment(self.fits)

    @property
    def experiments(self) -> list[str]:
        """The fitted experiments, in batch order."""
        return list(self._spooled.fitted) if self._spooled is not None else list(self._by_experiment)

    # --- a streamed batch (fit_to_folder): the tables on disk, fits refitted when asked for -------
    @property
    def _spooled(self) -> SpooledRun | None:
        return self.__dict__.get("_spooled_run")

    def _attach_spooled_run(self, run: SpooledRun) -> None:
        self.__dict__["_spooled_run"] = run
        object.__setattr__(self, "fits", RebuiltFits(self))

    def _refitted(self, experiment: str) -> list[CurveFit]:
        run = self._spooled
        cache = self.__dict__.setdefault("_refits", {})
        if experiment not in cache:
            points = next((p for p in self.inputs if p.experiment == experiment), None) if experiment in run.fitted_set else None
            if len(cache) >= 64:
                cache.clear()
            cache[experiment] = run.refit([points]) if points is not None else []
        return cache[experiment]

    def _rows_of(self, experiment: str) -> pd.DataFrame:
        """The completed rows of one experiment (those of :meth:`fits_table` before its view):
        kept for the console's experiments, else made again from the refitted experiment."""
        run = self._spooled
        if run.head is not None and experiment in set(run.head[0]["experiment"]):
            rows = run.head[0]
            return rows[rows["experiment"] == experiment]
        fits = self.fits_of(experiment)
        rows = completed_rows(run.options, fit_rows_frame(fits), fits)
        return rows[rows["experiment"] == experiment]

    # --- readable views and saving (tromplab.output.results) ---------------------------------------
    def __repr__(self) -> str:
        return workbench_repr(self)

    def _repr_html_(self) -> str:
        return workbench_html(self)

    def averages(self, *, level: float | None = None, jobs: int | None = 1, client=None) -> pd.DataFrame:
        """Akaike-weighted d_cut, Ep and eta per experiment (:func:`model_averages`), with
        intervals at ``level`` (default: the batch's ``ci``, else 0.95); the table of ``averages.csv``.

        Computed once per level and kept; ``jobs`` and ``client`` spread the first
        computation over workers (the table is the same whatever they are).
        """
        level = averages_level(self.ci) if level is None else check_probability(level, "level")
        check_optional(check_count, jobs, "jobs", minimum=0, maximum=MAX_JOBS)
        if level not in self._averages_by_level and self._spooled is not None and level == averages_level(self.ci):
            return self._spooled.read_table("averages")
        if level not in self._averages_by_level:
            self._keep_averages(level, model_averages(self, level=level, jobs=jobs, client=client))
        return self._averages_by_level[level].copy()

    @cached_property
    def _averages_by_level(self) -> dict[float, pd.DataFrame]:
        return {}  # a frozen dataclass keeps caches in __dict__

    def _keep_from_workers(self, found: ChunkResults) -> None:
        """What the workers made beside the fits: the rows of the fits (the table
        :func:`fit_rows_frame` makes) and, where they made them, the model averages at the
        batch's level and the CSV text of both tables (:meth:`formatted_parts`)."""
        self.__dict__["_fit_rows"] = found.rows
        if found.averages is not None:
            self._keep_averages(averages_level(self.ci), found.averages)
        if found.csv_parts:
            self.__dict__["_csv_parts"] = found.csv_parts

    def formatted_parts(self, table: str) -> list[CsvPart] | None:
        """The rows of ``fits.csv`` (``table="fits"``) or ``averages.csv`` (``"averages"``, at the
        batch's level) as the workers formatted them, chunk by chunk (None where they did not):
        the results folder joins them instead of formatting the whole table again
        (:func:`tromplab.output.csv_parts.csv_from_parts`)."""
        return self.__dict__.get("_csv_parts", {}).get(table)

    def __getstate__(self) -> dict:
        # the formatted text is for writing this run's folder; a saved batch formats again; a
        # streamed batch's refitted experiments are a cache, made again when asked for
        return {key: value for key, value in super().__getstate__().items() if key not in ("_csv_parts", "_refits")}

    def _keep_averages(self, level: float, table: pd.DataFrame) -> None:
        self._averages_by_level[level] = with_survey_columns(table, self.inputs)

    def failure_table(self) -> pd.DataFrame:
        """``experiment, formula, reason`` of every experiment or fit that failed (``failures.csv``)."""
        rows = [{"experiment": e, "formula": "", "reason": reason} for e, reason in self.failures.items()]
        rows += [
            {"experiment": experiment, "formula": formula, "reason": message or "the fit failed"}
            for experiment, formula, message in self._failed_fits()
        ]
        return pd.DataFrame(rows, columns=["experiment", "formula", "reason"])

    def _failed_fits(self) -> list[tuple[str, str, str | None]]:
        """``(experiment, formula id, message)`` of each failed fit, in batch order."""
        if self._spooled is not None:
            return list(self._spooled.failed_fits)
        return [(fit.experiment, fit.formula.id, fit.fit.message) for fit in self.fits if not fit.success]

    def check_fitted(self, source: str = "") -> None:
        """Raise :class:`~tromplab.errors.InputError` when no formula could be fitted to any
        experiment (the command line then writes nothing and exits 1)."""
        if self.n_successful:
            return
        reasons = dict(self.failures)
        for experiment, formula, message in self._failed_fits():
            reasons.setdefault(experiment, f"{formula}: {message}")
        listed = "; ".join(f"{experiment}: {reason}" for experiment, reason in reasons.items())
        raise InputError(f"no formula could be fitted to any experiment ({listed})", source=str(source) or None)

    def plot(self, experiment: str | None = None, *, ax=None, **options):
        """Measured points and fitted curves of one experiment (the first by default),
        best fit thick with its band; ``options`` go to :func:`tromplab.output.plotting.plot_tromp_fits`.

        Returns the matplotlib Axes.
        """
        experiment = self.experiments[0] if experiment is None else experiment
        if experiment not in self.experiments:
            raise KeyError(f"no experiment {experiment!r}; experiments: {', '.join(self.experiments)}")
        return plot_tromp_fits(self.fits_of(experiment), ax=ax, best=self.best_fit(experiment), **options)

    def summary(self) -> pd.DataFrame:
        """One row per experiment: its top-ranked fit (columns of ``fits.csv``), ``tied`` (how
        many fits share the top rank) and ``reason`` (why an experiment has no ranked fit)."""
        return experiment_summary(self)

    def to_frame(self) -> pd.DataFrame:
        """The main table, ``fits.csv`` (:meth:`fits_table`)."""
        return self.fits_table()

    def _result_context(self) -> str:
        return workbench_repr(self)

    def report(self, path=None, **options) -> str | dict:
        """Text: the batch in a line, then the top-ranked fit of every experiment (:meth:`summary`).

        Writing the HTML report with ``report(path, ...)`` is deprecated: use
        :meth:`write_report`, which takes the same arguments.
        """
        if path is not None:
            warnings.warn(
                "Workbench.report(path) is deprecated and will write nothing in a future release: "
                "report() returns text; write_report(path) writes the HTML report",
                FutureWarning,
                stacklevel=2,
            )
            return self.write_report(path, **options)
        if options:
            raise TypeError(f"report() takes no options without a path: {', '.join(options)}")
        return summary_text(self)

    def write_report(
        self,
        path,
        *,
        balances=None,
        level: float | None = None,
        size_unit: str | None = None,
        title: str = "tromplab report",
        jobs: int | None = 1,
    ):
        """Write the HTML report (and its Markdown twin) to ``path``, as ``tromplab report`` does.

        ``balances`` (default: those the batch was read with, :func:`tromplab.read_experiments`),
        ``level`` (default: the batch's ``ci``, else 0.95) and ``size_unit`` (default: the
        batch's) as for the command; ``jobs`` worker processes draw the per-experiment
        figures (None or 0: all cores; the report is the same for any number).  Returns
        ``{file name: path}`` of the written files.
        """
        check_optional(check_probability, level, "level")
        check_optional(check_count, jobs, "jobs", minimum=0, maximum=MAX_JOBS)
        sources = dict.fromkeys(fit.points.source for fit in self.fits if fit.points.source)
        built = build_report(
            self,
            list(self.balances if balances is None else balances),
            source=", ".join(sources) or "data given in Python",
            level=(self.ci or 0.95) if level is None else level,
            size_unit=self.size_unit if size_unit is None else size_unit,
            title=title,
            partition_to=self.partition_to,
            map_work=functools.partial(_map_work, jobs=jobs or None, client=None),
        )
        return write_report(built, path)

    def save(
        self,
        directory,
        *,
        figures: str = "auto",
        format: str = "csv",
        excel: bool = False,
        reloadable: bool = False,
        jobs: int | None = 1,
    ):
        """Write the results folder, the same files as ``tromplab fit ... -o DIRECTORY``:
        ``fits``, ``ranking`` and ``averages`` tables, figures, ``failures.csv`` when fits
        failed, ``results.xlsx`` with ``excel`` (only the workbook when ``directory`` ends in
        ``.xlsx``); with ``reloadable`` also the pickled batch, so :func:`load` reads it back.
        ``jobs`` worker processes draw the per-experiment figures (None or 0: all cores; the
        files are the same for any number).  See
        :func:`tromplab.output.folder.write_results_folder`.  Returns ``{file name: path}``.
        """
        check_optional(check_count, jobs, "jobs", minimum=0, maximum=MAX_JOBS)
        if self._spooled is not None:
            return self._spooled.copy_folder(directory, figures=figures, format=format, excel=excel, reloadable=reloadable)
        return write_results_folder(
            self,
            directory,
            figures=figures,
            format=format,
            excel=excel,
            reloadable=reloadable,
            map_work=functools.partial(_map_work, jobs=jobs or None, client=None),
        )


def _best_formulas_of(table: pd.DataFrame) -> dict[str, str]:
    """The formula of each experiment's best fit in ``table`` (completed rows, see :meth:`Workbench.best_fit`)."""
    rows = table[table["success"] & table["rank"].notna()].sort_values(["rank", "ssr", "equation"], kind="stable")
    return dict(rows.drop_duplicates("experiment")[["experiment", "formula"]].itertuples(index=False))


def _top_rows_of(table: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The rows sharing each experiment's top rank in ``table`` (completed rows)."""
    rows = table[table["success"] & table["rank"].notna()]
    rows = rows[rows["rank"] == rows.groupby("experiment", sort=False)["rank"].transform("min")]
    return {experiment: group for experiment, group in rows.groupby("experiment", sort=False)}


#: How read_csv reads back exactly the floats the folder's CSV files hold: pandas 3 does by
#: default (and deprecates the argument), pandas 2 with its round-trip converter.
_EXACT_FLOATS = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}


@dataclass
class SpooledRun:
    """What a streamed batch (:func:`~tromplab.workbench.fit_to_folder`) keeps in memory instead
    of its fits: the results folder holding its tables, the options its chunks were fitted with
    (to refit an experiment), the fitted experiments, each failed fit's ``(experiment, formula,
    message)``, the count of successful fits, the ranking (:func:`rank_formulas` of the batch,
    None when nothing is ranked), the console's rows (completed rows and ``fits.csv`` rows of
    the first experiments), the main process's seconds per step and the written file names.
    The ranks are kept per chunk (:class:`~tromplab.workbench.spool.BatchRanks`, None when
    nothing is ranked), a few bytes per experiment, and made into the ranking table when it is
    first asked for (:attr:`ranking`)."""

    folder: Path
    options: ChunkOptions
    fitted: tuple[str, ...]
    failed_fits: tuple
    successes: int
    ranks: object | None
    head: tuple | None
    seconds: dict
    written: tuple[str, ...] = ()

    @cached_property
    def fitted_set(self) -> frozenset:
        return frozenset(self.fitted)

    @property
    def ranking(self) -> pd.DataFrame | None:
        """:func:`rank_formulas` of the batch (None when no fit is ranked)."""
        return None if self.ranks is None else self.ranks.frame()

    def refit(self, experiments) -> list[CurveFit]:
        """The fits of ``experiments`` (TrompPoints) as the batch's workers made them."""
        return self.options.refit(experiments)

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

    def copy_folder(self, directory, *, figures: str, format: str, excel: bool, reloadable: bool) -> dict[str, Path]:
        """:meth:`Workbench.save` of a streamed batch: the files of its folder copied (figures
        as the run drew them; none with ``figures="none"``).  What needs the fits in memory is
        refused with an :class:`~tromplab.errors.OptionError`."""
        for option, refused in (("format", format != "csv"), ("excel", excel), ("reloadable", reloadable),
                                ("figures", figures in ("all", "best"))):  # fmt: skip
            if refused or str(directory).lower().endswith(".xlsx"):
                raise OptionError(
                    option if refused else "directory",
                    "needs the fits in memory, which a streamed batch does not keep: fit again with stream=False",
                )
        source = Path(self.folder)
        names = [name for name in self.written if figures != "none" or not name.endswith(".png")]
        return replace_folder({name: (lambda p, name=name: shutil.copyfile(source / name, p)) for name in names}, directory)


class RebuiltFits(Sequence):
    """The fits of a streamed batch in batch order, each experiment refitted when read
    (:meth:`SpooledRun.refit`, a chunk of experiments at a time when iterated)."""

    def __init__(self, bench: Workbench):
        self._bench = bench

    def __len__(self) -> int:
        run = self._bench._spooled
        return len(run.fitted) * len(run.options.formulas)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        index = index + len(self) if index < 0 else index
        if not 0 <= index < len(self):
            raise IndexError("fit index out of range")
        run = self._bench._spooled
        per_experiment = len(run.options.formulas)
        return self._bench.fits_of(run.fitted[index // per_experiment])[index % per_experiment]

    def __iter__(self):
        run = self._bench._spooled
        points = {p.experiment: p for p in self._bench.inputs}
        for start in range(0, len(run.fitted), MAX_CHUNK_SIZE):
            yield from run.refit([points[name] for name in run.fitted[start : start + MAX_CHUNK_SIZE]])

    def __repr__(self) -> str:
        return f"<{len(self)} fits of a streamed batch, refitted when read>"


def load(directory) -> Workbench:
    """A batch saved by :meth:`Workbench.save` (refused when saved by another major version).

    Only load directories you trust: the batch is unpickled.

    Parameters
    ----------
    directory : str or path-like
        A directory written by :meth:`Workbench.save` with ``reloadable=True`` (the
        pickled batch and its manifest are written only then).
    """
    expect_kind(directory, (str, os.PathLike), "directory", "a path (str or path-like) to a saved results folder")
    return load_workbench(directory)


def model_averages(bench: Workbench, *, level: float = 0.95, jobs: int | None = 1, client=None) -> pd.DataFrame:
    """Akaike-weighted d_cut, Ep and eta per experiment (the formulas ranked by the batch).

    Parameters
    ----------
    bench : Workbench
    level : float
        Confidence level of the intervals, 0..1.
    jobs, client
        Spread the experiments over worker processes or a Dask cluster as
        :func:`fit_experiments` does; the table is the same whatever they are.

    Returns
    -------
    pandas.DataFrame
        ``experiment, quantity, value, stderr, low, high`` and ``weight_<formula>`` columns.

    """
    expect_kind(bench, Workbench, "bench", "a Workbench (tromplab.fit_experiments)")
    check_probability(level, "level")
    check_optional(check_count, jobs, "jobs", minimum=0, maximum=MAX_JOBS)
    groups = _averaged_groups(bench.fits_by_experiment().values(), [f.id for f in bench.ranked_formulas])
    chunks = chunked(groups, workers=_worker_count(jobs, client))
    logger.info("model averages of %d experiment(s) at level %g", len(groups), level)
    return _averages_table(
        [frame for chunk in _map_work(_averages_of_chunk, chunks, level, jobs=jobs, client=client) for frame in chunk]
    )
