r"""The cut densities that give the most clean coal at a product ash: the equal-incremental-ash principle.

The plant's clean coal :math:`Y = \sum_j F_j Y_j(d_j)` is maximised over the cut densities
:math:`d_j` (within their bounds) subject to its ash,
:math:`\sum_j F_j M_j(d_j) \le A \sum_j F_j Y_j(d_j)` with :math:`M_j = Y_j A_j` the ash mass.
With the multiplier of the constraint written as an ash :math:`\lambda`, the Lagrangian splits
into one problem per size fraction,

.. math:: \max_{d_j}\; Y_j(d_j) - M_j(d_j)/\lambda,

whose interior solution has :math:`\mathrm{d}M_j/\mathrm{d}Y_j = \lambda`: the ash of the
marginal clean coal, the *incremental ash*, is the same in every size fraction (Mayer 1950's
M-curve; the principle behind the optimisation of parallel coal-washing circuits, King 2012;
Osborne 1988).  :func:`optimal_cuts` solves each fraction's problem on a grid of cuts refined
to the cut where its incremental ash rises through :math:`\lambda` (Brent's method), finds
:math:`\lambda` by bisection so that the blended ash meets the target (Everett 1963: each
Lagrangian solution is optimal for the ash it gives), splits the marginal fraction where the
cuts jump across the target (sharp curves), and polishes the cuts with SLSQP on the whole problem.  A cut on its bound keeps its own incremental ash.

Under the curves' uncertainty each device's actual curve is its estimate with the drawn error
(:mod:`tromplab.plant.draws`): the cut density the operator sets, :math:`d_j`, becomes
:math:`d_j + (\rho_{50,k} - \hat\rho_{50})` with the drawn scale :math:`s_k`.  The expected
clean coal and ash mass are then averages over the draws.

References
----------
Mayer, F. W. (1950). The M-curve (Mittelwertkurve) of washability. *Glückauf* 86 (not reached from the
development machine; cited as the coal-preparation literature cites it: the principle used here is derived
above from the Lagrange conditions).

Everett, H. (1963). Generalized Lagrange multiplier method for solving problems of optimum allocation of
resources. *Operations Research* 11(3), 399-417.

King, R. P. (2012). *Modeling and Simulation of Mineral Processing Systems*, 2nd ed. (Schneider & King),
SME, Englewood (gravity separation and coal-washing plants in MODSIM).

Osborne, D. G. (1988). *Coal Preparation Technology*. Graham & Trotman, London.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

from .inputs import Device, SizeFraction

#: Spacing of the grid of cuts each fraction's problem is first solved on (g/cm3).
GRID_STEP = 0.0005
#: Cuts of a grid are evaluated this many at a time (memory of the draws x cuts x density fractions).
CHUNK = 64
#: Design ashes the chance-constrained search tries at most (two ends, then bisection to 1e-4 points).
CHANCE_STEPS = 40
#: Step of the central differences of the incremental ash (g/cm3).
DERIVATIVE_STEP = 1e-5


@dataclass(frozen=True)
class CutResponse:
    """Clean coal and ash mass of one size fraction as functions of its cut (per cent of the size fraction).

    Attributes
    ----------
    fraction : SizeFraction
        The size fraction.
    device : Device
        Its device.
    offsets, scales : numpy.ndarray
        Per draw the error of the cut (``rho50`` drawn minus estimated) and the scale (Ep or I);
        one draw of no error for exact curves.
    low, high : float
        Bounds of the cut (g/cm3).
    """

    fraction: SizeFraction
    device: Device
    offsets: np.ndarray
    scales: np.ndarray
    low: float
    high: float

    def per_draw(self, cuts) -> tuple[np.ndarray, np.ndarray]:
        """Clean mass and ash mass for each cut (rows) and draw (columns)."""
        washability = self.fraction.washability
        cuts = np.atleast_1d(np.asarray(cuts, dtype=float))
        rho50 = np.maximum(cuts[:, None] + self.offsets[None, :], 1.0 + 1e-6)
        sinks = self.device.partition(washability.density, rho50[..., None], self.scales[None, :, None])
        clean = washability.mass_pct * (1.0 - sinks)
        return clean.sum(axis=-1), clean @ washability.ash_pct

    def expected(self, cuts) -> tuple[np.ndarray, np.ndarray]:
        """Clean mass and ash mass for each cut, averaged over the draws (in chunks of cuts)."""
        cuts = np.atleast_1d(np.asarray(cuts, dtype=float))
        parts = [self.per_draw(cuts[start : start + CHUNK]) for start in range(0, cuts.size, CHUNK)]
        return np.concatenate([p[0].mean(axis=1) for p in parts]), np.concatenate([p[1].mean(axis=1) for p in parts])

    def incremental_ash(self, cut: float) -> float:
        r"""The ash of the marginal clean coal at ``cut``, dM/dY (per cent).

        For a plain curve, :math:`\sum_i m_i a_i w_i / \sum_i m_i w_i` with :math:`w_i` the
        derivative of the partition of fraction :math:`i` in the cut,
        :math:`f(t_i)\,|\partial t_i/\partial d|` (``f`` the standard form's density; with Ep
        fixed :math:`|\partial t/\partial d| = k/E_p`, with Ep = I (d - 1) it is
        :math:`k(\rho_i - 1)/(I (d - 1)^2)`), summed over the draws, in logarithms so that a
        sharp curve far from every fraction keeps its ratio.  For a curve with limits, central
        differences (one-sided at a bound).  NaN for an ideal separation (Ep 0).
        """
        return float(self.incremental_ashes(np.array([cut]))[0])

    def incremental_ashes(self, cuts) -> np.ndarray:
        """:meth:`incremental_ash` at each of ``cuts`` (in chunks of cuts)."""
        cuts = np.atleast_1d(np.asarray(cuts, dtype=float))
        device = self.device
        if device.light_limit > 0 or device.heavy_limit < 1:
            return np.array([self._incremental_ash_by_differences(cut) for cut in cuts])
        return np.concatenate([self._analytic_increments(cuts[start : start + CHUNK]) for start in range(0, cuts.size, CHUNK)])

    def _analytic_increments(self, cuts: np.ndarray) -> np.ndarray:
        device, washability = self.device, self.fraction.washability
        rho50 = np.maximum(cuts[:, None] + self.offsets[None, :], 1.0 + 1e-6)[..., None]  # cuts x draws x 1
        scale = self.scales[None, :, None]
        ep = scale * (rho50 - 1.0) if device.scale_name == "imperfection" else np.broadcast_to(scale, rho50.shape)
        ideal = np.any(ep <= 0, axis=(1, 2))
        ep = np.where(ep > 0, ep, 1.0)
        form = device.curve.form
        t = form.centre + form.scale * (washability.density - rho50) / ep
        with np.errstate(divide="ignore"):
            log_weight = form.log_pdf(t) + np.log(washability.mass_pct) - np.log(ep)
            if device.scale_name == "imperfection":
                log_weight = log_weight + np.log(np.maximum(washability.density - 1.0, 1e-300)) - np.log(rho50 - 1.0)
        flat = log_weight.reshape(len(cuts), -1)
        top = np.max(flat, axis=1, keepdims=True)
        usable = np.isfinite(top[:, 0]) & ~ideal
        weight = np.exp(flat - np.where(np.isfinite(top), top, 0.0))
        ash = np.broadcast_to(washability.ash_pct, log_weight.shape).reshape(len(cuts), -1)
        with np.errstate(invalid="ignore"):
            ratio = np.sum(weight * ash, axis=1) / np.sum(weight, axis=1)
        return np.where(usable, ratio, np.nan)

    def _incremental_ash_by_differences(self, cut: float) -> float:
        low, high = max(cut - DERIVATIVE_STEP, self.low), min(cut + DERIVATIVE_STEP, self.high)
        clean, ash = self.expected(np.array([low, high]))
        gained = clean[1] - clean[0]
        return float((ash[1] - ash[0]) / gained) if gained > 1e-12 else np.nan


def _stationary_cut(response: CutResponse, grid, gain, increments, multiplier: float, best: int) -> float:
    """The cut where the incremental ash rises through ``multiplier`` (a local maximum of the gain) with the
    largest gain, refined by Brent's method; the grid's best cut when there is none or it gains less."""
    with np.errstate(invalid="ignore"):
        below = increments - multiplier < 0
        rising = np.flatnonzero(below[:-1] & (increments[1:] - multiplier >= 0))
    if rising.size == 0:
        return float(grid[best])
    step = rising[np.argmax(np.maximum(gain[rising], gain[rising + 1]))]
    if max(gain[step], gain[step + 1]) < gain[best] - 1e-9 * max(abs(gain[best]), 1.0):
        return float(grid[best])
    return float(scipy.optimize.brentq(lambda cut: response.incremental_ash(cut) - multiplier, grid[step], grid[step + 1],
                                       xtol=1e-12))  # fmt: skip


def cut_bounds(fraction: SizeFraction, device: Device) -> tuple[float, float]:
    """The device's ``rho50_min``/``rho50_max``, else the size fraction's closed density range within (1, 3.5]."""
    low = device.rho50_min if np.isfinite(device.rho50_min) else max(fraction.washability.closed_lower[0], 1.0 + 1e-6)
    high = device.rho50_max if np.isfinite(device.rho50_max) else min(fraction.washability.closed_upper[-1], 3.5)
    return float(low), float(high)


@dataclass(frozen=True)
class CutSolution:
    """Cut densities of the size fractions and the multiplier they were found with.

    Attributes
    ----------
    cuts : numpy.ndarray
        The cut density of each size fraction (g/cm3).
    multiplier : float
        The incremental ash :math:`\\lambda` of the Lagrangian (per cent); NaN when the target
        does not bind (every cut at its upper bound).
    binding : bool
        True when the ash constraint binds (the target ash is met with equality).
    """

    cuts: np.ndarray
    multiplier: float
    binding: bool


class Blend:
    """The plant's clean coal and ash for cut vectors, from the size fractions' responses and feed shares."""

    def __init__(self, responses: list[CutResponse], shares: np.ndarray):
        self.responses, self.shares = responses, shares
        self.grids = [
            np.linspace(r.low, r.high, int(np.clip(np.ceil((r.high - r.low) / GRID_STEP), 2, 4000)) + 1) for r in responses
        ]
        self.tables = [r.expected(grid) for r, grid in zip(responses, self.grids)]
        self.increments = [r.incremental_ashes(grid) for r, grid in zip(responses, self.grids)]

    def totals(self, cuts) -> tuple[float, float]:
        """Expected clean yield (per cent of the plant feed) and its ash (per cent) at ``cuts``."""
        clean = ash = 0.0
        for share, response, cut in zip(self.shares, self.responses, cuts):
            y, m = response.expected(np.array([cut]))
            clean, ash = clean + share * y[0], ash + share * m[0]
        return clean, ash / clean if clean > 0 else np.nan

    def ash_per_draw(self, cuts) -> np.ndarray:
        """The plant's clean-coal ash at ``cuts`` for each draw of the curves."""
        clean = ash = 0.0
        for share, response, cut in zip(self.shares, self.responses, cuts):
            y, m = response.per_draw(np.array([cut]))
            clean, ash = clean + share * y[0], ash + share * m[0]
        return np.divide(ash, clean, out=np.full(np.shape(clean), np.nan), where=np.asarray(clean) > 0)

    def lagrangian_cuts(self, multiplier: float, *, refine: bool = True) -> np.ndarray:
        """Each fraction's cut maximising clean mass - ash mass / ``multiplier``: on the grid, then (``refine``)
        the cut where the incremental ash rises through ``multiplier`` (the stationary point, by Brent's method)."""
        cuts = []
        for response, grid, (clean, ash), increments in zip(self.responses, self.grids, self.tables, self.increments):
            gain = clean - ash / multiplier
            best = int(np.argmax(gain))
            cut = grid[best]
            if refine:
                cut = _stationary_cut(response, grid, gain, increments, multiplier, best)
            cuts.append(cut)
        return np.array(cuts)

    def lowest_ash(self) -> float:
        """The lowest clean-coal ash the plant reaches on the equal-incremental-ash path (all cuts low)."""
        candidates = [self.totals([r.low for r in self.responses])[1]]
        candidates += [self.totals(self.lagrangian_cuts(multiplier))[1] for multiplier in np.geomspace(0.01, 100.0, 25)]
        return float(np.nanmin(candidates))


