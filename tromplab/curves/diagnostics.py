"""Residual diagnostics of a fitted curve.

A curve can pass the Fisher screen while missing the data systematically (residuals
that stay on one side of the curve over a range of sizes).  Two checks are reported for
every fit:

* the Wald-Wolfowitz runs test on the signs of the residuals ordered by size
  (statsmodels ``runstest_1samp``, cut-off 0, small-sample correction): few runs mean
  systematic deviations;
* the Shapiro-Wilk test of normality of the residuals (scipy), which the F test assumes.

A fit exact to rounding (root-mean-square residual below :data:`EXACT_FIT_RMS`, in
partition units) gives neither test anything to work on: the signs and the shape of
residuals at the level of floating-point and solver noise carry no information about the
curve, so both p-values are nan and the verdict is ``"exact"`` instead of an alarm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from .screening import EXACT_FIT_RMS

SYSTEMATIC_P = 0.05
#: Start of the warning of a fit adequate by F whose residuals fail a test.
RESIDUAL_WARNING = "adequate by F but the residuals"


@dataclass(frozen=True)
class ResidualDiagnostics:
    """p-values of the runs and normality tests (nan where a test cannot be run).

    ``alpha`` is the level below which a p-value counts as evidence; ``exact`` is True for
    a fit exact to rounding, whose residuals are not tested.
    """

    runs_p: float
    normality_p: float
    n_runs: int
    alpha: float = SYSTEMATIC_P
    exact: bool = False

    @property
    def systematic(self) -> bool:
        """Too few runs of signs: the curve misses the data over ranges of sizes."""
        return bool(np.isfinite(self.runs_p) and self.runs_p < self.alpha)

    @property
    def non_normal(self) -> bool:
        """The residuals are not normal (Shapiro-Wilk), as the F test assumes they are."""
        return bool(np.isfinite(self.normality_p) and self.normality_p < self.alpha)

    @property
    def verdict(self) -> str:
        """One phrase for tables: ``exact``, ``systematic``, ``not normal``, both, or ``random``."""
        if self.exact:
            return "exact"
        found = [word for word, flagged in (("systematic", self.systematic), ("not normal", self.non_normal)) if flagged]
        return ", ".join(found) or "random"


def _signs(residuals: np.ndarray) -> np.ndarray:
    """Signs of the residuals for the runs test; residuals below :data:`EXACT_FIT_RMS` count
    as zero: their signs follow rounding (a partition of 1e-274 against a curve of 1e-300),
    and they moved the runs test's p-value from 1.0 to 0.91 with the size unit."""
    return np.sign(residuals[np.abs(residuals) >= EXACT_FIT_RMS])


def residual_diagnostics(residuals, *, alpha: float = SYSTEMATIC_P) -> ResidualDiagnostics:
    """Runs test and normality test of residuals given in order of increasing size.

    Parameters
    ----------
    residuals : array_like
        Residuals (partition units) ordered by size.
    alpha : float
        Level of both tests.

    Examples
    --------
    >>> d = residual_diagnostics([0.1, 0.2, 0.1, 0.2, 0.3, 0.1, -0.1, -0.2, -0.1, -0.2, -0.3, -0.1])
    >>> d.n_runs, d.systematic
    (2, True)
    >>> residual_diagnostics([1e-15, -2e-16, 3e-16, 5e-16, -1e-16]).verdict
    'exact'
    """
    from statsmodels.sandbox.stats.runs import runstest_1samp

    residuals = np.asarray(residuals, dtype=float)
    signs = _signs(residuals)
    n_runs = int(1 + np.count_nonzero(np.diff(signs))) if signs.size else 0
    if residuals.size and np.sqrt(np.mean(residuals**2)) < EXACT_FIT_RMS:
        return ResidualDiagnostics(np.nan, np.nan, n_runs, alpha, exact=True)
    runs_p = np.nan
    if signs.size >= 3 and len(set(signs)) == 2:
        _, runs_p = runstest_1samp(signs, cutoff=0, correction=True)
    normality_p = np.nan
    if residuals.size >= 3 and np.ptp(residuals) > 0:
        normality_p = float(stats.shapiro(residuals).pvalue)
    return ResidualDiagnostics(float(runs_p), normality_p, n_runs, alpha)


