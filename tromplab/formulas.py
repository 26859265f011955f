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

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, special

LN2 = np.log(2.0)
SHUVALOV_2018 = (
    "Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a "
    "dependence for the Tromp separation curve approximation. Vestnik IGEU 6, 15-23. "
    "doi:10.17588/2072-2672.2018.6.015-023"
)


@dataclass(frozen=True)
class ExtraParameter:
    """A parameter beyond ``d_cut`` and the shape (bypass, fish-hook), with bounds and start."""

    name: str
    bounds: tuple[float, float]
    start: float
    meaning: str


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
    extras : tuple of ExtraParameter
        Further fitted parameters (extended curves only); ``phi`` takes them as keywords.
    family : str
        ``"paper"`` for the nine formulas of [Shuvalov2018]_, ``"extended"`` for the
        curves with bypass or fish-hook (kept out of the paper's ranking by default).
    nests : str or None
        Id of the paper formula this one reduces to when its extras vanish (for the
        extra-sum-of-squares test).
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
    extras: tuple[ExtraParameter, ...] = ()
    family: str = "paper"
    nests: str | None = None

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


def _as_array(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def _log(x: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return np.log(x)


# --- (3) Molerus -----------------------------------------------------------------------
def molerus(x, km1):
    r"""Molerus (1967): :math:`\varphi = 1 / (1 + e^{-k_{m1}(1 - x^2)})`.

    The only formula of the nine with :math:`\varphi(0) = 1/(1 + e^{-k_{m1}}) < 1`:
    some fines report to the coarse product.  Slope at the cut :math:`-k_{m1}/2`.

    Examples
    --------
    >>> float(molerus(1.0, 3.0))
    0.5
    """
    x = _as_array(x)
    return special.expit(km1 * (1.0 - x * x))


# --- (4) Molerus-Hoffmann --------------------------------------------------------------
def molerus_hoffmann(x, km2):
    r"""Molerus and Hoffmann (1969): :math:`\varphi = 1/(1 + x^2 e^{-k_{m2}(1 - x^2)})`.

    Slope at the cut :math:`-(1 + k_{m2})/2`.  With :math:`k_{m2} = 0` it is Plitt's
    formula with :math:`k_s = 2`.  For :math:`k_{m2} < 0` the curve has a minimum at
    :math:`x = 1/\sqrt{-k_{m2}}` and rises towards 1 beyond it.

    Examples
    --------
    >>> float(molerus_hoffmann(1.0, -0.2))
    0.5
    """
    x = _as_array(x)
    return special.expit(km2 * (1.0 - x * x) - 2.0 * _log(x))


# --- (5) Rosin-Rammler form ------------------------------------------------------------
def rosin_rammler(x, kr):
    r"""Rosin-Rammler form: :math:`\varphi = \exp(-\ln 2\, x^{k_r})`.

    Slope at the cut :math:`-k_r \ln 2 / 2`.

    Examples
    --------
    >>> round(float(rosin_rammler(2.0, 1.0)), 6)
    0.25
    """
    x = _as_array(x)
    return np.exp(-LN2 * np.power(x, kr))


def _rosin_rammler_area(lower, upper, kr):
    """Integral of the Rosin-Rammler form from ``lower`` to ``upper`` (closed form)."""
    a = 1.0 / kr
    scale = special.gamma(a) * LN2 ** (-a) / kr
    return scale * (special.gammainc(a, LN2 * upper**kr) - special.gammainc(a, LN2 * lower**kr))


def _rosin_rammler_efficiency(kr, x_max):
    return _rosin_rammler_area(0.0, 1.0, kr), _rosin_rammler_area(1.0, max(x_max, 1.0), kr)


# --- (6) Lynch -------------------------------------------------------------------------
def lynch(x, kl):
    r"""Lynch (1977): :math:`\varphi = 1 - (e^{k_l x} - 1)/(e^{k_l x} + e^{k_l} - 2)`.

    Evaluated as :math:`(e^{k_l} - 1)/(e^{k_l x} + e^{k_l} - 2)` scaled by
    :math:`e^{-k_l}` so that large sizes underflow to 0 instead of giving inf/inf.
    Slope at the cut :math:`-k_l e^{k_l} / (4 (e^{k_l} - 1))`, never shallower than
    -1/4 (the limit :math:`k_l \to 0` is Plitt's formula with :math:`k_s = 1`).

    Examples
    --------
    >>> float(lynch(1.0, 1.5936))
    0.5
    """
    x = _as_array(x)
    with np.errstate(over="ignore"):
        grow = np.exp(kl * (x - 1.0))
    tail = np.exp(-kl)
    return (1.0 - tail) / (grow + 1.0 - 2.0 * tail)


def _lynch_slope(kl):
    return -kl / (4.0 * -np.expm1(-kl))


# --- (7) Plitt -------------------------------------------------------------------------
def plitt(x, ks):
    r"""Plitt (1971): :math:`\varphi = 1/(1 + x^{k_s})`.

    Slope at the cut :math:`-k_s/4`.

    Examples
    --------
    >>> float(plitt(1.0, 2.0))
    0.5
    """
    x = _as_array(x)
    return special.expit(-ks * _log(x))


def _plitt_efficiency(ks, x_max):
    def area_to(upper):
        a = 1.0 / ks
        return upper * special.hyp2f1(1.0, a, 1.0 + a, -(upper**ks))

    eta = area_to(1.0)
    return eta, area_to(max(x_max, 1.0)) - eta


# --- (8) Ogawa, Allen's law ------------------------------------------------------------
def ogawa_allen(x, kp):
    r"""Ogawa's form of Allen's law: :math:`\varphi = 1/(1 + x e^{-k_p (1 - x)})`.

    The paper prints :math:`e^{-k_p x}`, which gives :math:`\varphi(1) \ne 0.5` and
    contradicts its own slope (17); the exponent :math:`-k_p (1 - x)` is implemented.
    Slope at the cut :math:`-(1 + k_p)/4`.  For :math:`k_p < 0` the curve rises again
    at large sizes.

    Examples
    --------
    >>> float(ogawa_allen(1.0, 1.0))
    0.5
    """
    x = _as_array(x)
    return special.expit(kp * (1.0 - x) - _log(x))


# --- (9) log-normal --------------------------------------------------------------------
def lognormal(x, kf):
    r"""Gauss integral of the log-normal law: :math:`\varphi = \tfrac12 \operatorname{erfc}(\ln x / k_f)`.

    :math:`k_f = \sqrt 2\, \sigma` of the natural log of size.  Slope at the cut
    :math:`-1/(\sqrt\pi\, k_f)`.

    Examples
    --------
    >>> float(lognormal(1.0, 1.1284))
    0.5
    """
    x = _as_array(x)
    return 0.5 * special.erfc(_log(x) / kf)


def _lognormal_efficiency(kf, x_max):
    eta = 0.5 + 0.5 * np.exp(kf**2 / 4.0) * special.erfc(kf / 2.0)
    big_x = max(x_max, 1.0)
    log_x = np.log(big_x)
    eps = (
        0.5 * big_x * special.erfc(log_x / kf)
        - 0.5
        + 0.5 * np.exp(kf**2 / 4.0) * (special.erf((log_x - kf**2 / 2.0) / kf) + special.erf(kf / 2.0))
    )
    return float(eta), float(eps)


# --- (10), (11) Rosin-Rammler with a flat fines plateau ---------------------------------
def rosin_rammler_plateau(x, kr, x_break):
    r"""Rosin-Rammler form above ``x_break``, constant :math:`\varphi(x_b)` below it."""
    x = _as_array(x)
    return rosin_rammler(np.maximum(x, x_break), kr)


def _plateau_efficiency(kr, x_max, x_break):
    plateau = x_break * float(rosin_rammler(x_break, kr))
    eta = plateau + _rosin_rammler_area(x_break, 1.0, kr)
    return float(eta), float(_rosin_rammler_area(1.0, max(x_max, 1.0), kr))


LUCKIE_AUSTIN_BREAK = 0.5


def luckie_austin(x, kr):
    r"""Luckie and Austin, piecewise: Rosin-Rammler above ``x = 1/2``, constant below.

    Printed as :math:`1 - \exp(-\ln 2\, x^{k_r})` (the coarse-product form copied from
    Luckie and Austin); the paper states the branch coincides with (5) and has its slope,
    so :math:`\exp(-\ln 2\, x^{k_r})` is implemented.  The constant below the break is
    the value at the break, which keeps the formula continuous and two-parameter.

    Examples
    --------
    >>> float(luckie_austin(0.1, 2.0)) == float(luckie_austin(0.5, 2.0))
    True
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
    return optimize.brentq(
        lambda xa: _plateau_efficiency(kr, 1.0, xa)[0] - measured_efficiency, 0.0, 1.0, xtol=1e-14
    )


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
    try:
        return shuvalov_break(kr, measured_efficiency)
    except NoBreakPointError:
        return 1.0 if measured_efficiency < 0.5 else 0.0


def shuvalov(x, kr, *, measured_efficiency):
    r"""Shuvalov (1992), piecewise: Rosin-Rammler above :math:`x_a`, constant below.

    :math:`x_a` is chosen so that the area under the curve on :math:`0 < x < 1` equals
    the classifier efficiency measured on the experimental curve (see
    :func:`shuvalov_break`).  Where no such :math:`x_a` exists the curve falls back to
    the nearer limit (plain (5) or a step at the cut); fits report this case.

    Examples
    --------
    >>> y = shuvalov([0.05, 0.1], 2.0, measured_efficiency=0.8)
    >>> bool(y[0] == y[1])
    True
    """
    return rosin_rammler_plateau(x, kr, _shuvalov_break_or_edge(kr, measured_efficiency))


def _shuvalov_efficiency(kr, x_max, *, measured_efficiency):
    return _plateau_efficiency(kr, x_max, _shuvalov_break_or_edge(kr, measured_efficiency))


def _lynch_shape_for_slope(s):
    target = -s
    if target <= 0.25:
        return 1e-6
    return optimize.brentq(lambda kl: -_lynch_slope(kl) - target, 1e-9, 800.0, xtol=1e-14)


def _rosin_rammler_shape_for_slope(s):
    return -2.0 * s / LN2


FORMULAS: tuple[Formula, ...] = (
    Formula(
        id="molerus",
        equation=3,
        title="Molerus (1967)",
        expression="1 / (1 + exp(-km1 (1 - x^2)))",
        shape_name="km1",
        shape_bounds=(1e-6, 60.0),
        phi=molerus,
        slope_at_cut=lambda km1: -km1 / 2.0,
        slope_expression="-km1/2",
        shape_for_slope=lambda s: -2.0 * s,
        citation="Molerus O. (1967), as formula (3) in " + SHUVALOV_2018,
        notes="phi(0) < 1: some fines report to the coarse product.",
    ),
    Formula(
        id="molerus_hoffmann",
        equation=4,
        title="Molerus and Hoffmann (1969)",
        expression="1 / (1 + x^2 exp(-km2 (1 - x^2)))",
        shape_name="km2",
        shape_bounds=(0.0, 60.0),
        phi=molerus_hoffmann,
        slope_at_cut=lambda km2: -(1.0 + km2) / 2.0,
        slope_expression="-(1+km2)/2",
        shape_for_slope=lambda s: -2.0 * s - 1.0,
        citation="Molerus O., Hoffmann H. (1969), as formula (4) in " + SHUVALOV_2018,
        notes="km2 = 0 is Plitt with ks = 2; km2 < 0 has a minimum at x = 1/sqrt(-km2) and rises again, so "
        "fits keep km2 >= 0 (slope at the cut -1/2 or steeper).",
        monotone=False,
        lower_bound_reason="km2 < 0 would make the curve rise again beyond x = 1/sqrt(-km2) (not a monotone "
        "partition curve); the best monotone curve is shown",
    ),
    Formula(
        id="rosin_rammler",
        equation=5,
        title="Rosin-Rammler form",
        expression="exp(-ln2 x^kr)",
        shape_name="kr",
        shape_bounds=(0.05, 40.0),
        phi=rosin_rammler,
        slope_at_cut=lambda kr: -LN2 * kr / 2.0,
        slope_expression="-ln2 kr/2",
        shape_for_slope=_rosin_rammler_shape_for_slope,
        citation="Rosin-Rammler distribution law, as formula (5) in " + SHUVALOV_2018,
        efficiency=_rosin_rammler_efficiency,
    ),
    Formula(
        id="lynch",
        equation=6,
        title="Lynch (1977)",
        expression="1 - (exp(kl x) - 1) / (exp(kl x) + exp(kl) - 2)",
        shape_name="kl",
        shape_bounds=(1e-6, 120.0),
        phi=lynch,
        slope_at_cut=_lynch_slope,
        slope_expression="-kl e^kl/(4(e^kl-1))",
        shape_for_slope=_lynch_shape_for_slope,
        citation="Lynch A.J. (1977), as formula (6) in " + SHUVALOV_2018,
        notes="The slope at the cut is never shallower than -1/4 (kl -> 0 is Plitt with ks = 1).",
    ),
    Formula(
        id="plitt",
        equation=7,
        title="Plitt (1971)",
        expression="1 / (1 + x^ks)",
        shape_name="ks",
        shape_bounds=(0.05, 60.0),
        phi=plitt,
        slope_at_cut=lambda ks: -ks / 4.0,
        slope_expression="-ks/4",
        shape_for_slope=lambda s: -4.0 * s,
        citation="Plitt L.R. (1971), as formula (7) in " + SHUVALOV_2018,
        efficiency=_plitt_efficiency,
    ),
    Formula(
        id="ogawa_allen",
        equation=8,
        title="Ogawa, Allen's law",
        expression="1 / (1 + x exp(-kp (1 - x)))",
        shape_name="kp",
        shape_bounds=(0.0, 60.0),
        phi=ogawa_allen,
        slope_at_cut=lambda kp: -(1.0 + kp) / 4.0,
        slope_expression="-(1+kp)/4",
        shape_for_slope=lambda s: -4.0 * s - 1.0,
        citation="Ogawa K. (Allen's law), as formula (8) in " + SHUVALOV_2018,
        notes="Printed with exp(-kp x); corrected to exp(-kp (1 - x)) (phi(1) = 0.5, slope (17)). "
        "kp < 0 rises again beyond x = -1/kp, so fits keep kp >= 0 (slope at the cut -1/4 or steeper).",
        monotone=False,
        lower_bound_reason="kp < 0 would make the curve rise again beyond x = -1/kp (not a monotone partition "
        "curve); the best monotone curve is shown",
    ),
    Formula(
        id="lognormal",
        equation=9,
        title="Log-normal (Gauss integral)",
        expression="1/2 erfc(ln x / kf)",
        shape_name="kf",
        shape_bounds=(0.01, 30.0),
        phi=lognormal,
        slope_at_cut=lambda kf: -1.0 / (np.sqrt(np.pi) * kf),
        slope_expression="-1/(sqrt(pi) kf)",
        shape_for_slope=lambda s: -1.0 / (np.sqrt(np.pi) * s),
        citation="Integral of the log-normal law, as formula (9) in " + SHUVALOV_2018,
        notes="kf = sqrt(2) sigma of ln(size).",
        efficiency=_lognormal_efficiency,
    ),
    Formula(
        id="luckie_austin",
        equation=10,
        title="Luckie and Austin, piecewise",
        expression="exp(-ln2 x^kr) for x > 1/2; exp(-ln2 2^-kr) for x <= 1/2",
        shape_name="kr",
        shape_bounds=(0.05, 40.0),
        phi=luckie_austin,
        slope_at_cut=lambda kr: -LN2 * kr / 2.0,
        slope_expression="-ln2 kr/2",
        shape_for_slope=_rosin_rammler_shape_for_slope,
        citation="Luckie P.T., Austin L.G., as formula (10) in " + SHUVALOV_2018,
        notes="Printed as the coarse-product branch 1 - exp(...); corrected to the fines branch of (5), "
        "with the plateau equal to the value at x = 1/2 (continuity).",
        efficiency=lambda kr, x_max: _plateau_efficiency(kr, x_max, LUCKIE_AUSTIN_BREAK),
    ),
    Formula(
        id="shuvalov",
        equation=11,
        title="Shuvalov (1992), piecewise",
        expression="exp(-ln2 x^kr) for x > x_a; phi(x_a) for x <= x_a (x_a from the measured efficiency)",
        shape_name="kr",
        shape_bounds=(0.05, 40.0),
        phi=shuvalov,
        slope_at_cut=lambda kr: -LN2 * kr / 2.0,
        slope_expression="-ln2 kr/2",
        shape_for_slope=_rosin_rammler_shape_for_slope,
        citation="Shuvalov S.I. (1992), as formula (11) in " + SHUVALOV_2018,
        notes="x_a makes the area under the curve on 0 < x < 1 equal the measured efficiency; "
        "printed with the coarse-product branch like (10).",
        efficiency=_shuvalov_efficiency,
        context_from_efficiency=True,
        defaults={"measured_efficiency": 0.75},
    ),
)

# --- extended curves: bypass and fish-hook ------------------------------------------------
NAPIER_MUNN_1996 = (
    "Napier-Munn T.J., Morrell S., Morrison R.D., Kojovic T. (1996). Mineral Comminution Circuits: "
    "Their Operation and Optimisation. JKMRC, Brisbane (Whiten's efficiency curve with the fish-hook term)"
)
PLITT_1976 = "Plitt L.R. (1976). A mathematical model of the hydrocyclone classifier. CIM Bulletin 69(776), 114-123"
KELSALL_1953 = "Kelsall D.F. (1953). A further study of the hydraulic cyclone. Chem. Eng. Sci. 2, 254-272 (bypass correction)"
BYPASS = ExtraParameter("bypass", (0.0, 0.95), 0.05, "share of every size sent to the coarse product unclassified")
FISHHOOK = ExtraParameter("fishhook", (0.0, 3.0), 0.1, "Whiten's beta: rise of the fines partition at small sizes")


def with_bypass(base: Formula, *, equation: int, citation: str) -> Formula:
    r"""``base`` with bypass: :math:`\varphi = (1 - \text{bypass})\,\varphi_{base}(x)`.

    A share of every size reports to the coarse product unclassified; ``d_cut`` becomes
    the corrected cut (partition 1/2 of the classified part) and the formula nests
    ``base`` (bypass = 0).
    """

    def phi(x, shape, *, bypass=0.0):
        return (1.0 - bypass) * base.phi(x, shape)

    phi.__name__ = f"{base.id}_bypass"
    return Formula(
        id=f"{base.id}_bypass",
        equation=equation,
        title=f"{base.title} with bypass",
        expression=f"(1 - bypass) [{base.expression}]",
        shape_name=base.shape_name,
        shape_bounds=base.shape_bounds,
        phi=phi,
        slope_at_cut=base.slope_at_cut,
        slope_expression=f"(1-bypass) [{base.slope_expression}]",
        shape_for_slope=base.shape_for_slope,
        citation=citation,
        notes="d_cut is the corrected cut; the actual curve is 0.5 (1 - bypass) there.",
        extras=(BYPASS,),
        family="extended",
        nests=base.id,
    )


def whiten_beta_star(alpha: float, fishhook: float) -> float:
    r"""Whiten's :math:`\beta^*`: keeps the reduced curve at 1/2 at ``x = 1`` for a given fish-hook.

    Solves :math:`(1 + \beta\beta^*)(e^\alpha - 1)/(e^{\alpha\beta^*} + e^\alpha - 2) = 1/2`;
    :math:`\beta^* = 1` when :math:`\beta = 0`.
    """
    if fishhook == 0.0:
        return 1.0

    def gap(star):
        return float((1.0 + fishhook * star) * lynch(star, alpha)) - 0.5

    high = 1.0
    while gap(high) > 0.0:
        high *= 2.0
    return optimize.brentq(gap, 0.0, high, xtol=1e-14)


def whiten(x, alpha, *, bypass=0.0, fishhook=0.0):
    r"""Whiten's efficiency curve to the fine product with bypass and fish-hook.

    .. math::
        \varphi = C \frac{(1 + \beta\beta^* x)(e^\alpha - 1)}{e^{\alpha\beta^* x} + e^\alpha - 2},
        \quad C = 1 - \text{bypass}

    With :math:`\beta = 0` and no bypass it is Lynch's formula (6) with :math:`k_l = \alpha`.
    For :math:`\beta > 0` the curve rises above ``C`` at small sizes (the fish-hook) and
    can exceed 1 when the bypass is small; fits report such a curve.
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
        expression="(1 - bypass)(1 + fishhook b* x)(e^alpha - 1)/(e^(alpha b* x) + e^alpha - 2)",
        shape_name="alpha",
        shape_bounds=(1e-3, 60.0),
        phi=whiten,
        slope_at_cut=_lynch_slope,
        slope_expression="as (6) when fishhook = 0, times (1-bypass)",
        shape_for_slope=_lynch_shape_for_slope,
        citation=NAPIER_MUNN_1996,
        notes="Reduces to Lynch (6) with kl = alpha without bypass and fish-hook; may exceed 1 for a large "
        "fish-hook with little bypass.",
        extras=(BYPASS, FISHHOOK),
        family="extended",
        nests="lynch",
        monotone=False,
    ),
)
ALL_FORMULAS = FORMULAS + EXTENDED_FORMULAS

_BY_ID = {formula.id: formula for formula in ALL_FORMULAS}
_BY_EQUATION = {formula.equation: formula for formula in FORMULAS}


def get_formula(key: str | int) -> Formula:
    """Look a formula up by id (``"plitt"``) or equation number (``7``, ``"7"``, ``"(7)"``)."""
    if isinstance(key, Formula):
        return key
    text = str(key).strip()
    if text in _BY_ID:
        return _BY_ID[text]
    number = text.strip("()")
    if number.isdigit() and int(number) in _BY_EQUATION:
        return _BY_EQUATION[int(number)]
    known = ", ".join(f"{f.id} ({f.equation})" for f in FORMULAS)
    raise KeyError(f"unknown formula {key!r}; known formulas: {known}")


def select_formulas(keys=None) -> tuple[Formula, ...]:
    """The formulas named by ``keys`` (ids or equation numbers), or all nine.

    ``"extended"`` in ``keys`` stands for every extended curve (bypass, fish-hook).
    """
    if keys is None:
        return FORMULAS
    if isinstance(keys, str):
        keys = [k for k in keys.replace(" ", "").split(",") if k]
    chosen = []
    for key in keys:
        group = EXTENDED_FORMULAS if key == "extended" else FORMULAS if key == "paper" else (get_formula(key),)
        chosen += [f for f in group if f not in chosen]
    return tuple(chosen)


def registry_table():
    """The registry as a :class:`pandas.DataFrame` (one row per formula)."""
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
            }
        )
    return pd.DataFrame(rows)
