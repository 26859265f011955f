"""Batch fitting: every formula to every experiment, screened and ranked
(:func:`fit_experiments`, what ``tromplab fit`` does, with its options as keywords).

A failing formula gives a failed :class:`~tromplab.curves.curve_fit.CurveFit`; a failing
experiment (too few points, say) is recorded in ``failures`` and skipped by the
ranking.  Neither stops the batch.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import NamedTuple

from ..curves.curve_fit import check_delta_max
from ..curves.engine import check_bootstrap_request
from ..curves.formulas import select_formulas
from ..curves.screening import DEFAULT_ALPHA
from ..errors import OptionError
from ..parallel import dask_client
from ..validation import FitSettings
from .chunks import fit_in_chunks
from .inputs import ExperimentsInPieces, FittableInPieces, data_size_unit, points_and_balances, screenable
from .result import Workbench
from .tables import ranked_among
from .worker import ChunkOptions


def fit_experiments(
    experiments,
    *,
    formulas=None,
    extended: bool = False,
    alpha: float = DEFAULT_ALPHA,
    delta_max: float | None = None,
    rank_by: str = "F",
    rank_extended: bool = False,
    size_unit: str = "",
    water_recovery: float | None = None,
    partition_to: str = "fine",
    ci: float | None = None,
    bootstrap: int = 0,
    bootstrap_method: str = "residuals",
    seed: int = 0,
    jobs: int | None = 1,
    scheduler: str | None = None,
    dask: str | None = None,
    client=None,
    single_fits: bool = False,
    progress: Callable[[int, int, str], None] | None = None,
) -> Workbench:
    """Fit, screen and rank ``formulas`` (default: all nine) on each experiment: what
    ``tromplab fit`` does, with its options as keywords of the same names.

    Parameters
    ----------
    experiments : path, DataFrame, Experiments, mapping or iterable of TrompPoints
        A points file or lab table (path) or a pandas DataFrame of one, read by
        :func:`tromplab.read_experiments` with its defaults; what that function returns (its mass
        balances kept for the report and workbook); a Dask DataFrame of points (columns
        ``experiment, size, partition_fine[, weight]``); a mapping of experiment name (str) to
        its ``TrompPoints`` (renamed to the key), to a DataFrame of its points or to a
        ``(sizes, partitions)`` pair; or an iterable of ``TrompPoints``.  Two experiments of one
        name, or none at all, are an :class:`~tromplab.errors.InputError`; anything else is a
        ``TypeError`` saying what is accepted.
    formulas : str or iterable of ids or equation numbers, optional
        ``"paper"``: the nine; ``"extended"``: the bypass and fish-hook curves; ``"other"``: other tools' curves.
    extended, rank_extended : bool
        Also fit the extended curves (reported, kept out of the ranking); rank them with the nine.
    alpha : float
        Significance level of the Fisher screen, in (0, 1).
    delta_max : float, optional
        Largest feed size for the misplacement index (default per experiment: its
        ``delta_max`` if known, else its largest size).
    rank_by : {"F", "aicc"}
    size_unit : str
        Unit of the sizes, for labels and records (the unit the loader found in the column names wins
        when all experiments share one).
    water_recovery : float, optional
        Hydrocyclones: share of the feed water reporting to the underflow, in [0, 1).  The formulas are
        still fitted to the actual partition; the fits table gains ``water_recovery`` and ``water_recovery_check``
        (the fitted bypass against it, :func:`tromplab.statistics.hydrocyclone.bypass_against_water_recovery`).
    partition_to : {"fine", "coarse"}
        Product whose partition the tables and figures show (the fits are the same).
    ci : float, optional
        Add interval columns at this level (profile likelihood for the parameters, the
        delta method for the indices); also the level of the model averages (default 0.95).
    bootstrap, seed : int
        Add bootstrap percentile intervals from ``bootstrap`` resamples (0: none), drawn by
        ``bootstrap_method`` from ``seed`` (the same seed gives the same intervals).
    bootstrap_method : {"residuals", "cases"}
    jobs : int or None
        Worker processes (None or 0: all cores).  The experiments are cut into chunks
        (:func:`chunked`) that are padded alike, so the results are identical for any number.
    scheduler, dask, client : optional
        Run the chunks on Dask: on the scheduler at ``scheduler`` (``tcp://host:8786``), on a
        local cluster of two workers (``dask="local"``) or on ``client`` (a ``dask.distributed.Client``).
    single_fits : bool
        Fit one experiment and formula at a time with lmfit
        (:func:`tromplab.curves.curve_fit.fit_formula`) instead of the batched engine.
    progress : callable, optional
        Called as ``progress(done, total, label)`` as experiments are fitted, then (with
        ``ci`` or ``bootstrap``) as fits get their intervals (labels ``"intervals: ..."``).

    Returns
    -------
    Workbench
        Every fit, with the fits, ranking and averages tables; never raises for a failing
        fit.  ``bench.save(DIR)`` writes what ``tromplab fit ... -o DIR`` writes.

    Examples
    --------
    >>> from tromplab import TrompPoints
    >>> points = TrompPoints("run", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])
    >>> bench = fit_experiments([points], formulas=["plitt", "lognormal", "molerus"])
    >>> bench.ranking_table()[["formula", "place"]].values.tolist()
    [['plitt', 1], ['lognormal', 2], ['molerus', 3]]
    """
    settings = FitSettings(
        formulas=formulas, extended=extended, alpha=alpha, delta_max=delta_max, rank_by=rank_by,
        rank_extended=rank_extended, size_unit=size_unit, water_recovery=water_recovery, partition_to=partition_to,
        ci=ci, bootstrap=bootstrap, bootstrap_method=bootstrap_method, seed=seed, jobs=jobs, scheduler=scheduler,
        dask=dask, single_fits=single_fits,
    )  # fmt: skip
    return fit_with_settings(experiments, settings, client=client, progress=progress)


def fit_with_settings(experiments, settings: FitSettings, *, client=None, progress=None) -> Workbench:
    """:func:`fit_experiments` with its settings as one record (what the command line passes).

    Parameters
    ----------
    experiments
        As for :func:`fit_experiments`.
    settings : FitSettings
        The settings of the fit (:class:`tromplab.validation.FitSettings`), checked when made.
    client, progress
        As for :func:`fit_experiments`.

    Returns
    -------
    Workbench
    """
    return fit_prepared(prepared_batch(experiments, settings), client=client, progress=progress)


def fit_prepared(plan: PreparedBatch, *, client=None, progress=None) -> Workbench:
    """:func:`fit_experiments` of a :func:`prepared_batch`, the fits kept in memory."""
    settings = plan.settings
    with dask_client(scheduler=settings.scheduler, dask=settings.dask, client=client) as cluster:
        found = fit_in_chunks(plan.fittable, plan.options, jobs=settings.jobs, client=cluster, progress=progress)
        return batch_workbench(plan, tuple(found.fits), found.notes, found.intervals, made=found)


class PreparedBatch(NamedTuple):
    """A batch checked and ready to fit (:func:`prepared_batch`): its experiments and mass
    balances, the chosen formulas, its settings, the experiments the screen cannot judge
    (``failures``), the others (``fittable``) and the options of every chunk (the settings
    with what the batch adds: the formulas' ids, the unit of the sizes, ...)."""

    experiments: list
    balances: tuple
    chosen: tuple
    settings: FitSettings
    failures: dict
    fittable: list
    options: ChunkOptions


def prepared_batch(experiments, settings: FitSettings, *, in_pieces: bool = False) -> PreparedBatch:
    """``experiments`` read and checked against ``settings`` (what only the data can say:
    ``delta_max`` against the sizes, the bootstrap's work against the number of fits, the
    formulas against the registry), before any fit (an :class:`~tromplab.errors.OptionError`
    names a wrong option).  With ``in_pieces``, an :class:`ExperimentsInPieces` is read once for
    its :func:`census` and stays on disk: its ``experiments`` is the source and its ``fittable``
    a :class:`FittableInPieces`."""
    if in_pieces and isinstance(experiments, ExperimentsInPieces):
        found = experiments.census()
        balances = tuple(experiments.balances)
        checked, n_experiments = list(found.smallest), found.total
        size_unit = next(iter(found.units)) if len(found.units) == 1 else settings.size_unit
        failures, fittable = found.failures, FittableInPieces(experiments, found)
    else:
        experiments, balances = points_and_balances(experiments)
        checked, n_experiments = experiments, len(experiments)
        size_unit = data_size_unit(experiments, settings.size_unit)
        failures, fittable = screenable(experiments)
    chosen = select_formulas(check_formula_selection(settings.formulas, settings.extended))
    _check_against_data(settings, checked, n_fits=n_experiments * len(chosen))
    options = ChunkOptions(
        settings=settings,
        formulas=tuple(f.id for f in chosen),
        ranked=tuple(f.id for f in ranked_among(chosen, settings.rank_extended)),
        size_unit=size_unit,
    )
    return PreparedBatch(experiments, balances, tuple(chosen), settings, failures, fittable, options)


def batch_workbench(plan: PreparedBatch, fits, notes, intervals, *, store=None, made=None) -> Workbench:
    """The :class:`Workbench` of a fitted batch: its fits in memory with what the workers
    ``made`` beside them (:class:`~tromplab.workbench.chunks.ChunkResults`), or read through ``store``."""
    return Workbench(
        fits, plan.failures, plan.chosen, notes, plan.settings, plan.options.size_unit, batch_inputs(plan), plan.balances,
        intervals, store, made,
    )  # fmt: skip


def batch_inputs(plan: PreparedBatch):
    """The points of the batch's experiments, as a :class:`Workbench` keeps them."""
    return plan.experiments if isinstance(plan.experiments, ExperimentsInPieces) else tuple(plan.experiments)


def check_formula_selection(formulas=None, extended: bool = False):
    """The selection :func:`formula_keys` makes, refused with an
    :class:`~tromplab.errors.OptionError` naming ``formulas`` when it names an unknown formula."""
    if isinstance(formulas, (list, tuple, set, frozenset)) and not formulas:
        raise OptionError("formulas", "names no formula; leave it out (None) for the nine formulas")
    if isinstance(formulas, str) and not formulas.replace(",", "").strip():
        raise OptionError("formulas", f"names no formula, got {formulas!r}")
    keys = formula_keys(formulas, extended)
    try:
        select_formulas(keys)
    except KeyError as error:
        raise OptionError("formulas", f"names an {error.args[0]}") from None
    return keys


def formula_keys(formulas=None, extended: bool = False):
    """The formula selection of ``formulas`` plus the extended curves when ``extended``
    (``formulas`` default: the nine), as :func:`tromplab.curves.formulas.select_formulas` reads it."""
    if not extended:
        return formulas
    keys = formulas if formulas is not None else "paper"
    keys = keys if isinstance(keys, str) else ",".join(str(key) for key in keys)
    return keys if "extended" in keys else f"{keys},extended"


def _check_against_data(settings: FitSettings, experiments, *, n_fits: int) -> None:
    """What of ``settings`` only the data can check: ``delta_max`` against the sizes of
    ``experiments``, the bootstrap's work against the ``n_fits`` fits (an
    :class:`~tromplab.errors.OptionError` names the option), before any fitting."""
    if settings.delta_max is not None:  # refused before any fitting, not in each fit
        check_delta_max(settings.delta_max, experiments)
    if settings.bootstrap:
        try:
            check_bootstrap_request(settings.bootstrap, n_fits=n_fits)
        except ValueError as error:  # too much work for these data, said before any fitting
            raise OptionError("bootstrap", str(error).removeprefix("--bootstrap ")) from None


def print_progress(i: int, total: int, experiment: str) -> None:
    """Progress line on standard error (for batches of more than one experiment)."""
    if total > 1:
        print(f"[{i}/{total}] fitting experiment {experiment}", file=sys.stderr, flush=True)
