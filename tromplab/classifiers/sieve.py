"""Sieve classifiers: passage probabilities, kinetics, identification, multi-deck model.

Models of Akhmadiev, Gizzyatov and co-authors for vibrating sieve classifiers (spec
section 6):

* geometric probability ``P_g`` of an elongated particle ``l x d`` passing a round hole
  ``D`` in a cell ``2a x 2b`` [Akhmadiev-kinetics]_;
* velocity probability ``P_v``: the one-sided form ``1 - Phi((Va - Vk)/sigma)``
  [Akhmadiev-kinetics]_ and the two-sided form ``2 - Phi(z) - Phi(z0)``
  [Akhmadiev-random-walk]_;
* kinetics on one sieve: sieving probability ``P = P_g P_v``, kinetic coefficient
  ``lambda = P V / (2a)``, oversize share ``gamma = exp(-P L / (2a))``, efficiency
  ``E = gamma_i^i (1 - gamma_i^{i+1})`` and capacity ``Q = rho h B V``;
* identification of ``(Vk, sigma)`` from residues measured at several speed regimes,
  through the common fitting layer (:mod:`tromplab.curves.fitting`);
* the multi-deck random-walk (Pascal) model: cell distribution, distance distribution
  on the m-th deck, bin design for a required recovery.

Lengths may be in any unit as long as they agree (the examples use metres for the sieve
length and the cell pitch, millimetres for the hole and the particle, as the papers do).

References
----------
.. [Akhmadiev-kinetics] Akhmadiev F.G., Gizzyatov R.F. et al. Kinetics of separation of
   granular materials on multi-deck sieve classifiers; identification; multi-criteria
   optimisation.
.. [Akhmadiev-random-walk] Akhmadiev F.G., Gizzyatov R.F. Mathematical modelling and
   computational experiment of separation of granular materials on sieve classifiers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import integrate, optimize, special, stats

from ..curves.fitting import ParameterFit, expression_function, least_squares
from ..curves.parameters import Parameter
from ..errors import InputError
from ..results_contract import ResultContract, parameters_frame
from ..validation import MAX_DECKS, check_count

SECONDS_PER_HOUR = 3600.0


# --- geometric probability --------------------------------------------------------------
@dataclass(frozen=True)
class _HoleGeometry:
    rho: float
    k: float
    phi0: float

    @classmethod
    def of(cls, hole_diameter, length, width):
        rho_sq = length**2 / 16.0 + width**2 / 4.0
        return cls(np.sqrt(rho_sq), 4.0 * rho_sq / hole_diameter**2, np.arctan2(2.0 * width, length))


def _free_width(theta, hole_diameter, length, width):
    """Uncapped lateral freedom psi(theta) before clipping at 0 (may be negative)."""
    g = _HoleGeometry.of(hole_diameter, length, width)
    widths = []
    for angle in (theta + g.phi0, theta - g.phi0):
        inside = np.maximum(0.0, 1.0 - g.k * np.cos(angle) ** 2)
        widths.append(0.5 * hole_diameter * np.sqrt(inside) - g.rho * np.abs(np.sin(angle)))
    return 2.0 * np.minimum(*widths)


def closed_form_valid(hole_diameter, length, width, half_cell_width) -> bool:
    """True where the elliptic-integral form of ``P_g`` holds: the particle fits the hole at
    every angle (``psi >= 0``, which needs ``k <= 1``) and the cell never caps it (``psi <= 2b``)."""
    g = _HoleGeometry.of(hole_diameter, length, width)
    if g.k > 1.0:
        return False
    psi = _free_width(np.linspace(0.0, np.pi / 2, 2001), hole_diameter, length, width)
    return bool(psi.min() >= -1e-12 and psi.max() <= 2.0 * half_cell_width)


def geometric_probability(hole_diameter, length, width, half_cell_width, *, method: str = "auto") -> float:
    r"""Probability that a particle ``l x d`` passes a round hole of a ``2a x 2b`` cell.

    The particle's angle is uniform on :math:`[0, \pi/2]` and its lateral offset uniform on
    :math:`[-b, b]`; its leading half must fit in the hole.  With
    :math:`\rho^2 = l^2/16 + d^2/4`, :math:`k = 4\rho^2/D^2`, :math:`\tan\varphi_0 = 2d/l`:

    .. math::
        P_g = \frac{1}{\pi b}\int_0^{\pi/2} \psi(\theta)\,d\theta
            = \frac{D\,[E(\varphi_0 + \pi \mid k) - E(\varphi_0 + \pi/2 \mid k)] - (l/2 + d)}{\pi b}

    Parameters
    ----------
    hole_diameter : float
        ``D``.
    length, width : float
        Particle length ``l`` (longest) and transverse size ``d``; shape factor ``d/l``.
    half_cell_width : float
        ``b``, half the cell width across the transport direction.
    method : {"auto", "closed", "quadrature"}
        The closed form holds while :func:`closed_form_valid`; "auto" uses it there and
        quadrature elsewhere; "closed" raises outside that range.

    Examples
    --------
    Published example: D = 2 mm, cell 3.2 x 3.2 mm, d/l = 0.5, l = 2.2 mm (printed 0.150):

    >>> round(geometric_probability(2.0, 2.2, 1.1, 1.6), 4)
    0.1511
    """
    if min(hole_diameter, length, width, half_cell_width) <= 0:
        raise InputError("hole diameter, particle sizes and cell width must be positive")
    if width > length:
        raise InputError(f"the width d = {width:g} must not exceed the length l = {length:g} (shape factor d/l <= 1)")
    valid = closed_form_valid(hole_diameter, length, width, half_cell_width)
    if method == "closed" or (method == "auto" and valid):
        if not valid:
            raise InputError("the closed form needs the particle to fit the hole at every angle and the cell not to cap it")
        g = _HoleGeometry.of(hole_diameter, length, width)
        arc = special.ellipeinc(g.phi0 + np.pi, g.k) - special.ellipeinc(g.phi0 + np.pi / 2, g.k)
        return float((hole_diameter * arc - (length / 2.0 + width)) / (np.pi * half_cell_width))
    if method not in ("auto", "quadrature"):
        raise ValueError(f"unknown method {method!r}")

    def capped(theta):
        return float(np.clip(_free_width(theta, hole_diameter, length, width), 0.0, 2.0 * half_cell_width))

    area, _ = integrate.quad(capped, 0.0, np.pi / 2, limit=400)
    return float(area / (np.pi * half_cell_width))


def geometric_probability_curves(hole_diameter, half_cell_width, shape_factors, relative_sizes):
    """``P_g`` against ``D/l`` for several shape factors ``d/l`` (Fig. 3 of the kinetics paper).

    Returns a tidy :class:`pandas.DataFrame` with columns ``shape_factor, D_over_l, P_g``.
    """
    import pandas as pd

    rows = []
    for factor in shape_factors:
        for ratio in relative_sizes:
            length = hole_diameter / ratio
            rows.append(
                {
                    "shape_factor": factor,
                    "D_over_l": ratio,
                    "P_g": geometric_probability(hole_diameter, length, factor * length, half_cell_width),
                }
            )
    return pd.DataFrame(rows)


# --- velocity probability and kinetics --------------------------------------------------
def velocity_probability(relative_speed, v_k, sigma):
    r"""One-sided velocity probability :math:`P_v = 0.5 - \Phi_0((V_a - V_k)/\sigma) = 1 - \Phi(z)`.

    Examples
    --------
    >>> round(float(velocity_probability(0.287, 0.148, 0.051)), 5)
    0.00321
    """
    return stats.norm.sf((np.asarray(relative_speed, dtype=float) - v_k) / sigma)


def velocity_probability_two_sided(relative_speed, v_k, sigma):
    r"""Two-sided form :math:`p_v = 2 - (\Phi(z) + \Phi(z_0))`, :math:`z = (V - V_k)/\sigma`,
    :math:`z_0 = V_k/\sigma`; :math:`p_v(0) = 1`.

    Examples
    --------
    >>> float(velocity_probability_two_sided(0.0, 0.2, 0.05))
    1.0
    """
    z = (np.asarray(relative_speed, dtype=float) - v_k) / sigma
    return stats.norm.sf(z) + stats.norm.sf(v_k / sigma)


def residue_share(sieving_probability, sieve_length, cell_pitch):
    r"""Oversize share left after a sieve of length ``L``: :math:`\gamma = \exp(-P L / (2a))`.

    ``cell_pitch`` is the cell length ``2a`` along the transport direction.
    """
    return np.exp(-np.asarray(sieving_probability, dtype=float) * sieve_length / cell_pitch)


def kinetic_coefficient(sieving_probability, transport_speed, cell_pitch):
    r"""Kinetic coefficient :math:`\lambda = P V / (2a)` (1/s)."""
    return np.asarray(sieving_probability, dtype=float) * transport_speed / cell_pitch


def sieve_efficiency(target_retained, next_retained):
    r"""Efficiency of sieve i, in %: :math:`E_i = \gamma_i^i (1 - \gamma_i^{i+1}) \cdot 100`.

    ``target_retained`` is the share of the target (coarse) fraction retained, and
    ``next_retained`` the share of the next finer fraction retained (the impurity).
    """
    return 100.0 * np.asarray(target_retained) * (1.0 - np.asarray(next_retained))


def capacity(bulk_density, gap_height, width, transport_speed):
    r"""Mass capacity :math:`Q = \rho h B V`, in kg/h for SI inputs (kg/m3, m, m, m/s)."""
    return bulk_density * gap_height * width * transport_speed * SECONDS_PER_HOUR


# --- identification from residues -------------------------------------------------------
@dataclass(frozen=True)
class VelocityLaw(ResultContract):
    """Identified normal law of the critical speed of one fraction on one sieve.

    Attributes
    ----------
    v_k, sigma : float
        Mean and standard deviation of the critical relative speed.
    fit : ParameterFit
        The least-squares fit of the observed quantiles.
    two_sided : bool
        Whether the two-sided velocity probability was fitted.
    observed_quantiles : numpy.ndarray
        The observed quantiles :math:`U_s` the law was fitted to.
    linear_v_k, linear_sigma : float
        The same from the straight line through the quantiles (nan when not computed).
    stderr : dict
        Standard errors of ``v_k`` and ``sigma``.
    """

    v_k: float
    sigma: float
    fit: ParameterFit
    two_sided: bool
    observed_quantiles: np.ndarray
    linear_v_k: float = np.nan
    linear_sigma: float = np.nan

    @property
    def stderr(self) -> dict[str, float]:
        return self.fit.stderr

    def summary(self):
        """One row per parameter (``v_k``, ``sigma``): value, stderr, and the straight line's value."""
        table = parameters_frame(self.fit)
        table["linear"] = table["parameter"].map({"v_k": self.linear_v_k, "sigma": self.linear_sigma})
        return table

    def _result_context(self) -> str:
        side = "two-sided" if self.two_sided else "one-sided"
        return f"Velocity law ({side}) from {len(self.observed_quantiles)} speed regimes"


