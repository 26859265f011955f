"""The nine two-parameter formulas (3)-(11) of Shuvalov et al. (2018): the ``paper`` group.

References
----------
.. [Shuvalov2018] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the
   choice of a dependence for the Tromp separation curve approximation. *Vestnik IGEU*
   6, 15-23. doi:10.17588/2072-2672.2018.6.015-023
"""

from __future__ import annotations

import math
import re
from functools import lru_cache

import numpy as np
import scipy  # scipy.special and scipy.optimize load when first used: tromplab export needs neither

from .records import LN2, SHUVALOV_2018, Formula, MovingBreak, as_array, safe_log


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
    x = as_array(x)
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
    x = as_array(x)
    return scipy.special.expit(km2 * (1.0 - x * x) - 2.0 * safe_log(x))


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
    x = as_array(x)
    return np.exp(-LN2 * np.power(x, kr))


def rosin_rammler_area(lower, upper, kr):
    """Integral of the Rosin-Rammler form from ``lower`` to ``upper`` (closed form)."""
    a = 1.0 / kr
    scale = scipy.special.gamma(a) * LN2 ** (-a) / kr
    return scale * (scipy.special.gammainc(a, LN2 * upper**kr) - scipy.special.gammainc(a, LN2 * lower**kr))


def _rosin_rammler_efficiency(kr, x_max):
    return rosin_rammler_area(0.0, 1.0, kr), rosin_rammler_area(1.0, np.maximum(x_max, 1.0), kr)


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
    x = as_array(x)
    with np.errstate(over="ignore"):
        grow = np.expm1(kl * (x - 1.0))
    passed = -np.expm1(-kl)  # 1 - e^-kl
    return passed / (grow + 2.0 * passed)


def lynch_at(x: float, kl: float) -> float:
    """:func:`lynch` at one relative size, with the math module: the same expression, a tenth
    of numpy's cost on a scalar (Whiten's ``beta*`` root evaluates it once per step)."""
    passed = -math.expm1(-kl)
    try:
        return passed / (math.expm1(kl * (x - 1.0)) + 2.0 * passed)
    except OverflowError:  # e^(kl (x - 1)) beyond the floats: the curve is 0 there, as lynch() gives
        return 0.0


def lynch_slope(kl):
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
    x = as_array(x)
    return scipy.special.expit(-ks * safe_log(x))


#: Above this ``ks ln x`` the power ``x^ks`` of Plitt's area nears the floating-point limit
#: (e^709): the area is then the whole area less the tail beyond x.
_PLITT_FAR = 600.0


def plitt_efficiency(ks, x_max):
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
    x = as_array(x)
    return scipy.special.expit(kp * (1.0 - x) - safe_log(x))


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
    x = as_array(x)
    return 0.5 * scipy.special.erfc(safe_log(x) / kf)


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
    x = as_array(x)
    return rosin_rammler(np.maximum(x, x_break), kr)


def _plateau_efficiency(kr, x_max, x_break):
    return _plateau_eta(kr, x_break), rosin_rammler_area(1.0, np.maximum(x_max, 1.0), kr)


def _plateau_eta(kr, x_break):
    """eta of the plateau form: the plateau's rectangle and the Rosin-Rammler area from the break to 1."""
    plateau = x_break * rosin_rammler(x_break, kr)
    return (plateau + rosin_rammler_area(x_break, 1.0, kr))[()]


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
    eta_plain = rosin_rammler_area(0.0, 1.0, kr)  # eta of the plain form (5)
    if not 0.5 <= measured_efficiency <= eta_plain:
        raise NoBreakPointError(kr, measured_efficiency, eta_plain)
    if measured_efficiency == eta_plain:
        return 0.0
    # _plateau_eta(kr, xa) with the parts that do not depend on xa (the gamma function and the
    # upper end of the area) computed once, not at each of the root finder's steps: the same
    # operations on the same numbers, so the same root to the last bit
    a = 1.0 / kr
    scale = scipy.special.gamma(a) * LN2 ** (-a) / kr
    upper = scipy.special.gammainc(a, LN2 * 1.0**kr)

    def plateau_eta_less_target(xa):
        plateau = xa * rosin_rammler(xa, kr)
        return (plateau + scale * (upper - scipy.special.gammainc(a, LN2 * xa**kr)))[()] - measured_efficiency

    return scipy.optimize.brentq(plateau_eta_less_target, 0.0, 1.0, xtol=1e-14)


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
    # rosin_rammler_area(x, 1, k) = scale * (whole - gammainc(1/k, ln2 x^k)): the parts without x
    # once, and eta_5 = rosin_rammler_area(0, 1, k) = scale * whole (gammainc(a, 0) = 0)
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


