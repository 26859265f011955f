r"""The linear least squares under the bounds of a large flowsheet, by a primal-dual interior point.

One step of the bounded reconciliation (:func:`tromplab.circuit.sparse_solve.bounded_sparse`)
solves the convex quadratic programme

.. math::
   \min_x \tfrac12 \lVert J x - g \rVert^2 \quad\text{subject to}\quad
   A x = b, \quad x \ge 0, \quad G x \ge 0

(:math:`J` the whitened Jacobian, :math:`A` the balances, :math:`G` the rows "a class's solids
flow less one component's flow", a grade at most 1).  Mehrotra's predictor-corrector (Nocedal &
Wright 2006, ch. 16.6; Wright 1997, ch. 10) takes about twenty Newton steps whatever the number
of bounds that bind, where an active set frees or holds one flow per solve.  Each step solves
the reduced KKT system

.. math::
   \begin{pmatrix} J^T J + X^{-1} Z + G^T S^{-1} W G + \rho I & A^T \\ A & -\delta I \end{pmatrix}

by one sparse LU in a reverse Cuthill-McKee order (a third of the fill of SuperLU's own orders
on the 30-node plant), refined against the unreduced residuals.  The small proximal term
:math:`\rho` keeps the directions no measurement sees (where :math:`J` is 0) regular and the
:math:`-\delta I` block makes the system quasi-definite.

References
----------
Mehrotra, S. (1992). On the implementation of a primal-dual interior point method. *SIAM J.
Optim.* 2, 575-601.

Nocedal, J. & Wright, S. J. (2006). *Numerical Optimization*, 2nd ed. Springer.

Wright, S. J. (1997). *Primal-Dual Interior-Point Methods*. SIAM.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The interior point stops when the duality gap is below this share of the sum of squares and
#: the residuals of the constraints and of the stationarity below those shares of the problem's
#: scale (the stationarity's floor is the rounding of the multipliers of the balances: 1e-10 to
#: 1e-7 of it on the 30-node plant, where the gap went on falling by tenfold a step).
GAP_TOLERANCE = 1e-12
RESIDUAL_TOLERANCE = 1e-10
STATIONARITY_TOLERANCE = 1e-8
#: At most this many Newton steps (Mehrotra's method takes 15-30 on the plants of the tests).
ITERATIONS = 80
#: The proximal weight on the scaled unknowns and the regularisation of the constraints' block.
PROXIMAL = 1e-9
CONSTRAINT_REGULARISATION = 1e-9
#: The share of the way to the boundary a step goes.
STEP_TO_BOUNDARY = 0.995
#: A warm start keeps each unknown, slack and multiplier at least this share of its typical
#: positive size (0.1: 14 Newton steps instead of 21 on the plant's second programme; 0.01 and
#: 0.001 took 16-18).
WARM_FLOOR = 0.1


@dataclass(frozen=True)
class BoundedStep:
    """The solution ``x`` of the quadratic programme, the multipliers of its bounds ``z`` (of
    ``x >= 0``) and ``w`` (of ``G x >= 0``), both at least 0, whether the bounds bind (``at_zero``:
    ``x`` small against its multiplier, ``grade_at_one``: likewise ``G x``), the Newton steps
    taken and whether the gap closed (``converged``)."""

    x: np.ndarray
    z: np.ndarray
    w: np.ndarray
    at_zero: np.ndarray
    grade_at_one: np.ndarray
    iterations: int
    converged: bool


def bounded_least_squares(J, g: np.ndarray, A, b: np.ndarray, G, start: np.ndarray, multipliers=None) -> BoundedStep:
    """The quadratic programme above (``J``, ``A``, ``G`` sparse, ``start`` a point near which to
    begin: the last iterate of the reconciliation, moved inside the bounds).  ``multipliers``:
    ``(z, w)`` of a programme like it (the last step's), to begin from (a warm start: about a
    third fewer Newton steps on the 30-node plant); else the interior point begins at 1."""
    from scipy import sparse

    norms = np.sqrt(np.asarray(J.multiply(J).sum(axis=0)).ravel())
    scale = np.where(norms > 0, norms, 1.0)  # the columns of J at unit norm (the Gauss-Newton scaling)
    unscale = sparse.diags(1.0 / scale)
    programme = _Programme((J @ unscale).tocsr(), g, (A @ unscale).tocsr(), b, (G @ unscale).tocsr(), start * scale)
    point = _Iterate(programme, None if multipliers is None else (multipliers[0] / scale, multipliers[1]))
    converged, iteration = False, 0
    for iteration in range(ITERATIONS):  # noqa: B007 (the count is reported)
        if point.optimal():
            converged = True
            break
        point.mehrotra_step()
    return BoundedStep(x=point.x / scale, z=point.z * scale, w=point.w, at_zero=point.x < point.z,
                       grade_at_one=point.s < point.w, iterations=iteration, converged=converged)  # fmt: skip


@dataclass(frozen=True)
class _Programme:
    """The scaled programme: min 1/2 |J x - g|^2 + rho/2 |x - x0|^2, A x = b, x >= 0, G x >= 0."""

    J: object
    g: np.ndarray
    A: object
    b: np.ndarray
    G: object
    x0: np.ndarray


class _Iterate:
    """A primal-dual point of the interior point: ``x``, the grades' slacks ``s = G x``, the
    multipliers ``lam`` (balances), ``z`` (bounds) and ``w`` (grades), with the residuals of the
    optimality conditions at it."""

    def __init__(self, programme: _Programme, multipliers=None):
        self.p = programme
        if multipliers is None:
            known = programme.x0[programme.x0 != 0]
            typical = max(1.0, float(np.median(np.abs(known)))) if known.size else 1.0
            self.x = np.maximum(programme.x0, 1e-2 * typical)
            self.s = np.maximum(programme.G @ self.x, 1e-2 * typical)
            self.z, self.w = np.ones(self.x.size), np.ones(self.s.size)
        else:  # near the last programme's solution: every pair kept a tenth of its typical size off 0
            self.x = _off_zero(programme.x0)
            self.s = _off_zero(programme.G @ self.x)
            self.z, self.w = _off_zero(multipliers[0]), _off_zero(multipliers[1])
        self.lam = np.zeros(programme.A.shape[0])
        self.bounds = self.x.size + self.s.size
        self.scale = 1.0 + float(np.linalg.norm(programme.J.T @ programme.g)) + float(np.linalg.norm(programme.b))
        self.system = _ReducedSystem(programme.J, programme.A, programme.G)
        self._residuals()

    def _residuals(self) -> None:
        p = self.p
        self.residual = p.J @ self.x - p.g
        gradient = p.J.T @ self.residual + PROXIMAL * (self.x - p.x0)
        self.dual = gradient - p.A.T @ self.lam - self.z - p.G.T @ self.w
        self.primal, self.grade = p.A @ self.x - p.b, p.G @ self.x - self.s
        self.gap = (self.x @ self.z + self.s @ self.w) / self.bounds

    def optimal(self) -> bool:
        return bool(
            self.gap * self.bounds <= GAP_TOLERANCE * (1.0 + float(self.residual @ self.residual))
            and max(np.linalg.norm(self.primal), np.linalg.norm(self.grade)) <= RESIDUAL_TOLERANCE * self.scale
            and np.linalg.norm(self.dual) <= STATIONARITY_TOLERANCE * self.scale
        )

    def _direction(self, complement_x: np.ndarray, complement_s: np.ndarray) -> tuple:
        """The Newton step ``(dx, dlam, dz, ds, dw)`` of the optimality conditions with the
        complementarity residuals ``complement_x`` (of x z) and ``complement_s`` (of s w)."""
        G = self.p.G
        rhs = -self.dual - complement_x / self.x - G.T @ ((complement_s + self.w * self.grade) / self.s)
        dx, dlam = self.system.solve(rhs, -self.primal)
        dz = (-complement_x - self.z * dx) / self.x
        ds = G @ dx + self.grade
        dw = (-complement_s - self.w * ds) / self.s
        return dx, dlam, dz, ds, dw

    def mehrotra_step(self) -> None:
        """One predictor-corrector step (Nocedal & Wright 2006, algorithm 16.4)."""
        self.system.factor(self.z / self.x, self.w / self.s)
        dx, _, dz, ds, dw = self._direction(self.x * self.z, self.s * self.w)
        primal = min(_to_boundary(self.x, dx), _to_boundary(self.s, ds))
        dual = min(_to_boundary(self.z, dz), _to_boundary(self.w, dw))
        affine_gap = ((self.x + primal * dx) @ (self.z + dual * dz) + (self.s + primal * ds) @ (self.w + dual * dw)) / self.bounds
        target = min(1.0, (affine_gap / self.gap) ** 3) * self.gap
        dx, dlam, dz, ds, dw = self._direction(self.x * self.z + dx * dz - target, self.s * self.w + ds * dw - target)
        primal = STEP_TO_BOUNDARY * min(_to_boundary(self.x, dx), _to_boundary(self.s, ds), 1.0 / STEP_TO_BOUNDARY)
        dual = STEP_TO_BOUNDARY * min(_to_boundary(self.z, dz), _to_boundary(self.w, dw), 1.0 / STEP_TO_BOUNDARY)
        self.x, self.s = self.x + primal * dx, self.s + primal * ds
        self.lam, self.z, self.w = self.lam + dual * dlam, self.z + dual * dz, self.w + dual * dw
        self._residuals()


def _off_zero(u: np.ndarray) -> np.ndarray:
    """``u`` (at least 0, NaN where unknown) with every entry at least :data:`WARM_FLOOR` of its
    typical positive entry (the unknown ones at it)."""
    positive = u[u > 0]
    floor = WARM_FLOOR * (float(np.median(positive)) if positive.size else 1.0)
    return np.maximum(np.nan_to_num(u, nan=floor), floor)


def _to_boundary(u: np.ndarray, du: np.ndarray) -> float:
    """The longest step ``a`` (at most 1) with ``u + a du >= 0``."""
    falling = du < 0
    return min(1.0, float(np.min(-u[falling] / du[falling]))) if falling.any() else 1.0


class _ReducedSystem:
    """The reduced KKT system of the interior point, its pattern ordered once (reverse
    Cuthill-McKee of the pattern at the first step), factored at each step."""

    def __init__(self, J, A, G):
        from scipy import sparse

        self.A, self.G = A, G
        self.normal = (J.T @ J).tocsr()
        self.n, self.m = J.shape[1], A.shape[0]
        self.order = None
        self.regularised = -CONSTRAINT_REGULARISATION * sparse.identity(self.m, format="csr")

    def factor(self, bound_weights: np.ndarray, grade_weights: np.ndarray) -> None:
        from scipy import sparse
        from scipy.sparse import csgraph
        from scipy.sparse import linalg as sparse_linalg

        block = self.normal + sparse.diags(bound_weights + PROXIMAL) + self.G.T @ sparse.diags(grade_weights) @ self.G
        self.matrix = sparse.bmat([[block, self.A.T], [self.A, self.regularised]], format="csc")
        if self.order is None:
            self.order = csgraph.reverse_cuthill_mckee(self.matrix, symmetric_mode=True)
            self.inverse = np.argsort(self.order)
        permuted = self.matrix[self.order][:, self.order].tocsc()
        self.lu = sparse_linalg.splu(permuted, permc_spec="NATURAL", diag_pivot_thresh=0.01,
                                     options={"SymmetricMode": True})  # fmt: skip

    def solve(self, top: np.ndarray, bottom: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(dx, dlam)`` of the system (``dlam`` the balances' multipliers' step), refined twice
        against the unregularised system (the ``-delta I`` block is a device of the factor)."""
        rhs = np.concatenate([top, bottom])
        solution = self._solve(rhs)
        for _ in range(2):
            residual = rhs - self.matrix @ solution
            residual[self.n :] -= CONSTRAINT_REGULARISATION * solution[self.n :]  # the -delta I block taken out
            solution = solution + self._solve(residual)
        return solution[: self.n], -solution[self.n :]

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        return self.lu.solve(rhs[self.order])[self.inverse]
