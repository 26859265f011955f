"""The nine two-parameter separation-curve formulas of Shuvalov et al. (2018).

Every formula is written in the relative size ``x = size / d_cut`` and returns the
partition number *to the fine product* ``phi(x)``, so that ``phi(1) = 0.5``.  Each one
is declared once, in :data:`FORMULAS`, together with everything the rest of the
package needs to know about it: the name and bounds of its shape parameter, the slope
at the cut, the shape that gives a requested slope (the paper's "equal sharpness"
families of Fig. 1 and 2), its equation number and its citation.  Fitting, screening,
ranking, plots and tests iterate over this registry; adding a formula touches this
file only (plus its reference rows in the tests).

References
----------
.. [Shuvalov2018] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the
   choice of a dependence for the Tromp separation curve approximation. *Vestnik IGEU*
   6, 15-23. doi:10.17588/2072-2672.2018.6.015-023
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from functools import cache, lru_cache

import numpy as np
import scipy  # scipy.special and scipy.optimize load when first used: tromplab export needs neither

from .parameters import Parameter, d_cut_parameter

LN2 = np.log(2.0)
SHUVALOV_2018 = (
    "Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a "
    "dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23. "
    "doi:10.17588/2072-2672.2018.6.015-023"
)


@dataclass(frozen=True)
class MovingBreak:
    """Hooks of a piecewise formula whose break point follows its shape and the measured efficiency.

    Formula (11) is ``phi(max(x, x_b))`` with a break ``x_b`` solved from the shape and the
    measured efficiency.  The batched engine (:mod:`tromplab.curves.engine`) and the batched
    indices (:func:`tromplab.curves.indices.batch_curve_indices`) call these hooks instead of
    ``phi``, so that a formula of this kind is declared here and nowhere else.

    Attributes
    ----------
    at : callable
        ``at(shape, measured_efficiency) -> float``: the break of one curve, as ``phi``
        places it (the nearer end of ``[0, 1]`` where none exists).
    on_arrays : callable
        ``on_arrays(shape, measured_efficiency) -> ndarray``: the same break points solved on
        arrays (broadcast), for the engine's many rows at once.
    phi : callable
        ``phi(x, shape, x_break) -> ndarray``: the curve with its break already solved
        (arrays broadcast), so that steps in ``d_cut`` reuse the break points.
    kink : callable or None
        ``kink(measured_efficiency, shape_bounds) -> ndarray``: the shape at which the break
        appears, where the sum of squares has a kink between two basins; the engine then
        starts on both sides of it and fits ``d_cut`` alone there.
    efficiency : callable or None
        ``efficiency(shape, x_max, x_break) -> (eta, eps)`` on arrays, the closed forms with
        the break already solved (the batched indices); None: per curve by ``Formula.efficiency``.
    """

    at: Callable[[float, float], float]
    on_arrays: Callable[..., np.ndarray]
    phi: Callable[..., np.ndarray]
    kink: Callable[..., np.ndarray] | None = None
    efficiency: Callable[..., tuple] | None = None


@dataclass(frozen=True)
class Formula:
    """Declaration of one separation-curve formula.

    Attributes
    ----------
    id : str
        Identifier used in tables, the CLI and tests (``"plitt"``).
    equation : int
        Equation number in [Shuvalov2018]_.
    title : str
        Human-readable name with the original author and year.
    expression : str
        The formula as plain text, in ``x = size/d_cut``.
    shape_name : str
        Name of the shape parameter as in the paper (``km1``, ``ks``, ...).
    shape_meaning : str
        What the shape parameter does to the curve (for :attr:`shape_parameter`).
    shape_bounds : tuple of float
        Closed interval of admissible shape values used by the fits.
    phi : callable
        ``phi(x, shape, **context) -> ndarray``, vectorised in ``x``.
    slope_at_cut : callable
        ``slope_at_cut(shape) -> float``: ``d phi / d x`` at ``x = 1``.
    slope_expression : str
        ``slope_at_cut`` as plain text, for tables.
    shape_for_slope : callable
        ``shape_for_slope(s) -> float``: inverse of ``slope_at_cut`` for ``s < 0``;
        values outside the attainable range are clipped to ``shape_bounds``.
    citation : str
        Source of the formula as given in [Shuvalov2018]_.
    notes : str
        Corrections of the printed form and behaviour worth knowing.
    efficiency : callable or None
        Closed-form ``(eta, eps)`` given ``(shape, x_max, **context)``, where one exists.
    context_from_efficiency : bool
        True when ``phi`` needs the measured classifier efficiency
        (``context = {"measured_efficiency": eta_exp}``), as (11) does.
    monotone : bool
        False when the curve rises again at large sizes for part of the shapes ``phi``
        accepts (the figures of the paper draw such curves); ``shape_bounds`` then keep
        the fits to the monotone shapes, and ``lower_bound_reason`` says why.
    lower_bound_reason : str
        Why the lower shape bound is where it is, for the warning of a fit that ends on it.
    extras : tuple of Parameter
        Further fitted parameters (extended curves only); ``phi`` takes them as keywords.
    family : str
        ``"paper"`` for the nine formulas of [Shuvalov2018]_, ``"extended"`` for the
        curves with bypass or fish-hook, ``"other"`` for the curves of other tools
        (both kept out of the paper's ranking by default).
    nests : str or None
        Id of the paper formula this one reduces to when its extras vanish (for the
        extra-sum-of-squares test).
    piecewise : bool
        True when ``phi`` is pieced together at a break (formulas (10) and (11)): the sum
        of squares has kinks where a measured point crosses the break, so the batched
        engine searches a finer shape grid with more starts and follows its
        Levenberg-Marquardt pass with a derivative-free search.
    moving_break : MovingBreak or None
        The break of a piecewise formula whose break point moves with the shape and the
        measured efficiency ((11)): the hooks the batched engine and the batched indices
        call instead of ``phi`` (:class:`MovingBreak`); None for every other formula.
    bypass_of : Formula or None
        The formula this one is with bypass (:func:`with_bypass`): ``phi = (1 - bypass)``
        times its ``phi``, so that the batched indices
        (:func:`tromplab.curves.indices.batch_curve_indices`) are built on the base's; None
        for every other formula.
    """

    id: str
    equation: int
    title: str
    expression: str
    shape_name: str
    shape_bounds: tuple[float, float]
    phi: Callable[..., np.ndarray]
    slope_at_cut: Callable[[float], float]
    shape_for_slope: Callable[[float], float]
    slope_expression: str
    citation: str
    notes: str = ""
    efficiency: Callable[..., tuple[float, float]] | None = None
    context_from_efficiency: bool = False
    monotone: bool = True
    lower_bound_reason: str = ""
    defaults: Mapping[str, float] = field(default_factory=dict)
    extras: tuple[Parameter, ...] = ()
    family: str = "paper"
    nests: str | None = None
    shape_meaning: str = ""
    piecewise: bool = False
    moving_break: MovingBreak | None = None
    bypass_of: Formula | None = None

    def __reduce__(self):
        # Records hold lambdas and closures; they travel (pickle, process pools) by their id.
        return (get_formula, (self.id,))

    @property
    def n_params(self) -> int:
        """Number of fitted parameters: d_cut, the shape and the extras."""
        return 2 + len(self.extras)

    def __call__(self, size, d_cut: float, shape: float, **context) -> np.ndarray:
        """Partition to fines at ``size`` (same unit as ``d_cut``)."""
        x = np.asarray(size, dtype=float) / d_cut
        return self.phi(x, shape, **context)

    def clip_shape(self, shape: float) -> float:
        low, high = self.shape_bounds
        return float(np.clip(shape, low, high))

    @property
    def shape_parameter(self) -> Parameter:
        """The shape parameter as a :class:`Parameter` record (dimensionless)."""
        return Parameter(
            self.shape_name,
            *self.shape_bounds,
            unit="1",
            meaning=self.shape_meaning,
            start_rule="the shape whose slope at the cut equals the measured slope (shape_for_slope)",
        )

    def parameters(self, sizes) -> tuple[Parameter, ...]:
        """Every fitted parameter for a curve measured at ``sizes``: d_cut, the shape, the extras."""
        return (d_cut_parameter(sizes), self.shape_parameter, *self.extras)


def _as_array(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def _log(x: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return np.log(x)


# --- (3) Molerus -----------------------------------------------------------------------
def molerus(x, km1):
    r"""Molerus' separation curve, formula (3) of Shuvalov et al. (2018).

    .. math::
        \varphi(x) = \frac{1}{1 + e^{-k_{m1}(1 - x^2)}}

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    km1 : float
        Shape, 1e-6..60 (dimensionless); larger is sharper.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Valid and decreasing for :math:`x > 0` and :math:`k_{m1} > 0`.  Slope at the cut
    :math:`-k_{m1}/2`.  The only formula of the nine with
    :math:`\varphi(0) = 1/(1 + e^{-k_{m1}}) < 1`: some fines report to the coarse product.

    References
    ----------
    .. [1] Molerus O. (1967). Stochastisches Modell der Gleichgewichtssichtung. Chemie Ingenieur
       Technik 39(13), 792-796.
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> round(float(molerus(1.5, 4.0)), 10)
    0.0066928509
    """
    x = _as_array(x)
    return scipy.special.expit(km1 * (1.0 - x * x))


# --- (4) Molerus-Hoffmann --------------------------------------------------------------
def molerus_hoffmann(x, km2):
    r"""Molerus and Hoffmann's separation curve, formula (4) of Shuvalov et al. (2018).

    .. math::
        \varphi(x) = \frac{1}{1 + x^2 e^{-k_{m2}(1 - x^2)}}

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    km2 : float
        Shape, 0..60 (dimensionless) as fitted; ``km2 = 0`` is Plitt's curve with ``ks = 2``.
        The curve is also defined for ``km2 < 0``, where it rises again (Notes).

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Decreasing for all :math:`x > 0` when :math:`k_{m2} \ge 0`; for :math:`k_{m2} < 0`
    the curve has a minimum at :math:`x = 1/\sqrt{-k_{m2}}` and rises towards 1 beyond
    it.  Slope at the cut :math:`-(1 + k_{m2})/2`.

    References
    ----------
    .. [1] Molerus O., Hoffmann H. (1969). Darstellung von Windsichtertrennkurven durch ein
       stochastisches Modell. Chemie Ingenieur Technik 41(5-6), 340-344.
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> round(float(molerus_hoffmann(1.5, 2.0)), 10)
    0.0351981161
    """
    x = _as_array(x)
    return scipy.special.expit(km2 * (1.0 - x * x) - 2.0 * _log(x))


# --- (5) Rosin-Rammler form ------------------------------------------------------------
def rosin_rammler(x, kr):
    r"""Rosin-Rammler form of the separation curve, formula (5) of Shuvalov et al. (2018).

    .. math::
        \varphi(x) = \exp(-\ln 2\; x^{k_r})

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    kr : float
        Shape, 0.05..40 (dimensionless): the uniformity exponent, larger is sharper.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Valid and decreasing for :math:`x > 0`, :math:`k_r > 0`, with :math:`\varphi(0) = 1`.
    Slope at the cut :math:`-k_r \ln 2 / 2`.  Base of formulas (10) and (11).

    References
    ----------
    .. [1] Rosin P., Rammler E. (1933). The laws governing the fineness of powdered coal.
       J. Inst. Fuel 7, 29-36.
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> round(float(rosin_rammler(1.5, 3.0)), 10)
    0.0963881766
    """
    x = _as_array(x)
    return np.exp(-LN2 * np.power(x, kr))


def _rosin_rammler_area(lower, upper, kr):
    """Integral of the Rosin-Rammler form from ``lower`` to ``upper`` (closed form)."""
    a = 1.0 / kr
    scale = scipy.special.gamma(a) * LN2 ** (-a) / kr
    return scale * (scipy.special.gammainc(a, LN2 * upper**kr) - scipy.special.gammainc(a, LN2 * lower**kr))


def _rosin_rammler_efficiency(kr, x_max):
    return _rosin_rammler_area(0.0, 1.0, kr), _rosin_rammler_area(1.0, np.maximum(x_max, 1.0), kr)


# --- (6) Lynch -------------------------------------------------------------------------
def lynch(x, kl):
    r"""Lynch and Rao's separation curve, formula (6) of Shuvalov et al. (2018).

    .. math::
        \varphi(x) = 1 - \frac{e^{k_l x} - 1}{e^{k_l x} + e^{k_l} - 2}

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    kl : float
        Shape, 1e-6..120 (dimensionless): Whiten's alpha, larger is sharper.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Valid and decreasing for :math:`x > 0`, :math:`k_l > 0`.  Evaluated as
    :math:`(1 - e^{-k_l})/(e^{k_l(x-1)} + 1 - 2e^{-k_l})`, which equals the printed form
    but lets large sizes underflow to 0 instead of giving inf/inf, with
    :math:`1 - e^{-k_l}` and :math:`e^{k_l(x-1)} - 1` taken by ``expm1`` (at the lower
    shape bound, :math:`k_l = 10^{-6}`, the plain differences lost ten digits).  Slope at the cut
    :math:`-k_l e^{k_l} / (4 (e^{k_l} - 1))`, never shallower than -1/4 (the limit
    :math:`k_l \to 0` is Plitt's curve with :math:`k_s = 1`).  Shuvalov et al. attribute
    it to Lynch (1977); the form was published by Lynch and Rao (1975).

    References
    ----------
    .. [1] Lynch A.J., Rao T.C. (1975). Modelling and scale-up of hydrocyclone classifiers.
       Proc. 11th International Mineral Processing Congress, Cagliari, 245-269.
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> round(float(lynch(1.5, 3.0)), 10)
    0.1765501004
    """
    x = _as_array(x)
    with np.errstate(over="ignore"):
        grow = np.expm1(kl * (x - 1.0))
    passed = -np.expm1(-kl)  # 1 - e^-kl
    return passed / (grow + 2.0 * passed)


def _lynch_at(x: float, kl: float) -> float:
    """:func:`lynch` at one relative size, with the math module: the same expression, a tenth
    of numpy's cost on a scalar (Whiten's ``beta*`` root evaluates it once per step)."""
    passed = -math.expm1(-kl)
    try:
        return passed / (math.expm1(kl * (x - 1.0)) + 2.0 * passed)
    except OverflowError:  # e^(kl (x - 1)) beyond the floats: the curve is 0 there, as lynch() gives
        return 0.0


def _lynch_slope(kl):
    return -kl / (4.0 * -np.expm1(-kl))


# --- (7) Plitt -------------------------------------------------------------------------
def plitt(x, ks):
    r"""Plitt's separation curve, formula (7) of Shuvalov et al. (2018).

    .. math::
        \varphi(x) = \frac{1}{1 + x^{k_s}}

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    ks : float
        Shape, 0.05..60 (dimensionless): larger is sharper.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Valid and decreasing for :math:`x > 0`, :math:`k_s > 0` (a log-logistic curve in
    size).  Slope at the cut :math:`-k_s/4`.

    References
    ----------
    .. [1] Plitt L.R. (1971). The analysis of solid-solid separations in classifiers. CIM Bulletin
       64(708), 42-47.
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> round(float(plitt(1.5, 3.0)), 10)
    0.2285714286
    """
    x = _as_array(x)
    return scipy.special.expit(-ks * _log(x))


#: Above this ``ks ln x`` the power ``x^ks`` of Plitt's area nears the floating-point limit
#: (e^709): the area is then the whole area less the tail beyond x.
_PLITT_FAR = 600.0


def _plitt_efficiency(ks, x_max):
    a = 1.0 / ks

    def area_to(upper):
        with np.errstate(over="ignore"):  # x^ks = inf gave 2F1 = 0 and a negative epsilon
            direct = upper * scipy.special.hyp2f1(1.0, a, 1.0 + a, -(upper**ks))
        far = (ks * np.log(upper) > _PLITT_FAR) & (ks > 1.0)
        if not np.any(far):
            return direct
        # the area from 0 to infinity, (pi/ks) / sin(pi/ks), less the tail from upper on:
        # upper^(1-ks) / (ks-1) 2F1(1, 1-a; 2-a; -upper^-ks) (term by term from the series)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            whole = np.pi * a / np.sin(np.pi * a)
            tail = upper ** (1.0 - ks) / (ks - 1.0) * scipy.special.hyp2f1(1.0, 1.0 - a, 2.0 - a, -(upper**-ks))
        return np.where(far, whole - tail, direct)

    eta = area_to(1.0)
    return eta, area_to(np.maximum(x_max, 1.0)) - eta


# --- (8) Ogawa, Allen's law ------------------------------------------------------------
def ogawa_allen(x, kp):
    r"""Ogawa's form of Allen's law, formula (8) of Shuvalov et al. (2018), corrected.

    .. math::
        \varphi(x) = \frac{1}{1 + x\, e^{-k_p (1 - x)}}

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    kp : float
        Shape, 0..60 (dimensionless) as fitted; ``kp = 0`` is Plitt's curve with ``ks = 1``.
        The curve is also defined for ``kp < 0``, where it rises again (Notes).

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    The paper prints :math:`e^{-k_p x}`, which gives :math:`\varphi(1) \ne 1/2` and
    contradicts its own slope (17); the exponent :math:`-k_p (1 - x)` is implemented
    (docs/errata.md).  Decreasing for :math:`k_p \ge 0`; for :math:`k_p < 0` the curve
    has a minimum at :math:`x = -1/k_p` and rises again.  Slope at the cut
    :math:`-(1 + k_p)/4`.

    References
    ----------
    .. [1] Ogawa K., Allen's-law form of the partition curve; the primary source could not be
       verified and is taken as given by Shuvalov et al. (2018).
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> round(float(ogawa_allen(1.5, 2.0)), 10)
    0.1969503133
    """
    x = _as_array(x)
    return scipy.special.expit(kp * (1.0 - x) - _log(x))


# --- (9) log-normal --------------------------------------------------------------------
def lognormal(x, kf):
    r"""Gauss integral of the log-normal law, formula (9) of Shuvalov et al. (2018).

    .. math::
        \varphi(x) = \tfrac12 \operatorname{erfc}\left(\frac{\ln x}{k_f}\right)

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    kf : float
        Shape, 0.01..30 (dimensionless): :math:`\sqrt 2\,\sigma` of :math:`\ln` size;
        smaller is sharper.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Valid and decreasing for :math:`x > 0`, :math:`k_f > 0`.  Slope at the cut
    :math:`-1/(\sqrt\pi\, k_f)`.

    References
    ----------
    .. [1] Log-normal (Gauss integral) form of the partition curve as given by Shuvalov et al.
       (2018); no single primary source is named there.
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> round(float(lognormal(1.5, 0.8)), 10)
    0.2367586858
    """
    x = _as_array(x)
    return 0.5 * scipy.special.erfc(_log(x) / kf)


def _lognormal_efficiency(kf, x_max):
    r"""``(eta, eps)`` of formula (9) in closed form, free of cancellation over the shape range.

    The textbook forms (package spec, section 3)

    .. math::
        \eta = \tfrac12 + \tfrac12 e^{k_f^2/4}\operatorname{erfc}(k_f/2), \qquad
        \varepsilon = \tfrac12 X \operatorname{erfc}(L/k_f) - \tfrac12
        + \tfrac12 e^{k_f^2/4}\left[\operatorname{erf}\left(\frac{L - k_f^2/2}{k_f}\right)
        + \operatorname{erf}(k_f/2)\right],\quad L = \ln X,

    multiply :math:`e^{k_f^2/4}` (1e23 at kf = 14.5) by a difference of two error functions
    near 1: eps lost 3e-3 at kf = 12 and 4-12 % at kf 14.5-30.  Written with the scaled
    complementary error function :math:`\operatorname{erfcx}(z) = e^{z^2}\operatorname{erfc}(z)`
    and :math:`c = k_f/2 - L/k_f` they read

    .. math::
        \eta = \tfrac12 + \tfrac12 \operatorname{erfcx}(k_f/2), \qquad
        \varepsilon = \tfrac12 (X - 1)\operatorname{erfc}(L/k_f) + \tfrac12 \left[G - \operatorname{erf}(L/k_f)\right],

    .. math::
        G = e^{k_f^2/4}\left[\operatorname{erfc}(c) - \operatorname{erfc}(k_f/2)\right]
          = e^{L - L^2/k_f^2}\operatorname{erfcx}(c) - \operatorname{erfcx}(k_f/2) \quad (c \ge 0),

    and for :math:`c < 0` (:math:`k_f^2 < 2L`, so :math:`e^{k_f^2/4} < \sqrt X` stays small)
    :math:`G` is taken as written.  Both terms of eps are non-negative (the bracket is
    :math:`\frac{2}{\sqrt\pi k_f}\int_0^L (e^u - 1) e^{-u^2/k_f^2} du`), so nothing large
    cancels: eta and eps agree with the printed forms evaluated by mpmath at 250 digits to
    2e-12 relative over kf 0.01..30 and X 1.001..1e300 (``tests/test_indices.py``).  As for
    every closed form, eps is a difference of order ``X - 1`` when ``X`` is within 1e-3 of
    the cut: its absolute error stays at 1e-16, its relative error grows as
    ``1e-16 / (X - 1)``.
    """
    eta = 0.5 + 0.5 * scipy.special.erfcx(kf / 2.0)
    big_x = np.maximum(x_max, 1.0)
    log_x = np.log(big_x)
    ratio = log_x / kf
    c = kf / 2.0 - ratio
    with np.errstate(over="ignore", invalid="ignore"):  # each branch where the other is taken may overflow
        shifted = np.where(
            c >= 0.0, np.exp(log_x - ratio * ratio) * scipy.special.erfcx(c), np.exp(kf * kf / 4.0) * scipy.special.erfc(c)
        )
    g = shifted - scipy.special.erfcx(kf / 2.0)
    eps = 0.5 * (big_x - 1.0) * scipy.special.erfc(ratio) + 0.5 * (g - scipy.special.erf(ratio))
    return eta, eps[()]


# --- (10), (11) Rosin-Rammler with a flat fines plateau ---------------------------------
def rosin_rammler_plateau(x, kr, x_break):
    r"""Rosin-Rammler form above ``x_break``, constant :math:`\varphi(x_b)` below it."""
    x = _as_array(x)
    return rosin_rammler(np.maximum(x, x_break), kr)


def _plateau_efficiency(kr, x_max, x_break):
    plateau = x_break * rosin_rammler(x_break, kr)
    eta = plateau + _rosin_rammler_area(x_break, 1.0, kr)
    return eta[()], _rosin_rammler_area(1.0, np.maximum(x_max, 1.0), kr)


LUCKIE_AUSTIN_BREAK = 0.5


def luckie_austin(x, kr):
    r"""Luckie and Austin's piecewise curve, formula (10) of Shuvalov et al. (2018), corrected.

    .. math::
        \varphi(x) = \exp\left(-\ln 2\, \max(x, \tfrac12)^{k_r}\right)

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    kr : float
        Shape, 0.05..40 (dimensionless), as in :func:`rosin_rammler`.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Printed as :math:`1 - \exp(-\ln 2\, x^{k_r})` (the coarse-product form); the paper
    states the branch coincides with (5) and has its slope, so the fines branch is
    implemented, held at its value at the break :math:`x = 1/2` below it (continuous,
    two parameters; docs/errata.md).  Non-increasing for :math:`k_r > 0`; slope at the
    cut :math:`-k_r \ln 2 / 2`.

    References
    ----------
    .. [1] Luckie P.T., Austin L.G. (1972). A review introduction to the solution of the grinding
       equations by digital computation. Minerals Science and Engineering 4(2), 24-51.
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> round(float(luckie_austin(0.3, 3.0)), 10), round(float(luckie_austin(1.5, 3.0)), 10)
    (0.9170040432, 0.0963881766)
    """
    return rosin_rammler_plateau(x, kr, LUCKIE_AUSTIN_BREAK)


def shuvalov_break(kr: float, measured_efficiency: float) -> float:
    r"""Break point :math:`x_a` of formula (11) for a given measured efficiency.

    Solves :math:`\eta_{exp} = x_a \varphi_5(x_a) + \int_{x_a}^1 \varphi_5\,dx`, whose
    right-hand side falls monotonically from the efficiency of (5) at :math:`x_a = 0`
    to 1/2 at :math:`x_a = 1`.

    Raises
    ------
    NoBreakPointError
        When ``measured_efficiency`` is outside ``[0.5, eta_5(kr)]``.
    """
    eta_plain, _ = _rosin_rammler_efficiency(kr, 1.0)
    if not 0.5 <= measured_efficiency <= eta_plain:
        raise NoBreakPointError(kr, measured_efficiency, eta_plain)
    if measured_efficiency == eta_plain:
        return 0.0
    return scipy.optimize.brentq(lambda xa: _plateau_efficiency(kr, 1.0, xa)[0] - measured_efficiency, 0.0, 1.0, xtol=1e-14)


class NoBreakPointError(ValueError):
    """Formula (11) has no break point for this shape and measured efficiency."""

    def __init__(self, kr, measured_efficiency, eta_plain):
        self.kr = kr
        self.measured_efficiency = measured_efficiency
        self.eta_plain = eta_plain
        super().__init__(
            f"formula (11): no break point x_a exists for kr = {kr:.4g}: the measured "
            f"efficiency {measured_efficiency:.4f} must lie in [0.5, {eta_plain:.4f}] "
            "(0.5 = step at the cut, upper end = efficiency of the plain Rosin-Rammler form (5))"
        )


def _shuvalov_break_or_edge(kr, measured_efficiency):
    """x_a, or the nearer end of [0, 1] when no break point exists (flagged by the fit)."""
    if np.ndim(kr) == 0 and np.ndim(measured_efficiency) == 0:
        return _break_or_edge_of(float(kr), float(measured_efficiency))
    return _break_or_edge_uncached(kr, measured_efficiency)


@lru_cache(maxsize=4096)
def _break_or_edge_of(kr: float, measured_efficiency: float) -> float:
    # Remembered: root finding and quadrature evaluate the curve of one fit hundreds of
    # times at the same shape, and each evaluation would solve for x_a again.
    return _break_or_edge_uncached(kr, measured_efficiency)


def _break_or_edge_uncached(kr, measured_efficiency):
    try:
        return shuvalov_break(kr, measured_efficiency)
    except NoBreakPointError:
        return 1.0 if measured_efficiency < 0.5 else 0.0


def shuvalov(x, kr, *, measured_efficiency):
    r"""Shuvalov's piecewise curve, formula (11) of Shuvalov et al. (2018), corrected.

    .. math::
        \varphi(x) = \exp\left(-\ln 2\, \max(x, x_a)^{k_r}\right),\quad
        x_a \varphi_5(x_a) + \int_{x_a}^1 \varphi_5\,dx = \eta_{exp}

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    kr : float
        Shape, 0.05..40 (dimensionless), as in :func:`rosin_rammler`.
    measured_efficiency : float
        Classifier efficiency of the measured curve, 0.5..1 (dimensionless;
        :func:`tromplab.curves.measured.measured_efficiency`).

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    :math:`x_a` (:func:`shuvalov_break`) makes the area under the curve on
    :math:`0 < x < 1` equal the measured efficiency.  Where no such :math:`x_a` exists
    the curve falls back to the nearer limit (plain (5) or a step at the cut); fits report
    this case.  Printed with the coarse-product branch like (10) (docs/errata.md).
    Non-increasing for :math:`k_r > 0`; slope at the cut :math:`-k_r \ln 2 / 2`.

    References
    ----------
    .. [1] Shuvalov S.I. (1992), piecewise partition curve; the primary source could not be verified
       and is taken as given by Shuvalov et al. (2018).
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23.
       doi:10.17588/2072-2672.2018.6.015-023

    Examples
    --------
    >>> [round(float(v), 8) for v in shuvalov([0.2, 1.5], 3.0, measured_efficiency=0.8)]
    [0.87066579, 0.09638818]
    """
    return rosin_rammler_plateau(x, kr, _shuvalov_break_or_edge(kr, measured_efficiency))


def _shuvalov_efficiency(kr, x_max, *, measured_efficiency):
    return _plateau_efficiency(kr, x_max, _shuvalov_break_or_edge(kr, measured_efficiency))


def shuvalov_breaks(kr, efficiency) -> np.ndarray:
    r"""Break points :math:`x_a` of formula (11), vectorised over ``kr`` and ``efficiency``.

    Solves :math:`F(x_a) = x_a \varphi_5(x_a) + \int_{x_a}^1 \varphi_5\,dx = \eta_{exp}`
    (the left side falls monotonically from :math:`\eta_5(k_r)` at 0 to 1/2 at 1) by Newton
    steps kept inside a bisection bracket.  The steps are taken in :math:`w = x_a^{k_r + 1}`:
    near :math:`x_a = 0` the left side is flat like :math:`x_a^{k_r + 1}`, so in :math:`x_a`
    Newton's steps stall (about 35 per root), while in :math:`w` the derivative
    :math:`dF/dw = -\ln 2\, k_r \varphi_5(x_a) / (k_r + 1)` never vanishes and a root
    takes about 7 steps.  Outside :math:`[1/2, \eta_5]` the nearer end is returned, as
    :func:`tromplab.curves.formulas.shuvalov` does.

    Examples
    --------
    >>> from tromplab.curves.formulas import shuvalov_break
    >>> bool(abs(shuvalov_breaks(2.0, 0.8) - shuvalov_break(2.0, 0.8)) < 1e-13)
    True
    """
    kr, efficiency = np.broadcast_arrays(np.asarray(kr, dtype=float), np.asarray(efficiency, dtype=float))
    # _rosin_rammler_area(x, 1, k) = scale * (whole - gammainc(1/k, ln2 x^k)): the parts without x
    # once, and eta_5 = _rosin_rammler_area(0, 1, k) = scale * whole (gammainc(a, 0) = 0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a = 1.0 / kr
        scale = scipy.special.gamma(a) * LN2 ** (-a) / kr
        whole = scipy.special.gammainc(a, LN2)
        eta_plain = scale * whole
    result = np.where(efficiency < 0.5, 1.0, 0.0)
    solve = (efficiency >= 0.5) & (efficiency < eta_plain)
    k, target = kr[solve], efficiency[solve]
    a, scale, whole = a[solve], scale[solve], whole[solve]
    exponent = 1.0 / (k + 1.0)
    low, high = np.zeros_like(k), np.ones_like(k)
    w = np.full_like(k, 0.5)
    open_ = np.arange(k.size)
    for _ in range(100):
        kk, ww = k[open_], w[open_]
        x = ww ** exponent[open_]
        power = x**kk
        phi = np.exp(-LN2 * power)
        value = x * phi + scale[open_] * (whole[open_] - scipy.special.gammainc(a[open_], LN2 * power)) - target[open_]
        lo = np.where(value > 0, ww, low[open_])
        hi = np.where(value > 0, high[open_], ww)
        newton = ww + value * (kk + 1.0) / (LN2 * kk * phi)
        step = np.where((newton > lo) & (newton < hi), newton, 0.5 * (lo + hi))
        converged = np.abs(value) <= 1e-16
        step = np.where(converged, ww, step)
        low[open_], high[open_], w[open_] = lo, hi, step
        done = converged | (np.abs(step - ww) <= 1e-15) | (hi - lo <= 1e-15)
        open_ = open_[~done]
        if not open_.size:
            break
    result[solve] = w**exponent
    return result


def shuvalov_kink(efficiency, bounds) -> np.ndarray:
    r"""Shape :math:`k_r^*` of formula (11) where the break point appears: :math:`\eta_5(k_r^*) = \eta_{exp}`.

    Below it (in a sharper-than-measured sense) no break exists and (11) is the plain
    Rosin-Rammler form (5); the sum of squares has a kink there that separates two basins,
    so the engine starts on both sides of it.  Clipped to ``bounds``.
    """
    efficiency = np.asarray(efficiency, dtype=float)
    low, high = np.full(efficiency.shape, np.log(bounds[0])), np.full(efficiency.shape, np.log(bounds[1]))
    for _ in range(60):  # eta_5 rises with kr from 1/2 towards 1
        middle = 0.5 * (low + high)
        above = _rosin_rammler_area(0.0, 1.0, np.exp(middle)) > efficiency
        low, high = np.where(above, low, middle), np.where(above, middle, high)
    return np.exp(0.5 * (low + high))


#: The moving break of (11): x_a from kr and the measured efficiency.
SHUVALOV_BREAK = MovingBreak(
    at=_shuvalov_break_or_edge,
    on_arrays=shuvalov_breaks,
    phi=rosin_rammler_plateau,
    kink=shuvalov_kink,
    efficiency=_plateau_efficiency,
)


#: Shape range searched for Lynch's start; its slope at the cut runs from -0.25 (kl -> 0) to -200.
_LYNCH_START_SHAPES = (1e-9, 800.0)


def _lynch_shape_for_slope(s):
    low, high = _LYNCH_START_SHAPES
    target = -s
    # compared with the slopes at the ends themselves, not with their limits: a measured slope
    # of -0.25000000000000006 (a size-unit rounding) lay beyond the slope at 1e-9, so the root
    # was not bracketed and the whole fit failed in one unit only
    if target <= -_lynch_slope(low):
        return 1e-6
    if target >= -_lynch_slope(high):
        return high
    return scipy.optimize.brentq(lambda kl: -_lynch_slope(kl) - target, low, high, xtol=1e-14)


def _rosin_rammler_shape_for_slope(s):
    return -2.0 * s / LN2


MOLERUS_1967 = "Molerus O. (1967). Stochastisches Modell der Gleichgewichtssichtung. Chemie Ingenieur Technik 39(13), 792-796"
MOLERUS_HOFFMANN_1969 = (
    "Molerus O., Hoffmann H. (1969). Darstellung von Windsichtertrennkurven durch ein stochastisches Modell. "
    "Chemie Ingenieur Technik 41(5-6), 340-344"
)
ROSIN_RAMMLER_1933 = "Rosin P., Rammler E. (1933). The laws governing the fineness of powdered coal. J. Inst. Fuel 7, 29-36"
LYNCH_RAO_1975 = (
    "Lynch A.J., Rao T.C. (1975). Modelling and scale-up of hydrocyclone classifiers. Proc. 11th International "
    "Mineral Processing Congress, Cagliari, 245-269"
)
PLITT_1971 = "Plitt L.R. (1971). The analysis of solid-solid separations in classifiers. CIM Bulletin 64(708), 42-47"
OGAWA = "Ogawa K., Allen's-law form of the partition curve (primary source not verified; as given by Shuvalov et al. 2018)"
LUCKIE_AUSTIN_1972 = (
    "Luckie P.T., Austin L.G. (1972). A review introduction to the solution of the grinding equations by digital "
    "computation. Minerals Science and Engineering 4(2), 24-51"
)
SHUVALOV_1992 = "Shuvalov S.I. (1992), piecewise partition curve (primary source not verified; as given by Shuvalov et al. 2018)"


def _in(source: str, equation: int) -> str:
    return f"{source}; as formula ({equation}) in {SHUVALOV_2018}"


def with_plateau(
    base: Formula,
    *,
    id: str,
    equation: int,
    title: str,
    phi,
    break_text: str,
    citation: str,
    notes: str,
    efficiency=None,
    context_from_efficiency: bool = False,
    defaults=None,
    moving_break: MovingBreak | None = None,
) -> Formula:
    """``base`` above a break ``x_b``, held at its value there below (formulas (10) and (11)).

    The shape, its bounds, the slope at the cut (``x_b < 1``) and the expression are the
    base formula's; ``break_text`` names the break (``"1/2"``, ``"x_a"``) in the expression.
    The record is ``piecewise``; ``moving_break`` declares a break that moves with the shape.
    """
    expression = re.sub(r"\bx\b", f"max(x, {break_text})", base.expression)
    return Formula(
        id=id,
        equation=equation,
        title=title,
        expression=expression,
        shape_name=base.shape_name,
        shape_bounds=base.shape_bounds,
        phi=phi,
        slope_at_cut=base.slope_at_cut,
        slope_expression=base.slope_expression,
        shape_for_slope=base.shape_for_slope,
        citation=citation,
        notes=notes,
        efficiency=efficiency,
        context_from_efficiency=context_from_efficiency,
        defaults=defaults or {},
        shape_meaning=base.shape_meaning,
        piecewise=True,
        moving_break=moving_break,
    )


_PAPER_BASES: tuple[Formula, ...] = (
    Formula(
        id="molerus",
        equation=3,
        title="Molerus (1967)",
        expression="1/(1 + exp(-km1*(1 - x^2)))",
        shape_name="km1",
        shape_bounds=(1e-6, 60.0),
        phi=molerus,
        slope_at_cut=lambda km1: -km1 / 2.0,
        slope_expression="-km1/2",
        shape_for_slope=lambda s: -2.0 * s,
        citation=_in(MOLERUS_1967, 3),
        notes="phi(0) < 1: some fines report to the coarse product.",
        shape_meaning="sharpness of the cut; also sets the fines lost to the coarse product, 1 - phi(0)",
    ),
    Formula(
        id="molerus_hoffmann",
        equation=4,
        title="Molerus and Hoffmann (1969)",
        expression="1/(1 + x^2*exp(-km2*(1 - x^2)))",
        shape_name="km2",
        shape_bounds=(0.0, 60.0),
        phi=molerus_hoffmann,
        slope_at_cut=lambda km2: -(1.0 + km2) / 2.0,
        slope_expression="-(1 + km2)/2",
        shape_for_slope=lambda s: -2.0 * s - 1.0,
        citation=_in(MOLERUS_HOFFMANN_1969, 4),
        notes="km2 = 0 is Plitt with ks = 2; km2 < 0 has a minimum at x = 1/sqrt(-km2) and rises again, so "
        "fits keep km2 >= 0 (slope at the cut -1/2 or steeper).",
        monotone=False,
        shape_meaning="sharpness beyond Plitt's ks = 2 curve (km2 = 0); fits keep km2 >= 0, as negative values let the "
        "curve rise again",
        lower_bound_reason="km2 < 0 would make the curve rise again beyond x = 1/sqrt(-km2) (not a monotone "
        "partition curve); the best monotone curve is shown",
    ),
    Formula(
        id="rosin_rammler",
        equation=5,
        title="Rosin-Rammler form",
        expression="exp(-ln2*x^kr)",
        shape_name="kr",
        shape_bounds=(0.05, 40.0),
        phi=rosin_rammler,
        slope_at_cut=lambda kr: -LN2 * kr / 2.0,
        slope_expression="-ln2*kr/2",
        shape_for_slope=_rosin_rammler_shape_for_slope,
        citation=_in(ROSIN_RAMMLER_1933, 5),
        efficiency=_rosin_rammler_efficiency,
        shape_meaning="uniformity exponent of the Rosin-Rammler law: larger kr, sharper cut",
    ),
    Formula(
        id="lynch",
        equation=6,
        title="Lynch and Rao (1975)",
        expression="1 - (exp(kl*x) - 1)/(exp(kl*x) + exp(kl) - 2)",
        shape_name="kl",
        shape_bounds=(1e-6, 120.0),
        phi=lynch,
        slope_at_cut=_lynch_slope,
        slope_expression="-kl*exp(kl)/(4*(exp(kl) - 1))",
        shape_for_slope=_lynch_shape_for_slope,
        citation=_in(LYNCH_RAO_1975, 6),
        notes="The slope at the cut is never shallower than -1/4 (kl -> 0 is Plitt with ks = 1).",
        shape_meaning="sharpness of the cut (alpha of Whiten's curve); kl -> 0 gives Plitt's ks = 1",
    ),
    Formula(
        id="plitt",
        equation=7,
        title="Plitt (1971)",
        expression="1/(1 + x^ks)",
        shape_name="ks",
        shape_bounds=(0.05, 60.0),
        phi=plitt,
        slope_at_cut=lambda ks: -ks / 4.0,
        slope_expression="-ks/4",
        shape_for_slope=lambda s: -4.0 * s,
        citation=_in(PLITT_1971, 7),
        efficiency=_plitt_efficiency,
        shape_meaning="sharpness of the cut: the log-logistic slope, larger ks steeper",
    ),
    Formula(
        id="ogawa_allen",
        equation=8,
        title="Ogawa, Allen's law",
        expression="1/(1 + x*exp(-kp*(1 - x)))",
        shape_name="kp",
        shape_bounds=(0.0, 60.0),
        phi=ogawa_allen,
        slope_at_cut=lambda kp: -(1.0 + kp) / 4.0,
        slope_expression="-(1 + kp)/4",
        shape_for_slope=lambda s: -4.0 * s - 1.0,
        citation=_in(OGAWA, 8),
        notes="Printed with exp(-kp x); corrected to exp(-kp (1 - x)) (phi(1) = 0.5, slope (17)). "
        "kp < 0 rises again beyond x = -1/kp, so fits keep kp >= 0 (slope at the cut -1/4 or steeper).",
        monotone=False,
        shape_meaning="sharpness beyond Plitt's ks = 1 curve (kp = 0); fits keep kp >= 0, as negative values let the "
        "curve rise again",
        lower_bound_reason="kp < 0 would make the curve rise again beyond x = -1/kp (not a monotone partition "
        "curve); the best monotone curve is shown",
    ),
    Formula(
        id="lognormal",
        equation=9,
        title="Log-normal (Gauss integral)",
        expression="erfc(ln(x)/kf)/2",
        shape_name="kf",
        shape_bounds=(0.01, 30.0),
        phi=lognormal,
        slope_at_cut=lambda kf: -1.0 / (np.sqrt(np.pi) * kf),
        slope_expression="-1/(sqrt(pi)*kf)",
        shape_for_slope=lambda s: -1.0 / (np.sqrt(np.pi) * s),
        citation=_in("Log-normal (Gauss integral) law of the partition curve", 9),
        notes="kf = sqrt(2) sigma of ln(size).",
        efficiency=_lognormal_efficiency,
        shape_meaning="spread: sqrt(2) times the standard deviation of ln(size); smaller kf, sharper cut",
    ),
)
_ROSIN_RAMMLER = _PAPER_BASES[2]

FORMULAS: tuple[Formula, ...] = (
    *_PAPER_BASES,
    with_plateau(
        _ROSIN_RAMMLER,
        id="luckie_austin",
        equation=10,
        title="Luckie and Austin (1972), piecewise",
        phi=luckie_austin,
        break_text="1/2",
        citation=_in(LUCKIE_AUSTIN_1972, 10),
        notes="Printed as the coarse-product branch 1 - exp(...); corrected to the fines branch of (5), "
        "with the plateau equal to the value at x = 1/2 (continuity).",
        efficiency=lambda kr, x_max: _plateau_efficiency(kr, x_max, LUCKIE_AUSTIN_BREAK),
    ),
    with_plateau(
        _ROSIN_RAMMLER,
        id="shuvalov",
        equation=11,
        title="Shuvalov (1992), piecewise",
        phi=shuvalov,
        break_text="x_a",
        citation=_in(SHUVALOV_1992, 11),
        notes="x_a makes the area under the curve on 0 < x < 1 equal the measured efficiency; "
        "printed with the coarse-product branch like (10).",
        efficiency=_shuvalov_efficiency,
        context_from_efficiency=True,
        defaults={"measured_efficiency": 0.75},
        moving_break=SHUVALOV_BREAK,
    ),
)

# --- extended curves: bypass and fish-hook ------------------------------------------------
NAPIER_MUNN_1996 = (
    "Napier-Munn T.J., Morrell S., Morrison R.D., Kojovic T. (1996). Mineral Comminution Circuits: "
    "Their Operation and Optimisation. JKMRC, Brisbane"
)
PLITT_1976 = "Plitt L.R. (1976). A mathematical model of the hydrocyclone classifier. CIM Bulletin 69(776), 114-123"
KELSALL_1953 = "Kelsall D.F. (1953). A further study of the hydraulic cyclone. Chem. Eng. Sci. 2, 254-272 (bypass correction)"
BYPASS = Parameter(
    "bypass",
    0.0,
    0.95,
    unit="1",
    meaning="share of every size sent to the coarse product unclassified",
    start=0.05,
    start_rule="fixed at 0.05",
)
FISHHOOK = Parameter(
    "fishhook",
    0.0,
    3.0,
    unit="1",
    meaning="Whiten's beta: rise of the fines partition at small sizes",
    start=0.1,
    start_rule="fixed at 0.1",
)


def with_bypass(base: Formula, *, equation: int, citation: str, family: str = "extended") -> Formula:
    r"""``base`` with bypass: :math:`\varphi = (1 - \text{bypass})\,\varphi_{base}(x)`.

    A share of every size reports to the coarse product unclassified; ``d_cut`` becomes
    the corrected cut (partition 1/2 of the classified part) and the formula nests
    ``base`` (bypass = 0).
    """

    def phi(x, shape, *, bypass=0.0):
        return (1.0 - bypass) * base.phi(x, shape)

    phi.__name__ = f"{base.id}_bypass"
    phi_slope = f"(1 - bypass)*({base.slope_expression})"
    phi.__doc__ = f"""{base.title} with bypass: ``(1 - bypass)`` times :func:`{base.phi.__name__}`.

    .. math::
        \\varphi(x) = (1 - \\text{{bypass}})\\,\\varphi_{{{base.equation}}}(x)

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    shape : float
        ``{base.shape_name}`` of the base formula, {base.shape_bounds[0]:g}..{base.shape_bounds[1]:g}.
    bypass : float
        Share of every size sent to the coarse product unclassified, {BYPASS.lower:g}..{BYPASS.upper:g}.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 - bypass.

    Notes
    -----
    Monotone where the base formula is; slope at the cut ``{phi_slope}``; ``d_cut`` is the
    corrected cut (partition 1/2 of the classified part).

    References
    ----------
    .. [1] {citation}
    .. [2] {SHUVALOV_2018} (the base formula, ({base.equation})).
    """
    return Formula(
        id=f"{base.id}_bypass",
        equation=equation,
        title=f"{base.title} with bypass",
        expression=f"(1 - bypass)*({base.expression})",
        shape_name=base.shape_name,
        shape_bounds=base.shape_bounds,
        phi=phi,
        slope_at_cut=base.slope_at_cut,
        slope_expression=f"(1 - bypass)*({base.slope_expression})",
        shape_for_slope=base.shape_for_slope,
        citation=citation,
        notes="d_cut is the corrected cut; the actual curve is 0.5 (1 - bypass) there.",
        extras=(BYPASS,),
        family=family,
        nests=base.id,
        shape_meaning=base.shape_meaning,
        bypass_of=base,
    )


def whiten_beta_star(alpha: float, fishhook: float) -> float:
    r"""Whiten's :math:`\beta^*`: keeps the reduced curve at 1/2 at ``x = 1`` for a given fish-hook.

    Solves :math:`(1 + \beta\beta^*)(e^\alpha - 1)/(e^{\alpha\beta^*} + e^\alpha - 2) = 1/2`;
    :math:`\beta^* = 1` when :math:`\beta = 0`.
    """
    if fishhook == 0.0:
        return 1.0
    return _beta_star_of(float(alpha), float(fishhook))


@lru_cache(maxsize=4096)
def _beta_star_of(alpha: float, fishhook: float) -> float:
    # Remembered: a fit evaluates the curve at the same (alpha, fish-hook) many times (the
    # Jacobian's steps in d_cut and bypass, the grid of cuts): 48 experiments asked 48,008
    # times for 5,796 distinct pairs
    def gap(star):
        # on floats: numpy's scalar overhead made this root (one per evaluation of the curve)
        # most of the time of Whiten's fits
        return (1.0 + fishhook * star) * _lynch_at(star, alpha) - 0.5

    high = 1.0
    while gap(high) > 0.0:
        high *= 2.0
    return scipy.optimize.brentq(gap, 0.0, high, xtol=1e-14)


def whiten(x, alpha, *, bypass=0.0, fishhook=0.0):
    r"""Whiten's efficiency curve to the fine product with bypass and fish-hook.

    .. math::
        \varphi = C \frac{(1 + \beta\beta^* x)(e^\alpha - 1)}{e^{\alpha\beta^* x} + e^\alpha - 2},
        \quad C = 1 - \text{bypass}

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    alpha : float
        Shape, 1e-3..60 (dimensionless): sharpness, as Lynch's ``kl``.
    bypass : float
        Share of every size sent to the coarse product unclassified, 0..0.95.
    fishhook : float
        Whiten's :math:`\beta`, 0..3: rise of the fines partition at small sizes.

    Returns
    -------
    ndarray
        Partition number to the fine product (dimensionless; may exceed 1, see Notes).

    Notes
    -----
    :math:`\beta^*` (:func:`whiten_beta_star`) keeps the reduced curve at 1/2 at
    :math:`x = 1`.  With :math:`\beta = 0` and no bypass it is Lynch's formula (6) with
    :math:`k_l = \alpha`, decreasing, slope at the cut
    :math:`-(1 - \text{bypass})\,\alpha e^\alpha / (4(e^\alpha - 1))`.  For
    :math:`\beta > 0` the curve rises above ``C`` at small sizes (the fish-hook) and can
    exceed 1 when the bypass is small; fits report such a curve.

    References
    ----------
    .. [1] Napier-Munn T.J., Morrell S., Morrison R.D., Kojovic T. (1996). Mineral Comminution
       Circuits: Their Operation and Optimisation. JKMRC, Brisbane.
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23
       (formula (6), the reduced curve).

    Examples
    --------
    >>> round(float(whiten(0.3, 3.0, bypass=0.1, fishhook=0.4)), 10)
    0.9340089396
    """
    x = _as_array(x)
    star = whiten_beta_star(alpha, fishhook)
    return (1.0 - bypass) * (1.0 + fishhook * star * x) * lynch(star * x, alpha)


_BASE = {formula.id: formula for formula in FORMULAS}
EXTENDED_FORMULAS: tuple[Formula, ...] = (
    with_bypass(_BASE["plitt"], equation=107, citation=PLITT_1976 + "; " + KELSALL_1953),
    with_bypass(_BASE["lognormal"], equation=109, citation=KELSALL_1953),
    Formula(
        id="whiten",
        equation=106,
        title="Whiten with bypass and fish-hook",
        expression="(1 - bypass)*(1 + fishhook*b_star*x)*(exp(alpha) - 1)/(exp(alpha*b_star*x) + exp(alpha) - 2)",
        shape_name="alpha",
        shape_bounds=(1e-3, 60.0),
        phi=whiten,
        slope_at_cut=_lynch_slope,
        slope_expression="(1 - bypass)*(-alpha*exp(alpha)/(4*(exp(alpha) - 1)))",
        shape_for_slope=_lynch_shape_for_slope,
        citation=NAPIER_MUNN_1996 + " (Whiten's efficiency curve with the fish-hook term)",
        notes="Reduces to Lynch (6) with kl = alpha without bypass and fish-hook; may exceed 1 for a large "
        "fish-hook with little bypass. b_star keeps phi(1) = (1 - bypass)/2 (whiten_beta_star); the slope "
        "expression holds for fishhook = 0.",
        shape_meaning="sharpness of the cut (Lynch's kl)",
        extras=(BYPASS, FISHHOOK),
        family="extended",
        nests="lynch",
        monotone=False,
    ),
)

# --- other curve families: the curves other tools use ------------------------------------
LN3 = np.log(3.0)
DYSSOL_2020 = (
    "Skorych V., Dosta M., Heinrich S. (2020). Dyssol - an open-source flowsheet simulation framework for "
    "particulate materials. SoftwareX 12, 100572. doi:10.1016/j.softx.2020.100572 (Screen unit models)"
)
KING_2001 = "King R.P. (2001). Modeling and Simulation of Mineral Processing Systems. Butterworth-Heinemann, Oxford (ch. 5, classification functions)"
TEIPEL_HENNIG_ALPHA = Parameter(
    "th_alpha",
    0.0,
    50.0,
    unit="1",
    meaning="Teipel/Hennig alpha: the exponent is (x + alpha) beta, written here as k (x + alpha)/(1 + alpha)",
    start=1.0,
    start_rule="fixed at 1",
)


def normal_linear(x, sigma_rel):
    r"""Normal distribution in linear size (the "probability" model of screens).

    .. math::
        \varphi(x) = \tfrac12 \operatorname{erfc}\left(\frac{x - 1}{\sqrt2\,\sigma_r}\right)

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    sigma_rel : float
        Shape, 0.001..10 (dimensionless): the standard deviation of the separation size
        relative to the cut, ``sigma / d_cut``; smaller is sharper.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Decreasing for :math:`\sigma_r > 0`.  Unlike the log-normal law (9) it gives
    :math:`\varphi(0) = \tfrac12 \operatorname{erfc}(-1/(\sqrt2\sigma_r)) < 1`.
    Slope at the cut :math:`-1/(\sqrt{2\pi}\,\sigma_r)`.

    References
    ----------
    .. [1] King R.P. (2001). Modeling and Simulation of Mineral Processing Systems.
       Butterworth-Heinemann, Oxford (ch. 5).
    .. [2] Skorych V., Dosta M., Heinrich S. (2020). Dyssol - an open-source flowsheet simulation
       framework for particulate materials. SoftwareX 12, 100572. doi:10.1016/j.softx.2020.100572
       (Screen unit, Probability model).
    .. [3] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23
       (the conventions: x = size/d_cut, partition to the fine product).

    Examples
    --------
    >>> round(float(normal_linear(1.2, 0.2)), 6)  # one sigma above the cut: 1 - Phi(1)
    0.158655
    """
    x = _as_array(x)
    return 0.5 * scipy.special.erfc((x - 1.0) / (np.sqrt(2.0) * sigma_rel))


def logistic_linear(x, imperfection):
    r"""Logistic curve in linear size, written with d50 and Ep.

    .. math::
        \varphi(x) = \frac{1}{1 + e^{\ln 3\,(x - 1)/I}}

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    imperfection : float
        Shape, 0.001..10 (dimensionless): the imperfection ``I = Ep / d_cut``; smaller is
        sharper.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    The factor :math:`\ln 3` puts ``d25`` and ``d75`` exactly at :math:`x = 1 \mp I`, so
    :math:`E_p = I\,d_{cut}`; some tools print it as 1.099 and call the curve the
    "Napier-Munn" partition.  Slope at the cut :math:`-\ln 3/(4 I)`.

    References
    ----------
    .. [1] Napier-Munn T.J., Morrell S., Morrison R.D., Kojovic T. (1996). Mineral Comminution
       Circuits: Their Operation and Optimisation. JKMRC, Brisbane.
    .. [2] King R.P. (2001). Modeling and Simulation of Mineral Processing Systems.
       Butterworth-Heinemann, Oxford (ch. 5).
    .. [3] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23
       (the conventions: x = size/d_cut, partition to the fine product).

    Examples
    --------
    >>> round(float(logistic_linear(1.1, 0.1)), 6)  # d75: a quarter to the fines
    0.25
    """
    x = _as_array(x)
    return scipy.special.expit(-LN3 * (x - 1.0) / imperfection)


def teipel_hennig(x, k, *, th_alpha=1.0, bypass=0.0):
    r"""Teipel/Hennig grade-efficiency curve with offset, to the fine product.

    .. math::
        \varphi(x) = (1 - \text{offset}) \left(1 + 3 x^{(x + \alpha)\beta}\right)^{-1/2},
        \quad \beta = k / (1 + \alpha)

    Parameters
    ----------
    x : array_like
        Relative size ``size / d_cut`` (> 0, dimensionless).
    k : float
        Shape, 0.05..60 (dimensionless): the exponent at the cut, ``(1 + alpha) beta``.
    th_alpha : float
        Teipel/Hennig's alpha, 0..50 (dimensionless): how fast the exponent grows with size.
    bypass : float
        The offset, 0..0.95: share of every size sent to the coarse product unclassified.

    Returns
    -------
    ndarray
        Partition number to the fine product, 0..1 (dimensionless).

    Notes
    -----
    Written with :math:`k = (1 + \alpha)\beta` so that the slope at the cut,
    :math:`-\tfrac{3}{16} k (1 - \text{offset})`, depends on the shape alone; for large
    :math:`\alpha` the curve tends to :math:`(1 + 3x^k)^{-1/2}`.  The form is the one of
    Dyssol's Screen unit, which names Teipel and Hennig; their primary publication could
    not be consulted.

    References
    ----------
    .. [1] Skorych V., Dosta M., Heinrich S. (2020). Dyssol - an open-source flowsheet simulation
       framework for particulate materials. SoftwareX 12, 100572. doi:10.1016/j.softx.2020.100572
       (Screen unit, Teipel & Hennig model).
    .. [2] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a
       dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23
       (the conventions: x = size/d_cut, partition to the fine product).

    Examples
    --------
    >>> round(float(teipel_hennig(2.0, 4.0, th_alpha=2.0)), 6)
    0.090553
    """
    x = _as_array(x)
    exponent = k * (x + th_alpha) / (1.0 + th_alpha)
    with np.errstate(over="ignore", divide="ignore"):
        return (1.0 - bypass) / np.sqrt(1.0 + 3.0 * np.power(x, exponent))


OTHER_FORMULAS: tuple[Formula, ...] = (
    Formula(
        id="normal",
        equation=201,
        title="Normal distribution in linear size",
        expression="erfc((x - 1)/(sqrt(2)*sigma_rel))/2",
        shape_name="sigma_rel",
        shape_bounds=(1e-3, 10.0),
        phi=normal_linear,
        slope_at_cut=lambda s: -1.0 / (np.sqrt(2.0 * np.pi) * s),
        slope_expression="-1/(sqrt(2*pi)*sigma_rel)",
        shape_for_slope=lambda slope: -1.0 / (np.sqrt(2.0 * np.pi) * slope),
        citation=KING_2001 + "; as the 'Probability' screen model (Mean, Deviation) in " + DYSSOL_2020,
        notes="sigma_rel = sigma/d_cut; phi(0) < 1. Dyssol's Probability model sums the normal density over its own "
        "size classes, so it equals this curve only on a fine grid.",
        family="other",
        shape_meaning="spread of the separation size relative to the cut, sigma/d_cut; smaller, sharper cut",
    ),
    Formula(
        id="logistic",
        equation=202,
        title="Logistic curve in linear size (d50, Ep)",
        expression="1/(1 + exp(ln(3)*(x - 1)/imperfection))",
        shape_name="imperfection",
        shape_bounds=(1e-3, 10.0),
        phi=logistic_linear,
        slope_at_cut=lambda i: -LN3 / (4.0 * i),
        slope_expression="-ln(3)/(4*imperfection)",
        shape_for_slope=lambda slope: -LN3 / (4.0 * slope),
        citation=NAPIER_MUNN_1996 + " (partition curve in d50 and Ep); " + KING_2001,
        notes="I = Ep/d_cut; d25 and d75 lie at x = 1 -+ I. Other tools print ln 3 rounded (1.099) and call this "
        "the Napier-Munn partition.",
        family="other",
        shape_meaning="imperfection Ep/d_cut: d25 and d75 lie at x = 1 -+ I; smaller, sharper cut",
    ),
    Formula(
        id="teipel_hennig",
        equation=203,
        title="Teipel/Hennig with offset",
        expression="(1 - bypass)*(1 + 3*x^((x + th_alpha)*k/(1 + th_alpha)))^(-1/2)",
        shape_name="k",
        shape_bounds=(0.05, 60.0),
        phi=teipel_hennig,
        slope_at_cut=lambda k: -3.0 * k / 16.0,
        slope_expression="(1 - bypass)*(-3*k/16)",
        shape_for_slope=lambda slope: -16.0 * slope / 3.0,
        citation="Teipel U., Hennig M., grade-efficiency function of screens, as the 'Teipel & Hennig' screen model "
        "(Xcut, Alpha, Beta, Offset) of " + DYSSOL_2020 + " (primary publication not seen)",
        notes="k = (1 + alpha) beta is the exponent at the cut; Dyssol's Beta = k/(1 + alpha). The offset is "
        "tromplab's bypass (share to the coarse product).",
        extras=(TEIPEL_HENNIG_ALPHA, BYPASS),
        family="other",
        shape_meaning="exponent of x at the cut, (1 + alpha) beta: larger, sharper cut",
    ),
    # Plitt's (1976) hydrocyclone curve: the Rosin-Rammler form with bypass, as simulators write "Plitt".
    with_bypass(
        _BASE["rosin_rammler"], equation=105, citation=PLITT_1976 + " (corrected efficiency with bypass Rf)", family="other"
    ),
)

#: Names that mean different curves in different tools (printed by ``tromplab formulas``).
NAME_CLASHES = (
    "'Plitt' in hydrocyclone models (Plitt 1976) and in Dyssol's Screen unit is tromplab's rosin_rammler "
    "(5) (with bypass: rosin_rammler_bypass), written to the coarse product as 1 - exp(-0.693 (d/d50)^m); "
    "tromplab's plitt (7) is Plitt's 1971 log-logistic 1/(1 + x^ks).",
    "'Whiten' in JKSimMet and Napier-Munn et al. (1996) is tromplab's whiten (alpha, beta, beta*, d50c, C = 1 - bypass, "
    "to the fine product); a plain 'Whiten' curve without beta (to the coarse product, (e^(alpha x) - 1)/(e^(alpha x) + "
    "e^alpha - 2)) is tromplab's lynch (6).",
    "'Napier-Munn' partition in some geometallurgy tools is tromplab's logistic: 1/(1 + exp(1.099 (d50 - d)/Ep)) to the "
    "coarse product.",
    "'Molerus & Hoffmann' in Dyssol is tromplab's molerus_hoffmann (4) with alpha = km2; 'Probability' is normal "
    "(Mean = d_cut, Deviation = sigma_rel d_cut, summed over the class grid).",
)
ALL_FORMULAS = FORMULAS + EXTENDED_FORMULAS + OTHER_FORMULAS

_BY_ID = {formula.id: formula for formula in ALL_FORMULAS}
_BY_EQUATION = {formula.equation: formula for formula in FORMULAS}


#: Names the expression texts may use besides x, the parameters and derived variables.
EXPRESSION_FUNCTIONS = ("exp", "ln", "erfc", "sqrt", "max", "pi", "ln2")


def evaluate_expression(text: str, values: Mapping[str, object], functions: Mapping[str, object] | None = None):
    """Evaluate a registry expression text (``expression`` or ``slope_expression``).

    The texts are written for readers - ``^`` is a power, ``ln`` the natural log - and
    are evaluated here with asteval (no Python ``eval``) so that tests can hold each text
    against its function.  ``functions`` replaces the numpy implementations of
    :data:`EXPRESSION_FUNCTIONS`, e.g. with mpmath's for high-precision references.

    Examples
    --------
    >>> round(float(evaluate_expression(get_formula("plitt").expression, {"x": 2.0, "ks": 3.0})), 12)
    0.111111111111
    """
    from asteval import Interpreter

    if functions is None:
        functions = {
            "exp": np.exp,
            "ln": np.log,
            "erfc": scipy.special.erfc,
            "sqrt": np.sqrt,
            "max": np.maximum,
            "pi": np.pi,
            "ln2": LN2,
        }
    interpreter = Interpreter(minimal=True, use_numpy=False)
    interpreter.symtable.update(functions)
    interpreter.symtable.update(values)
    return interpreter.eval(text.replace("^", "**"), show_errors=False, raise_errors=True)


def get_formula(key: str | int) -> Formula:
    """Look a formula up by id (``"plitt"``) or equation number (``7``, ``"7"``, ``"(7)"``).

    Parameters
    ----------
    key : str, int or Formula
        Id, equation number of Shuvalov et al. (2018), or a record (returned as is).

    Returns
    -------
    Formula

    Raises
    ------
    KeyError
        For an unknown key, listing the known formulas.
    TypeError
        For a key that is no name at all (None, a boolean, a collection).

    Examples
    --------
    >>> get_formula("(9)").id
    'lognormal'
    """
    if isinstance(key, Formula):
        return key
    if key is None or isinstance(key, (bool, np.bool_, bytes, list, tuple, dict, set, np.ndarray)):
        raise TypeError(f"a formula is named by its id (str) or its equation number (int), got {type(key).__name__}")
    text = str(key).strip()
    if text in _BY_ID:
        return _BY_ID[text]
    number = text.strip("()")
    if number.isdigit() and int(number) in _BY_EQUATION:
        return _BY_EQUATION[int(number)]
    raise KeyError(unknown_formula_message(key))


#: The groups a formula selection may name (``--formulas paper,other``), in the order listed.
FORMULA_GROUPS = {"paper": FORMULAS, "other": OTHER_FORMULAS, "extended": EXTENDED_FORMULAS}


def unknown_formula_message(key) -> str:
    """Why ``key`` names no formula: the closest ids and groups (:func:`difflib.get_close_matches`),
    then every id with its equation number, group by group.

    Examples
    --------
    >>> unknown_formula_message("plit").split(";")[0]
    "unknown formula 'plit' (did you mean plitt?)"
    """
    import difflib

    names = [*_BY_ID, *FORMULA_GROUPS]
    close = difflib.get_close_matches(str(key).strip().lower(), names, n=3, cutoff=0.6)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    groups = "; ".join(
        f"{group}: " + ", ".join(f"{f.id} ({f.equation})" for f in formulas) for group, formulas in FORMULA_GROUPS.items()
    )
    return f"unknown formula {key!r}{hint}; give an id, an equation number or a group ({', '.join(FORMULA_GROUPS)}). {groups}"


def select_formulas(keys=None) -> tuple[Formula, ...]:
    """The formulas named by ``keys`` (ids or equation numbers), or all nine.

    Parameters
    ----------
    keys : str, int, iterable of str/int, or None
        Ids or equation numbers (a comma-separated string is split); ``"extended"``
        stands for every extended curve (bypass, fish-hook), ``"paper"`` for the nine,
        ``"other"`` for the curves of other tools (normal, logistic, Teipel/Hennig,
        Plitt 1976).

    Returns
    -------
    tuple of Formula

    Examples
    --------
    >>> [f.id for f in select_formulas("plitt,9,extended")][:3]
    ['plitt', 'lognormal', 'plitt_bypass']
    """
    if keys is None:
        return FORMULAS
    if isinstance(keys, str):
        keys = [k for k in keys.replace(" ", "").split(",") if k]
    elif isinstance(keys, (int, np.integer, Formula)):
        keys = [keys]
    elif not isinstance(keys, Iterable) or isinstance(keys, Mapping):
        raise TypeError(f"formulas are ids or equation numbers (a str, an int or an iterable of them), got {type(keys).__name__}")
    chosen = []
    for key in keys:
        group = FORMULA_GROUPS[key] if isinstance(key, str) and key in FORMULA_GROUPS else (get_formula(key),)
        chosen += [f for f in group if f not in chosen]
    return tuple(chosen)


def registry_table():
    """The registry as a :class:`pandas.DataFrame` (one row per formula).

    Columns: ``id, equation, title, formula, shape_name, shape_bounds, slope_at_cut,
    shape_at_slope_-0.5, extras, family, shape_meaning`` (what ``tromplab formulas`` prints).

    Examples
    --------
    >>> table = registry_table().set_index("id")
    >>> row = table.loc["ogawa_allen"]
    >>> row["formula"], row["slope_at_cut"], float(row["shape_at_slope_-0.5"])
    ('1/(1 + x*exp(-kp*(1 - x)))', '-(1 + kp)/4', 1.0)
    """
    import pandas as pd

    rows = []
    for formula in ALL_FORMULAS:
        shape_at_half = formula.shape_for_slope(-0.5)
        rows.append(
            {
                "id": formula.id,
                "equation": formula.equation,
                "title": formula.title,
                "formula": formula.expression,
                "shape_name": formula.shape_name,
                "shape_bounds": f"[{formula.shape_bounds[0]:g}, {formula.shape_bounds[1]:g}]",
                "slope_at_cut": formula.slope_expression,
                "shape_at_slope_-0.5": round(shape_at_half, 4),
                "extras": ", ".join(extra.name for extra in formula.extras),
                "family": formula.family,
                "shape_meaning": formula.shape_meaning,
            }
        )
    return pd.DataFrame(rows)


def formula_table_markdown(family: str = "paper") -> str:
    """The README's formula table (Markdown), generated from the registry.

    A test keeps the README's copy equal to this text.
    """
    lines = ["| id | eq. | phi(x), x = size/d_cut | shape | bounds | slope at the cut |", "|---|---|---|---|---|---|"]
    for formula in ALL_FORMULAS:
        if formula.family != family:
            continue
        low, high = formula.shape_bounds
        lines.append(
            f"| {formula.id} | ({formula.equation}) | `{formula.expression}` | {formula.shape_name} | "
            f"[{low:g}, {high:g}] | `{formula.slope_expression}` |"
        )
    return "\n".join(lines)


# --- the curves on arrays ----------------------------------------------------------------
def is_batchable(formula) -> bool:
    """True when the engine can evaluate ``formula`` on arrays of parameters."""
    return _batchable(get_formula(formula).id)


@cache
def _batchable(formula_id: str) -> bool:
    formula = get_formula(formula_id)
    if formula.moving_break is not None:  # evaluated through its break hooks
        return True
    if len(formula.extras) >= 2:  # interacting extras (Teipel-Hennig's alpha and bypass): one start is not enough
        return False
    x = np.array([[0.5, 1.0, 2.0], [0.5, 1.0, 2.0]])
    shape = np.array([[formula.clip_shape(1.0)], [formula.clip_shape(2.0)]])
    extras = {extra.name: np.full((2, 1), extra.start) for extra in formula.extras}
    try:
        with np.errstate(all="ignore"):
            value = np.asarray(formula.phi(x, shape, **extras), dtype=float)
    except (TypeError, ValueError):  # needs a scalar parameter (a root per parameter set)
        return False
    return value.shape == x.shape