def shuvalov_breaks_of_shape(kr, efficiencies) -> tuple[float, ...]:
    """Break points of formula (11) for one shape ``kr`` and several measured efficiencies, each
    the same number as :func:`shuvalov` places it (``_shuvalov_break_or_edge``, one ``brentq``
    per efficiency): the searches run side by side in one :func:`~tromplab.curves.roots.brent_roots`,
    step for step as ``brentq``, on the same values of the function.  A joint fit of several
    surveys (:func:`tromplab.trend.joint_fit`) needs them at every step of its optimiser.

    Examples
    --------
    >>> shuvalov_breaks_of_shape(2.0, [0.8, 0.7, 0.4]) == tuple(_shuvalov_break_or_edge(2.0, e) for e in (0.8, 0.7, 0.4))
    True
    """
    return _breaks_of_shape(float(kr), tuple(float(e) for e in efficiencies))


@lru_cache(maxsize=256)
def _breaks_of_shape(kr: float, efficiencies: tuple[float, ...]) -> tuple[float, ...]:
    # remembered as _break_or_edge_of is: the optimiser's steps in d_cut keep the shape
    from ..roots import brent_roots

    target = np.array(efficiencies)
    breaks = [None] * target.size
    if np.isfinite(kr) and kr > 0:
        a = 1.0 / kr  # the parts of plateau_eta_less_target without x_a, as shuvalov_break takes them
        scale = scipy.special.gamma(a) * LN2 ** (-a) / kr
        upper = scipy.special.gammainc(a, LN2 * 1.0**kr)

        def gap(xa, rows):
            # x_a**kr by Python's power, as brentq's float argument gets it (numpy's power of an
            # array differs from it in the last bit); the rest elementwise as on one number
            powers = np.array([x**kr for x in xa.tolist()])
            return xa * rosin_rammler(xa, kr) + scale * (upper - scipy.special.gammainc(a, LN2 * powers)) - target[rows]

        eta_plain = rosin_rammler_area(0.0, 1.0, kr)
        inside = (target >= 0.5) & (target < eta_plain)
        roots, found = brent_roots(gap, np.zeros(target.size), np.ones(target.size), xtol=1e-14)
        for i in np.flatnonzero(inside & found).tolist():
            breaks[i] = float(roots[i])
    # the edges, and whatever the side-by-side search left (a same sign at both ends, a nan): one by one
    return tuple(_break_or_edge_uncached(kr, e) if known is None else known for e, known in zip(efficiencies, breaks))


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
        above = rosin_rammler_area(0.0, 1.0, np.exp(middle)) > efficiency
        low, high = np.where(above, low, middle), np.where(above, middle, high)
    return np.exp(0.5 * (low + high))


#: The moving break of (11): x_a from kr and the measured efficiency.
SHUVALOV_BREAK = MovingBreak(
    at=_shuvalov_break_or_edge,
    at_shape=shuvalov_breaks_of_shape,
    on_arrays=shuvalov_breaks,
    phi=rosin_rammler_plateau,
    kink=shuvalov_kink,
    efficiency=_plateau_efficiency,
)


#: Shape range searched for Lynch's start; its slope at the cut runs from -0.25 (kl -> 0) to -200.
_LYNCH_START_SHAPES = (1e-9, 800.0)


def lynch_shape_for_slope(s):
    low, high = _LYNCH_START_SHAPES
    target = -s
    # compared with the slopes at the ends themselves, not with their limits: a measured slope
    # of -0.25000000000000006 (a size-unit rounding) lay beyond the slope at 1e-9, so the root
    # was not bracketed and the whole fit failed in one unit only
    if target <= -lynch_slope(low):
        return 1e-6
    if target >= -lynch_slope(high):
        return high
    return scipy.optimize.brentq(lambda kl: -lynch_slope(kl) - target, low, high, xtol=1e-14)


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
        slope_at_cut=lynch_slope,
        slope_expression="-kl*exp(kl)/(4*(exp(kl) - 1))",
        shape_for_slope=lynch_shape_for_slope,
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
        efficiency=plitt_efficiency,
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
