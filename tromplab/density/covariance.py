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

:func:`covariance_table` evaluates the deviance of every binomial fit at all the points of its
central differences in one array operation per curve and number of densities
(:func:`_binomial_covariances`): the same arithmetic, element by element, as
:func:`index_covariance` of each fit alone, so the same numbers to the last bit.

References
----------
Collett, D. (2003). *Modelling Binary Data*, 2nd ed. Chapman & Hall/CRC (the observed information).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..curves.likelihood import central_hessian
from .batch import deviance_terms
from .fitting import DensityCurveFit, fit_data, index_model, index_vector, objective_of
from .joint import JOINT_METHOD
from .profiles import curve_of_indices

#: The parameters whose covariance ``covariance.csv`` gives, in order.
COVARIANCE_PARAMETERS = ("rho50", "ep")


def index_covariance(fit: DensityCurveFit) -> np.ndarray | None:
    """The 2 x 2 covariance of ``(rho50, ep)`` of a fit (g/cm3 squared); None when it cannot be made.

    None for a failed fit, a curve without rho50 or Ep, a singular or indefinite curvature, or a
    limit (of a curve with limits) closer to its bound than the difference step of the curvature.
    """
    if not fit.success or fit.indices is None or math.isnan(fit.indices.rho50) or math.isnan(fit.indices.ep):
        return None
    return _checked(_joint_covariance(fit) if fit.method == JOINT_METHOD else _profile_covariance(fit))


def _binomial_profile(fit: DensityCurveFit) -> bool:
    """Whether :func:`index_covariance` of ``fit`` is the curvature of a binomial deviance."""
    usable = fit.success and fit.indices is not None and not math.isnan(fit.indices.rho50) and not math.isnan(fit.indices.ep)
    return usable and fit.method == "binomial"


def _free_indices(fit: DensityCurveFit) -> tuple[np.ndarray, list[int]]:
    """The index vector ``(rho50, ep[, l, h])`` of a fit and the positions free in its curvature (a limit on its bound is held)."""
    vector, _ = index_vector(fit.curve, fit.params, fit.indices, "ep")
    names = ["rho50", "ep", "light_limit", "heavy_limit"][: vector.size]
    return vector, [i for i, name in enumerate(names) if i < 2 or not fit.curve.limit_on_bound(name, vector[i])]


def _curvature_steps(start: np.ndarray) -> np.ndarray:
    return 1e-4 * np.maximum(np.abs(start), 1e-2)


def _profile_covariance(fit: DensityCurveFit, data=None) -> np.ndarray | None:
    vector, free = _free_indices(fit)
    model = index_model(fit.curve, "ep")
    data = fit_data(fit.sample, fit.method) if data is None else data
    objective = objective_of(data)

    def value(moved):
        q = vector.copy()
        q[free] = moved
        return objective(fit.curve.partition(data.density, **model(q)))

    start = vector[free]
    try:
        hessian = central_hessian(value, start, _curvature_steps(start))
    except ValueError:  # a limit within a difference step of its bound: the steps leave the curve's range
        return None
    return _from_curvature(fit, hessian, binomial=data.binomial)


def _from_curvature(fit: DensityCurveFit, hessian: np.ndarray, *, binomial: bool) -> np.ndarray | None:
    scale = (fit.dispersion if fit.overdispersed else 1.0) if binomial else fit.dispersion
    try:
        covariance = 2.0 * scale * np.linalg.inv(hessian)
    except np.linalg.LinAlgError:
        return None
    return covariance[:2, :2]


def _checked(covariance: np.ndarray | None) -> np.ndarray | None:
    if covariance is None or not np.all(np.isfinite(covariance)) or np.any(np.diag(covariance) <= 0):
        return None
    return covariance


# --- the binomial fits of a file at once -------------------------------------------------------
def _difference_points(start: np.ndarray, steps: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The points :func:`~tromplab.curves.likelihood.central_hessian` evaluates, four per pair
    ``i <= j`` (``x + di + dj, x + di - dj, x - di + dj, x - di - dj``), as rows, and the pairs."""
    unit = np.eye(start.size)
    pairs = [(i, j) for i in range(start.size) for j in range(i, start.size)]
    points = []
    for i, j in pairs:
        di, dj = unit[i] * steps[i], unit[j] * steps[j]
        points += [start + di + dj, start + di - dj, start - di + dj, start - di - dj]
    return np.array(points), pairs


def _index_parameters(curve, q: np.ndarray) -> dict[str, np.ndarray] | None:
    """The curve's parameters (each (points, 1)) at the index vectors ``q`` (points, 2 or 4)
    (:func:`~tromplab.density.profiles.curve_of_indices`); None when a limit leaves the range in
    which the indices exist (:meth:`~tromplab.density.registry.DensityCurve.from_indices` raises there)."""
    if curve.has_limits:
        light, heavy = q[:, 2], q[:, 3]
        if not np.all((light >= 0.0) & (light < 0.25) & (heavy > 0.75) & (heavy <= 1.0)):
            return None
    return curve_of_indices(curve, q, np.zeros(len(q), dtype=bool))


def _deviances(curve, data, params: dict[str, np.ndarray]) -> np.ndarray:
    """The binomial deviance of the fit's data at each row of parameters (``objective_of``'s, row by row)."""
    return 2.0 * deviance_terms(data.sinks, data.trials, curve.partition(data.density[None, :], **params)).sum(axis=1)


def _binomial_curvature(fit: DensityCurveFit, data) -> np.ndarray | None:
    """The central-difference Hessian of the deviance of a binomial fit in its free indices,
    every point of the differences in one evaluation (``central_hessian``'s arithmetic)."""
    vector, free = _free_indices(fit)
    start = vector[free]
    steps = _curvature_steps(start)
    moved, pairs = _difference_points(start, steps)
    q = np.tile(vector, (len(moved), 1))
    q[:, free] = moved
    params = _index_parameters(fit.curve, q)
    if params is None:  # a limit within a difference step of its bound
        return None
    value = _deviances(fit.curve, data, params).reshape(len(pairs), 4)
    hessian = np.empty((start.size, start.size))
    for (i, j), (a, b, c, d) in zip(pairs, value):
        hessian[i, j] = hessian[j, i] = (a - b - c + d) / (4 * steps[i] * steps[j])
    return hessian


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
    read: dict[int, object] = {}  # each sample's arrays, read once for all its curves
    for fit in fits:
        if _binomial_profile(fit) and id(fit.sample) not in read:
            read[id(fit.sample)] = fit_data(fit.sample, fit.method)
        data = read.get(id(fit.sample)) if _binomial_profile(fit) else None
        if data is not None and data.binomial:
            hessian = _binomial_curvature(fit, data)
            covariance = _checked(None if hessian is None else _from_curvature(fit, hessian, binomial=True))
        else:
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
