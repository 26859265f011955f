r"""Productivity of a pulp (paper-stock) pressure screen with pulsation cleaning.

The open area of the screen plate clogs as :math:`dk/dt = -\alpha a k`, so
:math:`k = k_0 e^{-\alpha a t}`; a pulsation every :math:`1/N` seconds cleans it.  The
mass rate averaged over a pulse interval is

.. math::
    Q = \frac{F k_0 N c}{\alpha} e^{-\alpha a t_1} \left(1 - e^{-\alpha a / N}\right).

Both the clogging rate :math:`\alpha` and the specific flow :math:`a` grow with the
pressure drop :math:`H`, which for rotor screens includes the rotor's pulsation,
:math:`H = H' + \varphi N^\tau`.  The paper's relations (10)-(12) between
:math:`\alpha`, :math:`a` and :math:`H` are lost in its print; this module uses the
readable guess :math:`\alpha = \beta H^r`, :math:`a = \lambda H^s` (spec section 8,
``docs/errata.md``).  Units follow the inputs (SI in the examples).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING

import numpy as np

from ..curves.parameters import Parameter
from ..errors import OptionError
from ..options import PULP_COEFFICIENT_RANGES as COEFFICIENT_RANGES
from ..results_contract import ResultContract, parameters_frame
from ..validation import check_range

# scipy and lmfit are imported where a screen is optimised or fitted; the ranges and defaults
# are declared in tromplab.options (the command line builds its options from them, without this module)
if TYPE_CHECKING:
    from ..curves.fitting import ParameterFit


@dataclass(frozen=True)
class PulpScreen:
    """Parameters of the productivity model (defaults: the spec's illustrative values).

    Attributes
    ----------
    area : float
        Screen area ``F``, m^2.
    open_area : float
        Initial open-area fraction ``k0``.
    consistency : float
        Pulp consistency ``c``, kg/m^3.
    delay : float
        ``t1``, s: time before the flow through a cleaned plate starts to count.
    beta, r : float
        Clogging rate ``alpha = beta H^r``.
    lam, s : float
        Specific flow ``a = lam H^s``.
    phi, tau : float
        Rotor contribution to the pressure drop ``phi N^tau`` (``phi = 0``: none).
    """

    area: float = 1.0
    open_area: float = 0.2
    consistency: float = 10.0
    delay: float = 0.01
    beta: float = 2.0
    r: float = 2.0
    lam: float = 3.0
    s: float = 0.5
    phi: float = 0.0
    tau: float = 2.0

    def __post_init__(self):
        for item in fields(self):  # an OptionError (a ValueError) naming the coefficient
            low, high, low_open = COEFFICIENT_RANGES[item.name]
            check_range(getattr(self, item.name), item.name, low=low, high=high, low_open=low_open)

    def pressure_drop(self, applied, frequency):
        """Effective pressure drop ``H = H' + phi N^tau``."""
        return np.asarray(applied, dtype=float) + self.phi * np.asarray(frequency, dtype=float) ** self.tau

    def productivity(self, applied, frequency):
        """Mass rate ``Q`` at applied pressure drop ``H'`` and pulsation frequency ``N``.

        Examples
        --------
        >>> round(float(PulpScreen().productivity(1.0, 10.0)), 4)
        4.2491
        """
        frequency = np.asarray(frequency, dtype=float)
        head = self.pressure_drop(applied, frequency)
        alpha = self.beta * head**self.r
        flow = self.lam * head**self.s
        rate = alpha * flow
        # N (1 - e^(-alpha a / N)) / alpha written as a (1 - e^-x) / x with x = alpha a / N: the
        # same number, without 0 / 0 where alpha underflows at a tiny pressure drop (H' = 1e-308)
        x = rate / frequency
        x_safe = np.where(x > 0, x, 1.0)
        passed = np.where(x > 0, -np.expm1(-x_safe) / x_safe, 1.0)
        return self.area * self.open_area * self.consistency * flow * np.exp(-rate * self.delay) * passed

    def best_pressure_drop(self, frequency, *, bounds=(1e-6, 100.0)) -> tuple[float, float]:
        """``(H', Q)`` maximising the productivity at a fixed frequency (bounded search)."""
        from scipy import optimize

        result = optimize.minimize_scalar(
            lambda h: -self.productivity(h, frequency), bounds=bounds, method="bounded", options={"xatol": 1e-10}
        )
        return float(result.x), float(-result.fun)

    def best_frequency(self, applied, *, bounds=(1e-3, 1e4)) -> tuple[float, float, bool]:
        """``(N, Q, interior)`` maximising the productivity at a fixed applied pressure drop.

        ``interior`` is False when the best frequency is the upper bound: the productivity
        still rises there, as it does for every frequency when ``phi = 0``.

        Raises
        ------
        OptionError
            ``applied`` 0 on a screen without rotor pulsation (``phi = 0``): no pressure drop
            drives the flow (as ``tromplab pulp optimum --applied 0`` says).
        """
        from scipy import optimize

        if np.all(np.asarray(applied, dtype=float) == 0) and self.phi == 0:
            raise OptionError("applied", "0 with phi 0 leaves no pressure drop to drive the flow")

        log_low, log_high = np.log(bounds[0]), np.log(bounds[1])
        result = optimize.minimize_scalar(
            lambda u: -self.productivity(applied, np.exp(u)),
            bounds=(log_low, log_high),
            method="bounded",
            options={"xatol": 1e-10},
        )
        frequency = float(np.exp(result.x))
        interior = frequency < bounds[1] * (1 - 1e-6)
        return frequency, float(-result.fun), bool(interior)


@dataclass(frozen=True)
class PulpFit(ResultContract):
    """Model coefficients identified from measured productivity.

    :meth:`summary` has one row per fitted coefficient.

    Attributes
    ----------
    screen : PulpScreen
        The screen model at the fitted coefficients.
    fit : ParameterFit
        Values, standard errors and sum of squares of the fitted coefficients.
    """

    screen: PulpScreen
    fit: ParameterFit

    def summary(self):
        """One row per fitted coefficient: ``parameter, value, stderr, ssr, success``."""
        return parameters_frame(self.fit)

    def _result_context(self) -> str:
        return f"Pulp screen fitted to measured productivity ({'converged' if self.fit.success else 'failed'})"


def fit_pulp_screen(applied, frequency, productivity, *, fitted=("beta", "lam"), fixed: PulpScreen | None = None) -> PulpFit:
    """Fit coefficients of :class:`PulpScreen` to measured ``Q`` at ``(H', N)``.

    ``fitted`` names the coefficients to fit (default ``beta`` and ``lam``; any of
    ``beta, r, lam, s, phi, tau, delay``); the others come from ``fixed``.  Residuals are
    relative, so small and large rates weigh alike.
    """
    from ..curves.fitting import least_squares

    base = fixed or PulpScreen()
    applied, frequency, productivity = (np.asarray(v, dtype=float) for v in (applied, frequency, productivity))
    if not applied.shape == frequency.shape == productivity.shape:
        raise ValueError("pressure drops, frequencies and productivities must have the same length")
    if productivity.size <= len(fitted):
        raise ValueError(f"{productivity.size} measurements cannot determine {len(fitted)} coefficients")
    if np.any(productivity <= 0):
        raise ValueError("measured productivities must be positive")
    allowed = {"beta", "r", "lam", "s", "phi", "tau", "delay"}
    unknown = set(fitted) - allowed
    if unknown:
        raise ValueError(f"cannot fit {', '.join(sorted(unknown))}; choose from {', '.join(sorted(allowed))}")
    upper = {"beta": 1e4, "r": 10.0, "lam": 1e4, "s": 10.0, "phi": 1.0, "tau": 5.0, "delay": 10.0}
    lower = {"phi": 0.0, "delay": 0.0}
    specs = [Parameter(name, lower.get(name, 1e-6), upper[name]) for name in fitted]

    def residual(values):
        return base_with(values).productivity(applied, frequency) / productivity - 1.0

    def base_with(values):
        return replace(base, **values)

    starts = [{name: getattr(base, name) for name in fitted}]
    starts += [{name: max(getattr(base, name), 1e-3) * factor for name in fitted} for factor in (0.3, 3.0)]
    fit = least_squares(residual, specs, starts)
    return PulpFit(base_with(fit.values) if fit.success else base, fit)