def optimal_cuts(blend: Blend, target_ash_pct: float, *, polish: bool = True, refine: bool = True) -> CutSolution:
    """The cuts of the most clean coal at a clean-coal ash of at most ``target_ash_pct`` (the caller checked it is reachable).

    ``refine``: each fraction's cut refined by Brent's method between the grid's points (else the grid's);
    ``polish``: the cuts polished by SLSQP on the whole problem.
    """
    highest = np.array([r.high for r in blend.responses])
    if blend.totals(highest)[1] <= target_ash_pct:
        return CutSolution(highest, np.nan, False)
    low, high = np.log(1e-3), np.log(1e4)  # ln of the multiplier (an ash, per cent)
    for _ in range(80):
        middle = (low + high) / 2
        if blend.totals(blend.lagrangian_cuts(np.exp(middle), refine=refine))[1] <= target_ash_pct:
            low = middle
        else:
            high = middle
        if high - low < (1e-12 if refine else 1e-6):
            break
    cuts = blend.lagrangian_cuts(np.exp(low), refine=refine)  # the feasible side of the bracket
    if refine:
        cuts = _filled(blend, cuts, blend.lagrangian_cuts(np.exp(high), refine=refine), target_ash_pct)
    if polish:
        cuts = _polished(blend, cuts, target_ash_pct)
    return CutSolution(cuts, float(np.exp(low)), True)


