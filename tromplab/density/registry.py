r"""Density partition curves of gravity separators (Tromp curves by relative density).

Every curve gives the partition number *to the sinks* (the heavy product) ``P(rho)`` of
material of relative density ``rho`` (g/cm3, water = 1), rising in ``rho``.  The plain
curves are written with the cut density ``rho50`` (``P = 1/2``) and the probable error
``Ep = (rho75 - rho25) / 2`` (in density units, *not* divided by ``rho50``, unlike the size
curves' ``Ep / d50``), through one standard form ``F``:

.. math::
    P(\rho) = F\!\left(q_{50} + k\,\frac{\rho - \rho_{50}}{E_p}\right),
    \qquad k = \frac{q_{75} - q_{25}}{2},\quad q_p = F^{-1}(p),

so that ``P(rho50) = 1/2`` and ``P(rho50 -/+ Ep) = 1/4, 3/4`` for the symmetric curves.
Each has a variant with two limits (misplaced material that no density separates, as the
size curves' bypass): ``P = l + (h - l) F(...)``, with ``rho_c`` and ``ep_c`` the cut and
probable error of the separating part ``F``; ``rho25``, ``rho50``, ``rho75``, ``Ep`` and
the imperfection ``I = Ep / (rho50 - 1)`` are then read from ``P`` itself
(:meth:`DensityCurve.indices`) and do not exist when ``P`` never reaches 1/4 or 3/4.

The curves are declared once, in :data:`DENSITY_CURVES`; fitting, tables, figures and tests
iterate over it.

References
----------
.. [Tromp1937] Tromp K.F. (1937). Neue Wege für die Beurteilung der Aufbereitung von
   Steinkohlen. *Glückauf* 73, 125-131 and 151-156.
.. [Wills2016] Wills B.A., Finch J.A. (2016). *Wills' Mineral Processing Technology*, 8th ed.
   Butterworth-Heinemann, Oxford (ch. 11, dense medium separation: partition curve, Ep,
   imperfection).
.. [NapierMunn1991] Napier-Munn T.J. (1991). Modelling and simulating dense medium separation
   processes - a progress report. *Minerals Engineering* 4(3-4), 329-346.
.. [McCullagh1989] McCullagh P., Nelder J.A. (1989). *Generalized Linear Models*, 2nd ed.
   Chapman & Hall, London (sect. 4.3: the logit, probit and complementary log-log links).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import scipy.special

from ..curves.likelihood import on_bound
from ..curves.parameters import Parameter

#: Probabilities of the quartiles and the cut that the indices are read at.
QUARTILES = (0.25, 0.5, 0.75)
#: How close to a bound (in partition units) a fitted limit is taken to be on it.
LIMIT_ON_BOUND = 1e-6

TROMP_1937 = "Tromp K.F. (1937). Neue Wege für die Beurteilung der Aufbereitung von Steinkohlen. Glückauf 73, 125-131 and 151-156"
WILLS_2016 = (
    "Wills B.A., Finch J.A. (2016). Wills' Mineral Processing Technology, 8th ed. Butterworth-Heinemann, Oxford "
    "(ch. 11, dense medium separation)"
)
NAPIER_MUNN_1991 = (
    "Napier-Munn T.J. (1991). Modelling and simulating dense medium separation processes - a progress report. "
    "Minerals Engineering 4(3-4), 329-346"
)
MCCULLAGH_NELDER_1989 = "McCullagh P., Nelder J.A. (1989). Generalized Linear Models, 2nd ed. Chapman & Hall, London (sect. 4.3)"

#: The cut density of the fits: above water's and below the heaviest media in use.
RHO50 = Parameter(
    "rho50",
    1.0,
    8.0,
    unit="g/cm3",
    meaning="cut density: the relative density with partition 1/2 to each product",
    start_rule="where the measured partition crosses 1/2, interpolated in density",
)
EP = Parameter(
    "ep",
    1e-4,
    2.0,
    unit="g/cm3",
    meaning="probable error (rho75 - rho25)/2, in density units; smaller is sharper",
    start_rule="half the density span between the measured partitions 1/4 and 3/4",
)
RHO_C = Parameter(
    "rho_c",
    1.0,
    8.0,
    unit="g/cm3",
    meaning="cut density of the separating part F (the curve before the limits)",
    start_rule="where the measured partition crosses 1/2, interpolated in density",
)
EP_C = Parameter(
    "ep_c",
    1e-4,
    2.0,
    unit="g/cm3",
    meaning="probable error of the separating part F (the curve before the limits)",
    start_rule="half the density span between the measured partitions 1/4 and 3/4",
)
LIGHT_LIMIT = Parameter(
    "light_limit",
    0.0,
    0.5,
    unit="1",
    meaning="partition to sinks of the lightest material: light material misplaced to the sinks",
    start=0.01,
    start_rule="fixed at 0.01",
)
HEAVY_LIMIT = Parameter(
    "heavy_limit",
    0.5,
    1.0,
    unit="1",
    meaning="partition to sinks of the heaviest material (1 - the heavy material misplaced to the floats)",
    start=0.99,
    start_rule="fixed at 0.99",
)


@dataclass(frozen=True)
class StandardForm:
    """A standard distribution function ``F`` that a density curve is a location-scale copy of.

    Attributes
    ----------
    cdf : callable
        ``F(t)``, vectorised, increasing from 0 to 1.
    quantile : callable
        ``F^-1(p)`` on ``0 < p < 1``, vectorised.
    pdf : callable
        ``f(t) = F'(t)``, vectorised: the GLM's derivative of the mean in the linear predictor.
    log_pdf : callable
        ``ln f(t)``, vectorised, finite far into the tails (the plant's weights of a sharp curve).
    link : str
        The binomial GLM link whose inverse is ``F`` (``"probit"``, ``"logit"``,
        ``"cloglog"``): a plain curve is fitted to tracer counts as that GLM.
    text : str
        ``F`` as plain text in ``t``, the functions of :data:`EXPRESSION_FUNCTIONS`.
    """

    cdf: Callable[[np.ndarray], np.ndarray]
    quantile: Callable[[np.ndarray], np.ndarray]
    pdf: Callable[[np.ndarray], np.ndarray]
    log_pdf: Callable[[np.ndarray], np.ndarray]
    link: str
    text: str

    @property
    def centre(self) -> float:
        """``q50 = F^-1(1/2)``."""
        return float(self.quantile(0.5))

    @property
    def scale(self) -> float:
        """``k = (F^-1(3/4) - F^-1(1/4)) / 2``: the standardised probable error."""
        return float(self.quantile(0.75) - self.quantile(0.25)) / 2.0


def _gompertz_cdf(t):
    # exp(710) overflows; F is 1 to the last bit from t = 4 on, so the cap changes nothing
    return -np.expm1(-np.exp(np.minimum(t, 700.0)))


def _gompertz_quantile(p):
    return np.log(-np.log1p(-np.asarray(p, dtype=float)))


def _gompertz_pdf(t):
    t = np.minimum(t, 700.0)
    return np.exp(t - np.exp(t))


def _gompertz_log_pdf(t):
    return t - np.exp(np.minimum(t, 700.0))


def _normal_pdf(t):
    return np.exp(-0.5 * t * t) / math.sqrt(2.0 * math.pi)


def _normal_log_pdf(t):
    return -0.5 * t**2 - 0.5 * np.log(2 * np.pi)


def _logistic_pdf(t):
    p = scipy.special.expit(t)
    return p * (1.0 - p)


def _logistic_log_pdf(t):
    magnitude = np.abs(t)
    return -magnitude - 2.0 * np.log1p(np.exp(-magnitude))


NORMAL_FORM = StandardForm(scipy.special.ndtr, scipy.special.ndtri, _normal_pdf, _normal_log_pdf, "probit", "erfc(-t/sqrt(2))/2")
LOGISTIC_FORM = StandardForm(
    scipy.special.expit, scipy.special.logit, _logistic_pdf, _logistic_log_pdf, "logit", "1/(1 + exp(-t))"
)
GOMPERTZ_FORM = StandardForm(_gompertz_cdf, _gompertz_quantile, _gompertz_pdf, _gompertz_log_pdf, "cloglog", "1 - exp(-exp(t))")

#: Names the expression texts use besides ``rho`` and the parameters.
EXPRESSION_FUNCTIONS = ("exp", "ln", "erfc", "sqrt")


@dataclass(frozen=True)
class DensityIndices:
    """The indices of one density partition curve, read from ``P`` itself.

    Attributes
    ----------
    rho25, rho50, rho75 : float
        Densities (g/cm3) at partition 1/4, 1/2, 3/4 to the sinks; NaN where ``P`` never
        reaches that partition.
    ep : float
        Probable error ``(rho75 - rho25) / 2`` (g/cm3); NaN where a quartile does not exist.
    imperfection : float
        ``ep / (rho50 - 1)`` (dimensionless); NaN where ``ep`` does not exist or
        ``rho50 <= 1``.
    note : str
        Why an index does not exist, in words; empty when all exist.
    """

    rho25: float
    rho50: float
    rho75: float
    ep: float
    imperfection: float
    note: str = ""

    def as_dict(self) -> dict[str, float | str]:
        """The indices by name (the column names of the fits table)."""
        return {
            "rho25": self.rho25,
            "rho50": self.rho50,
            "rho75": self.rho75,
            "ep": self.ep,
            "imperfection": self.imperfection,
        }


@dataclass(frozen=True)
class DensityCurve:
    """Declaration of one density partition curve (partition to the sinks).

    Attributes
    ----------
    id : str
        Identifier used in tables, the CLI and tests (``"normal"``, ``"logistic_limits"``).
    title : str
        Human-readable name with its origin.
    form : StandardForm
        The standard form ``F``: its function, inverse, binomial link and text.
    parameters : tuple of Parameter
        The fitted parameters, in order: ``rho50, ep`` for a plain curve,
        ``rho_c, ep_c, light_limit, heavy_limit`` for a curve with limits.
    citation : str
        Sources of the curve.
    notes : str
        What is worth knowing about the curve's shape.
    limits_of : DensityCurve or None
        The plain curve this one adds the two limits to; None for a plain curve.
    """

    id: str
    title: str
    form: StandardForm
    parameters: tuple[Parameter, ...]
    citation: str
    notes: str = ""
    limits_of: DensityCurve | None = None

    def __reduce__(self):
        # Records hold functions; they travel (pickle, process pools) by their id.
        return (get_density_curve, (self.id,))

    @property
    def has_limits(self) -> bool:
        """True for a curve with the light-end and heavy-end limits."""
        return self.limits_of is not None

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Names of the fitted parameters, in order."""
        return tuple(parameter.name for parameter in self.parameters)

    @property
    def n_params(self) -> int:
        """Number of fitted parameters."""
        return len(self.parameters)

    @property
    def link(self) -> str:
        """The binomial GLM link of the standard form (a plain curve is that GLM)."""
        return self.form.link

    @property
    def expression(self) -> str:
        """The curve as plain text in ``rho`` and its parameters."""
        if self.has_limits:
            return f"light_limit + (heavy_limit - light_limit)*F(t), t = {self._standardised('rho_c', 'ep_c')}, F(t) = {self.form.text}"
        return f"F(t), t = {self._standardised('rho50', 'ep')}, F(t) = {self.form.text}"

    def _standardised(self, cut: str, ep: str) -> str:
        form = self.form
        centre = "" if form.centre == 0.0 else f"{form.centre:.15g} + "
        return f"{centre}{form.scale:.15g}*(rho - {cut})/{ep}"

    def limit_on_bound(self, name: str, value: float) -> bool:
        """True for a limit (``light_limit``, ``heavy_limit``) within :data:`LIMIT_ON_BOUND` of
        one of its bounds: the fits hold it there (its curvature is one-sided), as the size
        curves hold a parameter :func:`~tromplab.curves.likelihood.on_bound` finds on its bound.

        Examples
        --------
        >>> curve = get_density_curve("normal_limits")
        >>> curve.limit_on_bound("light_limit", 5e-7), curve.limit_on_bound("light_limit", 0.01), curve.limit_on_bound("rho_c", 1.0)
        (True, False, False)
        """
        if name not in ("light_limit", "heavy_limit"):
            return False
        parameter = next(p for p in self.parameters if p.name == name)
        return any(on_bound(value, bound, atol=LIMIT_ON_BOUND) for bound in parameter.bounds)

    def _check_parameters(self, params: Mapping[str, object]) -> None:
        names = set(self.parameter_names)
        if set(params) != names:
            missing = sorted(names - set(params))
            unknown = sorted(set(params) - names)
            detail = "; ".join(
                part for part in (f"missing {missing}" if missing else "", f"unknown {unknown}" if unknown else "") if part
            )
            raise TypeError(f"curve {self.id!r} takes the parameters {', '.join(self.parameter_names)}: {detail}")

    def partition(self, rho, **params) -> np.ndarray:
        """Partition to the sinks at the relative densities ``rho`` (arrays broadcast).

        Parameters
        ----------
        rho : array_like
            Relative density (g/cm3).
        **params : float or array_like
            The curve's parameters by name (:attr:`parameter_names`).

        Returns
        -------
        ndarray
            Partition number to the sinks, 0..1.

        Examples
        --------
        >>> round(float(get_density_curve("logistic").partition(1.55, rho50=1.5, ep=0.05)), 12)
        0.75
        """
        self._check_parameters(params)
        rho = np.asarray(rho, dtype=float)
        if self.has_limits:
            cut, ep = params["rho_c"], params["ep_c"]
        else:
            cut, ep = params["rho50"], params["ep"]
        t = self.form.centre + self.form.scale * (rho - np.asarray(cut, dtype=float)) / np.asarray(ep, dtype=float)
        inside = self.form.cdf(t)
        if not self.has_limits:
            return inside
        light = np.asarray(params["light_limit"], dtype=float)
        heavy = np.asarray(params["heavy_limit"], dtype=float)
        return light + (heavy - light) * inside

    def density_at(self, partition, **params) -> np.ndarray:
        """The density at which the curve has the given ``partition`` to sinks (exact inverse).

        NaN where the curve never takes that value (a curve with limits stays between its
        light-end and heavy-end limits).

        Examples
        --------
        >>> round(float(get_density_curve("normal").density_at(0.75, rho50=1.5, ep=0.04)), 12)
        1.54
        """
        self._check_parameters(params)
        p = np.asarray(partition, dtype=float)
        if self.has_limits:
            cut, ep = np.asarray(params["rho_c"], dtype=float), np.asarray(params["ep_c"], dtype=float)
            light = np.asarray(params["light_limit"], dtype=float)
            heavy = np.asarray(params["heavy_limit"], dtype=float)
            with np.errstate(invalid="ignore", divide="ignore"):
                inside = (p - light) / (heavy - light)
            reached = (light < p) & (p < heavy)
        else:
            cut, ep = np.asarray(params["rho50"], dtype=float), np.asarray(params["ep"], dtype=float)
            inside = p
            reached = (p > 0.0) & (p < 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = self.form.quantile(np.where(reached, inside, 0.5))
        return np.where(reached, cut + ep * (t - self.form.centre) / self.form.scale, np.nan)

    def indices(self, **params) -> DensityIndices:
        """``rho25``, ``rho50``, ``rho75``, ``Ep`` and the imperfection of one curve, read from ``P``.

        For a curve with limits they exist only when the light-end limit is below 1/4
        (for ``rho25``) and the heavy-end limit above 3/4 (for ``rho75``); ``note`` says
        which does not exist and why.  The imperfection ``Ep / (rho50 - 1)`` does not exist
        at or below ``rho50 = 1``.

        Examples
        --------
        >>> round(get_density_curve("normal").indices(rho50=1.5, ep=0.04).imperfection, 12)
        0.08
        >>> print(get_density_curve("normal_limits").indices(rho_c=1.5, ep_c=0.04, light_limit=0.3, heavy_limit=1.0).note)
        rho25 does not exist: the light-end limit 0.3 is at or above 1/4, so the partition never falls to 1/4; Ep and the imperfection do not exist
        """
        scalars = {name: float(value) for name, value in params.items()}
        rho25, rho50, rho75 = (float(v) for v in self.density_at(np.array(QUARTILES), **scalars))
        reasons = []
        light, heavy = scalars.get("light_limit", 0.0), scalars.get("heavy_limit", 1.0)
        for name, p, exists in (("rho25", 0.25, rho25), ("rho50", 0.5, rho50), ("rho75", 0.75, rho75)):
            if math.isnan(exists):
                if light >= p:
                    reasons.append(
                        f"{name} does not exist: the light-end limit {light:g} is at or above {_fraction(p)}, "
                        f"so the partition never falls to {_fraction(p)}"
                    )
                else:
                    reasons.append(
                        f"{name} does not exist: the heavy-end limit {heavy:g} is at or below {_fraction(p)}, "
                        f"so the partition never rises to {_fraction(p)}"
                    )
        # a plain curve's Ep is its parameter (the quartiles' half-distance up to rounding)
        ep = scalars["ep"] if not self.has_limits else (rho75 - rho25) / 2.0
        if math.isnan(ep):
            reasons[-1] += "; Ep and the imperfection do not exist"
            imperfection = math.nan
        elif rho50 <= 1.0:
            imperfection = math.nan
            reasons.append(f"the imperfection does not exist: rho50 = {rho50:g} is not above 1 (water)")
        else:
            imperfection = ep / (rho50 - 1.0)
        return DensityIndices(rho25, rho50, rho75, ep, imperfection, "; ".join(reasons))

    def from_indices(self, *, rho50: float, ep: float, light_limit: float = 0.0, heavy_limit: float = 1.0) -> dict[str, float]:
        """The parameters of the curve whose ``P`` has the cut ``rho50`` and probable error ``ep``.

        For a plain curve these are its parameters; for a curve with limits, the
        ``rho_c`` and ``ep_c`` of its separating part that give ``P`` those indices with
        the given limits (``light_limit < 1/4``, ``heavy_limit > 3/4``).

        Examples
        --------
        >>> curve = get_density_curve("logistic_limits")
        >>> params = curve.from_indices(rho50=1.6, ep=0.05, light_limit=0.02, heavy_limit=0.97)
        >>> index = curve.indices(**params)
        >>> round(index.rho50, 12), round(index.ep, 12)
        (1.6, 0.05)
        """
        if not self.has_limits:
            return {"rho50": float(rho50), "ep": float(ep)}
        if not (0.0 <= light_limit < 0.25 and 0.75 < heavy_limit <= 1.0):
            raise ValueError(
                f"rho50 and Ep exist only for a light-end limit in [0, 1/4) and a heavy-end limit in (3/4, 1]; "
                f"got {light_limit:g} and {heavy_limit:g}"
            )
        span = heavy_limit - light_limit
        q25, q50, q75 = (float(self.form.quantile((p - light_limit) / span)) for p in QUARTILES)
        # P's quartiles sit at q25, q75 of F's standardised variable t; its cut at q50
        scale_c = self.form.scale
        ep_c = ep * 2.0 * scale_c / (q75 - q25)
        rho_c = rho50 - ep_c * (q50 - self.form.centre) / scale_c
        return {"rho_c": rho_c, "ep_c": ep_c, "light_limit": float(light_limit), "heavy_limit": float(heavy_limit)}


def _fraction(p: float) -> str:
    return {0.25: "1/4", 0.5: "1/2", 0.75: "3/4"}[p]


def with_limits(base: DensityCurve) -> DensityCurve:
    """The curve ``base`` with a light-end and a heavy-end limit: ``P = l + (h - l) F``."""
    return DensityCurve(
        id=f"{base.id}_limits",
        title=f"{base.title} with light-end and heavy-end limits",
        form=base.form,
        parameters=(RHO_C, EP_C, LIGHT_LIMIT, HEAVY_LIMIT),
        citation=f"{base.citation}; limits (misplaced material): {WILLS_2016}; {NAPIER_MUNN_1991}",
        notes=(
            "The limits are the partition to sinks of the lightest and of the heaviest material: light material "
            "misplaced to the sinks, heavy material misplaced to the floats, that no density separates (as the size "
            "curves' bypass). rho25, rho50, rho75, Ep and the imperfection are read from P itself; rho25 does not exist "
            "when light_limit >= 1/4 and rho75 when heavy_limit <= 3/4."
        ),
        limits_of=base,
    )


NORMAL = DensityCurve(
    id="normal",
    title="Normal (error-function) curve of Tromp (1937)",
    form=NORMAL_FORM,
    parameters=(RHO50, EP),
    citation=f"{TROMP_1937}; {WILLS_2016}",
    notes="Symmetric about rho50; P = Phi(z75 (rho - rho50)/Ep), z75 = Phi^-1(3/4) = 0.6744897502. The probit link.",
)
LOGISTIC = DensityCurve(
    id="logistic",
    title="Logistic curve",
    form=LOGISTIC_FORM,
    parameters=(RHO50, EP),
    citation=f"{NAPIER_MUNN_1991}; {WILLS_2016}",
    notes="Symmetric about rho50; P = 1/(1 + exp(-ln 3 (rho - rho50)/Ep)), heavier tails than the normal curve. The logit link.",
)
GOMPERTZ = DensityCurve(
    id="gompertz",
    title="Gompertz (complementary log-log) curve",
    form=GOMPERTZ_FORM,
    parameters=(RHO50, EP),
    citation=f"{MCCULLAGH_NELDER_1989}; Gompertz B. (1825). On the nature of the function expressive of the law of "
    "human mortality. Phil. Trans. R. Soc. Lond. 115, 513-583",
    notes=(
        "Asymmetric: P = 1 - exp(-exp(t)) rises slowly from the light end and closes quickly on 1 at the heavy end, "
        "so rho50 - rho25 > rho75 - rho50 (1.118 Ep against 0.882 Ep). The complementary log-log link."
    ),
)

#: The plain curves (two parameters: rho50 and Ep).
PLAIN_CURVES: tuple[DensityCurve, ...] = (NORMAL, LOGISTIC, GOMPERTZ)
#: The same curves with the two limits (four parameters).
LIMIT_CURVES: tuple[DensityCurve, ...] = tuple(with_limits(curve) for curve in PLAIN_CURVES)
#: Every density curve, plain ones first.
DENSITY_CURVES: tuple[DensityCurve, ...] = PLAIN_CURVES + LIMIT_CURVES

_BY_ID = {curve.id: curve for curve in DENSITY_CURVES}
_GROUPS = {"plain": PLAIN_CURVES, "limits": LIMIT_CURVES, "all": DENSITY_CURVES}


def get_density_curve(key) -> DensityCurve:
    """Look a density curve up by id (``"normal"``, ``"gompertz_limits"``); a record is returned as is.

    Raises
    ------
    KeyError
        For an unknown id, listing the known ones.

    Examples
    --------
    >>> get_density_curve("logistic_limits").limits_of.id
    'logistic'
    """
    if isinstance(key, DensityCurve):
        return key
    text = str(key).strip()
    if text in _BY_ID:
        return _BY_ID[text]
    raise KeyError(f"unknown density curve {key!r}; known curves: {', '.join(_BY_ID)}")


def select_density_curves(keys=None) -> tuple[DensityCurve, ...]:
    """The curves named by ``keys`` (ids, or the groups ``plain``, ``limits``, ``all``); default: all.

    Examples
    --------
    >>> [curve.id for curve in select_density_curves("normal,limits")]
    ['normal', 'normal_limits', 'logistic_limits', 'gompertz_limits']
    """
    if keys is None:
        return DENSITY_CURVES
    if isinstance(keys, str):
        keys = [key for key in keys.replace(" ", "").split(",") if key]
    chosen: list[DensityCurve] = []
    for key in keys:
        group = _GROUPS.get(key, None) or (get_density_curve(key),)
        chosen += [curve for curve in group if curve not in chosen]
    if not chosen:  # an empty list or text: fitting nothing would report a test without a curve as a success
        raise KeyError(f"names no curve: give curve ids ({', '.join(c.id for c in DENSITY_CURVES)}) or plain, limits, all")
    return tuple(chosen)


def density_registry_table():
    """The density curves as a :class:`pandas.DataFrame` (one row per curve).

    Columns: ``id, title, expression, parameters, link, citation, notes``; ``parameters``
    lists each with its bounds and unit.

    Examples
    --------
    >>> density_registry_table().set_index("id").loc["gompertz", "link"]
    'cloglog'
    """
    import pandas as pd

    rows = [
        {
            "id": curve.id,
            "title": curve.title,
            "expression": curve.expression,
            "parameters": "; ".join(
                f"{p.name} in [{p.lower:g}, {p.upper:g}]{f' [{p.unit}]' if p.unit else ''}: {p.meaning}" for p in curve.parameters
            ),
            "link": curve.link,
            "citation": curve.citation,
            "notes": curve.notes,
        }
        for curve in DENSITY_CURVES
    ]
    return pd.DataFrame(rows)
