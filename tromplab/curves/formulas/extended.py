"""The extended curves: paper formulas with bypass, and Whiten's curve with bypass and fish-hook."""

from __future__ import annotations

from functools import lru_cache

import scipy

from ..parameters import Parameter
from .paper import FORMULAS, lynch, lynch_at, lynch_shape_for_slope, lynch_slope
from .records import SHUVALOV_2018, Formula, as_array

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
        return (1.0 + fishhook * star) * lynch_at(star, alpha) - 0.5

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
    x = as_array(x)
    star = whiten_beta_star(alpha, fishhook)
    return (1.0 - bypass) * (1.0 + fishhook * star * x) * lynch(star * x, alpha)


PAPER_BY_ID = {formula.id: formula for formula in FORMULAS}
EXTENDED_FORMULAS: tuple[Formula, ...] = (
    with_bypass(PAPER_BY_ID["plitt"], equation=107, citation=PLITT_1976 + "; " + KELSALL_1953),
    with_bypass(PAPER_BY_ID["lognormal"], equation=109, citation=KELSALL_1953),
    Formula(
        id="whiten",
        equation=106,
        title="Whiten with bypass and fish-hook",
        expression="(1 - bypass)*(1 + fishhook*b_star*x)*(exp(alpha) - 1)/(exp(alpha*b_star*x) + exp(alpha) - 2)",
        shape_name="alpha",
        shape_bounds=(1e-3, 60.0),
        phi=whiten,
        slope_at_cut=lynch_slope,
        slope_expression="(1 - bypass)*(-alpha*exp(alpha)/(4*(exp(alpha) - 1)))",
        shape_for_slope=lynch_shape_for_slope,
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
