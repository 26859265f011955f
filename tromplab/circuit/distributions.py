"""The four distribution functions the circuit's tests read, from :mod:`scipy.special`.

``scipy.stats`` takes about a third of a second to import (its hundred distributions, their
docstrings, the resampling and the spatial modules) and the circuit commands need four of its
functions, each a thin wrapper over one special function: these are the same computations
(``tests/test_circuit_speed.py`` checks them bit for bit against scipy.stats), without the import.
"""

from __future__ import annotations

import numpy as np
from scipy import special


def chi2_sf(statistic, dof):
    """Upper tail of the chi-square distribution: ``scipy.stats.chi2.sf(statistic, dof)``."""
    return special.chdtrc(dof, np.asarray(statistic, dtype=float))[()]


def chi2_ppf(probability, dof):
    """Quantile of the chi-square distribution: ``scipy.stats.chi2.ppf(probability, dof)``."""
    return (2 * special.gammaincinv(np.asarray(dof, dtype=float) / 2, probability))[()]


def norm_sf(value):
    """Upper tail of the standard normal distribution: ``scipy.stats.norm.sf(value)``."""
    return special.ndtr(-np.asarray(value, dtype=float))[()]


def norm_isf(probability):
    """Upper quantile of the standard normal distribution: ``scipy.stats.norm.isf(probability)``."""
    return (-special.ndtri(np.asarray(probability, dtype=float)))[()]