def _filled(blend: Blend, feasible: np.ndarray, beyond: np.ndarray, target: float) -> np.ndarray:
    """Where the Lagrangian cuts jump across the target (a sharp curve takes a density fraction all or nothing
    as the multiplier passes its ash), the one fraction's cut between the two sides that meets the target
    exactly, the others held (Everett's gap closed by splitting the marginal fraction)."""
    best, best_yield = feasible, blend.totals(feasible)[0]
    for j in np.flatnonzero(np.abs(beyond - feasible) > 1e-12):

        def excess(cut, j=j):
            trial = feasible.copy()
            trial[j] = cut
            return blend.totals(trial)[1] - target

        if excess(feasible[j]) <= 0 < excess(beyond[j]):
            inside, outside = feasible[j], beyond[j]  # bisection that keeps the feasible end
            for _ in range(100):
                middle = (inside + outside) / 2
                inside, outside = (middle, outside) if excess(middle) <= 0 else (inside, middle)
                if abs(outside - inside) < 1e-13:
                    break
            trial = feasible.copy()
            trial[j] = inside
            if blend.totals(trial)[0] > best_yield:
                best, best_yield = trial, blend.totals(trial)[0]
    return best


def _polished(blend: Blend, start: np.ndarray, target: float) -> np.ndarray:
    """SLSQP on the whole problem from the Lagrangian cuts; kept when feasible and better."""

    def clean(cuts):
        return -blend.totals(cuts)[0]

    def slack(cuts):
        total, ash = blend.totals(cuts)
        return total * (target - ash) / 100.0  # ash mass below the target's, per cent of the feed

    bounds = [(r.low, r.high) for r in blend.responses]
    try:
        result = scipy.optimize.minimize(clean, start, method="SLSQP", bounds=bounds,
                                         constraints=[{"type": "ineq", "fun": slack}], options={"ftol": 1e-12, "maxiter": 200})  # fmt: skip
    except (ValueError, np.linalg.LinAlgError):
        return start
    cuts = np.clip(result.x, [b[0] for b in bounds], [b[1] for b in bounds])
    # a gain within rounding is no gain: on the flat stretches of a sharp curve it would move the cuts anywhere
    better = blend.totals(cuts)[0] > blend.totals(start)[0] + 1e-9 and blend.totals(cuts)[1] <= target + 1e-10
    return cuts if better else start