def observed_quantiles(residues, geometric_prob, sieve_length, cell_pitch) -> np.ndarray:
    r"""Observed quantiles :math:`U_s = \Phi^{-1}(1 - P_s/P_g)`, :math:`P_s = -(2a/L)\ln\gamma_s`.

    Raises
    ------
    ValueError
        When a residue is not strictly between 0 and 1, or ``P_s/P_g`` is not.
    """
    residues = np.asarray(residues, dtype=float)
    bad = np.flatnonzero(~((residues > 0) & (residues < 1)))
    if bad.size:
        raise ValueError(f"residue {residues[bad[0]]:g} of regime {bad[0] + 1} must lie strictly between 0 and 1")
    ratio = -(cell_pitch / sieve_length) * np.log(residues) / geometric_prob
    bad = np.flatnonzero(~((ratio > 0) & (ratio < 1)))
    if bad.size:
        raise ValueError(
            f"regime {bad[0] + 1}: sieving probability / P_g = {ratio[bad[0]]:.4g} must lie in (0, 1); "
            "check the residue, the sieve length, the cell pitch and P_g"
        )
    return stats.norm.isf(ratio)


def identify_velocity_law(relative_speeds, residues, *, geometric_prob, sieve_length, cell_pitch, two_sided=False) -> VelocityLaw:
    r"""Identify :math:`(V_k, \sigma)` of one fraction from residues at several speed regimes.

    Minimises :math:`\sum_s (U_s^{obs} - U_s^{calc})^2` with
    :math:`U^{calc} = (V_a - V_k)/\sigma` (one-sided) or
    :math:`\Phi^{-1}(\Phi(z) + \Phi(z_0) - 1)` (two-sided), through the common fitting
    layer.  For the one-sided form the problem is linear in :math:`(1/\sigma, V_k/\sigma)`
    and its closed-form solution is returned as ``linear_v_k``, ``linear_sigma``.

    Parameters
    ----------
    relative_speeds : array
        Amplitude of the particles' speed relative to the sieve per regime (>= 2 regimes;
        the papers use 4 or more).
    residues : array
        Share of the fraction left on the sieve per regime, in (0, 1).
    geometric_prob, sieve_length, cell_pitch : float
        ``P_g``, ``L`` and ``2a``.
    two_sided : bool
        Use the two-sided velocity probability.
    """
    speeds = np.asarray(relative_speeds, dtype=float)
    residues = np.asarray(residues, dtype=float)
    _check_regimes(speeds, residues, "residues")
    if not 0 < geometric_prob <= 1:
        raise ValueError(f"P_g = {geometric_prob:g} must lie in (0, 1]")
    return fit_velocity_quantiles(
        speeds, observed_quantiles(residues, geometric_prob, sieve_length, cell_pitch), two_sided=two_sided
    )


