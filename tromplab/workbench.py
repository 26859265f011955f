"""Batch fitting: every formula to every experiment, screened and ranked.

A failing formula gives a failed :class:`~tromplab.curves.CurveFit`; a failing
experiment (too few points, say) is recorded in ``failures`` and skipped by the
ranking.  Neither stops the batch.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd

from .curves import CurveFit, fit_formula
from .fitting import ParameterFit, ParameterSpec
from .formulas import Formula, select_formulas
from .points import TrompPoints
from .ranking import add_ranks, rank_formulas
from .screening import DEFAULT_ALPHA
from .validation import check_optional, check_positive, check_probability

#: Columns of ``fits.csv``, in order.
FIT_COLUMNS = (
    "experiment", "equation", "formula", "n", "d_cut", "d_cut_stderr", "shape_name", "shape", "shape_stderr",
    "ssr", "F", "F_crit", "adequate", "rank", "eta", "epsilon", "slope", "d25", "d75", "ep", "imperfection",
    "aic", "aicc", "bic", "bypass", "fishhook", "runs_p", "normality_p", "x_break", "success", "message", "warnings",
)  # fmt: skip


@dataclass(frozen=True)
class Workbench:
    """All fits of a batch with their tables."""

    fits: tuple[CurveFit, ...]
    failures: dict[str, str] = field(default_factory=dict)
    formulas: tuple[Formula, ...] = ()
    rank_by: str = "F"
    alpha: float = DEFAULT_ALPHA
    rank_extended: bool = False
    notes: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def fits_table(self) -> pd.DataFrame:
        """One row per experiment and formula (columns :data:`FIT_COLUMNS`)."""
        return self._fits_frame.copy()

    @cached_property
    def _fits_frame(self) -> pd.DataFrame:
        # built once: the ranking, the best fits, the CLI and the report all read it
        rows = [fit.row() for fit in self.fits]
        for experiment, reason in self.failures.items():
            for formula in self.formulas:
                rows.append({"experiment": experiment, "equation": formula.equation, "formula": formula.id,
                             "shape_name": formula.shape_name, "adequate": False, "success": False,
                             "message": reason})  # fmt: skip
        table = pd.DataFrame(rows).reindex(columns=[c for c in FIT_COLUMNS if c != "rank"])
        table["adequate"] = table["adequate"].astype(bool)
        table["success"] = table["success"].astype(bool)
        in_ranking = table["formula"].isin([f.id for f in self.ranked_formulas])
        ranked = add_ranks(table[in_ranking], by=self.rank_by)
        table["rank"] = ranked["rank"]  # curves kept out of the ranking get no rank
        table.loc[table["experiment"].isin(list(self.failures)), "rank"] = np.nan
        return table.reindex(columns=list(FIT_COLUMNS))

    @property
    def ranked_formulas(self) -> tuple[Formula, ...]:
        """The formulas the ranking covers: the paper's nine unless extended curves are ranked too."""
        return tuple(f for f in self.formulas if self.rank_extended or f.family == "paper")

    def best_fit(self, experiment: str) -> CurveFit | None:
        """The top-ranked successful fit of an experiment."""
        table = self._fits_frame
        rows = table[(table["experiment"] == experiment) & table["success"] & table["rank"].notna()]
        if rows.empty:
            return None
        best = rows.sort_values("rank").iloc[0]["formula"]
        return next(f for f in self.fits_of(experiment) if f.formula.id == best)

    def ranking_table(self) -> pd.DataFrame:
        """Ranks per experiment, points and place per formula (failed experiments left out)."""
        table = self._fits_frame
        table = table[~table["experiment"].isin(list(self.failures)) & table["rank"].notna()]
        if table.empty:
            return pd.DataFrame(columns=["equation", "formula", "points", "place"])
        ranking = rank_formulas(table, by=self.rank_by, key="formula")
        equation = {f.id: f.equation for f in self.formulas}
        ranking.insert(0, "equation", ranking["formula"].map(equation))
        return ranking.sort_values(["place", "equation"]).reset_index(drop=True)

    def fits_of(self, experiment: str) -> list[CurveFit]:
        return [fit for fit in self.fits if fit.experiment == experiment]

    @property
    def experiments(self) -> list[str]:
        return list(dict.fromkeys(fit.experiment for fit in self.fits))