def chance_constrained_cuts(
    blend: Blend, target_ash_pct: float, confidence: float, lowest: float, *, progress=None
) -> tuple[CutSolution, float, float]:
    """The cuts of the most expected clean coal whose ash stays at or below ``target_ash_pct`` with probability ``confidence``.

    Searched along the equal-incremental-ash path of the expected products: the largest design ash
    A' <= A whose optimal cuts keep P(ash <= A) >= ``confidence`` over the draws (bisection on A').

    ``progress(done, total, label)`` is called after each design ash tried (at most
    :data:`CHANCE_STEPS`).

    Returns
    -------
    tuple
        ``(solution, design_ash, probability)``; ``solution`` None when not even the lowest
        reachable design ash gives that probability.
    """
    tried = []

    def probability(design: float) -> tuple[CutSolution, float]:
        solution = optimal_cuts(blend, design, polish=False, refine=False)
        tried.append(design)
        if progress is not None:
            progress(len(tried), CHANCE_STEPS, "design ash")
        return solution, float(np.mean(blend.ash_per_draw(solution.cuts) <= target_ash_pct))

    solution, chance = probability(target_ash_pct)
    if chance >= confidence:
        return solution, target_ash_pct, chance
    low_solution, low_chance = probability(lowest + 1e-9)
    if low_chance < confidence:
        return None, lowest, low_chance
    low, high, best = lowest + 1e-9, target_ash_pct, (low_solution, low_chance)
    for _ in range(CHANCE_STEPS - 2):
        middle = (low + high) / 2
        solution, chance = probability(middle)
        if chance >= confidence:
            low, best = middle, (solution, chance)
        else:
            high = middle
        if high - low < 1e-4:
            break
    return best[0], low, best[1]
