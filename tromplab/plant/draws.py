r"""Parametric bootstrap of the devices' partition curves: draws of each curve's cut and scale.

The parameters of device :math:`j`, :math:`\theta_j = (\rho_{50}, s)` with :math:`s` the
probable error or the imperfection, are drawn as

.. math::
    (\rho_{50}, \ln s) \sim N\big((\hat\rho_{50}, \ln \hat s),\ J \Sigma_j J^\top\big),
    \qquad J = \mathrm{diag}(1, 1/\hat s),

with :math:`\Sigma_j` the covariance of :math:`(\rho_{50}, s)` (the plant table's standard
deviations, or a ``density fit`` folder's ``covariance.csv``), independently between devices
(each device is tested on its own).  The scale is drawn on the log scale so that every draw is
positive; a drawn cut outside (1, 3.5] is set to that bound.  Every quantity of the plant is
computed for each draw and its interval is the percentile interval of the draws
(Efron & Tibshirani 1993, ch. 6 and 13: the parametric bootstrap, percentile intervals), so
it stays within the quantity's range.

References
----------
Efron, B. & Tibshirani, R. J. (1993). *An Introduction to the Bootstrap*. Chapman & Hall, New York.
"""

from __future__ import annotations

import numpy as np

from ..validation import MAX_CUT_DENSITY
from .inputs import Device

#: Parameter draws when none are asked for.
DEFAULT_DRAWS = 2000
#: Largest number of draws accepted.
MAX_DRAWS = 200_000


def parameter_draws(devices: list[Device], draws: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(rho50, scale)`` arrays of ``draws + 1`` values per device: the estimate first, then the draws.

    A device without covariance repeats its estimate.

    Examples
    --------
    >>> from tromplab.density.curves import get_density_curve
    >>> device = Device("c", "dmc", get_density_curve("normal"), 1.5, "ep", 0.03, np.diag([0.01**2, 0.003**2]))
    >>> [(rho50, scale)] = parameter_draws([device], 20000, seed=1)
    >>> round(float(rho50[0]), 6), round(float(np.std(rho50[1:])), 3), round(float(np.std(np.log(scale[1:]))), 2)
    (1.5, 0.01, 0.1)
    """
    generator = np.random.default_rng(seed)
    result = []
    for device in devices:
        rho50 = np.full(draws + 1, device.rho50)
        scale = np.full(draws + 1, device.scale)
        if device.uncertain and draws:
            jacobian = np.diag([1.0, 1.0 / device.scale])
            covariance = jacobian @ device.covariance @ jacobian.T
            centre = np.array([device.rho50, np.log(device.scale)])
            drawn = generator.multivariate_normal(centre, covariance, size=draws, method="eigh")
            rho50[1:] = np.clip(drawn[:, 0], 1.0 + 1e-6, MAX_CUT_DENSITY)
            scale[1:] = np.exp(drawn[:, 1])
        result.append((rho50, scale))
    return result


def percentile_interval(values: np.ndarray, ci: float) -> tuple[float, float]:
    """The ``ci`` percentile interval of the finite draws (NaN when fewer than half of them are finite)."""
    finite = values[np.isfinite(values)]
    if finite.size < max(values.size / 2, 2):
        return np.nan, np.nan
    low, high = np.quantile(finite, [(1 - ci) / 2, (1 + ci) / 2])
    return float(low), float(high)
