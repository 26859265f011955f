"""Multi-criteria choice of an operating point (the sieve papers' optimisation procedure).

Two criteria to maximise (capacity ``Q`` and efficiency ``E`` in the papers), functions
of bounded decision variables, under inequality constraints.  The procedure of the
papers (spec section 6):

1. single-criterion optima, each with the other criterion constrained (``Q`` max with
   ``E >= 80 %``; ``E`` max with ``Q >= 80 %`` of its maximum);
2. normalisation of each criterion between its value at the other criterion's optimum
   and its own optimum (the pay-off table);
3. the Pareto set by sweeping the linear convolution
   ``W = l1 Qn + (1 - l1) En`` over ``l1``;
4. the compromise by the guaranteed result: maximise ``min(Qn, En)``.

Every optimisation uses :func:`scipy.optimize.differential_evolution` (seeded) with the
constraints as :class:`scipy.optimize.NonlinearConstraint`, polished locally.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import optimize

from ..results_contract import ResultContract
from .sieve import capacity, sieve_efficiency


@dataclass(frozen=True)
class Variable:
    """A bounded decision variable."""

    name: str
    lower: float
    upper: float


@dataclass(frozen=True)
class Criterion:
    """A criterion to maximise: ``function(**variables) -> float``."""

    name: str
    function: Callable[..., float]


@dataclass(frozen=True)
class Constraint:
    """``function(**variables) >= 0`` must hold."""

    name: str
    function: Callable[..., float]


@dataclass(frozen=True)
class Problem:
    """Two criteria over bounded variables with constraints."""

    variables: tuple[Variable, ...]
    criteria: tuple[Criterion, Criterion]
    constraints: tuple[Constraint, ...] = ()
    seed: int = 0

    def values(self, x) -> dict[str, float]:
        return {v.name: float(value) for v, value in zip(self.variables, np.atleast_1d(x))}

    def evaluate(self, x) -> dict[str, float]:
        point = self.values(x)
        return {**point, **{c.name: float(c.function(**point)) for c in self.criteria}}


@dataclass(frozen=True)
class Optimum:
    """A point found by an optimisation, with both criteria evaluated there."""

    point: dict[str, float]
    success: bool
    message: str


def _solve(problem: Problem, objective, extra: Sequence[Constraint] = ()) -> Optimum:
    bounds = [(v.lower, v.upper) for v in problem.variables]
    constraints = [
        optimize.NonlinearConstraint(lambda x, c=c: c.function(**problem.values(x)), 0.0, np.inf)
        for c in (*problem.constraints, *extra)
    ]
    with warnings.catch_warnings():
        # trust-constr's quasi-Newton update warns on flat stretches of a max-min objective
        warnings.filterwarnings("ignore", message="delta_grad == 0.0", category=UserWarning)
        result = optimize.differential_evolution(
            lambda x: -objective(problem.values(x)),
            bounds,
            constraints=constraints,
            seed=problem.seed,
            tol=1e-10,
            polish=True,
            maxiter=2000,
        )
    return Optimum(problem.evaluate(result.x), bool(result.success), str(result.message))


@dataclass(frozen=True)
class ChoiceResult(ResultContract):
    """Single-criterion optima, the pay-off normalisation, the Pareto front and the compromise.

    :meth:`summary` has one row per optimum, :meth:`to_frame` is the Pareto front.

    Attributes
    ----------
    best_first, best_second : Optimum
        The optimum of each criterion alone.
    ranges : dict
        Criterion -> ``(low, high)``: its values at the two single-criterion optima (the pay-off normalisation).
    pareto : pandas.DataFrame
        The Pareto front: one row per point, the variables and both criteria.
    compromise : Optimum
        The point chosen on the front.
    notes : tuple of str
        What the reader must know about the choice.
    """

    best_first: Optimum
    best_second: Optimum
    ranges: dict[str, tuple[float, float]]
    pareto: pd.DataFrame
    compromise: Optimum
    notes: tuple[str, ...] = field(default_factory=tuple)

    def summary(self) -> pd.DataFrame:
        """One row per optimum (``best_first``, ``best_second``, ``compromise``): its point, both criteria, success."""
        optima = {"best_first": self.best_first, "best_second": self.best_second, "compromise": self.compromise}
        rows = [{"optimum": name, **optimum.point, "success": optimum.success} for name, optimum in optima.items()]
        return pd.DataFrame(rows)

    def to_frame(self) -> pd.DataFrame:
        """The Pareto front (:attr:`pareto`)."""
        return self.pareto.copy()

    def _result_context(self) -> str:
        return f"Choice of a classifier: {len(self.pareto)} Pareto points" + (f"; {'; '.join(self.notes)}" if self.notes else "")


def choose(
    problem: Problem, *, floor_second: float | None = None, share_of_first: float | None = None, weights=None
) -> ChoiceResult:
    """Run the whole procedure.

    Parameters
    ----------
    problem : Problem
    floor_second : float, optional
        Lower bound on the second criterion while maximising the first (``E >= 80``).
    share_of_first : float, optional
        While maximising the second criterion, the first must reach this share of its
        maximum (``0.8``).
    weights : array, optional
        Values of ``l1`` for the Pareto sweep (default 0, 0.1, ..., 1).
    """
    weights = np.linspace(0.0, 1.0, 11) if weights is None else np.asarray(weights, dtype=float)
    first, second = problem.criteria
    extra_first = (
        [Constraint(f"{second.name} >= {floor_second}", lambda **v: second.function(**v) - floor_second)]
        if floor_second is not None
        else []
    )
    best_first = _solve(problem, lambda v: first.function(**v), extra_first)
    top = best_first.point[first.name]
    extra_second = (
        [Constraint(f"{first.name} >= {share_of_first} max", lambda **v: first.function(**v) - share_of_first * top)]
        if share_of_first is not None
        else []
    )
    best_second = _solve(problem, lambda v: second.function(**v), extra_second)
    ranges = {
        first.name: (best_second.point[first.name], best_first.point[first.name]),
        second.name: (best_first.point[second.name], best_second.point[second.name]),
    }
    notes = []
    for name, (low, high) in ranges.items():
        if not high > low:
            notes.append(f"{name}: the two optima give the same value ({high:.6g}); the criteria do not conflict")

    def normalised(values):
        out = {}
        for criterion in problem.criteria:
            low, high = ranges[criterion.name]
            span = high - low if high > low else 1.0
            out[criterion.name] = (criterion.function(**values) - low) / span
        return out

    rows = []
    for weight in weights:
        optimum = _solve(problem, lambda v, w=weight: _convolution(normalised(v), first.name, second.name, w))
        rows.append({"l1": float(weight), **optimum.point, "success": optimum.success})
    compromise = _solve(problem, lambda v: min(normalised(v).values()))
    return ChoiceResult(best_first, best_second, ranges, pd.DataFrame(rows), compromise, tuple(notes))


def _convolution(normalised, first, second, weight):
    return weight * normalised[first] + (1.0 - weight) * normalised[second]


# --- worked example: one sieve of the kinetics paper -------------------------------------
def sieve_speed_problem(
    *,
    lambda_target=1.31e-3,
    lambda_next=0.127,
    sieve_length=1.6,
    bulk_density=1150.0,
    gap_height=0.004,
    width=1.0,
    purity_limit=0.08,
    speed_bounds=(0.02, 0.2),
) -> Problem:
    """Capacity and efficiency of a sieve against its mean transport speed ``V``.

    ``gamma = exp(-lambda L / V)`` with the kinetic coefficients printed at the paper's
    compromise (``Va = 0.287 m/s``); ``Q = rho h B V``; ``E = gamma_target (1 - gamma_next)``
    in %; purity: ``gamma_next <= purity_limit``.  The papers' vibratory-transport model
    linking vibration frequency and angle to ``V`` and ``Va`` is not given, so the
    decision variable is ``V`` itself (see ``docs/process_models.md`` and ``docs/errata.md``).
    """

    def retained(coefficient, speed):
        with np.errstate(over="ignore", divide="ignore"):  # the optimiser may probe beyond the speed bounds
            return np.exp(-coefficient * sieve_length / speed)

    return Problem(
        variables=(Variable("V", *speed_bounds),),
        criteria=(
            Criterion("Q", lambda V: capacity(bulk_density, gap_height, width, V)),
            Criterion("E", lambda V: float(sieve_efficiency(retained(lambda_target, V), retained(lambda_next, V)))),
        ),
        constraints=(Constraint("purity", lambda V: purity_limit - retained(lambda_next, V)),),
    )
