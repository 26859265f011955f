"""Efficiency indices of a separation curve.

All indices are computed from a formula of :mod:`tromplab.curves.formulas` with given ``d_cut``
and shape, in the conventions of Shuvalov et al. (2018), section 3 of the package spec:

* classifier efficiency (Ushakov), the recovery of fines:
  :math:`\\eta = \\int_0^1 \\varphi(x)\\,dx`;
* misplacement of coarse particles into the fines:
  :math:`\\varepsilon = \\int_1^{x_{max}} \\varphi(x)\\,dx`, :math:`x_{max} = \\delta_{max}/d_{cut}`;
* the mineral-processing indices on the partition *to the coarse product*: ``d25``
  (:math:`\\varphi = 0.75`), ``d75`` (:math:`\\varphi = 0.25`), the Ecart probable
  ``Ep = (d75 - d25)/2``, the imperfection ``Ep/d_cut`` and the sharpness ``d25/d75``.

Closed forms are used where the formula declares one and checked against quadrature in
the tests; otherwise :func:`scipy.integrate.quad` integrates the curve.

Given the measured size range, :func:`curve_indices` also names the indices that rest on
the curve outside it (``CurveIndices.extrapolated``): ``d25`` or ``d75`` outside the
smallest..largest measured size, ``eta`` when more than :data:`EXTRAPOLATED_SHARE` of its
area lies below the smallest measured size, ``epsilon`` when more than that share of its
area lies above the largest measured size (``delta_max`` beyond the data).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np
from scipy import integrate, optimize

from ..results_contract import ResultContract
from ..validation import check_number, check_size
from .formulas import Formula, get_formula, is_batchable

#: Share of eta or epsilon that may come from sizes outside the measured range before the
#: index is flagged as extrapolated: a tenth of the index would then rest on the formula's
#: tail alone, where no point constrained it.
EXTRAPOLATED_SHARE = 0.1


@dataclass(frozen=True)
class CurveIndices(ResultContract):
    """Indices of one separation curve (sizes in the unit of ``d_cut``).

    For curves with bypass or fish-hook the *actual* curve (what the classifier does)
    and the *corrected* curve (bypass removed) differ: ``d_cut`` is the corrected cut
    d50c, ``d50`` the actual cut (where the actual curve crosses 1/2), ``d25``, ``d75``,
    ``ep`` and ``imperfection = ep / d50`` belong to the actual curve (nan where it never
    reaches the level), ``ep_c`` and ``imperfection_c = ep_c / d50c`` to the corrected
    curve.  For the nine paper formulas both curves are the same curve.  :meth:`summary`
    is one row of them all (definitions in ``docs/columns.md``).

    Attributes
    ----------
    d_cut, d50c : float
        The corrected cut size (the fitted ``d_cut``).
    slope : float
        Slope of the curve at the cut, ``d phi / dx`` at ``x = 1``.
    eta : float
        Efficiency: area under the curve from ``x = 0`` to 1.
    epsilon : float
        Misplacement: area under the curve from ``x = 1`` to ``delta_max / d_cut``.
    d25, d75 : float
        Sizes where the actual curve (partition to fines) is 0.75 and 0.25.
    ep, imperfection : float
        ``Ep = (d75 - d25) / 2`` and ``Ep / d50`` of the actual curve.
    sharpness : float
        ``d25 / d75`` of the actual curve.
    d50 : float
        The actual cut, where the actual curve crosses 1/2.
    ep_c, imperfection_c : float
        The same of the corrected curve.
    extrapolated : tuple of str
        Indices read beyond the measured sizes.
    """

    d_cut: float
    slope: float
    eta: float
    epsilon: float
    d25: float
    d75: float
    ep: float
    imperfection: float
    sharpness: float
    d50: float = np.nan
    ep_c: float = np.nan
    imperfection_c: float = np.nan
    extrapolated: tuple[str, ...] = ()

    @property
    def d50c(self) -> float:
        """Corrected cut size (the fitted ``d_cut``)."""
        return self.d_cut

    def summary(self):
        """One row: every index, ``d50c`` beside ``d_cut`` and the indices read beyond the data."""
        import pandas as pd

        row = {field.name: getattr(self, field.name) for field in fields(self)}
        return pd.DataFrame([{**row, "d50c": self.d50c, "extrapolated": ";".join(self.extrapolated)}])

    def _result_context(self) -> str:
        return f"Indices of a separation curve with d_cut = {self.d_cut:.4g}"


def efficiency_by_quadrature(formula: Formula, shape: float, x_max: float, **context) -> tuple[float, float]:
    """``(eta, eps)`` by adaptive quadrature (reference for the closed forms).

    A sharp curve falls from 1/2 to nothing within a few per cent of the cut; over a long
    interval ``[1, x_max]`` the first Gauss-Kronrod rule can miss that step entirely and
    report eps of about 0 (Molerus with km1 = 30 on ``[1, 500]`` gave 1.7e-18 instead of
    0.0113).  Break points close to the cut (``x = 1 +- 1e-3, 1e-2, 0.1``) and then
    doubling towards ``x_max`` make every subinterval start where the curve still has
    weight, so the adaptive rule resolves it.
    """

    def curve(x):
        return float(formula.phi(x, shape, **context))

    # 0.5 is the kink of the piecewise formulas; the rest resolve sharp curves near the cut.
    eta, _ = integrate.quad(curve, 0.0, 1.0, points=[0.5, 0.9, 0.99, 0.999], limit=200, epsabs=1e-13, epsrel=1e-12)
    upper = max(x_max, 1.0)
    eps = 0.0
    if upper > 1.0:
        cuts = _break_points_above_cut(upper)  # one per doubling: 1,000 when x_max is near 1e300
        eps, _ = integrate.quad(curve, 1.0, upper, points=cuts, limit=max(400, 2 * len(cuts)), epsabs=1e-13, epsrel=1e-12)
    return float(eta), float(eps)


def _break_points_above_cut(upper: float) -> list[float]:
    """Break points on ``(1, upper)``: dense next to the cut, then doubling."""
    near = [1.001, 1.01, 1.1, 1.5]
    doubling = 2.0 ** np.arange(1, max(int(np.ceil(np.log2(upper))), 1))
    return [float(x) for x in (*near, *doubling) if 1.0 < x < upper]


def efficiency(formula: Formula, shape: float, x_max: float, **context) -> tuple[float, float]:
    """Classifier efficiency eta and misplacement eps of a curve.

    Parameters
    ----------
    formula : Formula or str
        Registry entry or its id.
    shape : float
        Shape parameter.
    x_max : float
        Largest relative size ``delta_max / d_cut``; eps is 0 when ``x_max <= 1``.
    **context
        Extra inputs of the formula (``measured_efficiency`` for (11)).

    Examples
    --------
    >>> eta, eps = efficiency("plitt", 2.0, 6.0)
    >>> round(eta, 6)  # pi / 4
    0.785398
    """
    formula = get_formula(formula)
    if formula.efficiency is not None:
        eta, eps = formula.efficiency(shape, x_max, **context)
        return float(eta), float(eps)
    return efficiency_by_quadrature(formula, shape, x_max, **context)


def _relative_size_at(formula: Formula, shape: float, level: float, context: dict) -> float:
    """Relative size where the curve crosses ``level`` next to the cut (nan when it never does).

    The search starts at ``x = 1`` and widens towards larger sizes when the curve is above
    ``level`` there, towards smaller sizes otherwise; so it finds the crossing nearest the
    cut also for curves that rise again, or whose value at the cut is not 1/2 (bypass).
    """

    def gap(x):
        return float(formula.phi(x, shape, **context)) - level

    at_cut = gap(1.0)
    if at_cut == 0.0:
        return 1.0
    factor = 2.0 if at_cut > 0 else 0.5
    outer = 1.0
    while True:
        inner, outer = outer, outer * factor
        if not 1e-12 < outer < 1e12:
            return float("nan")
        if np.sign(gap(outer)) != np.sign(at_cut):
            return optimize.brentq(gap, min(inner, outer), max(inner, outer), xtol=1e-13, rtol=1e-13)


def _relative_size_cached(formula: Formula, shape: float, level: float, context: dict) -> float:
    """:func:`_relative_size_at`, remembered per formula, shape and context: the relative
    sizes do not depend on d_cut, so the delta method's steps in d_cut and the model
    averages of a batch ask for the same ones again."""
    if not _registered(formula):  # nothing to key it by
        return _relative_size_at(formula, shape, level, context)
    return _relative_size_by_key(formula.id, float(shape), level, tuple(sorted(context.items())))


def _registered(formula: Formula) -> bool:
    """True for a registry entry (False for a formula made elsewhere, such as a test's
    ``with_bypass`` of another base, even when its id is unknown to the registry)."""
    try:
        return get_formula(formula.id) is formula
    except KeyError:
        return False


@lru_cache(maxsize=50_000)
def _relative_size_by_key(formula_id: str, shape: float, level: float, context: tuple) -> float:
    return _relative_size_at(get_formula(formula_id), shape, level, dict(context))


#: Half-width of the central difference that gives the slope at the cut of curves with extras.
SLOPE_STEP = 1e-6


def _numeric_slope(formula: Formula, shape: float, context: dict) -> float:
    """Slope of the actual curve at x = 1 for curves with bypass or fish-hook (central difference)."""
    h = SLOPE_STEP
    return float((formula.phi(1.0 + h, shape, **context) - formula.phi(1.0 - h, shape, **context)) / (2 * h))


def curve_indices(
    formula, d_cut: float, shape: float, *, delta_max: float, measured_sizes: tuple[float, float] | None = None, **context
) -> CurveIndices:
    """All indices of one fitted curve.

    Parameters
    ----------
    formula : Formula or str
        Registry entry or its id.
    d_cut, shape : float
        Curve parameters (``d_cut`` in the size unit of the data).
    delta_max : float
        Largest particle size in the feed, same unit as ``d_cut``.
    measured_sizes : (float, float), optional
        Smallest and largest measured size; when given, ``extrapolated`` names the indices
        that rest on the curve outside them (see the module notes).
    **context
        Extra inputs of the formula (``measured_efficiency`` for (11); ``bypass`` and
        ``fishhook`` for the extended curves: ``d_cut`` is then the corrected cut, the
        slope is taken numerically on the actual curve, and the indices of the actual
        and the corrected curve are told apart as described in :class:`CurveIndices`).

    Examples
    --------
    >>> ind = curve_indices("plitt", 100.0, 2.0, delta_max=600.0, measured_sizes=(60.0, 600.0))
    >>> round(ind.d25, 3), round(ind.d75, 3), round(ind.ep, 3), ind.extrapolated
    (57.735, 173.205, 57.735, ('d25', 'eta'))
    """
    formula, d_cut, shape, delta_max = _checked_curve_arguments(formula, d_cut, shape, delta_max)
    eta, eps = efficiency(formula, shape, delta_max / d_cut, **context)
    slope = formula.slope_at_cut(shape) if not formula.extras else _numeric_slope(formula, shape, context)
    d25 = d_cut * _relative_size_cached(formula, shape, 0.75, context)
    d75 = d_cut * _relative_size_cached(formula, shape, 0.25, context)
    ep = (d75 - d25) / 2.0
    d50, ep_c = _actual_cut_and_corrected_ep(formula, d_cut, shape, ep, context)
    extrapolated = ()
    if measured_sizes is not None:
        extrapolated = extrapolated_indices(
            formula,
            d_cut,
            shape,
            d25=d25,
            d75=d75,
            eta=eta,
            epsilon=eps,
            delta_max=delta_max,
            measured_sizes=measured_sizes,
            **context,
        )
    return CurveIndices(
        d_cut=float(d_cut),
        slope=float(slope),
        eta=eta,
        epsilon=eps,
        d25=float(d25),
        d75=float(d75),
        ep=float(ep),
        imperfection=float(ep / d50),
        sharpness=float(d25 / d75),
        d50=float(d50),
        ep_c=float(ep_c),
        imperfection_c=float(ep_c / d_cut),
        extrapolated=extrapolated,
    )


def _checked_curve_arguments(formula, d_cut, shape, delta_max) -> tuple:
    for argument, value in (("d_cut", d_cut), ("shape", shape), ("delta_max", delta_max)):
        if value is None or isinstance(value, (str, bytes, list, tuple, dict, set)):
            raise TypeError(f"{argument} must be a number, got {type(value).__name__}")
    formula = get_formula(formula)
    return formula, check_size(d_cut, "d_cut"), check_number(shape, "shape"), check_size(delta_max, "delta_max")


def _actual_cut_and_corrected_ep(formula, d_cut: float, shape: float, ep: float, context: dict) -> tuple[float, float]:
    """``(d50, ep_c)``: the cut of the actual curve and the Ep of the corrected one (the same
    curve without bypass); ``(d_cut, ep)`` for a curve without bypass."""
    if "bypass" not in context:
        return d_cut, ep
    corrected = {**context, "bypass": 0.0}
    d50 = d_cut * _relative_size_at(formula, shape, 0.5, context)
    ep_c = d_cut * (_relative_size_at(formula, shape, 0.25, corrected) - _relative_size_at(formula, shape, 0.75, corrected)) / 2.0
    return d50, ep_c


def extrapolated_indices(
    formula,
    d_cut: float,
    shape: float,
    *,
    d25: float,
    d75: float,
    eta: float,
    epsilon: float,
    delta_max: float,
    measured_sizes: tuple[float, float],
    **context,
) -> tuple[str, ...]:
    """Names of the indices that rest on the curve outside the measured sizes.

    ``d25`` / ``d75``: outside ``[smallest, largest]``.  ``eta``: the area of the curve
    on ``0 <= size <= min(smallest, d_cut)`` is more than :data:`EXTRAPOLATED_SHARE` of
    eta.  ``epsilon``: the area on ``max(largest, d_cut) <= size <= delta_max`` is more
    than that share of epsilon.

    Examples
    --------
    >>> extrapolated_indices("plitt", 1.0, 3.0, d25=0.69, d75=1.44, eta=0.83, epsilon=0.3, delta_max=8.0,
    ...                      measured_sizes=(0.05, 2.0))
    ('epsilon',)
    """
    formula = get_formula(formula)
    smallest, largest = measured_sizes
    flags = [name for name, size in (("d25", d25), ("d75", d75)) if np.isfinite(size) and not smallest <= size <= largest]
    below = min(smallest / d_cut, 1.0)
    if eta > 0 and _area(formula, shape, 0.0, below, context) > EXTRAPOLATED_SHARE * eta:
        flags.append("eta")
    above, x_max = max(largest / d_cut, 1.0), delta_max / d_cut
    if epsilon > 0 and x_max > above and _area(formula, shape, above, x_max, context) > EXTRAPOLATED_SHARE * epsilon:
        flags.append("epsilon")
    return tuple(flags)


def _area(formula: Formula, shape: float, lower: float, upper: float, context: dict) -> float:
    """Area under the curve between two relative sizes (adaptive quadrature)."""
    if upper <= lower:
        return 0.0
    cuts = [x for x in (0.5, 1.0, *_break_points_above_cut(upper)) if lower < x < upper]
    limit = max(400, 2 * len(cuts))  # quad needs more subintervals than break points (x_max up to 1e308)
    area, _ = integrate.quad(lambda x: float(formula.phi(x, shape, **context)), lower, upper, points=cuts or None, limit=limit)
    return float(area)


# --- historical approximations (20)-(23) of Shuvalov et al. (2018) ----------------------
def eta_plitt_printed(ks):
    """Printed approximation (20): ``eta = 0.6 ks^0.1``.

    Not reproducible: it lies 13.4 % (ks = 1) to 19.9 % (ks = 3) below the exact Plitt
    efficiency on ks = 1..3 (the best power law there is about ``0.696 ks^0.170``).  Kept
    for comparison only; see ``docs/errata.md``.
    """
    return 0.6 * np.power(ks, 0.1)


def eta_lognormal_printed(kf):
    """Printed approximation (21): ``eta = 0.807 / kf^0.175`` (within 0.006 on kf 0.75..2.25)."""
    return 0.807 / np.power(kf, 0.175)


def eps_plitt_printed(ks):
    """Printed approximation (22): ``eps = 1.185 / ks^1.47``; not reproducible (``docs/errata.md``)."""
    return 1.185 / np.power(ks, 1.47)


def eps_lognormal_printed(kf):
    """Printed approximation (23): ``eps = -0.0835 kf^2 + 0.876 kf - 0.305`` (X = 6; within 0.025)."""
    kf = np.asarray(kf, dtype=float)
    return -0.0835 * kf**2 + 0.876 * kf - 0.305


# --- many curves of one formula at once ------------------------------------------------------
#: Break points of the fixed-order quadrature on ``[0, inf)``: dense around the cut, where sharp
#: curves fall from 1 to 0, then doubling (more are added up to the largest upper limit).
_QUADRATURE_BREAKS = (0.0, 0.5, 0.8, 0.9, 0.95, 0.97, 0.99, 0.997, 0.999, 1.0, 1.001, 1.003, 1.01, 1.03, 1.05, 1.1, 1.2, 1.5)
#: Gauss-Legendre nodes per piece: with the pieces above, every paper formula over its whole
#: shape range agrees with adaptive quadrature (:func:`efficiency_by_quadrature`) to 1e-9
#: (``tests/test_indices.py``).
GAUSS_LEGENDRE_NODES = 24
#: Doublings of the relative size searched for a crossing of d25 / d75 (as :func:`_relative_size_at`:
#: from x = 1 out to 2**39, about 5e11, or in to 2**-39).
_DOUBLINGS = 39


def batchable_indices(formula) -> bool:
    """True when :func:`batch_curve_indices` covers ``formula``: curves without extra
    parameters whose ``phi`` takes arrays of shapes (the nine paper formulas), and such a
    curve with bypass (``Formula.bypass_of``: ``plitt_bypass``, ``lognormal_bypass``)."""
    formula = get_formula(formula)
    if formula.bypass_of is not None:
        return batchable_indices(formula.bypass_of)
    return not formula.extras and is_batchable(formula)


def batch_curve_indices(
    formula, d_cut, shape, *, delta_max, measured_sizes=None, measured_efficiency=None, bypass=None
) -> list[CurveIndices]:
    """:func:`curve_indices` of many curves of one formula at once (arrays over curves).

    The same indices by the same definitions, computed on arrays: the closed forms of
    eta and eps where the formula declares them (the same functions :func:`efficiency`
    calls), else fixed-order Gauss-Legendre quadrature on pieces that resolve sharp curves
    next to the cut (:data:`GAUSS_LEGENDRE_NODES` nodes per piece, within 1e-9 of adaptive
    quadrature); d25 and d75 by bracketing the crossing with the same doubling search from
    ``x = 1`` and Chandrupatla's method (:func:`scipy.optimize.elementwise.find_root`, to
    1e-13 as :func:`scipy.optimize.brentq` before); the areas behind ``extrapolated`` by
    the same quadrature.

    Parameters
    ----------
    formula : Formula or str
        A formula with :func:`batchable_indices` true.
    d_cut, shape, delta_max : array_like, shape (N,)
        Parameters of each curve and its largest feed size (size unit of ``d_cut``).
    measured_sizes : (array_like, array_like), optional
        Smallest and largest measured size of each curve, for ``extrapolated``.
    measured_efficiency : array_like, optional
        The measured efficiency of each curve (formula (11) only).
    bypass : array_like, optional
        The bypass of each curve (the curves with bypass only, where it is required).

    Returns
    -------
    list of CurveIndices
        One per curve, in order.

    Examples
    --------
    >>> [round(i.d25, 3) for i in batch_curve_indices("plitt", [100.0, 50.0], [2.0, 2.0], delta_max=[600.0, 600.0])]
    [57.735, 28.868]
    """
    columns, flags = batch_index_columns(
        formula,
        d_cut,
        shape,
        delta_max=delta_max,
        measured_sizes=measured_sizes,
        measured_efficiency=measured_efficiency,
        bypass=bypass,
    )
    names = [field.name for field in fields(CurveIndices) if field.name != "extrapolated"]
    return [
        CurveIndices(**dict(zip(names, (float(v) for v in row))), extrapolated=flag)
        for row, flag in zip(zip(*(columns[name].tolist() for name in names)), flags)
    ]


def batch_index_columns(
    formula, d_cut, shape, *, delta_max, measured_sizes=None, measured_efficiency=None, bypass=None, epsilon: bool = True
) -> tuple[dict[str, np.ndarray], list[tuple[str, ...]]]:
    """The indices of :func:`batch_curve_indices` as one array per :class:`CurveIndices` field
    (``extrapolated`` aside, returned as the list of each curve's flags): the rows of many
    curves without a result object per curve (the delta method and the bootstrap evaluate
    tens of thousands).  ``epsilon=False`` leaves epsilon nan, and out of the flags, for a
    caller that does not report it (the model averages): without a closed form it is the
    costliest integral."""
    formula = get_formula(formula)
    if not batchable_indices(formula):
        raise ValueError(f"formula {formula.id} has no batched indices; use curve_indices")
    if formula.bypass_of is not None:
        if bypass is None:
            raise ValueError(f"formula {formula.id}: the batched indices need the bypass of each curve")
        return _bypass_index_columns(
            formula.bypass_of, d_cut, shape, bypass, delta_max=delta_max, measured_sizes=measured_sizes, epsilon=epsilon
        )
    d_cut, shape, delta_max = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (d_cut, shape, delta_max))
    d_cut, shape, delta_max = np.broadcast_arrays(d_cut, shape, delta_max)
    x_max = delta_max / d_cut
    efficiency_of = None
    if formula.context_from_efficiency:
        efficiency_of = np.broadcast_to(np.asarray(measured_efficiency, dtype=float), shape.shape)
    flags = [()] * shape.size
    if epsilon or measured_sizes is not None:
        x_break, curve, eta, eps, x25, x75, slope = _shape_indices(formula, shape, efficiency_of, x_max, epsilon)
    else:  # the rest rests on the curve's shape alone: once per distinct curve (the delta method's steps in d_cut repeat it)
        key = shape if efficiency_of is None else shape + 1j * efficiency_of
        _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
        distinct = _shape_indices(
            formula, shape[first], None if efficiency_of is None else efficiency_of[first], x_max[first], False
        )
        eta, eps, x25, x75, slope = (np.asarray(column)[inverse.ravel()] for column in distinct[2:])
    d25, d75 = d_cut * x25, d_cut * x75
    if measured_sizes is not None:
        flags = _batched_extrapolated(curve, d25, d75, eta, eps, d_cut, x_max, x_break, measured_sizes)
    ep = (d75 - d25) / 2.0
    imperfection = ep / d_cut
    columns = {"d_cut": d_cut, "slope": slope, "eta": np.asarray(eta, dtype=float), "epsilon": np.asarray(eps, dtype=float)}
    columns |= {"d25": d25, "d75": d75, "ep": ep, "imperfection": imperfection, "sharpness": d25 / d75}
    columns |= {"d50": d_cut, "ep_c": ep, "imperfection_c": imperfection}
    return columns, flags


def _shape_indices(formula: Formula, shape, efficiency_of, x_max, epsilon: bool) -> tuple:
    """``(x_break, curve, eta, eps, x25, x75, slope)`` of the curves of ``shape`` (and the
    measured efficiencies ``efficiency_of`` of a formula that takes them): the indices in
    relative size, which do not depend on ``d_cut`` (eps on ``x_max``, nan without ``epsilon``)."""
    x_break = None
    if formula.moving_break is not None:  # (11): x_a of every curve, solved on arrays (within 1e-13 of one by one)
        x_break = formula.moving_break.on_arrays(shape, efficiency_of)
    curve = _curve_on_arrays(formula, shape, x_break)
    eta, eps = _batched_efficiency(formula, curve, shape, x_max, efficiency_of, x_break, epsilon)
    x25, x75 = _relative_sizes_at(curve, (0.75, 0.25), shape.size)
    slope = np.array([float(formula.slope_at_cut(k)) for k in shape.tolist()])  # scalar forms, as one curve's
    return x_break, curve, eta, eps, x25, x75, slope


def _bypass_index_columns(
    base: Formula, d_cut, shape, bypass, *, delta_max, measured_sizes, epsilon: bool
) -> tuple[dict[str, np.ndarray], list[tuple[str, ...]]]:
    """:func:`batch_index_columns` of ``base`` with bypass, ``phi = (1 - bypass) phi_base``, by
    the definitions of :func:`curve_indices`: the corrected curve is ``base`` itself (its
    batched indices give ``ep_c``); the actual curve's eta and eps are ``(1 - bypass)`` times
    the base's (both are areas of the actual curve), its d25, d50 and d75 the crossings of
    0.75, 0.5 and 0.25 by the actual curve (the same doubling search from ``x = 1``, so nan
    where the bypass keeps it below the level), its slope the same central difference."""
    d_cut, shape, delta_max, bypass = np.broadcast_arrays(
        *(np.atleast_1d(np.asarray(v, dtype=float)) for v in (d_cut, shape, delta_max, bypass))
    )
    corrected, _ = batch_index_columns(base, d_cut, shape, delta_max=delta_max, epsilon=epsilon)
    actual = _scaled_curve(_curve_on_arrays(base, shape, None), 1.0 - bypass)
    eta, eps = (1.0 - bypass) * corrected["eta"], (1.0 - bypass) * corrected["epsilon"]
    d25, d50, d75 = (d_cut * x for x in _relative_sizes_at(actual, (0.75, 0.5, 0.25), d_cut.size))
    flags = [()] * d_cut.size
    if measured_sizes is not None:
        flags = _batched_extrapolated(actual, d25, d75, eta, eps, d_cut, delta_max / d_cut, None, measured_sizes)
    around_cut = actual(np.broadcast_to([1.0 + SLOPE_STEP, 1.0 - SLOPE_STEP], (d_cut.size, 2)))
    slope = (around_cut[:, 0] - around_cut[:, 1]) / (2 * SLOPE_STEP)  # as _numeric_slope
    ep = (d75 - d25) / 2.0
    columns = {"d_cut": d_cut, "slope": slope, "eta": eta, "epsilon": eps, "d25": d25, "d75": d75, "ep": ep}
    columns |= {"imperfection": ep / d50, "sharpness": d25 / d75, "d50": d50}
    columns |= {"ep_c": corrected["ep"], "imperfection_c": corrected["ep"] / d_cut}
    return columns, flags


def _scaled_curve(curve, factor: np.ndarray):
    """``factor`` times each curve of :func:`_curve_on_arrays` (the same call signature)."""

    def scaled(x, rows=slice(None)):
        expand = (slice(None),) + (None,) * (np.ndim(x) - 1)
        return factor[rows][expand] * curve(x, rows)

    return scaled


def _batched_efficiency(
    formula: Formula, curve, shape, x_max, efficiency_of, x_break, epsilon: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """eta and eps of each curve: the formula's closed forms on arrays (with the solved breaks
    of a moving break), one curve at a time where the closed form needs the measured
    efficiencies in another way, else batched quadrature.  On arrays the closed forms agree
    with their values one curve at a time to 1e-15 relative (numpy's vectorised powers).
    ``epsilon=False``: eps is nan (not integrated)."""
    if formula.efficiency is None:
        eta = _pieces_area(curve, np.zeros_like(x_max), np.ones_like(x_max))
        eps = _pieces_area(curve, np.ones_like(x_max), np.maximum(x_max, 1.0)) if epsilon else np.full(x_max.shape, np.nan)
        return eta, eps
    moving = formula.moving_break
    if moving is not None and moving.efficiency is not None:
        eta, eps = moving.efficiency(shape, x_max, x_break)
    elif efficiency_of is None:
        eta, eps = formula.efficiency(shape, x_max)
    else:
        pairs = [
            formula.efficiency(float(k), float(x), measured_efficiency=float(e)) for k, x, e in zip(shape, x_max, efficiency_of)
        ]
        eta, eps = np.array([float(p[0]) for p in pairs]), np.array([float(p[1]) for p in pairs])
    eps = eps if epsilon else np.nan  # a closed form gives it with eta: left out alike
    return np.broadcast_to(np.asarray(eta, dtype=float), shape.shape), np.broadcast_to(np.asarray(eps, dtype=float), shape.shape)


def _batched_extrapolated(curve, d25, d75, eta, eps, d_cut, x_max, x_break, measured_sizes) -> list[tuple[str, ...]]:
    """``extrapolated`` of each curve: the areas of eta and eps outside the measured sizes by
    the batched quadrature, then the same flags as :func:`extrapolated_indices`."""
    smallest, largest = (np.broadcast_to(np.asarray(v, dtype=float), d_cut.shape) for v in measured_sizes)
    below = np.minimum(smallest / d_cut, 1.0)
    above = np.maximum(largest / d_cut, 1.0)
    area_below = _pieces_area(curve, np.zeros_like(below), below, x_break)
    area_above = _pieces_area(curve, above, np.where(x_max > above, x_max, above), x_break)
    return [
        _extrapolated_flags(
            d25[i], d75[i], eta[i], eps[i], x_max[i], above[i], area_below[i], area_above[i], smallest[i], largest[i]
        )
        for i in range(d_cut.size)
    ]


def _extrapolated_flags(d25, d75, eta, epsilon, x_max, above, area_below, area_above, smallest, largest) -> tuple[str, ...]:
    """The rule of :func:`extrapolated_indices` on areas already integrated."""
    flags = [name for name, size in (("d25", d25), ("d75", d75)) if np.isfinite(size) and not smallest <= size <= largest]
    if eta > 0 and area_below > EXTRAPOLATED_SHARE * eta:
        flags.append("eta")
    if epsilon > 0 and x_max > above and area_above > EXTRAPOLATED_SHARE * epsilon:
        flags.append("epsilon")
    return tuple(flags)


def _curve_on_arrays(formula: Formula, shape: np.ndarray, x_break):
    """``phi(x)`` of each curve, ``x`` of shape ``(N, ...)`` against the ``N`` shapes (``x_break``:
    the solved break points of a moving break, ``Formula.moving_break``)."""

    def curve(x, rows=slice(None)):
        expand = (slice(None),) + (None,) * (np.ndim(x) - 1)
        with np.errstate(all="ignore"):
            if x_break is not None:
                return formula.moving_break.phi(x, shape[rows][expand], x_break[rows][expand])
            return formula.phi(x, shape[rows][expand])

    return curve


def _pieces_area(curve, lower: np.ndarray, upper: np.ndarray, x_break=None) -> np.ndarray:
    """Area under each curve from ``lower`` to ``upper`` (0 where ``upper <= lower``) by
    Gauss-Legendre quadrature on the pieces cut by :data:`_QUADRATURE_BREAKS`, the
    doublings beyond them and the curve's own kink ``x_break``."""
    top = float(np.max(upper, initial=1.0))
    doubling = 2.0 ** np.arange(1, max(int(np.ceil(np.log2(top))), 1) + 1)
    breaks = np.concatenate([_QUADRATURE_BREAKS, doubling])
    edges = np.broadcast_to(breaks, (lower.size, breaks.size))
    if x_break is not None:
        edges = np.sort(np.column_stack([edges, x_break]), axis=1)
    edges = np.clip(edges, lower[:, None], np.maximum(upper, lower)[:, None])
    edges = np.column_stack([lower, edges, np.maximum(upper, lower)])
    nodes, weights = _gauss_legendre()
    half = (edges[:, 1:] - edges[:, :-1]) / 2.0
    middle = (edges[:, 1:] + edges[:, :-1]) / 2.0
    # the curve only on the pieces of positive width (an edge clipped to the limits leaves the
    # others empty: about half of them for eta, more for the areas outside the measured sizes)
    curves, pieces = np.nonzero(half > 0)
    values = np.zeros((*half.shape, nodes.size))
    values[curves, pieces] = curve(middle[curves, pieces, None] + half[curves, pieces, None] * nodes, curves)
    return np.einsum("npk,k,np->n", values, weights, half)


@lru_cache(maxsize=1)
def _gauss_legendre() -> tuple[np.ndarray, np.ndarray]:
    return np.polynomial.legendre.leggauss(GAUSS_LEGENDRE_NODES)


def _relative_sizes_at(curve, levels: tuple[float, ...], count: int) -> list[np.ndarray]:
    """Relative size of each curve's crossing of each of ``levels`` next to the cut (nan where
    none): the bracket of :func:`_relative_size_at` (doubling away from x = 1), then
    Chandrupatla's method, for the roots of all levels in one call (elementwise: each root as
    found alone)."""
    from scipy.optimize import elementwise

    at_one = curve(np.ones((count, 1)))[:, 0]
    powers = 2.0 ** np.arange(0, _DOUBLINGS + 1)
    roots, pending = [], []
    for level in levels:
        at_cut = at_one - level
        outward = np.where(at_cut[:, None] > 0, powers, 1.0 / powers)  # (N, D + 1): 1, 2, 4, ... or 1, 1/2, ...
        gaps = curve(outward) - level
        crossed = np.sign(gaps[:, 1:]) != np.sign(at_cut)[:, None]
        found = crossed.any(axis=1) & (at_cut != 0)
        step = np.argmax(crossed, axis=1)
        rows = np.arange(count)
        inner, outer = outward[rows, step], outward[rows, step + 1]
        roots.append(np.where(at_cut == 0, 1.0, np.nan))
        which = np.flatnonzero(found)
        pending.append((which, np.minimum(inner, outer)[which], np.maximum(inner, outer)[which], np.full(which.size, level)))
    which, low, high, level_of = (np.concatenate(parts) for parts in zip(*pending))
    if which.size:

        def gap(x, rows_of, levels_of):
            return curve(x[:, None], rows_of.astype(int))[:, 0] - levels_of

        result = elementwise.find_root(gap, (low, high), args=(which.astype(float), level_of), tolerances={"xrtol": 1e-14})
        first = 0
        for root, (rows_of, *_) in zip(roots, pending):
            root[rows_of] = result.x[first : first + rows_of.size]
            first += rows_of.size
    return roots