def _check_regimes(speeds, values, what):
    if speeds.shape != values.shape:
        raise ValueError(f"{speeds.size} speeds but {values.size} {what}: give one per speed regime")
    if speeds.size < 2:
        raise ValueError("at least two speed regimes are needed to identify two parameters")


def fit_velocity_quantiles(relative_speeds, u_obs, *, two_sided=False) -> VelocityLaw:
    """Least-squares ``(Vk, sigma)`` from observed quantiles ``U_s`` at the speeds ``Va_s``
    (the common core of :func:`identify_velocity_law` and :func:`identify_from_bin_shares`)."""
    speeds = np.asarray(relative_speeds, dtype=float)
    u_obs = np.asarray(u_obs, dtype=float)
    inverse_sigma, offset = np.polyfit(speeds, u_obs, 1) if np.ptp(speeds) > 0 else (np.nan, np.nan)
    linear_sigma = 1.0 / inverse_sigma
    linear_v_k = -offset * linear_sigma

    def computed(values):
        v_k, sigma = values["v_k"], values["sigma"]
        if two_sided:
            level = stats.norm.cdf((speeds - v_k) / sigma) + stats.norm.cdf(v_k / sigma) - 1.0
            return stats.norm.ppf(np.clip(level, 1e-300, 1 - 1e-16))
        return (speeds - v_k) / sigma

    scale = max(float(np.abs(speeds).max()), 1e-12)
    start_sigma = linear_sigma if np.isfinite(linear_sigma) and linear_sigma > 0 else 0.3 * scale
    start_v_k = linear_v_k if np.isfinite(linear_v_k) else float(np.mean(speeds))
    specs = [
        Parameter("v_k", 1e-9 * scale if two_sided else -10 * scale, 10 * scale),
        Parameter("sigma", 1e-6 * scale, 10 * scale),
    ]
    starts = [{"v_k": start_v_k, "sigma": start_sigma}, {"v_k": float(np.mean(speeds)), "sigma": 0.3 * scale}]
    fit = least_squares(lambda values: computed(values) - u_obs, specs, starts)
    return VelocityLaw(
        fit.values["v_k"],
        fit.values["sigma"],
        fit,
        two_sided,
        u_obs,
        linear_v_k if not two_sided else np.nan,
        linear_sigma if not two_sided else np.nan,
    )


