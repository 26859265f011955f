"""The few distribution functions the density fits and the circuit's tests read, from :mod:`scipy.special`.

Each is the formula :mod:`scipy.stats` evaluates for that distribution (its ``_ppf``,
``_sf``, ``_logpmf``), so the numbers are the same to the last bit
(``tests/test_density_batch.py`` and ``tests/test_circuit_speed.py`` check them against
:mod:`scipy.stats`), without importing :mod:`scipy.stats`: its hundred distributions, their
docstrings and the resampling and spatial modules take about a third of a second to import
on a quiet machine (seconds on a loaded one), a large share of the start of ``tromplab density
fit`` and ``tromplab circuit``.  A number in gives a number out, an array an array.

Each function imports :mod:`scipy.special` when it is first called (a dictionary look-up on
later calls): importing this module costs nothing, so a command that computes no test
(``tromplab circuit design`` of a flowsheet without a survey) does not pay the 30 ms of
:mod:`scipy.special` and its array-API layer.
"""

from __future__ import annotations

import numpy as np


def chi2_ppf(q, df):
    """Quantile of the chi-squared distribution with ``df`` degrees of freedom (``scipy.stats.chi2.ppf``)."""
    import scipy.special

    return (2 * scipy.special.gammaincinv(np.asarray(df, dtype=float) / 2, q))[()]


def chi2_sf(x, df):
    """Upper tail of the chi-squared distribution (``scipy.stats.chi2.sf``)."""
    import scipy.special

    return scipy.special.chdtrc(df, np.asarray(x, dtype=float))[()]


def f_ppf(q, dfn, dfd):
    """Quantile of Fisher's F distribution (``scipy.stats.f.ppf``)."""
    import scipy.special

    return scipy.special.fdtri(dfn, dfd, q)


def t_ppf(q, df):
    """Quantile of Student's t distribution (``scipy.stats.t.ppf``)."""
    import scipy.special

    return scipy.special.stdtrit(df, q)


def norm_ppf(q):
    """Quantile of the standard normal distribution (``scipy.stats.norm.ppf``)."""
    import scipy.special

    return scipy.special.ndtri(q)


def norm_sf(x):
    """Upper tail of the standard normal distribution (``scipy.stats.norm.sf``)."""
    import scipy.special

    return scipy.special.ndtr(-np.asarray(x, dtype=float))[()]


def norm_isf(q):
    """Upper quantile of the standard normal distribution (``scipy.stats.norm.isf``)."""
    import scipy.special

    return (-scipy.special.ndtri(np.asarray(q, dtype=float)))[()]


def binom_logpmf(k, n, p):
    """Log-probability of ``k`` successes in ``n`` trials of probability ``p`` (``scipy.stats.binom.logpmf``, 0 < p < 1)."""
    import scipy.special

    k, n, p = (np.asarray(value, dtype=float) for value in (k, n, p))
    k = np.floor(k)
    combinations = scipy.special.gammaln(n + 1) - (scipy.special.gammaln(k + 1) + scipy.special.gammaln(n - k + 1))
    return combinations + scipy.special.xlogy(k, p) + scipy.special.xlog1py(n - k, -p)