def _signs_and_spreads(vectors: list[np.ndarray]):
    """Per vector, as :func:`residual_diagnostics` finds them: the runs of the signs of
    :func:`_signs`, the positive and negative signs, whether the fit is exact (root mean
    square below :data:`EXACT_FIT_RMS`) and whether Shapiro-Wilk applies (3 values or more,
    not all equal); on the vectors laid end to end instead of one at a time."""
    count = len(vectors)
    lengths = np.array([vector.size for vector in vectors], dtype=int)
    owner = np.repeat(np.arange(count), lengths)
    values = np.concatenate(vectors) if count else np.zeros(0)
    kept = np.abs(values) >= EXACT_FIT_RMS
    signs, kept_owner = np.sign(values[kept]), owner[kept]
    n_positive = np.bincount(kept_owner[signs > 0], minlength=count)
    n_negative = np.bincount(kept_owner[signs < 0], minlength=count)
    changes = (signs[1:] != signs[:-1]) & (kept_owner[1:] == kept_owner[:-1])
    n_runs = np.where(n_positive + n_negative > 0, 1 + np.bincount(kept_owner[1:][changes], minlength=count), 0)
    exact = np.zeros(count, dtype=bool)
    normal_testable = np.zeros(count, dtype=bool)
    filled = np.flatnonzero(lengths)
    if filled.size:
        starts = np.concatenate(([0], np.cumsum(lengths)[:-1]))[filled]
        # each vector's own mean, as residual_diagnostics takes it (the same summation)
        mean_square = np.array([np.mean(vectors[i] ** 2) for i in filled.tolist()])
        exact[filled] = np.sqrt(mean_square) < EXACT_FIT_RMS
        spread = np.maximum.reduceat(values, starts) - np.minimum.reduceat(values, starts)
        normal_testable[filled] = (lengths[filled] >= 3) & (spread > 0)
    return n_runs, n_positive, n_negative, exact, normal_testable


def batch_residual_diagnostics(residuals: Sequence, *, alpha=SYSTEMATIC_P) -> list[ResidualDiagnostics]:
    """:func:`residual_diagnostics` of many residual vectors at once, with the same values.

    The runs test's normal approximation (statsmodels ``runstest_1samp`` with cut-off 0
    and its small-sample correction, the same arithmetic on arrays) is computed for all
    vectors together, and the Shapiro-Wilk test once per group of vectors of one length
    (``scipy.stats.shapiro`` along an axis); per vector this saved about 0.1 ms of call
    overhead, which added up to seconds over a batch of thousands of fits.

    Parameters
    ----------
    residuals : sequence of array_like
        Residuals of each fit (partition units), ordered by size.
    alpha : float or sequence of float
        Level of both tests, one for all or one per vector.

    Examples
    --------
    >>> found = batch_residual_diagnostics([[0.1, 0.2, 0.1, -0.2, -0.3, -0.1], [1e-15, -2e-16, 3e-16]])
    >>> [d.verdict for d in found], found[0].n_runs
    (['random', 'exact'], 2)
    """
    vectors = [np.asarray(r, dtype=float).ravel() for r in residuals]
    alphas = np.broadcast_to(np.asarray(alpha, dtype=float), (len(vectors),))
    count = len(vectors)
    n_runs, n_positive, n_negative, exact, normal_testable = _signs_and_spreads(vectors)
    runs_p = np.full(count, np.nan)
    # both signs among at least 3 signs, so at least 2 runs (statsmodels' single-run branch never applies)
    testable = ~exact & (n_positive + n_negative >= 3) & (n_positive > 0) & (n_negative > 0)
    if testable.any():
        npo, nne, runs = n_positive[testable], n_negative[testable], n_runs[testable]
        n = npo + nne
        npn = npo * nne
        rmean = 2.0 * npn / n + 1
        rvar = 2.0 * npn * (2.0 * npn - n) / n**2.0 / (n - 1.0)
        rdemean = runs - rmean
        corrected = np.where(rdemean > 0.5, rdemean - 0.5, np.where(rdemean < 0.5, rdemean + 0.5, 0.0))
        z = np.where(n >= 50, rdemean, corrected) / np.sqrt(rvar)
        runs_p[testable] = 2 * stats.norm.sf(np.abs(z))
    normality_p = np.full(count, np.nan)
    normal_testable &= ~exact
    lengths = np.array([vector.size for vector in vectors])
    for length in np.unique(lengths[normal_testable]):
        rows = np.flatnonzero(normal_testable & (lengths == length))
        normality_p[rows] = stats.shapiro(np.stack([vectors[i] for i in rows]), axis=1).pvalue
    return [
        ResidualDiagnostics(
            np.nan if exact[i] else float(runs_p[i]),
            np.nan if exact[i] else float(normality_p[i]),
            int(n_runs[i]),
            float(alphas[i]),
            exact=bool(exact[i]),
        )
        for i in range(count)
    ]