# --- multi-deck random walk (Pascal) ---------------------------------------------------
def cell_probability(decks, cell, p):
    r"""Probability that a particle reaches the ``decks``-th deck at cell ``cell``:
    :math:`P(m, j) = \binom{m+j-2}{j-1} p^m (1-p)^{j-1}` (negative binomial).

    Solves :math:`P(i, j) = p P(i-1, j) + (1-p) P(i, j-1)`, :math:`P(0, 1) = 1`.
    """
    return stats.nbinom.pmf(np.asarray(cell) - 1, decks, p)


def cell_moments(decks, p) -> tuple[float, float]:
    """Mean ``(p + m(1-p))/p`` and variance ``m(1-p)/p^2`` of the cell reached on deck m."""
    return (p + decks * (1 - p)) / p, decks * (1 - p) / p**2


def distance_cdf(x, decks, c):
    r""":math:`F_m(x) = P(m, C x^2/2)`, the regularised lower gamma function: the distance
    travelled on the m-th deck when passages form a Poisson stream of intensity ``C x``."""
    return special.gammainc(decks, c * np.asarray(x, dtype=float) ** 2 / 2.0)


def distance_pdf(x, decks, c):
    r""":math:`f_m(x) = C x (C x^2/2)^{m-1} e^{-C x^2/2} / (m-1)!`."""
    x = np.asarray(x, dtype=float)
    u = c * x**2 / 2.0
    return c * x * np.exp((decks - 1) * np.log(np.maximum(u, 1e-300)) - u - special.gammaln(decks))


