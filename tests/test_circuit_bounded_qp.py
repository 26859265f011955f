"""The interior point of one step of a large flowsheet's bounds (tromplab.circuit.bounded_qp):
min 1/2 |J x - g|^2 subject to A x = b, x >= 0, G x >= 0, against scipy's solvers of the same
programme (``lsq_linear`` with the bounds alone; SLSQP with the balances and the grade rows), on
random problems with binding bounds."""

import numpy as np
import pytest
from scipy import optimize, sparse

from tromplab.circuit.bounded_qp import bounded_least_squares


def _problem(seed: int, unknowns: int = 12, rows: int = 20, balances: int = 3):
    rng = np.random.default_rng(seed)
    J = sparse.random(rows, unknowns, density=0.5, random_state=rng, format="csr") + sparse.eye(rows, unknowns)
    g = rng.normal(size=rows) * 3.0  # a target the bounds cut: some unknowns want to be negative
    A = sparse.csr_matrix(rng.choice([-1.0, 0.0, 1.0], size=(balances, unknowns), p=[0.2, 0.6, 0.2]))
    inside = rng.uniform(0.5, 1.5, unknowns)
    return J.tocsr(), g, A, A @ inside, inside


@pytest.mark.parametrize("seed", range(5))
def test_the_bounds_alone_give_scipy_s_bounded_least_squares(seed):
    J, g, _, _, inside = _problem(seed)
    none = sparse.csr_matrix((0, J.shape[1]))
    result = bounded_least_squares(J, g, none, np.zeros(0), none, inside)
    reference = optimize.lsq_linear(J.toarray(), g, bounds=(0.0, np.inf), method="bvls", tol=1e-14)
    assert result.converged and np.any(reference.x == 0.0)  # some bound binds
    np.testing.assert_allclose(result.x, reference.x, atol=1e-7 * max(1.0, np.abs(reference.x).max()))
    np.testing.assert_array_equal(result.at_zero, reference.x <= 1e-9 * np.abs(reference.x).max())


@pytest.mark.parametrize("seed", range(5))
def test_balances_and_grade_rows_give_slsqp_s_optimum(seed):
    """Rows x_0 - x_k >= 0 (a grade at most 1 of the flows k under the flow 0) and three balances."""
    J, g, A, b, inside = _problem(seed)
    unknowns = J.shape[1]
    G = sparse.csr_matrix(np.hstack([np.ones((3, 1)), -np.eye(3, unknowns - 1, 4)]))
    inside[0] = 3.0  # the start inside the grades too
    b = A @ inside
    result = bounded_least_squares(J, g, A, b, G, inside)
    dense_J, dense_A, dense_G = J.toarray(), A.toarray(), G.toarray()
    reference = optimize.minimize(
        lambda x: 0.5 * np.sum((dense_J @ x - g) ** 2), inside, jac=lambda x: dense_J.T @ (dense_J @ x - g),
        method="SLSQP", bounds=[(0.0, None)] * unknowns, options={"ftol": 1e-12, "maxiter": 500},
        constraints=[{"type": "eq", "fun": lambda x: dense_A @ x - b, "jac": lambda x: dense_A},
                     {"type": "ineq", "fun": lambda x: dense_G @ x, "jac": lambda x: dense_G}],
    )  # fmt: skip
    assert result.converged and reference.success
    objective = 0.5 * np.sum((dense_J @ result.x - g) ** 2)
    assert objective == pytest.approx(reference.fun, rel=1e-8)
    np.testing.assert_allclose(result.x, reference.x, atol=1e-5 * np.abs(reference.x).max())
    assert np.abs(dense_A @ result.x - b).max() < 1e-9 and result.x.min() >= 0.0 and (dense_G @ result.x).min() >= -1e-12
    assert np.all(result.z >= 0.0) and np.all(result.w >= 0.0)


@pytest.mark.parametrize("seed", range(3))
def test_a_warm_start_from_a_nearby_programme_s_multipliers_reaches_the_same_optimum(seed):
    """The next step's programme (the target moved by 1 %) from the last one's multipliers, with
    one multiplier unknown (NaN: an unknown the last step held), as the bounds' steps begin."""
    J, g, A, b, inside = _problem(seed)
    G = sparse.csr_matrix(np.hstack([np.ones((3, 1)), -np.eye(3, J.shape[1] - 1, 4)]))
    inside[0] = 3.0
    b = A @ inside
    last = bounded_least_squares(J, g, A, b, G, inside)
    moved = g * (1.0 + 0.01 * np.random.default_rng(seed).normal(size=g.size))
    cold = bounded_least_squares(J, moved, A, b, G, last.x)
    z = last.z.copy()
    z[1] = np.nan
    warm = bounded_least_squares(J, moved, A, b, G, last.x, (z, last.w))
    assert cold.converged and warm.converged
    np.testing.assert_allclose(warm.x, cold.x, atol=1e-7 * np.abs(cold.x).max())
    np.testing.assert_array_equal(warm.at_zero, cold.at_zero)
