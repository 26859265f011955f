"""Fisher adequacy screen of a fitted curve (Shuvalov et al. 2018, section 4 of the spec).

``S0^2`` is the variance of the measured partition numbers about their mean
(``n - 1`` degrees of freedom), ``S_res^2 = SSR / (n - p)`` the residual variance with
``p = 2`` fitted parameters, and ``F = S0^2 / S_res^2``.  A curve is adequate when
``F > F_crit``, the ``1 - alpha`` quantile of Fisher's distribution with
``(n - 1, n - p)`` degrees of freedom.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import stats

from ..options import DEFAULT_ALPHA

#: Residuals with a root mean square below this (partition units: 1e-5 %) are solver and
#: rounding noise - three orders below the best measured partition (about 1e-4) and at the
#: level the least-squares solver stops (relative tolerance 1e-8 on the sum of squares).
EXACT_FIT_RMS = 1e-7


@dataclass(frozen=True)
class FisherScreen:
    """Outcome of the Fisher screen of one fit."""

    n: int
    n_params: int
    alpha: float
    s0_sq: float
    s_res_sq: float
    F: float
    F_crit: float

    @property
    def adequate(self) -> bool:
        """``F > F_crit``; False when F is undefined (flat data, ``S0^2 = 0``)."""
        return bool(self.F > self.F_crit)


@lru_cache(maxsize=4096)  # a batch asks for the same few (n, alpha, p) thousands of times
def critical_f(n: int, *, alpha: float = DEFAULT_ALPHA, n_params: int = 2) -> float:
    """Critical value ``F(1 - alpha; n - 1, n - n_params)``.

    Examples
    --------
    >>> round(critical_f(5), 2), round(critical_f(13), 2)
    (9.12, 2.79)
    """
    check_screenable(n, n_params=n_params)
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    return float(stats.f.ppf(1.0 - alpha, n - 1, n - n_params))


def check_screenable(n: int, *, n_params: int = 2) -> None:
    if n <= n_params:
        raise ValueError(
            f"{n} points cannot be screened: the Fisher test needs more points than the "
            f"{n_params} fitted parameters (n - {n_params} residual degrees of freedom)"
        )


def observed_variance(observed, weights=None) -> float:
    """``S0^2`` of :func:`fisher_screen`: the (weighted) variance of the measured partition
    numbers about their (weighted) mean, ``n - 1`` degrees of freedom."""
    observed = np.asarray(observed, dtype=float)
    if weights is None:
        return float(np.var(observed, ddof=1))
    weights = np.asarray(weights, dtype=float)
    mean = np.average(observed, weights=weights)
    return float(np.sum(weights * (observed - mean) ** 2) / (observed.size - 1))


def fisher_screen(
    observed, ssr: float, *, alpha: float = DEFAULT_ALPHA, n_params: int = 2, weights=None, s0_sq: float | None = None
) -> FisherScreen:
    """Screen a fit with sum of squared residuals ``ssr`` to the ``observed`` values.

    With ``weights`` (scaled to mean 1, as the fit uses them) ``ssr`` is the weighted sum
    of squares and ``S0^2`` the weighted variance about the weighted mean, so that both
    variances of the ratio are on the same scale.  ``s0_sq`` is that variance when the
    caller has it (:func:`observed_variance`; the formulas fitted to one experiment share it).

    Examples
    --------
    >>> screen = fisher_screen([0.9, 0.7, 0.5, 0.3, 0.1], ssr=0.001)
    >>> round(screen.F, 1), screen.adequate
    (300.0, True)
    """
    observed = np.asarray(observed, dtype=float)
    n = observed.size
    f_crit = critical_f(n, alpha=alpha, n_params=n_params)
    if s0_sq is None:
        s0_sq = observed_variance(observed, weights)
    s_res_sq = float(ssr) / (n - n_params)
    if s0_sq == 0:
        f_value = np.nan  # flat data: 0/0, neither adequate nor rankable
    else:
        f_value = s0_sq / s_res_sq if s_res_sq > 0 else np.inf
    return FisherScreen(n=n, n_params=n_params, alpha=alpha, s0_sq=s0_sq, s_res_sq=s_res_sq, F=float(f_value), F_crit=f_crit)