def distance_moments(decks, c) -> tuple[float, float]:
    r"""Exact mean :math:`\sqrt{2/C}\,\Gamma(m + 1/2)/\Gamma(m)` and variance :math:`2m/C - M^2`."""
    mean = np.sqrt(2.0 / c) * np.exp(special.gammaln(decks + 0.5) - special.gammaln(decks))
    return float(mean), float(2.0 * decks / c - mean**2)


def distance_moments_printed(decks, c) -> tuple[float, float]:
    """The papers' large-m approximations (11): ``M = sqrt((4m-1)/(2C))``, ``D = 1/(2C)``."""
    return float(np.sqrt((4 * decks - 1) / (2 * c))), float(1 / (2 * c))


@dataclass(frozen=True)
class BinDesign(ResultContract):
    """Position of the collecting bin of the target fraction on the bottom deck.

    Attributes
    ----------
    c : float
        Passage intensity coefficient ``C`` (passages form a Poisson stream of intensity
        ``C x``) that puts the bin's far edge at the sieve's end.
    x1, x2 : float
        Start and end of the bin along the bottom deck, in the unit of the sieve length
        (``x2`` is the sieve length).
    recovery : float
        The recovery the bin achieves, ``F_m(x2) - F_m(x1)``.
    method : str
        ``"exact"`` (regularised gamma) or ``"normal"`` approximation.
    """

    c: float
    x1: float
    x2: float
    recovery: float
    method: str

    def summary(self):
        """One row: ``c, x1, x2, recovery, method``."""
        import pandas as pd

        return pd.DataFrame([{"c": self.c, "x1": self.x1, "x2": self.x2, "recovery": self.recovery, "method": self.method}])

    def _result_context(self) -> str:
        return f"Collecting bin for recovery {self.recovery:g} ({self.method})"


def design_bin(decks, sieve_length, recovery, *, method="exact") -> BinDesign:
    r"""Bin ``[x1, x2]`` with ``F_m(x1) = (1-g)/2``, ``F_m(x2) = (1+g)/2`` and ``x2 = L``.

    ``method="exact"`` inverts the regularised gamma function; ``"normal"`` uses the
    papers' normal approximation ``x = M +- z sqrt(D)`` with the moments (11),
    ``z = Phi^-1((1+g)/2)``.

    Examples
    --------
    >>> b = design_bin(12, 1.6, 0.9)
    >>> round(b.c, 2), round(b.x1, 4)
    (14.22, 0.9867)
    """
    check_count(decks, "decks", maximum=MAX_DECKS)
    if not 0 < recovery < 1:
        raise InputError(f"the required recovery must lie in (0, 1), got {recovery}")
    if method == "exact":
        c = 2.0 * special.gammaincinv(decks, (1 + recovery) / 2) / sieve_length**2
        x1 = np.sqrt(2.0 * special.gammaincinv(decks, (1 - recovery) / 2) / c)
    elif method == "normal":
        z = stats.norm.isf((1 - recovery) / 2)

        def upper_gap(c):
            mean, var = distance_moments_printed(decks, c)
            return mean + z * np.sqrt(var) - sieve_length

        c = optimize.brentq(upper_gap, 1e-9, 1e9)
        mean, var = distance_moments_printed(decks, c)
        x1 = mean - z * np.sqrt(var)
    else:
        raise ValueError(f"unknown method {method!r}; use 'exact' or 'normal'")
    achieved = float(distance_cdf(sieve_length, decks, c) - distance_cdf(x1, decks, c))
    return BinDesign(float(c), float(x1), float(sieve_length), achieved, method)


def bin_recovery(x1, x2, decks, c) -> float:
    r"""Recovery of a fraction in the bin: :math:`g = \int_{x_1}^{x_2} f_m\,dx = F_m(x_2) - F_m(x_1)`."""
    return float(distance_cdf(x2, decks, c) - distance_cdf(x1, decks, c))


def bin_efficiency(recovery, impurity) -> float:
    """Separation efficiency in %: ``E = g (1 - S) 100`` with ``S`` the share of other fractions in the bin."""
    return 100.0 * recovery * (1.0 - impurity)


