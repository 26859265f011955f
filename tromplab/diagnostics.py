"""Residual diagnostics of a fitted curve.

A curve can pass the Fisher screen while missing the data systematically (residuals
that stay on one side of the curve over a range of sizes).  Two checks are reported for
every fit:

* the Wald-Wolfowitz runs test on the signs of the residuals ordered by size
  (statsmodels ``runstest_1samp``, cut-off 0, small-sample correction): few runs mean
  systematic deviations;
* the Shapiro-Wilk test of normality of the residuals (scipy), which the F test assumes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

SYSTEMATIC_P = 0.05


@dataclass(frozen=True)
class ResidualDiagnostics:
    """p-values of the runs and normality tests (nan where a test cannot be run)."""

    runs_p: float
    normality_p: float
    n_runs: int

    @property
    def systematic(self) -> bool:
        return bool(np.isfinite(self.runs_p) and self.runs_p < SYSTEMATIC_P)


def residual_diagnostics(residuals) -> ResidualDiagnostics:
    """Runs test and normality test of residuals given in order of increasing size.

    Examples
    --------
    >>> d = residual_diagnostics([0.1, 0.2, 0.1, 0.2, 0.3, 0.1, -0.1, -0.2, -0.1, -0.2, -0.3, -0.1])
    >>> d.n_runs, d.systematic
    (2, True)
    """
    from statsmodels.sandbox.stats.runs import runstest_1samp

    residuals = np.asarray(residuals, dtype=float)
    signs = np.sign(residuals[residuals != 0])
    n_runs = int(1 + np.count_nonzero(np.diff(signs))) if signs.size else 0
    runs_p = np.nan
    if signs.size >= 3 and len(set(signs)) == 2:
        _, runs_p = runstest_1samp(signs, cutoff=0, correction=True)
    normality_p = np.nan
    if residuals.size >= 3 and np.ptp(residuals) > 0:
        normality_p = float(stats.shapiro(residuals).pvalue)
    return ResidualDiagnostics(float(runs_p), normality_p, n_runs)