def fit_experiments(
    experiments: Sequence[TrompPoints],
    *,
    formulas=None,
    alpha: float = DEFAULT_ALPHA,
    delta_max: float | None = None,
    rank_by: str = "F",
    rank_extended: bool = False,
    progress: Callable[[int, int, str], None] | None = None,
) -> Workbench:
    """Fit, screen and rank ``formulas`` (default: all nine) on each experiment.

    Parameters
    ----------
    experiments : sequence of TrompPoints
    formulas : iterable of ids or equation numbers, optional
    alpha : float
        Significance level of the Fisher screen.
    delta_max : float, optional
        Largest feed size for the misplacement index; default per experiment, its
        ``delta_max`` if known, else its largest size.
    rank_by : {"F", "aicc"}
    rank_extended : bool
        Rank the extended curves (bypass, fish-hook) with the nine; by default they are
        fitted and reported but kept out of the paper's ranking.
    progress : callable, optional
        Called as ``progress(i, total, experiment)`` before each experiment.
    """
    check_probability(alpha, "alpha")
    check_optional(check_positive, delta_max, "delta_max")
    chosen = select_formulas(formulas)
    fits, failures, notes = [], {}, {}
    for i, points in enumerate(experiments):
        if progress is not None:
            progress(i + 1, len(experiments), points.experiment)
        if points.n <= 2:
            failures[points.experiment] = (
                f"experiment '{points.experiment}' has {points.n} points; the Fisher screen needs at least 3"
            )
            continue
        if np.ptp(points.partition_fine) == 0:  # F = 0/0: no curve can be told from another
            failures[points.experiment] = (
                f"experiment '{points.experiment}' is flat: every partition equals {points.partition_fine[0]:g}, "
                "so there is no cut to fit and the Fisher screen is undefined (0/0)"
            )
            continue
        notes[points.experiment] = data_notes(points)
        for formula in chosen:
            fits.append(_fit_guarded(points, formula, alpha, delta_max))
    return Workbench(tuple(fits), failures, chosen, rank_by, alpha, rank_extended, {k: v for k, v in notes.items() if v})


def data_notes(points: TrompPoints) -> tuple[str, ...]:
    """Warnings about the measured points themselves, before any fit."""
    from scipy import stats

    notes = []
    if points.n >= 3 and np.ptp(points.partition_fine) > 0:
        rho = stats.spearmanr(points.size, points.partition_fine).statistic
        if rho > 0.5:
            notes.append(f"the partition to fines rises with size (Spearman {rho:.2f}): is the column the partition to the "
                         "coarse product? (use partition_coarse)")  # fmt: skip
    if np.all(points.partition_fine > 0.5) or np.all(points.partition_fine < 0.5):
        side = "above" if points.partition_fine[0] > 0.5 else "below"
        notes.append(f"every point lies {side} 1/2: the cut size is extrapolated beyond the measured sizes")
    return tuple(notes)


def model_averages(bench: Workbench, *, level: float = 0.95) -> pd.DataFrame:
    """Akaike-weighted d_cut, Ep and eta per experiment (the formulas ranked by the batch)."""
    from .uncertainty import model_average

    frames = []
    for experiment in bench.experiments:
        fits = [f for f in bench.fits_of(experiment) if f.success and f.formula in bench.ranked_formulas]
        if fits:
            frames.append(model_average(fits, level=level).assign(experiment=experiment))
    if not frames:
        return pd.DataFrame()
    table = pd.concat(frames, ignore_index=True)
    return table[["experiment", *[c for c in table.columns if c != "experiment"]]]


def _fit_guarded(points, formula, alpha, delta_max) -> CurveFit:
    try:
        return fit_formula(points, formula, alpha=alpha, delta_max=delta_max)
    except Exception as error:  # a batch reports a broken fit instead of stopping
        specs = [ParameterSpec("d_cut"), ParameterSpec(formula.shape_name)]
        failed = ParameterFit.failed(specs, points.n, f"{type(error).__name__}: {error}")
        return CurveFit(formula=formula, points=points, fit=failed)


def print_progress(i: int, total: int, experiment: str) -> None:
    """Progress line on standard error (for batches of more than one experiment)."""
    if total > 1:
        print(f"[{i}/{total}] fitting experiment {experiment}", file=sys.stderr, flush=True)


def write_atomically(outputs: dict[str, Callable[[Path], None]], outdir) -> dict[str, Path]:
    """Write every output to a temporary file first, then move them all into ``outdir``.

    ``outputs`` maps file names to writers taking a path.  If any writer fails, nothing
    is left in ``outdir``.  For a whole output folder that replaces the previous run in
    one step, see :func:`tromplab.outputs.replace_folder`.
    """
    from .outputs import write_files

    return write_files(outputs, outdir)
