"""Markov-chain model of fines segregation and passage in a layer on a vibrating sieve.

The layer is ``m`` cells deep (cell 1 on top, cell ``m`` on the sieve); ``C_i`` is the
fines concentration of cell ``i``.  Each step the fines move by a tridiagonal,
column-stochastic transition matrix: up with probability ``d`` (not from the top active
cell), down with probability ``d + v0 (1 - C_{i+1})`` (nonlinear: segregation slowed by
the fines already in the cell below) or ``d + v0`` (linear), never down from the bottom
cell, and stay otherwise.  Then a share ``vf`` of the bottom cell's fines passes the
sieve.  Extraction is the passed amount over the initial amount.

Layer thinning: when the top active cell's concentration falls below a threshold, its
content moves down, the cell is locked, and the passage becomes
``vf = vf0 sqrt((m - i)/m)`` with ``i`` locked cells (the paper's eq. (14), its Fig. 3b,
"variable passage"); with ``constant_passage`` it stays ``vf0`` after a lock (Fig. 3a).

The paper states ``m = 4`` cells and an initial fines concentration of 50 % for its
experiment; it does not state the lock threshold.  All three are explicit inputs here
(spec section 7; ``docs/errata.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..curves.fitting import ParameterFit, least_squares
from ..curves.parameters import Parameter
from ..results_contract import ResultContract, parameters_frame


@dataclass(frozen=True)
class LayerModel:
    """Parameters of the layer model.

    Attributes
    ----------
    diffusion : float
        ``d``, probability of moving one cell up (and part of moving down) per step.
    segregation : float
        ``v0``, extra probability of moving down per step.
    passage : float
        ``vf0``, share of the bottom cell's fines passing the sieve per step.
    nonlinear : bool
        Segregation slowed by the fines in the cell below.
    lock_threshold : float or None
        Concentration below which the top active cell empties and locks (None: never).
    constant_passage : bool
        Keep the passage at ``vf0`` after a lock (the paper's Fig. 3a, "constant"); by
        default it falls as ``vf0 sqrt((m - i)/m)`` with ``i`` locked cells (eq. (14),
        Fig. 3b).  Without locking both are the same model.
    """

    diffusion: float
    segregation: float
    passage: float
    nonlinear: bool = True
    lock_threshold: float | None = None
    constant_passage: bool = False

    def __post_init__(self):
        for name in ("diffusion", "segregation", "passage"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1], got {value:g}")
        if 2 * self.diffusion + self.segregation > 1.0:
            raise ValueError(
                f"2 d + v0 = {2 * self.diffusion + self.segregation:g} exceeds 1: the probability of staying would be negative"
            )

    def simulate(self, initial, steps: int) -> LayerSimulation:
        """Run ``steps`` steps from the initial concentrations (scalar or one per cell).

        Examples
        --------
        >>> run = LayerModel(0.005, 0.026, 0.21).simulate([0.5] * 4, 300)
        >>> [round(float(run.extraction[k - 1]), 3) for k in (50, 100, 200, 300)]
        [0.506, 0.708, 0.921, 0.983]
        """
        concentration = np.array(initial, dtype=float, ndmin=1)
        if concentration.size < 2:
            raise ValueError("give one initial concentration per cell (at least 2 cells)")
        if np.any((concentration < 0) | (concentration > 1)):
            raise ValueError("initial concentrations must lie in [0, 1]")
        if steps < 1:
            raise ValueError("steps must be at least 1")
        cells = concentration.size
        total = concentration.sum()
        if total <= 0:
            raise ValueError("the layer holds no fines")
        history = np.empty((steps, cells))
        extraction = np.empty(steps)
        locked_history = np.empty(steps, dtype=int)
        passed, locked = 0.0, 0
        for k in range(steps):
            concentration = self._transition(concentration, locked)
            vf = self.passage if self.constant_passage else self.passage * np.sqrt((cells - locked) / cells)
            flow = concentration[-1] * vf
            concentration[-1] -= flow
            passed += flow
            if self.lock_threshold is not None and locked < cells - 1 and concentration[locked] < self.lock_threshold:
                concentration[locked + 1] += concentration[locked]
                concentration[locked] = 0.0
                locked += 1
            history[k] = concentration
            extraction[k] = passed / total
            locked_history[k] = locked
        return LayerSimulation(history, extraction, locked_history)

    def _transition(self, concentration: np.ndarray, locked: int) -> np.ndarray:
        cells = concentration.size
        up = np.full(cells, self.diffusion)
        up[: locked + 1] = 0.0
        below = np.append(concentration[1:], 0.0)
        down = self.diffusion + self.segregation * ((1.0 - below) if self.nonlinear else np.ones(cells))
        down[-1] = 0.0
        down[:locked] = 0.0
        moved_down, moved_up = down * concentration, up * concentration
        new = concentration - moved_down - moved_up
        new[1:] += moved_down[:-1]
        new[:-1] += moved_up[1:]
        return new


@dataclass(frozen=True)
class LayerSimulation:
    """Concentrations per cell and extraction after each step."""

    concentrations: np.ndarray
    extraction: np.ndarray
    locked: np.ndarray

    def table(self, step_seconds: float | None = None) -> pd.DataFrame:
        """One row per step: ``step`` (and ``time``), ``C_1..C_m``, ``extraction``, ``locked``."""
        frame = pd.DataFrame(self.concentrations, columns=[f"C_{i + 1}" for i in range(self.concentrations.shape[1])])
        frame.insert(0, "step", np.arange(1, len(frame) + 1))
        if step_seconds is not None:
            frame.insert(1, "time", frame["step"] * step_seconds)
        frame["extraction"] = self.extraction
        frame["locked"] = self.locked
        return frame

    def steps_to_reach(self, level: float) -> int | None:
        """First step at which the extraction reaches ``level`` (None if never)."""
        reached = np.flatnonzero(self.extraction >= level)
        return int(reached[0] + 1) if reached.size else None

    @property
    def first_lock(self) -> int | None:
        """Step at which the first cell locked (None if none did)."""
        locked = np.flatnonzero(self.locked > 0)
        return int(locked[0] + 1) if locked.size else None


@dataclass(frozen=True)
class LayerFit(ResultContract):
    """Layer-model parameters identified from measured extraction.

    ``profile`` holds, when the lock threshold was identified, the sum of squares of the
    best three-parameter fit at each threshold tried (columns ``lock_threshold, ssr``).
    The threshold acts through a discrete event, so it has no standard error.
    :meth:`summary` has one row per fitted parameter.

    Attributes
    ----------
    model : LayerModel or None
        The model at the fitted parameters (None when the fit failed).
    fit : ParameterFit
        Values, standard errors and sum of squares of the fitted parameters.
    profile : pandas.DataFrame or None
        Sum of squares per lock threshold tried (None when the threshold was not identified).
    """

    model: LayerModel | None
    fit: ParameterFit
    profile: pd.DataFrame | None = None

    def summary(self) -> pd.DataFrame:
        """One row per fitted parameter: ``parameter, value, stderr, ssr, success``."""
        return parameters_frame(self.fit)

    def _result_context(self) -> str:
        return f"Layer model fitted to measured extraction ({'converged' if self.fit.success else 'failed'})"


def fit_layer_model(
    steps,
    extraction,
    *,
    initial,
    nonlinear: bool = True,
    lock_threshold: float | None = None,
    fit_threshold: bool = False,
    threshold_bounds=(1e-3, 0.2),
) -> LayerFit:
    """Identify ``d``, ``v0`` and ``vf0`` (and optionally the lock threshold) from measured
    extraction at the given step numbers, through the common fitting layer.

    Parameters
    ----------
    steps : array of int
        Step numbers of the measurements (time / step length).
    extraction : array
        Measured extraction (0..1) at those steps.
    initial : array
        Initial concentration per cell (fixes the number of cells).
    nonlinear : bool
        Model variant.
    lock_threshold : float, optional
        Fixed lock threshold (ignored when ``fit_threshold``).
    fit_threshold : bool
        Also identify the threshold: the sum of squares is a step function of it (a cell
        locks one step earlier or later), so it is profiled over a log grid within
        ``threshold_bounds`` (and "never locks"), refined by a bounded scalar search.
    """
    steps = np.asarray(steps, dtype=int)
    extraction = np.asarray(extraction, dtype=float)
    if steps.shape != extraction.shape or steps.size < 4:
        raise ValueError("give at least four (step, extraction) pairs of equal length")
    if np.any(steps < 1):
        raise ValueError("step numbers must be positive")
    if not fit_threshold:
        return _fit_rates(steps, extraction, initial, nonlinear, lock_threshold)
    from scipy import optimize

    tried = {}

    def profiled(threshold):
        key = None if threshold is None else float(threshold)
        if key not in tried:
            # neighbouring thresholds have nearly the same rates: warm-start from the best fit so far
            good = [t.fit for t in tried.values() if t.fit.success]
            warm = [dict(min(good, key=lambda f: f.ssr).values)] if good else None
            tried[key] = _fit_rates(steps, extraction, initial, nonlinear, key, starts=warm)
        fit = tried[key].fit
        return fit.ssr if fit.success else np.inf

    grid = np.geomspace(*threshold_bounds, 25)
    scores = [profiled(value) for value in grid]
    best = int(np.argmin(scores))
    low, high = grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]
    optimize.minimize_scalar(profiled, bounds=(low, high), method="bounded", options={"xatol": 1e-6 * high})
    profiled(None)
    key = min(tried, key=lambda k: tried[k].fit.ssr if tried[k].fit.success else np.inf)
    profile = pd.DataFrame(
        {"lock_threshold": [np.inf if k is None else k for k in tried], "ssr": [tried[k].fit.ssr for k in tried]}
    ).sort_values("lock_threshold")
    chosen = tried[key]
    return LayerFit(chosen.model, chosen.fit, profile.reset_index(drop=True))


def _fit_rates(steps, extraction, initial, nonlinear, lock_threshold, starts=None) -> LayerFit:
    horizon = int(steps.max())
    specs = [Parameter("diffusion", 0.0, 0.3), Parameter("segregation", 0.0, 0.4), Parameter("passage", 1e-6, 1.0)]

    def model_of(values):
        return LayerModel(values["diffusion"], values["segregation"], values["passage"], nonlinear, lock_threshold)

    def residual(values):
        return model_of(values).simulate(initial, horizon).extraction[steps - 1] - extraction

    default = [
        {"diffusion": d, "segregation": v0, "passage": vf}
        for d, v0, vf in [(0.01, 0.05, 0.2), (0.05, 0.1, 0.05), (0.002, 0.02, 0.5), (0.1, 0.2, 0.02)]
    ]
    fit = least_squares(residual, specs, starts + default[:1] if starts else default)
    return LayerFit(model_of(fit.values) if fit.success else None, fit)