def identify_c(x1, x2, decks, shares, *, lost_side: str) -> np.ndarray:
    """Process parameter ``C`` per regime from the share of a fraction found in the bin.

    For a fixed bin the share ``F_m(x2) - F_m(x1)`` rises and then falls with ``C``, so
    each share below the peak has two solutions: with the rest of the fraction passing
    before ``x1`` (``lost_side="before"``, the larger ``C``) or travelling beyond ``x2``
    (``lost_side="beyond"``, the smaller ``C``).  Which one applies is a fact of the
    experiment and must be stated.

    Examples
    --------
    >>> b = design_bin(12, 1.6, 0.9)
    >>> c = identify_c(b.x1, b.x2, 12, [0.9], lost_side="beyond")
    >>> round(float(c[0]), 2)
    14.22
    """
    if lost_side not in ("before", "beyond"):
        raise ValueError("lost_side must be 'before' (larger C) or 'beyond' (smaller C)")
    shares = np.asarray(shares, dtype=float)

    def recovery_at(log_c):
        return bin_recovery(x1, x2, decks, np.exp(log_c))

    peak = optimize.minimize_scalar(lambda lc: -recovery_at(lc), bounds=(-20.0, 20.0), method="bounded", options={"xatol": 1e-10})
    best = recovery_at(peak.x)
    bracket = (-20.0, peak.x) if lost_side == "beyond" else (peak.x, 20.0)
    result = []
    for g in shares:
        if not 0 < g < best:
            raise InputError(f"a share of {g:g} in the bin cannot be reached (largest possible {best:.4f})")
        result.append(np.exp(optimize.brentq(lambda lc, share=g: recovery_at(lc) - share, *bracket, xtol=1e-13)))
    return np.asarray(result)


def passage_probability_from_c(c, decks, cell_pitch) -> float:
    """Sieving probability per cell ``p = m 2a / M`` from the exact mean distance ``M``."""
    mean, _ = distance_moments(decks, c)
    return float(decks * cell_pitch / mean)


# --- fractions without residues ---------------------------------------------------------
DEFAULT_DEPENDENCE = "c0 + c1 * l / D"


@dataclass(frozen=True)
class Dependence(ResultContract):
    """A fitted dependence of a velocity-law parameter on hole size ``D`` and particle size ``l``.

    Attributes
    ----------
    form : str
        The expression fitted, in ``D`` and ``l``.
    fit : ParameterFit
        Values and standard errors of its coefficients.
    function : callable
        The expression as a function of ``D``, ``l`` and the coefficients.
    """

    form: str
    fit: ParameterFit
    function: object

    def summary(self):
        """One row per coefficient: ``parameter, value, stderr, ssr, success``."""
        return parameters_frame(self.fit)

    def _result_context(self) -> str:
        return f"Dependence {self.form}"

    def __getstate__(self):
        # the function asteval made of an expression does not pickle: it is made again on load
        # (a function given as a callable is pickled as it is, so it must be importable)
        state = super().__getstate__()
        if self._from_expression():
            state["function"] = None
        return state

    def __setstate__(self, state):
        super().__setstate__(state)
        if self.function is None:
            object.__setattr__(self, "function", expression_function(self.form, ["D", "l"])[0])

    def _from_expression(self) -> bool:
        try:
            expression_function(self.form, ["D", "l"])
        except (InputError, SyntaxError, ValueError):
            return False
        return True

    def predict(self, hole_diameter, length) -> np.ndarray:
        return self.function(D=np.asarray(hole_diameter, dtype=float), l=np.asarray(length, dtype=float), **self.fit.values)


def fit_dependence(hole_diameter, length, values, *, form=DEFAULT_DEPENDENCE) -> Dependence:
    """Fit ``values`` (``Vk`` or ``sigma`` of the fractions with residues) as a function of
    ``D`` and ``l``, to predict fractions without residues.

    The forms (8.1) for woven and (8.2) for punched sieves of the kinetics paper are lost
    in its print, so the form is the user's: an expression in ``D``, ``l`` and parameters
    (default ``"c0 + c1 * l / D"``, linear in the relative size), or a callable
    ``f(D, l, p1, p2, ...)`` whose further arguments are the parameters.

    Examples
    --------
    >>> dep = fit_dependence([2.0, 2.0, 2.0], [1.0, 2.0, 3.0], [0.1, 0.2, 0.3])
    >>> round(float(dep.predict(2.0, 4.0)), 6)
    0.4
    """
    import inspect

    D, l, y = (np.asarray(v, dtype=float) for v in (hole_diameter, length, values))
    if not D.shape == l.shape == y.shape:
        raise ValueError("hole sizes, particle sizes and values must have the same length")
    if isinstance(form, str):
        function, names = expression_function(form, ["D", "l"])
        label = form
    else:
        names = tuple(list(inspect.signature(form).parameters)[2:])
        function = lambda D, l, **p: np.asarray(form(D, l, **p), dtype=float)  # noqa: E731
        label = getattr(form, "__name__", "callable")
    if y.size <= len(names):
        raise ValueError(f"{y.size} fractions cannot determine the {len(names)} parameters of {label!r}")
    specs = [Parameter(name) for name in names]
    fit = least_squares(
        lambda p: function(D=D, l=l, **p) - y, specs, [{name: 0.1 for name in names}, {name: 1.0 for name in names}]
    )
    return Dependence(label, fit, function)


