r"""Parametric bootstrap of the devices' partition curves: draws of each curve's cut and scale.

The parameters of device :math:`j`, :math:`\theta_j = (\rho_{50}, s)` with :math:`s` the
probable error or the imperfection, are drawn through the coefficients of the curve's linear
predictor, :math:`P(\rho) = F(\alpha + \beta\rho)` with :math:`\beta = k/E_p` and
:math:`\alpha = q_{50} - \beta\rho_{50}` (:mod:`tromplab.density.curves`; for a probit,
logit or cloglog fit of tracer counts the GLM's own coefficients, whose sampling distribution
is close to normal where the ratio :math:`\rho_{50} = (q_{50} - \alpha)/\beta` is not):

.. math::
    (\alpha, \beta) \sim N\big((\hat\alpha, \hat\beta),\ J \Sigma_j J^\top\big),
    \qquad \rho_{50} = (q_{50} - \alpha)/\beta, \quad E_p = k/\beta,

with :math:`\Sigma_j` the covariance of :math:`(\rho_{50}, s)` (the plant table's standard
deviations, or a ``density fit`` folder's ``covariance.csv``) and :math:`J` the Jacobian of
:math:`(\alpha, \beta)` in :math:`(\rho_{50}, s)` (delta method), independently between devices
(each device is tested on its own).  A draw with :math:`\beta \le 0` (no separation) is drawn
again; a drawn cut outside (1, 3.5] is set to that bound.  Every quantity of the plant is
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
    >>> device = Device("c", "dmc", get_density_curve("normal"), 1.5, "ep", 0.03, np.diag([0.005**2, 0.002**2]))
    >>> [(rho50, scale)] = parameter_draws([device], 20000, seed=1)
    >>> round(float(rho50[0]), 6), round(float(np.std(rho50[1:])), 3), round(float(np.std(scale[1:])), 3)
    (1.5, 0.005, 0.002)
    """
    generator = np.random.default_rng(seed)
    result = []
    for device in devices:
        rho50 = np.full(draws + 1, device.rho50)
        scale = np.full(draws + 1, device.scale)
        if device.uncertain and draws and device.scale == 0:  # an ideal separation: only its cut is uncertain
            rho50[1:] = np.clip(
                generator.normal(device.rho50, np.sqrt(device.covariance[0, 0]), draws), 1.0 + 1e-6, MAX_CUT_DENSITY
            )
        elif device.uncertain and draws:
            rho50[1:], scale[1:] = _drawn(device, draws, generator)
        result.append((rho50, scale))
    return result


def _drawn(device: Device, draws: int, generator: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Draws of (rho50, scale) through the coefficients (alpha, beta) of the curve's linear predictor."""
    form = device.curve.form
    centre, jacobian = _coefficients(device)
    covariance = jacobian @ device.covariance @ jacobian.T
    drawn = generator.multivariate_normal(centre, covariance, size=draws, method="eigh")
    for _ in range(100):  # a slope at or below 0 is no separation: drawn again (rare unless the test says nothing)
        flat = drawn[:, 1] <= 1e-9 * centre[1]
        if not flat.any():
            break
        drawn[flat] = generator.multivariate_normal(centre, covariance, size=int(flat.sum()), method="eigh")
    alpha, beta = drawn[:, 0], np.maximum(drawn[:, 1], 1e-9 * centre[1])
    rho50 = np.clip((form.centre - alpha) / beta, 1.0 + 1e-6, MAX_CUT_DENSITY)
    ep = form.scale / beta
    return rho50, ep / (rho50 - 1.0) if device.scale_name == "imperfection" else ep


def _coefficients(device: Device) -> tuple[np.ndarray, np.ndarray]:
    """The linear predictor's (alpha, beta) at the estimate and their Jacobian in (rho50, scale)."""
    q50, k, rho50, scale = device.curve.form.centre, device.curve.form.scale, device.rho50, device.scale
    if device.scale_name == "imperfection":
        ep = scale * (rho50 - 1.0)
        d_ep = np.array([scale, rho50 - 1.0])  # dEp/d(rho50, I)
    else:
        ep = scale
        d_ep = np.array([0.0, 1.0])
    beta = k / ep
    d_beta = -k / ep**2 * d_ep
    d_alpha = -beta * np.array([1.0, 0.0]) - rho50 * d_beta
    return np.array([q50 - beta * rho50, beta]), np.vstack([d_alpha, d_beta])


def percentile_interval(values: np.ndarray, ci: float) -> tuple[float, float]:
    """The ``ci`` percentile interval of the finite draws (NaN when fewer than half of them are finite)."""
    finite = values[np.isfinite(values)]
    if finite.size < max(values.size / 2, 2):
        return np.nan, np.nan
    low, high = np.quantile(finite, [(1 - ci) / 2, (1 + ci) / 2])
    return float(low), float(high)
