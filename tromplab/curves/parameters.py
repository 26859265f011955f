"""One record for every fitted parameter: name, bounds, unit, meaning and start rule.

The formula registry declares its shape and extra parameters with it, the cut size of
every curve comes from :func:`d_cut_parameter`, and the fitting layer
(:func:`tromplab.curves.fitting.least_squares`) takes the same records as its bounds, so a
parameter is described in one place only.  This module imports numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The cut size is searched between the smallest measured size / 100 and the largest x 100.
D_CUT_RANGE_FACTOR = 100.0


@dataclass(frozen=True)
class Parameter:
    """A fitted parameter and everything a reader or a fit needs to know about it.

    Attributes
    ----------
    name : str
        Name used in results and tables (``"d_cut"``, ``"ks"``, ``"bypass"``).
    lower, upper : float
        Closed bounds of the admissible values (``-inf``/``inf`` when unbounded).
    unit : str
        ``"size"`` for the size unit of the data, ``"1"`` for dimensionless.
    meaning : str
        What the parameter does to the curve, in one phrase.
    start : float or None
        Fixed starting value, when the start is not derived from the data.
    start_rule : str
        How the starting value is chosen.

    Examples
    --------
    >>> bypass = Parameter("bypass", 0.0, 0.95, unit="1", meaning="unclassified share", start=0.05)
    >>> bypass.bounds, bypass.clip(1.2)
    ((0.0, 0.95), 0.95)
    """

    name: str
    lower: float = -np.inf
    upper: float = np.inf
    unit: str = ""
    meaning: str = ""
    start: float | None = None
    start_rule: str = ""

    @property
    def bounds(self) -> tuple[float, float]:
        """``(lower, upper)``."""
        return (self.lower, self.upper)

    def clip(self, value: float) -> float:
        """``value`` moved into the bounds."""
        return float(np.clip(value, self.lower, self.upper))


def d_cut_parameter(sizes) -> Parameter:
    """The cut-size parameter for a curve measured at ``sizes`` (same unit as the sizes).

    Its bounds are ``min(sizes) / 100`` and ``max(sizes) * 100``: wide enough for a cut
    extrapolated beyond the measured sizes, narrow enough to keep the solver finite.

    Examples
    --------
    >>> d_cut_parameter([0.1, 2.0]).bounds
    (0.001, 200.0)
    """
    sizes = np.asarray(sizes, dtype=float)
    return Parameter(
        "d_cut",
        float(sizes.min() / D_CUT_RANGE_FACTOR),
        float(sizes.max() * D_CUT_RANGE_FACTOR),
        unit="size",
        meaning="cut size: the size with partition 1/2 to each product",
        start_rule="where the measured curve crosses 1/2, interpolated in log size",
    )