# --- tables -----------------------------------------------------------------------------
def _refuse_outside(table, values, column: str, rule: str, *, upper: float = np.inf, upper_allowed: bool = False) -> None:
    """Raise the :class:`~tromplab.errors.InputError` of the first value of ``column`` not in
    ``(0, upper)`` (``(0, upper]`` when ``upper_allowed``), naming its row."""
    inside = (values > 0) & ((values <= upper) if upper_allowed else (values < upper))
    if not inside.all():
        i = int(np.flatnonzero(~inside)[0])
        raise table.error(f"{column} {values[i]:g} {rule}", index=i, column=column)


IDENTIFY_COLUMNS = ("sieve", "fraction", "relative_speed", "residue", "sieve_length", "cell_pitch")
PG_COLUMNS = ("hole_diameter", "length", "width", "half_cell_width")
#: Largest relative speed of a residue table (m/s): vibrating sieves move at a few m/s at
#: most; a larger value is a mistyped unit, and near 1e308 the fit's bounds overflowed.
MAX_RELATIVE_SPEED = 1e3
#: Largest length of a residue table (any one unit, as for ``tromplab sieve pg``): only
#: ratios of the lengths matter, and within 1e-100..1e100 their squares stay finite.
MAX_LENGTH = 1e100
#: The columns :func:`identify_from_table` returns, in order.
IDENTIFIED_COLUMNS = (
    "sieve",
    "fraction",
    "n_regimes",
    "P_g",
    "v_k",
    "v_k_stderr",
    "v_k_low",
    "v_k_high",
    "sigma",
    "sigma_stderr",
    "sigma_low",
    "sigma_high",
    "linear_v_k",
    "linear_sigma",
    "success",
    "message",
)


def identify_from_table(table, *, two_sided: bool = False, level: float = 0.95):
    """Identify ``(Vk, sigma)`` for every sieve and fraction of a residue table.

    The table has one row per regime x fraction x sieve with the columns
    :data:`IDENTIFY_COLUMNS` and either ``P_g`` or :data:`PG_COLUMNS` (then ``P_g`` is
    computed).  A cell no identification could use is refused as input, naming the file,
    row and column: a residue outside the open interval (0, 1) (the share retained on the
    sieve; 0 and 1 carry no quantile), a sieve length or cell pitch that is not positive,
    a ``P_g`` outside (0, 1].  A group that cannot be identified from valid cells (fewer
    than two regimes, a sieving probability above ``P_g``) gets ``success = False`` and
    the reason; the others go on.

    Raises
    ------
    InputError
        When a column is missing or unknown, or a cell is outside its range.

    Returns
    -------
    DataFrame
        Columns :data:`IDENTIFIED_COLUMNS`: ``sieve, fraction, n_regimes, P_g, v_k, v_k_stderr,
        v_k_low, v_k_high, sigma, sigma_stderr, sigma_low, sigma_high, linear_v_k, linear_sigma,
        success, message``.
    """
    import pandas as pd

    numbers, pg = _checked_residue_table(table)
    keys = list(zip(table.frame["sieve"].astype(str), table.frame["fraction"].astype(str)))
    rows = []
    for key in dict.fromkeys(keys):
        index = np.array([k == key for k in keys])
        row = {"sieve": key[0], "fraction": key[1], "n_regimes": int(index.sum()), "P_g": float(pg[index][0])}
        rows.append(_identified_row(row, {column: values[index] for column, values in numbers.items()}, two_sided, level))
    return pd.DataFrame(rows).reindex(columns=IDENTIFIED_COLUMNS)


