"""The result of a batch: :class:`Workbench` (every fit with its fits, ranking and averages
tables, figures, report and results folder), :func:`load` of a saved batch, and
:func:`model_averages` of a batch spread over workers.
"""

from __future__ import annotations

import functools
import logging
import os
import warnings
from dataclasses import InitVar, dataclass, field
from functools import cached_property

import pandas as pd

from ..curves.curve_fit import CurveFit
from ..curves.formulas import Formula
from ..curves.ranking import fit_verdicts
from ..errors import InputError, expect_kind
from ..loading.lab import MassBalance
from ..loading.points import TrompPoints
from ..loading.surveys import with_survey_columns
from ..notices import Notice, notice_table
from ..output.csv_parts import CsvPart
from ..output.plotting import plot_tromp_fits
from ..output.report import build_report, write_report
from ..output.results import experiment_summary, load_workbench, summary_text, workbench_html, workbench_repr
from ..parallel import chunked, map_on_workers, worker_count
from ..results_contract import ResultContract
from ..validation import MAX_JOBS, FitSettings, check_count, check_optional, check_probability
from .averages import averaged_groups, averages_level, averages_of_chunk, averages_table
from .chunks import ChunkResults
from .inputs import batch_notices
from .store import FitsInMemory, FitStore
from .tables import ranked_among

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

    The workbench reads its fits and their tables through its ``store``
    (:class:`~tromplab.workbench.store.FitStore`): every fit in memory
    (:class:`~tromplab.workbench.store.FitsInMemory`), or, for a batch streamed to disk
    (:func:`~tromplab.workbench.fit_to_folder`, from :data:`~tromplab.workbench.STREAM_THRESHOLD`
    experiments), none (:class:`~tromplab.workbench.store.FitsOnDisk`): its ``fits`` is a
    sequence that refits the experiments when read, its tables come from its results folder,
    and :meth:`fit` refits one experiment (docs/performance.md, "Large batches").  The batch
    layer makes a workbench with ``made``, what the workers made beside the fits (the rows of
    the fits table, the model averages at the batch's level, the CSV text of both tables),
    which the store and the workbench keep instead of making them again.

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
    store : FitStore
        Where the fits and their tables are read (default: :class:`FitsInMemory` of ``fits``).
    ranked_formulas : tuple of Formula
        The formulas the ranking covers.
    experiments : list of str
        The experiments, in batch order.
    equations : dict
        Formula id -> equation number, of the batch's formulas.
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
    store: FitStore | None = field(default=None, repr=False, compare=False)
    made: InitVar[ChunkResults | None] = None

    def __post_init__(self, made: ChunkResults | None) -> None:
        if self.store is None:
            object.__setattr__(self, "store", FitsInMemory(self, None if made is None else made.rows))
        if made is not None and made.averages is not None:
            self._keep_averages(averages_level(self.ci), made.averages)
        if made is not None and made.csv_parts:
            self.__dict__["_csv_parts"] = made.csv_parts

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
        if self.__dict__.get("store") is None:  # pickled before the fits were read through a store
            object.__setattr__(self, "store", FitsInMemory(self, state.get("_fit_rows")))

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
        return self.store.fits_table(None if experiments is None else list(experiments))

    @property
    def ranked_formulas(self) -> tuple[Formula, ...]:
        """The formulas the ranking covers: the paper's nine unless extended curves are ranked too."""
        return ranked_among(self.formulas, self.rank_extended)

    def best_fit(self, experiment: str) -> CurveFit | None:
        """The top-ranked successful fit of an experiment; among fits sharing the top rank
        (indistinguishable by the tie rule) the one with the lowest sum of squares."""
        best = self.store.best_formula(experiment)
        if best is None:
            return None
        return next(f for f in self.fits_of(experiment) if f.formula.id == best)

    def top_ranked(self, experiment: str) -> pd.DataFrame:
        """Rows of the fits table that share the top rank of ``experiment`` (several when tied)."""
        top = self.store.top_rows(experiment)
        return self.store.experiment_rows(experiment).iloc[0:0] if top is None else top

    def ranking_table(self, *, per_experiment: bool = True) -> pd.DataFrame:
        """Ranks per experiment, points and place per formula (failed experiments left out);
        with ``per_experiment=False`` only the equation, formula, points and place, which a
        streamed batch makes from its chunks' points without the table of every rank."""
        standings = None if per_experiment else self.store.standings(self.equations)
        if standings is not None:
            return standings
        table = self._ranking_frame
        return (table if per_experiment else table[["equation", "formula", "points", "place"]]).copy()

    @property
    def equations(self) -> dict[str, int]:
        """Formula id -> equation number, of the batch's formulas."""
        return {formula.id: formula.equation for formula in self.formulas}

    @cached_property
    def _ranking_frame(self) -> pd.DataFrame:
        # built once: the results folder, the console and the report all read it
        ranking = self.store.ranking()
        if ranking is None:
            return pd.DataFrame(columns=["equation", "formula", "points", "place"])
        ranking = ranking.copy()
        ranking.insert(0, "equation", ranking["formula"].map(self.equations))
        return ranking.sort_values(["place", "equation"]).reset_index(drop=True)

    def verdicts(self, experiment: str) -> list[str]:
        """Plain-language statements on the fits of an experiment (:func:`tromplab.curves.ranking.fit_verdicts`)."""
        table = self.store.experiment_rows(experiment)
        fits = self.fits_of(experiment)
        sizes = (float(fits[0].points.size.min()), float(fits[0].points.size.max())) if fits else None
        return fit_verdicts(table[table["experiment"] == experiment], by=self.rank_by, measured_sizes=sizes)

    def fits_of(self, experiment: str) -> list[CurveFit]:
        """The fits of ``experiment`` in formula order (none for an experiment not fitted); a
        streamed batch refits the experiment (:meth:`fit`)."""
        return self.store.fits_of(experiment)

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
        return self.store.n_successful()

    def fits_by_experiment(self) -> dict[str, list[CurveFit]]:
        """The fits grouped by experiment, in batch order."""
        return self.store.fits_by_experiment()

    @property
    def experiments(self) -> list[str]:
        """The fitted experiments, in batch order."""
        return self.store.experiments()

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
        if level not in self._averages_by_level and (written := self.store.averages_read(level)) is not None:
            return written
        if level not in self._averages_by_level:
            self._keep_averages(level, model_averages(self, level=level, jobs=jobs, client=client))
        return self._averages_by_level[level].copy()

    @cached_property
    def _averages_by_level(self) -> dict[float, pd.DataFrame]:
        return {}  # a frozen dataclass keeps caches in __dict__

    def formatted_parts(self, table: str) -> list[CsvPart] | None:
        """The rows of ``fits.csv`` (``table="fits"``) or ``averages.csv`` (``"averages"``, at the
        batch's level) as the workers formatted them, chunk by chunk (None where they did not):
        the results folder joins them instead of formatting the whole table again
        (:func:`tromplab.output.csv_parts.csv_from_parts`)."""
        return self.__dict__.get("_csv_parts", {}).get(table)

    def __getstate__(self) -> dict:
        # the formatted text is for writing this run's folder; a saved batch formats again
        return {key: value for key, value in super().__getstate__().items() if key != "_csv_parts"}

    def _keep_averages(self, level: float, table: pd.DataFrame) -> None:
        self._averages_by_level[level] = with_survey_columns(table, self.inputs)

    def failure_table(self) -> pd.DataFrame:
        """``experiment, formula, reason`` of every experiment or fit that failed (``failures.csv``)."""
        rows = [{"experiment": e, "formula": "", "reason": reason} for e, reason in self.failures.items()]
        rows += [
            {"experiment": experiment, "formula": formula, "reason": message or "the fit failed"}
            for experiment, formula, message in self.store.failed_fits()
        ]
        return pd.DataFrame(rows, columns=["experiment", "formula", "reason"])

    def notices(self) -> list[Notice]:
        """Every warning of the batch, one :class:`~tromplab.notices.Notice` per experiment and
        kind: the notes of the mass balances (with the classes left out) and the notes on the
        points, experiment by experiment in batch order; :meth:`warnings_table` as records."""
        return batch_notices([*self.experiments, *self.failures], self.balances, self.notes)

    def warnings_table(self) -> pd.DataFrame:
        """``experiment, formula, code, message`` of every warning of the batch (``warnings.csv``;
        the codes: :data:`tromplab.notices.WARNING_KINDS`, docs/outputs.md)."""
        return notice_table(self.notices())

    def check_fitted(self, source: str = "") -> None:
        """Raise :class:`~tromplab.errors.InputError` when no formula could be fitted to any
        experiment (the command line then writes nothing and exits 1)."""
        if self.n_successful:
            return
        reasons = dict(self.failures)
        for experiment, formula, message in self.store.failed_fits():
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
        progress=None,
    ):
        """Write the HTML report (and its Markdown twin) to ``path``, as ``tromplab report`` does.

        ``balances`` (default: those the batch was read with, :func:`tromplab.read_experiments`),
        ``level`` (default: the batch's ``ci``, else 0.95) and ``size_unit`` (default: the
        batch's) as for the command; ``jobs`` worker processes draw the per-experiment
        figures (None or 0: all cores; the report is the same for any number); ``progress(done,
        total, label)`` is told as they are drawn (``"figures: ..."``).  Returns ``{file name:
        path}`` of the written files.
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
            map_work=functools.partial(map_on_workers, jobs=jobs or None, client=None),
            progress=progress,
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
        return self.store.save(self, directory, figures=figures, format=format, excel=excel, reloadable=reloadable, jobs=jobs)


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
    groups = averaged_groups(bench.fits_by_experiment().values(), [f.id for f in bench.ranked_formulas])
    chunks = chunked(groups, workers=worker_count(jobs, client))
    logger.info("model averages of %d experiment(s) at level %g", len(groups), level)
    return averages_table(
        [frame for chunk in map_on_workers(averages_of_chunk, chunks, level, jobs=jobs, client=client) for frame in chunk]
    )
