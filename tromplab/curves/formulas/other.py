"""The ``other`` curves: the partition curves other tools and simulators use."""

from __future__ import annotations

import numpy as np
import scipy

from ..parameters import Parameter
from .extended import BYPASS, NAPIER_MUNN_1996, PAPER_BY_ID, PLITT_1976, with_bypass
from .records import Formula, as_array

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
    x = as_array(x)
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
    x = as_array(x)
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
    x = as_array(x)
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
        PAPER_BY_ID["rosin_rammler"], equation=105, citation=PLITT_1976 + " (corrected efficiency with bypass Rf)", family="other"
    ),
)
