"""The record of a separation-curve formula and the helpers every formula module shares.

:class:`Formula` declares one curve with everything the rest of the package needs to know
about it; :class:`MovingBreak` declares the break hooks of a piecewise curve whose break
moves with its shape ((11)).  The curves themselves are in :mod:`.paper`, :mod:`.extended`
and :mod:`.other`; the registry that looks them up is :mod:`tromplab.curves.formulas`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..parameters import Parameter, d_cut_parameter

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
    at_shape : callable or None
        ``at_shape(shape, efficiencies) -> tuple``: the breaks of one shape for several measured
        efficiencies, each the number ``at`` gives, found side by side (a joint fit through
        several surveys, :func:`tromplab.trend.joint_fit`); None: ``at`` one by one.
    """

    at: Callable[[float, float], float]
    on_arrays: Callable[..., np.ndarray]
    phi: Callable[..., np.ndarray]
    kink: Callable[..., np.ndarray] | None = None
    efficiency: Callable[..., tuple] | None = None
    at_shape: Callable[..., tuple] | None = None


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
        return (_registered, (self.id,))

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


def as_array(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def safe_log(x: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return np.log(x)


#: The registry by id, filled by :mod:`tromplab.curves.formulas` once every formula is declared.
FORMULAS_BY_ID: dict[str, Formula] = {}


def _registered(formula_id: str) -> Formula:
    # what a pickled record turns back into: importing this module runs the package first, which fills FORMULAS_BY_ID
    return FORMULAS_BY_ID[formula_id]