def _checked_residue_table(table) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The numeric columns of a residue table and ``P_g`` of each row (given or computed from
    :data:`PG_COLUMNS`), every cell checked (an :class:`~tromplab.errors.InputError` names it)."""
    table.require(*IDENTIFY_COLUMNS)
    table.refuse_unknown((*IDENTIFY_COLUMNS, "P_g", *PG_COLUMNS), what="residue table")
    numbers = {c: table.numeric(c) for c in IDENTIFY_COLUMNS[2:]}
    _refuse_outside(table, numbers["residue"], "residue", "must lie strictly between 0 and 1 (the share retained)", upper=1.0)
    _refuse_outside(
        table, numbers["relative_speed"], "relative_speed", f"must lie in (0, {MAX_RELATIVE_SPEED:g}] m/s", upper=MAX_RELATIVE_SPEED,
        upper_allowed=True,
    )  # fmt: skip
    for column in ("sieve_length", "cell_pitch"):
        _refuse_outside(table, numbers[column], column, f"must lie in (0, {MAX_LENGTH:g}]", upper=MAX_LENGTH, upper_allowed=True)
    if "P_g" in table.frame.columns:
        pg = table.numeric("P_g")
        _refuse_outside(table, pg, "P_g", "must lie in (0, 1]", upper=1.0, upper_allowed=True)
    elif all(c in table.frame.columns for c in PG_COLUMNS):
        sizes = [table.numeric(c) for c in PG_COLUMNS]
        for column, values in zip(PG_COLUMNS, sizes):
            outside = np.flatnonzero(~((values >= 1.0 / MAX_LENGTH) & (values <= MAX_LENGTH)))
            if outside.size:
                i = int(outside[0])
                raise table.error(
                    f"{column} {values[i]:g} must lie in [{1 / MAX_LENGTH:g}, {MAX_LENGTH:g}]", index=i, column=column
                )
        pg = np.array([geometric_probability(*row) for row in zip(*sizes)])
    else:
        raise InputError(f"give a 'P_g' column or the columns {', '.join(PG_COLUMNS)}", source=table.source)
    return numbers, pg


def _identified_row(row: dict, numbers: dict[str, np.ndarray], two_sided: bool, level: float) -> dict:
    """``row`` (one sieve and fraction) with its identified law, or ``success = False`` and the reason;
    ``numbers`` are the columns of its regimes."""
    try:
        for column in ("sieve_length", "cell_pitch"):
            if np.ptp(numbers[column]) > 0:
                raise ValueError(f"{column} differs between the regimes of one sieve")
        law = identify_velocity_law(
            numbers["relative_speed"],
            numbers["residue"],
            geometric_prob=row["P_g"],
            sieve_length=numbers["sieve_length"][0],
            cell_pitch=numbers["cell_pitch"][0],
            two_sided=two_sided,
        )
    except ValueError as error:
        return {**row, "success": False, "message": str(error)}
    intervals = law.fit.confidence_intervals(level)
    for name in ("v_k", "sigma"):
        row.update(
            {
                name: law.fit.values[name],
                f"{name}_stderr": law.fit.stderr[name],
                f"{name}_low": intervals[name][0],
                f"{name}_high": intervals[name][1],
            }
        )
    row.update(
        {"linear_v_k": law.linear_v_k, "linear_sigma": law.linear_sigma, "success": law.fit.success, "message": law.fit.message}
    )
    return row


def identify_from_bin_shares(
    relative_speeds, shares, *, x1, x2, decks, cell_pitch, geometric_prob, lost_side, two_sided=True
) -> VelocityLaw:
    """Velocity law of a fraction from its shares in the bin at several speed regimes.

    Per regime: ``C`` from the share (:func:`identify_c`), then the sieving probability
    per cell ``p = m 2a / M`` (:func:`passage_probability_from_c`), then the observed
    quantile ``U = Phi^-1(1 - p/P_g)``; finally ``(Vk, sigma)`` by least squares
    (two-sided velocity law by default, as in the random-walk paper).
    """
    speeds = np.asarray(relative_speeds, dtype=float)
    shares = np.asarray(shares, dtype=float)
    _check_regimes(speeds, shares, "shares")
    c = identify_c(x1, x2, decks, shares, lost_side=lost_side)
    ratio = np.array([passage_probability_from_c(value, decks, cell_pitch) for value in c]) / geometric_prob
    bad = np.flatnonzero(~((ratio > 0) & (ratio < 1)))
    if bad.size:
        raise ValueError(f"regime {bad[0] + 1}: p / P_g = {ratio[bad[0]]:.4g} must lie in (0, 1)")
    return fit_velocity_quantiles(speeds, stats.norm.isf(ratio), two_sided=two_sided)
