r"""The reconciliation of a circuit survey as a numerical problem: unknowns, constraints, solution.

The unknowns are the class flows :math:`m_{s,i}` of every stream (then, when per cent solids
are measured, the water flows; then, when the survey holds per-class assays, the class flows
:math:`c_{k,s,i}` of every component :math:`k`, whose assay is :math:`c_{k,s,i}/m_{s,i}`);
the node balances, the fixed flows and the exact
measurements are linear constraints :math:`A m = b`, so the feasible set is
:math:`m = m_0 + N z` with :math:`N` an orthonormal basis of the null space of :math:`A`.
:func:`solve` minimises the whitened residuals in :math:`z` by Gauss-Newton,
:func:`bounded_solution` adds the bounds :math:`m \ge 0` by an active set, and
:func:`decompose` makes the one rank decision of a reconciliation (redundancy, covariance,
observability and the projections of the tests all read it).  The method is in
``docs/circuit.md`` and :mod:`tromplab.circuit.reconciliation`.

References
----------
Lawson, C. L. & Hanson, R. J. (1974). *Solving Least Squares Problems*. Prentice-Hall.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import NamedTuple

import numpy as np
import pandas as pd

from ..errors import InputError
from ..options import CIRCUIT_BASIS
from . import linear_algebra as linalg  # numpy's LAPACK: a small flowsheet does not import scipy.linalg
from .flowsheet import Flowsheet
from .linear_algebra import sparse  # scipy.sparse, imported when a large flowsheet first uses it
from .measurements import Survey

#: Flow of the first feed when no solids flow is measured: flows are then per 100 of that feed.
BASIS = CIRCUIT_BASIS
#: Singular values of the whitened Jacobian below this x the largest are zero: the one rank
#: decision of a reconciliation (redundancy, covariance, observability, the tests' projection).
RANK_TOL = 1e-9
#: A class or water flow below -this x the largest unknown is negative: it is held at its bound 0.
BOUND_TOL = 1e-12
#: From this many unknowns on, the whitened Jacobian is formed with sparse matrices
#: (:meth:`Problem.whitened_jacobian`); below it (the bundled example has 176) the dense product
#: is as fast and its arithmetic that of the earlier versions.
SPARSE_UNKNOWNS = 500
#: A measurement is testable (redundant) when the balances carry more than this share of its
#: information (its adjustment's variance over its own): below it, the share is rounding of the
#: covariance (an assayed survey's just-determined assays came out at 1e-8 to 2.5e-8, either side
#: of the former 1e-8, from one start to another).
TESTABLE_SHARE = 1e-6


@dataclass(frozen=True)
class Problem:
    """The reconciliation problem in class flows (internal)."""

    n_streams: int
    n_classes: int
    A: np.ndarray  # linear constraints A m = b
    b: np.ndarray
    m0: np.ndarray
    N: np.ndarray  # orthonormal null-space basis of A
    kinds: np.ndarray  # "share" / "flow" per measurement (sd > 0)
    stream: np.ndarray  # stream index per measurement
    klass: np.ndarray  # class index per measurement (-1 for flows)
    y: np.ndarray
    sd: np.ndarray  # of each measurement (of a closed analysis's share: before the closure)
    cov: np.ndarray  # covariance of the measurements (closed analyses: P D P^T blocks)
    W: np.ndarray  # whitening: W cov W^T = I on the range of cov (rows: independent pieces of information)
    effects: np.ndarray  # column j: what a unit error in raw measurement j does to the reported values (P blocks)
    n_water: int = 0  # water flows after the class flows (solids streams, then water streams); 0: water not balanced
    at_bound: tuple[int, ...] = ()  # unknowns held at their bound 0: the last rows of A
    n_components: int = 0  # component class flows after the water flows (component, stream, class)
    component: np.ndarray | None = None  # component index per measurement (-1: not an assay)

    @property
    def component_offset(self) -> int:
        """Index of the first component class flow among the unknowns."""
        return self.n_streams * self.n_classes + self.n_water

    def component_index(self, k, s, i):
        """Index among the unknowns of the flow of component ``k`` in class ``i`` of stream ``s``."""
        return self.component_offset + (k * self.n_streams + s) * self.n_classes + i

    def fixed_at_zero(self, active: np.ndarray) -> Problem:
        """The problem with the unknowns flagged in ``active`` held at 0 (rows appended to the
        balances); a class whose solids flow is held holds every component's flow there too, and
        its assays (of an empty class) leave the measurements."""
        active = active | self.emptied(active)
        held = tuple(int(k) for k in np.flatnonzero(active))
        A = np.vstack([self.A[: self.A.shape[0] - len(self.at_bound)], np.eye(self.m0.size)[list(held)]])
        b = np.concatenate([self.b[: self.b.size - len(self.at_bound)], np.zeros(len(held))])
        if self.m0.size >= SPARSE_UNKNOWNS and not self.at_bound:
            m0, N = _held_affine_form(self.m0, self.N, list(held))
        else:
            m0, N = _affine_form(A, b)
        current = replace(self, A=A, b=b, m0=m0, N=N, at_bound=held)
        empty_class = active[self.stream * self.n_classes + np.maximum(self.klass, 0)]
        return current._measurements(~((self.kinds == "assay") & empty_class)) if self.n_components else current

    def emptied(self, active: np.ndarray) -> np.ndarray:
        """The component flows of the classes whose solids flow ``active`` holds at 0."""
        forced = np.zeros(active.size, dtype=bool)
        if self.n_components:
            forced[self.component_offset :] = np.tile(active[: self.n_streams * self.n_classes], self.n_components)
        return forced

    def _measurements(self, keep: np.ndarray) -> Problem:
        """The problem with the measurements flagged in ``keep`` only (those left out independent of the rest)."""
        if keep.all():
            return self
        W = self.W[:, keep]
        return replace(self, kinds=self.kinds[keep], stream=self.stream[keep], klass=self.klass[keep], y=self.y[keep],
                       sd=self.sd[keep], cov=self.cov[np.ix_(keep, keep)], W=W[np.abs(W).sum(axis=1) > 0],
                       effects=self.effects[np.ix_(keep, keep)], component=self.component[keep])  # fmt: skip

    @property
    def variance(self) -> np.ndarray:
        return np.diag(self.cov)

    def _flows(self, v: np.ndarray) -> np.ndarray:
        return v[: self.n_streams * self.n_classes].reshape(self.n_streams, self.n_classes).sum(axis=1)

    def predict(self, v: np.ndarray) -> np.ndarray:
        """The measured quantities at the unknowns ``v`` (class flows, then water flows)."""
        flows = self._flows(v)
        out = np.empty(self.y.size)
        share, pct, assay = self.kinds == "share", self.kinds == "pct", self.kinds == "assay"
        s, i = self.stream[share], self.klass[share]
        out[share] = v[s * self.n_classes + i] / flows[s]
        s, i = self.stream[assay], self.klass[assay]
        with np.errstate(invalid="ignore", divide="ignore"):  # an empty class: its assay is not defined
            out[assay] = v[self.component_index(self.component[assay], s, i)] / v[s * self.n_classes + i]
        flow = ~share & ~pct & ~assay
        out[flow] = flows[self.stream[flow]]
        s = self.stream[pct]
        out[pct] = 100.0 * flows[s] / (flows[s] + v[self.n_streams * self.n_classes + s])
        return out

    def whitened_residual(self, z: np.ndarray) -> np.ndarray:
        """Whitened residuals (prediction - measurement) at ``m0 + N z``: their squares sum to the chi-square."""
        return self.W @ (self.predict(self.m0 + self.N @ z) - self.y)

    def whitened_jacobian(self, z: np.ndarray) -> np.ndarray:
        """The whitened Jacobian ``W H N`` at ``m0 + N z`` (read-only: the last one is kept, as
        :func:`solve` decomposes it at the point where Gauss-Newton's last step formed it)."""
        key = z.tobytes()
        if self._last_jacobian[0] != key:
            H = self.jacobian(self.m0 + self.N @ z)
            if self.m0.size < SPARSE_UNKNOWNS:
                J = self.W @ H @ self.N
            else:
                # a large flowsheet: W (block diagonal) and H (a few entries a row) as sparse matrices,
                # the dense product W H N of a 30-node plant with assays took 7 s, this 0.2 s
                J = np.asarray((self._sparse_whitening @ sparse.csr_matrix(H)) @ self.N)
            J.flags.writeable = False
            self._last_jacobian[:] = key, J
        return self._last_jacobian[1]

    @cached_property
    def _last_jacobian(self) -> list:
        """``[bytes of z, whitened Jacobian at z]`` of the last :meth:`whitened_jacobian` (per problem)."""
        return [None, None]

    @cached_property
    def _sparse_whitening(self):
        return sparse.csr_matrix(self.W)

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        """d(prediction)/d(v), measurements x unknowns."""
        n = self.n_classes
        flows = self._flows(v)
        H = np.zeros((self.y.size, v.size))
        rows = np.arange(self.y.size)
        block = self.stream[:, None] * n + np.arange(n)[None, :]  # each measurement's stream's class flows
        share, pct, assay = self.kinds == "share", self.kinds == "pct", self.kinds == "assay"
        j, s = rows[share], self.stream[share]
        own = s * n + self.klass[share]
        H[j[:, None], block[share]] = (-v[own] / flows[s] ** 2)[:, None]
        H[j, own] += 1.0 / flows[s]
        j, s = rows[pct], self.stream[pct]
        water = self.n_streams * n + s
        total = flows[s] + v[water]
        H[j[:, None], block[pct]] = (100.0 * v[water] / total**2)[:, None]
        H[j, water] = -100.0 * flows[s] / total**2
        j, s = rows[assay], self.stream[assay]
        own = s * n + self.klass[assay]
        component = self.component_index(self.component[assay], s, self.klass[assay])
        H[j, component] = 1.0 / v[own]
        H[j, own] = -v[component] / v[own] ** 2
        flow = ~share & ~pct & ~assay
        H[rows[flow][:, None], block[flow]] = 1.0
        return H


def solve(problem: Problem, start: np.ndarray, xtol: float | None = None) -> tuple[np.ndarray, bool, str]:
    """The weighted least squares in the free unknowns ``z``, started from ``start`` projected onto the constraints.

    Directions that no measurement sees (water flows the survey leaves undetermined) keep
    their starting values: the solver's rounding would otherwise let them wander without bound.
    """
    z0 = problem.N.T @ (assayed_classes_filled(problem, start) - problem.m0)
    if not (problem.N.shape[1] and problem.y.size):
        return z0, True, "nothing to adjust"
    if not np.all(np.isfinite(problem.whitened_residual(z0))):
        return z0, False, "the measurements' predictions are not finite at the starting point (an empty class or stream)"
    z, success, message = gauss_newton(problem, z0, GAUSS_NEWTON_XTOL if xtol is None else xtol)
    unseen = decompose(problem, z).unseen
    return z - unseen @ (unseen.T @ (z - z0)), success, message


#: Gauss-Newton (:func:`gauss_newton`) stops when its step would move ``z`` by less than this share of it.
GAUSS_NEWTON_XTOL = 1e-13
#: A sum of squares within this share of the last one is the same to rounding: near the minimum
#: the steps keep shrinking (linearly, the residuals not being 0) below what the sum resolves.
GAUSS_NEWTON_ROUNDING = 1e-12
GAUSS_NEWTON_ITERATIONS = 200


def gauss_newton(problem: Problem, z0: np.ndarray, xtol: float = GAUSS_NEWTON_XTOL) -> tuple[np.ndarray, bool, str]:
    """The weighted least squares by Gauss-Newton steps, each the minimum-norm least-squares
    solution of the linearised residuals with the Jacobian's columns scaled to unit norm
    (LAPACK's ``gelsd``; its pivoted-QR sibling ``gelsy`` stopped 1e-5 short on a plant with
    assays, whose weights span many orders), shortened by halves until the sum of squares falls.
    Unscaled, the steps of an assayed survey stalled at 1e-10 of ``z`` (rounding of the
    ill-conditioned solve) for a dozen iterations; scaled, they keep shrinking.

    Every operation is numpy's and LAPACK's on the arrays given, so the same survey gives the
    same bits in every run.  MINPACK's Levenberg-Marquardt (``scipy.optimize.least_squares(
    method="lm")``, used before) does not: its result depends on memory left by earlier
    allocations (measured: the same inputs in one process, the heap filled with other bytes,
    moved the water survey's flows by 2e-10 and, through the bounds' active set, an assayed
    survey's by 1e-4).  The minimum is the same (the problem is a mildly nonlinear one, the
    shares being class flows over stream flows, started near its solution).
    """
    z = z0.copy()
    residual = problem.whitened_residual(z)
    cost, moved = float(residual @ residual), np.inf
    for _ in range(GAUSS_NEWTON_ITERATIONS):
        step = _scaled_step(problem, z, residual)
        size = float(np.linalg.norm(step))
        if size <= xtol * (float(np.linalg.norm(z)) + xtol):
            return z, True, "Gauss-Newton converged"
        shortened = _shortened(problem, z, step, cost, size, moved)
        if shortened is None:  # at the minimum to rounding: no step lowers the sum of squares
            return z, True, "Gauss-Newton converged (no step lowers the sum of squares)"
        z, residual, cost, moved = shortened
    return z, False, f"Gauss-Newton did not converge in {GAUSS_NEWTON_ITERATIONS} steps"


def error_model_point(problem: Problem, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(shares, flows, grades)`` at the unknowns ``v``, where the error model is evaluated:
    shares 0 in an empty stream, flows clipped at 0, grades None without assays."""
    S, n = problem.n_streams, problem.n_classes
    class_flows = v[: S * n].reshape(S, n)
    flows = class_flows.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        shares = np.where(flows[:, None] > 0, class_flows / flows[:, None], 0.0)
    return shares, np.clip(flows, 0.0, None), grades_at(problem, v)


def grades_at(problem: Problem, v: np.ndarray) -> np.ndarray | None:
    """The assays at the unknowns ``v`` (components x streams x classes; 0 in an empty class), None without components."""
    if not problem.n_components:
        return None
    S, n = problem.n_streams, problem.n_classes
    components = v[problem.component_offset :].reshape(problem.n_components, S, n)
    class_flows = v[: S * n].reshape(S, n)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(class_flows > 0, components / class_flows, 0.0)


def gauss_newton_step(problem: Problem, z: np.ndarray) -> np.ndarray:
    """One step of :func:`gauss_newton` from ``z`` (``z`` itself when no step lowers the sum of squares)."""
    residual = problem.whitened_residual(z)
    step = _scaled_step(problem, z, residual)
    shortened = _shortened(problem, z, step, float(residual @ residual), float(np.linalg.norm(step)), np.inf)
    return z if shortened is None else shortened[0]


def _scaled_step(problem: Problem, z: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """The Gauss-Newton step at ``z``: the minimum-norm least-squares solution of the linearised
    residuals, the Jacobian's columns scaled to unit norm."""
    jacobian = problem.whitened_jacobian(z)
    scale = np.linalg.norm(jacobian, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    return np.linalg.lstsq(jacobian / scale, -residual, rcond=None)[0] / scale


def _shortened(problem: Problem, z: np.ndarray, step: np.ndarray, cost: float, size: float, moved: float):
    """``(z, residual, cost, length moved)`` after ``step`` shortened by halves until the sum of
    squares ``cost`` falls (or stays within rounding of it, the step shorter than the last one,
    ``moved``); None when no step lowers it."""
    length = 1.0
    while True:
        trial = z + length * step
        trial_residual = problem.whitened_residual(trial)
        trial_cost = float(trial_residual @ trial_residual)
        if trial_cost <= cost or (trial_cost <= cost * (1.0 + GAUSS_NEWTON_ROUNDING) and length * size < moved):
            return trial, trial_residual, trial_cost, length * size
        length /= 2.0
        if length < 1e-12:
            return None


def assayed_classes_filled(problem: Problem, start: np.ndarray) -> np.ndarray:
    """``start`` with every assayed class flow not held at 0 raised to a millionth of the largest
    class flow at least: the assay of an empty class, 0/0, has no value to start from."""
    if not problem.n_components:
        return start
    S, n = problem.n_streams, problem.n_classes
    assay = problem.kinds == "assay"
    assayed = np.zeros(start.size, dtype=bool)
    assayed[problem.stream[assay] * n + problem.klass[assay]] = True
    assayed[list(problem.at_bound)] = False
    floor = 1e-6 * max(float(np.abs(start[: S * n]).max(initial=0.0)), 1e-300)
    return np.where(assayed & (start < floor), floor, start)


def bounded_solution(problem: Problem, fitted: np.ndarray) -> tuple[tuple[int, ...], np.ndarray]:
    """``(held, v)``: the least squares with every class flow and water flow at least 0, by an
    active-set iteration started from the unbounded solution ``fitted``.

    A flow that comes out negative is held at 0 (it joins the linear constraints) and the survey
    is reconciled again; a flow held at 0 is released when its Lagrange multiplier says the sum
    of squares would fall by raising it (Lawson & Hanson 1974, ch. 23), once at most (a flow
    released and negative again stays held: the iteration cannot cycle).  Without a negative
    flow this is ``fitted``, untouched (``held`` empty); NaN if the iteration does not settle.
    """
    active = fitted < -BOUND_TOL * max(np.abs(fitted).max(initial=0.0), 1e-300)
    if not active.any():
        return (), np.clip(fitted, 0.0, None)  # what is below 0 is rounding
    start = np.clip(fitted, 0.0, None)
    released_before = np.zeros(fitted.size, dtype=bool)
    for _ in range(2 * fitted.size + 1):
        current = problem.fixed_at_zero(active)
        z, _, _ = solve(current, start)
        v = current.m0 + current.N @ z
        negative = (v < -BOUND_TOL * max(np.abs(v).max(), 1e-300)) & ~active
        if negative.any():
            active |= negative
        else:
            released = _wrong_sign_multiplier(current, v, released_before)
            if released is None:
                return current.at_bound, np.clip(v, 0.0, None)
            active[released] = False
            released_before[released] = True  # released once only: the iteration cannot cycle
        start = np.clip(v, 0.0, None)
    return tuple(np.flatnonzero(active)), np.full(fitted.size, np.nan)


def _wrong_sign_multiplier(problem: Problem, v: np.ndarray, released_before: np.ndarray) -> int | None:
    """The unknown held at 0 whose multiplier is most negative (raising it lowers the sum of squares), or
    None; an unknown released before (then negative again) stays held."""
    return most_wrong_held(*held_multipliers(problem, v), released_before)


def most_wrong_held(held: np.ndarray, multipliers: np.ndarray, threshold: float, released_before: np.ndarray) -> int | None:
    """Of :func:`held_multipliers`' ``(held, multipliers, threshold)``, the held unknown whose
    multiplier is most negative below ``threshold``, or None; one ``released_before`` stays held
    (the rule of the active set on both paths)."""
    if held.size == 0:
        return None
    multipliers = np.where(released_before[held], np.inf, multipliers)
    worst = int(np.argmin(multipliers))
    return int(held[worst]) if multipliers[worst] < threshold else None


def held_multipliers(problem: Problem, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(held, multipliers, threshold)`` at the solution ``v`` of ``problem`` (whose bounds are
    its constraints' last rows, :meth:`Problem.fixed_at_zero`): the unknowns held at 0, their
    Lagrange multipliers (inf for a component's flow held with its class, not on its own) and
    the level below which a multiplier says that raising the unknown lowers the sum of squares
    (:data:`WRONG_SIGN` of the gradient's largest entry).  Empty without held unknowns or measurements."""
    held = np.array(problem.at_bound, dtype=int)
    if held.size == 0 or not problem.y.size:
        return held[:0], np.zeros(0), 0.0
    gradient = (problem.W @ problem.jacobian(v)).T @ (problem.W @ (problem.predict(v) - problem.y))
    multipliers = np.linalg.lstsq(problem.A.T, gradient, rcond=None)[0][-held.size :]  # the bounds are A's last rows
    return held_outcome(problem, held, multipliers, gradient)


def held_outcome(problem: Problem, held: np.ndarray, multipliers: np.ndarray, gradient: np.ndarray) -> tuple:
    """``(held, multipliers, threshold)`` of :func:`held_multipliers` from the multipliers of the
    ``held`` unknowns and the gradient (either path's): a component's flow held with its class,
    not on its own, gets inf."""
    active = np.zeros(gradient.size, dtype=bool)
    active[held] = True
    multipliers = np.where(problem.emptied(active)[held], np.inf, multipliers)
    return held, multipliers, -WRONG_SIGN * max(np.abs(gradient).max(), 1e-300)


#: A held unknown's multiplier below minus this share of the gradient's largest entry has the
#: wrong sign (raising the unknown would lower the sum of squares); above it, rounding.
WRONG_SIGN = 1e-8


def held_against_multipliers(problem: Problem, v: np.ndarray, held: tuple[int, ...]) -> int:
    """How many of the unknowns ``held`` at 0 (the bounded solution ``v`` of the unbounded
    ``problem``) have a multiplier of the wrong sign: flows the active set holds for good after
    their release made them negative again, which a lower sum of squares would have free."""
    if not held:
        return 0
    active = np.zeros(v.size, dtype=bool)
    active[list(held)] = True
    _, multipliers, threshold = held_multipliers(problem.fixed_at_zero(active), v)
    return int(np.sum(multipliers < threshold))


def check_positive_flows(flowsheet: Flowsheet, survey: Survey, flows: np.ndarray) -> None:
    if np.any(flows <= 0):
        bad = [flowsheet.stream_names[s] for s in np.flatnonzero(flows <= 0)]
        raise InputError(
            f"the reconciled solids flow of stream(s) {', '.join(bad)} is not positive: the measurements contradict the "
            "flowsheet (check the stream names in both files)",
            source=survey.source,
        )


class Decomposition(NamedTuple):
    """The whitened Jacobian :math:`J` of the measurements in the free unknowns at one point,
    split by the one rank decision of a reconciliation (singular values above :data:`RANK_TOL`
    times the largest)."""

    rank: int
    range_basis: np.ndarray  # orthonormal columns spanning the range of J
    singular: np.ndarray  # its ``rank`` singular values
    seen: np.ndarray  # rows: the directions of z that the measurements see
    unseen: np.ndarray  # columns: the directions of z that no measurement sees

    def covariance(self) -> np.ndarray:
        """:math:`(J^T J)^+` of rank :attr:`rank`: the linearised covariance of ``z``."""
        return (self.seen.T / self.singular**2) @ self.seen


def decompose(problem: Problem, z: np.ndarray) -> Decomposition:
    """The :class:`Decomposition` of the whitened Jacobian at ``m0 + N z``."""
    free = problem.N.shape[1]
    if not problem.y.size or not free:
        return Decomposition(0, np.zeros((problem.W.shape[0], 0)), np.zeros(0), np.zeros((0, free)), np.eye(free))
    J = problem.whitened_jacobian(z)
    # every right singular vector (the unseen directions) but only the left ones of the range: on a
    # large flowsheet the full left basis (residuals squared) is most of the work
    thin = problem.m0.size >= SPARSE_UNKNOWNS and J.shape[0] >= J.shape[1]
    U, singular, Vt = np.linalg.svd(J, full_matrices=not thin)
    rank = int(np.sum(singular > RANK_TOL * singular.max(initial=0.0)))
    return Decomposition(rank, U[:, :rank], singular[:rank], Vt[:rank], Vt[rank:].T)


def linearised(problem: Problem, z: np.ndarray) -> tuple[float, Decomposition, np.ndarray]:
    """``(chi-square, decomposition, covariance of the unknowns)`` at ``z``."""
    decomposition = decompose(problem, z)
    if not problem.y.size:
        return 0.0, decomposition, np.zeros((problem.N.shape[0],) * 2)
    residual = problem.whitened_residual(z)
    return float(residual @ residual), decomposition, problem.N @ decomposition.covariance() @ problem.N.T


class _Constraints:
    """Rows of the linear constraints ``A v = b``, added one at a time."""

    def __init__(self, size: int):
        self.size, self.rows, self.rhs = size, [], []

    def add(self, value: float = 0.0) -> np.ndarray:
        self.rows.append(np.zeros(self.size))
        self.rhs.append(value)
        return self.rows[-1]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array(self.rows) if self.rows else np.zeros((0, self.size))), np.array(self.rhs)


def build_problem(flowsheet: Flowsheet, survey: Survey) -> tuple[Problem, str]:
    """The :class:`Problem` of ``survey`` on ``flowsheet`` and the basis of its flows ("" when a flow is measured)."""
    S = len(flowsheet.streams)
    n = max(survey.n_classes, 1)
    n_water = S + len(flowsheet.water_streams) if len(survey.pct_solids) else 0
    layout = Problem(n_streams=S, n_classes=n, A=None, b=None, m0=None, N=None, kinds=None, stream=None, klass=None, y=None,
                     sd=None, cov=None, W=None, effects=None, n_water=n_water, n_components=len(survey.components))  # fmt: skip
    A, b, basis = linear_constraints(flowsheet, survey, layout)
    m0, N = _affine_form(A, b)
    if np.linalg.norm(A @ m0 - b) > 1e-8 * max(1.0, np.linalg.norm(b)):
        raise InputError(
            "the flows, shares, per cent solids and assays given with a standard deviation of 0 contradict the balances "
            f"of the flowsheet: {survey.exact_measurements()}; give them a standard deviation above 0, or correct them",
            source=survey.source,
        )
    shares = survey.shares[survey.shares["sd"] > 0]
    measured = measurement_arrays(survey, flowsheet.stream_index)
    cov, W, effects = _measurement_covariance(shares["stream"].to_numpy(), closure_point(shares), measured["sd"],
                                              survey.closed_streams)  # fmt: skip
    problem = replace(layout, A=A, b=b, m0=m0, N=N, cov=cov, W=W, effects=effects, **measured)
    return problem, basis


def closure_point(shares: pd.DataFrame) -> np.ndarray:
    """The shares at which each closed analysis is linearised: where the error model was
    evaluated (column ``at``), else the measured values."""
    values = shares["value"].to_numpy(float)
    if "at" in shares.columns:
        at = shares["at"].to_numpy(float)
        values = np.where(np.isfinite(at), at, values)
    return values


class SurveyErrors:
    """The error model of a survey's measurements as arrays: the standard deviations of
    :meth:`Survey.with_errors_at <tromplab.circuit.measurements.Survey.with_errors_at>` at a
    point, by the same arithmetic, without building its tables (the error model's rounds at the
    reconciled values evaluate it a dozen times per reconciliation).

    Rows: the shares, the flows, the per cent solids and the assays, in the order of the
    survey's tables (those of sd 0 included); :attr:`sd` holds the survey's own.
    """

    def __init__(self, survey: Survey, stream_index: dict):
        shares, flows, assays, pct = survey.shares, survey.flows, survey.assays, survey.pct_solids
        self.closed = survey.closed_streams
        self.share_streams = shares["stream"].to_numpy()
        self.share_values = shares["value"].to_numpy(float)
        self.share_rows = (shares["stream"].map(stream_index).to_numpy(int), shares["class_index"].to_numpy(int))
        self.share_model = _modelled_sd(shares)
        self.flow_rows = flows["stream"].map(stream_index).to_numpy(int)
        self.flow_model = _modelled_sd(flows)
        order = {name: k for k, name in enumerate(survey.components)}
        self.assay_rows = (assays["component"].map(order).to_numpy(int), assays["stream"].map(stream_index).to_numpy(int),
                           assays["class_index"].to_numpy(int))  # fmt: skip
        self.assay_model = _modelled_sd(assays)
        self.pct_sd = pct["sd"].to_numpy(float)
        self.sd = np.concatenate([self.share_model[3], self.flow_model[3], self.pct_sd, self.assay_model[3]])
        #: the rows whose sd the error model can move (not the per cent solids')
        self.movable = np.ones(self.sd.size, dtype=bool)
        self.movable[len(shares) + len(flows) : len(shares) + len(flows) + len(pct)] = False

    def at(self, shares: np.ndarray, flows: np.ndarray, grades: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """``(sd of every row, the shares' point of closure)`` with the error model at ``shares``
        (streams x classes), ``flows`` (clipped at 0) and ``grades`` (components x streams x classes, or None)."""
        share_at = np.clip(shares[self.share_rows], 0.0, 1.0)
        modelled, relative, absolute, given = self.share_model
        share_sd = np.where(modelled, np.sqrt((relative * share_at) ** 2 + absolute**2), given)
        modelled, relative, _, given = self.flow_model
        flow_sd = np.where(modelled, relative * flows[self.flow_rows], given)
        modelled, relative, absolute, given = self.assay_model
        assay_sd = given
        if grades is not None and given.size:  # an assay lies in 0..1, as tromplab.circuit.assays.assays_at clips it
            grade_at = np.clip(np.nan_to_num(grades[self.assay_rows], nan=0.0), 0.0, 1.0)
            assay_sd = np.where(modelled, np.sqrt((relative * grade_at) ** 2 + absolute**2), given)
        return np.concatenate([share_sd, flow_sd, self.pct_sd, assay_sd]), share_at


def _modelled_sd(table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(modelled, relative, absolute, given sd)`` of a table's rows (modelled: the error model gives its sd)."""
    relative = table["relative"].to_numpy(float) if "relative" in table else np.full(len(table), np.nan)
    absolute = table["absolute"].to_numpy(float) if "absolute" in table else np.zeros(len(table))
    return ~np.isnan(relative), relative, absolute, table["sd"].to_numpy(float)


def with_errors(problem: Problem, errors: SurveyErrors, sd: np.ndarray, share_at: np.ndarray) -> Problem:
    """``problem`` with the standard deviations ``sd`` of every row (:meth:`SurveyErrors.at`) and
    the closed analyses linearised at ``share_at``: what :func:`build_problem` makes of the
    survey with those sds, the constraints unchanged (the rows of sd 0 must be those of ``problem``)."""
    used = sd > 0
    shares = used[: errors.share_streams.size]
    values = np.where(np.isfinite(share_at), share_at, errors.share_values)[shares]  # as closure_point reads the table
    cov, W, effects = _measurement_covariance(errors.share_streams[shares], values, sd[used], errors.closed)
    return replace(problem, sd=sd[used], cov=cov, W=W, effects=effects)


def linear_constraints(flowsheet: Flowsheet, survey: Survey, layout: Problem) -> tuple[np.ndarray, np.ndarray, str]:
    """``(A, b, basis)``: the node balances and the exact measurements as the rows of ``A v = b``
    (dense) in the unknowns laid out as ``layout`` says, and the basis in words ("" without)."""
    S, n = layout.n_streams, layout.n_classes
    constraints = _Constraints(S * n + layout.n_water + layout.n_components * S * n)
    _node_balances(constraints, flowsheet, layout)
    basis = _exact_measurements(constraints, flowsheet, survey, layout)
    A, b = constraints.arrays()
    return A, b, basis


def measurement_arrays(survey: Survey, index: dict) -> dict:
    """The measurements with an sd (shares, flows, per cent solids, assays, in this order) as
    the arrays of :class:`Problem`: ``kinds, stream, klass, component, y, sd``."""
    parts = {"share": survey.shares, "flow": survey.flows, "pct": survey.pct_solids, "assay": survey.assays}
    parts = {kind: table[table["sd"] > 0] for kind, table in parts.items()}
    order = {name: k for k, name in enumerate(survey.components)}
    klass = {"share": lambda t: t["class_index"], "flow": lambda t: np.full(len(t), -1), "pct": lambda t: np.full(len(t), -2),
             "assay": lambda t: t["class_index"]}  # fmt: skip
    return {
        "kinds": np.array([kind for kind, table in parts.items() for _ in range(len(table))], dtype=object),
        "stream": np.array([index[name] for table in parts.values() for name in table["stream"]], dtype=int),
        "klass": np.concatenate([np.asarray(klass[kind](table), dtype=int) for kind, table in parts.items()]).astype(int),
        "component": np.concatenate(
            [
                np.full(sum(len(t) for k, t in parts.items() if k != "assay"), -1),
                parts["assay"]["component"].map(order).to_numpy(dtype=int),
            ]
        ).astype(int),  # fmt: skip
        "y": np.concatenate([table["value"].to_numpy(float) for table in parts.values()]),
        "sd": np.concatenate([table["sd"].to_numpy(float) for table in parts.values()]),
    }


def _node_balances(constraints: _Constraints, flowsheet: Flowsheet, layout: Problem) -> None:
    """Every class of every separator and junction, the total solids of every mill, the same for
    every component, and (per cent solids measured) the water of every node."""
    S, n = layout.n_streams, layout.n_classes
    M = flowsheet.incidence()
    for offset in [0] + [layout.component_index(k, 0, 0) for k in range(layout.n_components)]:
        for k, node in enumerate(flowsheet.nodes):
            if node.balances_classes:
                for i in range(n):
                    constraint = constraints.add()
                    constraint[offset + np.arange(S) * n + i] = M[k]
            else:
                constraints.add()[offset : offset + S * n] = np.repeat(M[k], n)
    if layout.n_water:  # water balances at every node, the declared water streams its only additions and removals
        water_incidence = np.hstack([M, flowsheet.water_incidence()])
        for k in range(len(flowsheet.nodes)):
            constraints.add()[S * n : S * n + layout.n_water] = water_incidence[k]


def _exact_measurements(constraints: _Constraints, flowsheet: Flowsheet, survey: Survey, layout: Problem) -> str:
    """Flows, shares, per cent solids and assays given with an sd of 0 (and the basis when no
    flow is measured) as linear constraints; returns the basis in words ("" without)."""
    S, n = layout.n_streams, layout.n_classes
    index = flowsheet.stream_index

    def solids_of(stream: str, row: np.ndarray) -> np.ndarray:
        return row[index[stream] * n : (index[stream] + 1) * n]

    for stream, value in _exact(survey.flows, "stream", "value"):
        solids_of(stream, constraints.add(value))[:] = 1.0
    basis = ""
    if survey.flows.empty:
        feed = flowsheet.feeds[0]
        solids_of(feed, constraints.add(BASIS))[:] = 1.0
        basis = f"{BASIS:g} for stream '{feed}' (no solids flow measured)"
    for stream, i, value in _exact(survey.shares, "stream", "class_index", "value"):  # m_si - x sum_j m_sj = 0: linear
        row = solids_of(stream, constraints.add())
        row[:] = -value
        row[i] += 1.0
    for stream, value in _exact(survey.pct_solids, "stream", "value"):  # (100 - p) F - p w = 0: linear too
        row = constraints.add()
        solids_of(stream, row)[:] = 100.0 - value
        row[S * n + index[stream]] = -value
    order = {name: k for k, name in enumerate(survey.components)}
    for stream, i, component, value in _exact(survey.assays, "stream", "class_index", "component", "value"):  # c_ksi - a m_si = 0
        row, s = constraints.add(), index[stream]
        row[layout.component_index(order[component], s, i)] = 1.0
        row[s * n + i] = -value
    return basis


def _exact(table: pd.DataFrame, *columns: str):
    """The ``columns`` of the rows of ``table`` given with an sd of 0, row by row (none: nothing
    built, the usual case)."""
    exact = table["sd"].to_numpy(float) == 0
    if not exact.any():
        return []
    return zip(*(table[column].to_numpy()[exact].tolist() for column in columns))


#: The last affine forms computed, by the bytes of ``(A, b)``: the rounds of the error model
#: rebuild the problem with the same constraints (only the sds move), and the active set of the
#: bounds returns to the same held flows; each pays for one SVD of ``A`` once.
_AFFINE_FORMS: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
_AFFINE_FORMS_KEPT = 16


def _affine_form(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(m0, N)``: a point of ``A m = b`` (least squares) and an orthonormal basis of the null space of ``A``."""
    if not A.shape[0]:
        return np.zeros(A.shape[1]), np.eye(A.shape[1])
    key = A.shape[1].to_bytes(8, "little") + A.tobytes() + b.tobytes()
    if key not in _AFFINE_FORMS:
        if len(_AFFINE_FORMS) >= _AFFINE_FORMS_KEPT:
            _AFFINE_FORMS.pop(next(iter(_AFFINE_FORMS)))
        m0, N = np.linalg.lstsq(A, b, rcond=None)[0], linalg.null_space(A, rcond=1e-10)
        m0.flags.writeable = N.flags.writeable = False  # shared between problems: never changed in place
        _AFFINE_FORMS[key] = m0, N
    return _AFFINE_FORMS[key]


def _held_affine_form(m0: np.ndarray, N: np.ndarray, held: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The affine form of the constraints with the unknowns ``held`` at 0 added, from that of the
    constraints without them: the directions ``N y`` that leave the held unknowns at 0, by a
    pivoted QR of ``N``'s held rows (a few dozen), not an SVD of the whole constraint matrix
    (0.4 s each on the 30-node plant)."""
    if not held or not N.shape[1]:
        return m0, N
    rows = N[held]
    Q, R, _ = linalg.qr(rows.T, pivoting=True, mode="full")
    diagonal = np.abs(np.diag(R))
    rank = int(np.sum(diagonal > 1e-10 * diagonal.max(initial=0.0))) if diagonal.size else 0
    shift = np.linalg.lstsq(rows, m0[held], rcond=None)[0]
    return m0 - N @ shift, N @ Q[:, rank:]


def _measurement_covariance(
    streams: np.ndarray, values: np.ndarray, sd: np.ndarray, closed
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covariance of the measurements, its whitening and the effects of the raw errors.

    The errors are independent, except in a closed (normalised) analysis: an error in one raw
    class moves every reported share of the stream, by :math:`P = I - x 1^T`, so the block is
    :math:`P D P^T`.  The third matrix holds :math:`P` (identity elsewhere).  ``streams`` and
    ``values``: the stream of each share measured (the first measurements) and the share at
    which its analysis's closure is linearised (:func:`closure_point`).
    """
    cov = np.diag(sd**2)
    effects = np.eye(sd.size)
    pieces = []
    done = np.zeros(sd.size, dtype=bool)
    for stream in closed:
        where = np.flatnonzero(streams == stream)
        if where.size == 0:
            continue
        x = values[where] / values[where].sum()  # the point of the closure: it sums to 1, as a closed analysis
        P = np.eye(where.size) - np.outer(x, np.ones(where.size))
        block = P @ np.diag(sd[where] ** 2) @ P.T
        # a stream's shares are consecutive measurements: slices, not numpy.ix_ (10 us a call, every round)
        square = (slice(where[0], where[-1] + 1),) * 2 if where[-1] - where[0] + 1 == where.size else np.ix_(where, where)
        cov[square] = block
        effects[square] = P
        eigenvalues, vectors = np.linalg.eigh(block)
        keep = eigenvalues > 1e-12 * eigenvalues.max()
        rows = np.zeros((int(keep.sum()), sd.size))
        rows[:, where] = (vectors[:, keep] / np.sqrt(eigenvalues[keep])).T
        pieces.append(rows)
        done[where] = True
    single = np.flatnonzero(~done)
    rows = np.zeros((single.size, sd.size))
    rows[np.arange(single.size), single] = 1.0 / sd[single]
    pieces.append(rows)
    return cov, np.vstack(pieces), effects


def starting_point(flowsheet: Flowsheet, survey: Survey, problem: Problem) -> np.ndarray:
    """A feasible starting point: measured (or average) distributions, flows from a bounded
    linear least-squares fit of the balances, projected onto the constraints."""
    S, n = problem.n_streams, problem.n_classes
    index = flowsheet.stream_index
    guess = np.full((S, n), np.nan)
    for record in survey.shares.itertuples():
        guess[index[record.stream], record.class_index] = record.value
    measured = np.isfinite(guess).any(axis=1)
    average = np.nanmean(guess[measured], axis=0) if measured.any() else np.full(n, 1.0 / n)
    average = np.where(np.isfinite(average), average, 1.0 / n)
    for s in range(S):
        row = guess[s]
        if not np.isfinite(row).any():
            guess[s] = average / average.sum()
            continue
        missing = ~np.isfinite(row)
        rest = max(1.0 - np.nansum(row), 0.0)
        row[missing] = rest * average[missing] / max(average[missing].sum(), 1e-12) if missing.any() else 0
        guess[s] = np.clip(row, 1e-6, None) / np.clip(row, 1e-6, None).sum()
    # flows: class balances with the guessed distributions, the fixed and measured flows
    rows, rhs = [], []
    M = flowsheet.incidence()
    for k, node in enumerate(flowsheet.nodes):
        rows.append(M[k] * 10.0)
        rhs.append(0.0)
        if node.balances_classes:
            for i in range(n):
                rows.append(M[k] * guess[:, i])
                rhs.append(0.0)
    scale = BASIS
    for record in survey.flows.itertuples():
        row = np.zeros(S)
        row[index[record.stream]] = 10.0
        rows.append(row)
        rhs.append(10.0 * record.value)
        scale = record.value
    if survey.flows.empty:
        row = np.zeros(S)
        row[index[flowsheet.feeds[0]]] = 10.0
        rows.append(row)
        rhs.append(10.0 * BASIS)
    flows = _bounded_least_squares(np.array(rows), np.array(rhs), 1e-3 * scale)
    m = (flows[:, None] * guess).ravel()
    if problem.n_water:
        m = np.concatenate([m, _start_water(flowsheet, survey, flows)])
    if problem.n_components:
        m = np.concatenate([m, start_components(survey, index, m[: S * n].reshape(S, n))])
    if problem.A.shape[0]:
        m = m - np.linalg.lstsq(problem.A, problem.A @ m - problem.b, rcond=None)[0]
    return m


def solids_first_start(flowsheet: Flowsheet, survey: Survey, problem: Problem) -> np.ndarray:
    """The starting point of a survey with assays: the survey reconciled without its assays
    (its solids and water flows), the component flows of the measured assays at those class
    flows, projected onto the component balances.

    An assay predicts a component flow over a class flow; started from class flows that the
    projection of :func:`starting_point` leaves near 0, its rows would outweigh every other
    measurement by orders of magnitude and blur the rank decision.
    """
    solids_survey = replace(survey, assays=survey.assays.iloc[:0], components=())
    solids_problem, _ = build_problem(flowsheet, solids_survey)
    start = starting_point(flowsheet, solids_survey, solids_problem)
    check_observable(flowsheet, solids_survey, solids_problem, start)
    z, _, _ = solve(solids_problem, start, xtol=1e-6)  # a start: the assayed survey's solve refines it
    solids = solids_problem.m0 + solids_problem.N @ z
    S, n = problem.n_streams, problem.n_classes
    v = np.concatenate([solids, start_components(survey, flowsheet.stream_index, solids[: S * n].reshape(S, n))])
    return v - np.linalg.lstsq(problem.A, problem.A @ v - problem.b, rcond=None)[0]


def start_components(survey: Survey, index: dict, class_flows: np.ndarray) -> np.ndarray:
    """Component class flows: the measured assays times the starting class flows; a class not
    assayed takes the component's mean assay of that class over the streams assayed there (else
    over all classes)."""
    S, n = class_flows.shape
    grades = np.full((len(survey.components), S, n), np.nan)
    order = {name: k for k, name in enumerate(survey.components)}
    for record in survey.assays.itertuples():
        grades[order[record.component], index[record.stream], record.class_index] = record.value
    for k in range(grades.shape[0]):
        overall = np.nanmean(grades[k]) if np.isfinite(grades[k]).any() else 0.0
        given = np.isfinite(grades[k])
        by_class = np.where(
            given.any(axis=0), np.where(given, grades[k], 0.0).sum(axis=0) / np.maximum(given.sum(axis=0), 1), overall
        )
        grades[k] = np.where(np.isfinite(grades[k]), grades[k], by_class[None, :])
    return (grades * class_flows[None, :, :]).ravel()


def _start_water(flowsheet: Flowsheet, survey: Survey, flows: np.ndarray) -> np.ndarray:
    """Water flows from the measured per cent solids at the starting solids flows, completed by
    the water balances (non-negative least squares)."""
    incidence = np.hstack([flowsheet.incidence(), flowsheet.water_incidence()])
    rows, rhs = list(incidence), [0.0] * len(incidence)
    for record in survey.pct_solids.itertuples():
        row = np.zeros(incidence.shape[1])
        row[flowsheet.stream_index[record.stream]] = 1.0
        rows.append(row)
        rhs.append(flows[flowsheet.stream_index[record.stream]] * (100.0 - record.value) / record.value)
    return _bounded_least_squares(np.array(rows), np.array(rhs), 0.0)


def _bounded_least_squares(A: np.ndarray, b: np.ndarray, lower: float) -> np.ndarray:
    """The least-squares solution of ``A x = b`` with every ``x`` at least ``lower``, as
    ``scipy.optimize.lsq_linear(A, b, bounds=(lower, inf))`` gives it, to the bit.

    That function first solves without the bounds (``numpy.linalg.lstsq`` with ``rcond=-1``)
    and returns the solution when it keeps them, as here; only when it does not (a survey's
    water flows, with per cent solids) does it run its trust-region iteration, imported then.
    Another bounded solver (an exact active set, Lawson & Hanson's NNLS) would do as well as a
    start, but not to the bit: the start's components that no measurement sees (undetermined
    water flows, the assayed survey's unassayed directions) are kept by :func:`solve`, and the
    solids pass of an assayed survey stops at 1e-6 (:func:`solids_first_start`), so a start
    that moves by rounding moves the outputs (an own NNLS, tried before, moved the assayed
    surveys' outputs by 1e-6 relative).
    """
    unbounded = np.linalg.lstsq(A, b, rcond=-1)[0]
    if np.all(unbounded >= lower):  # False with a NaN, as scipy's check
        return unbounded
    from scipy.optimize import lsq_linear  # the trust-region iteration: 0.1 s of start-up when needed only

    return lsq_linear(A, b, bounds=(lower, np.inf)).x


def unseen_directions(problem: Problem, v: np.ndarray) -> np.ndarray:
    """Directions of the unknowns (columns) that keep every constraint and move no measurement
    at ``v``: what the survey cannot determine."""
    return problem.N @ decompose(problem, problem.N.T @ (v - problem.m0)).unseen


def check_observable(flowsheet: Flowsheet, survey: Survey, problem: Problem, v: np.ndarray) -> None:
    """Refuse a survey that cannot determine every solids flow and distribution (naming the
    streams); water flows left undetermined are reported by the balance, not refused."""
    S, n = problem.n_streams, problem.n_classes
    directions = unseen_directions(problem, v)[: S * n]
    if directions.shape[1] == 0:
        return
    m = v[: S * n]
    flows = m.reshape(S, n).sum(axis=1)
    blocks = directions.reshape(S, n, -1)
    flow_change = np.abs(blocks.sum(axis=1)).max(axis=1) / np.maximum(np.abs(flows), 1e-12)
    share_change = np.abs(blocks - (m.reshape(S, n) / flows[:, None])[:, :, None] * blocks.sum(axis=1)[:, None, :]).max(
        axis=(1, 2)
    )
    share_change = share_change / np.maximum(np.abs(flows), 1e-12)
    flow_bad = [flowsheet.stream_names[s] for s in np.flatnonzero(flow_change > 1e-6)]
    share_bad = [
        flowsheet.stream_names[s] for s in np.flatnonzero(share_change > 1e-6) if flowsheet.stream_names[s] not in flow_bad
    ]
    if not flow_bad and not share_bad:
        return
    nodes = sorted({n for s in flow_bad + share_bad for n in (flowsheet.stream(s).source, flowsheet.stream(s).target) if n})
    parts = []
    if flow_bad:
        parts.append(f"the solids flow of stream(s) {', '.join(flow_bad)}")
    if share_bad:
        parts.append(f"the size distribution of stream(s) {', '.join(share_bad)}")
    raise InputError(
        f"the survey cannot determine {' and '.join(parts)} (unobservable: degrees of freedom left at node(s) "
        f"{', '.join(nodes)}); measure the size distribution or the solids flow of one of these streams",
        source=survey.source,
    )
