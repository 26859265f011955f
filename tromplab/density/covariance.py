r"""The covariance of each fitted curve's cut density and probable error: ``covariance.csv`` of ``density fit``.

A plant prediction (``tromplab plant predict --curves-from DIR``) carries the uncertainty of the
fitted curves to the plant's yield and ash; it needs the joint uncertainty of ``rho50`` and
``Ep``, not their two intervals alone.  For a fit on the partitions the covariance of the index
vector :math:`q = (\rho_{50}, E_p[, l, h])` is

.. math:: C = 2 s\, H^{-1},

:math:`H` the Hessian of the objective (binomial deviance or weighted sum of squares) in
:math:`q` by central differences and :math:`s` the scale (the quasi-binomial scale when the
counts are overdispersed, else 1; the residual variance for least squares) - the curvature the
delta-method band of :func:`tromplab.density.fitting.partition_band` uses, in the indices'
parametrisation; limits on their bounds are held there.  For a joint fit of three float-sink
analyses it is the joint fit's sandwich covariance carried to :math:`(\rho_{50}, E_p)` by the
Jacobian of the indices (delta method).  The table keeps the :math:`(\rho_{50}, E_p)` block
(the limits' uncertainty is in it, as their marginal).

References
----------
Collett, D. (2003). *Modelling Binary Data*, 2nd ed. Chapman & Hall/CRC (the observed information).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..curves.likelihood import central_hessian
from .fitting import DensityCurveFit, fit_data, index_model, index_vector, objective_of
from .joint import JOINT_METHOD

#: The parameters whose covariance ``covariance.csv`` gives, in order.
COVARIANCE_PARAMETERS = ("rho50", "ep")


def index_covariance(fit: DensityCurveFit) -> np.ndarray | None:
    """The 2 x 2 covariance of ``(rho50, ep)`` of a fit (g/cm3 squared); None when it cannot be made.

    None for a failed fit, a curve without rho50 or Ep, a singular or indefinite curvature, or a
    limit (of a curve with limits) closer to its bound than the difference step of the curvature.
    """
    if not fit.success or fit.indices is None or math.isnan(fit.indices.rho50) or math.isnan(fit.indices.ep):
        return None
    covariance = _joint_covariance(fit) if fit.method == JOINT_METHOD else _profile_covariance(fit)
    if covariance is None or not np.all(np.isfinite(covariance)) or np.any(np.diag(covariance) <= 0):
        return None
    return covariance


def _profile_covariance(fit: DensityCurveFit) -> np.ndarray | None:
    vector, _ = index_vector(fit.curve, fit.params, fit.indices, "ep")
    model = index_model(fit.curve, "ep")
    names = ["rho50", "ep", "light_limit", "heavy_limit"][: vector.size]
    free = [i for i, name in enumerate(names) if i < 2 or not fit.curve.limit_on_bound(name, vector[i])]
    data = fit_data(fit.sample, fit.method)
    objective = objective_of(data)

    def value(moved):
        q = vector.copy()
        q[free] = moved
        return objective(fit.curve.partition(data.density, **model(q)))

    start = vector[free]
    try:
        hessian = central_hessian(value, start, 1e-4 * np.maximum(np.abs(start), 1e-2))
    except ValueError:  # a limit within a difference step of its bound: the steps leave the curve's range
        return None
    scale = (fit.dispersion if fit.overdispersed else 1.0) if data.binomial else fit.dispersion
    try:
        covariance = 2.0 * scale * np.linalg.inv(hessian)
    except np.linalg.LinAlgError:
        return None
    return covariance[:2, :2]


def _joint_covariance(fit: DensityCurveFit) -> np.ndarray | None:
    joint = fit.raw
    values = np.array([joint.params[name] for name in joint.free])
    steps = 1e-6 * np.maximum(np.abs(values), 1e-2)

    def indices(vector):
        index = fit.curve.indices(**{**joint.params, **dict(zip(joint.free, vector))})
        return np.array([index.rho50, index.ep])

    unit = np.eye(values.size)
    jacobian = np.column_stack([(indices(values + unit[i] * steps[i]) - indices(values - unit[i] * steps[i])) / (2 * steps[i])
                                for i in range(values.size)])  # fmt: skip
    return jacobian @ joint.covariance @ jacobian.T


def covariance_table(fits: list[DensityCurveFit], *, sizes: bool) -> pd.DataFrame:
    """``covariance.csv``: two rows per fit with a covariance (``parameter`` rho50 and ep), its covariance with each.

    Columns ``test``, (``size_fraction``, ``size_lower``, ``size_upper`` with ``sizes``), ``curve``,
    ``parameter``, ``rho50``, ``ep``: the row of the covariance matrix of ``(rho50, ep)``, g/cm3 squared.
    """
    rows = []
    for fit in fits:
        covariance = index_covariance(fit)
        if covariance is None:
            continue
        sample = fit.sample
        for name, line in zip(COVARIANCE_PARAMETERS, covariance):
            rows.append({"test": sample.test, "size_fraction": sample.size_fraction, "size_lower": sample.size_lower,
                         "size_upper": sample.size_upper, "curve": fit.curve.id, "parameter": name,
                         "rho50": line[0], "ep": line[1]})  # fmt: skip
    columns = ["test", "size_fraction", "size_lower", "size_upper", "curve", "parameter", *COVARIANCE_PARAMETERS]
    table = pd.DataFrame(rows, columns=columns)
    return table if sizes else table.drop(columns=["size_fraction", "size_lower", "size_upper"])
