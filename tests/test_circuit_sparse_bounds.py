"""The bounds stage of the sparse path (tromplab.circuit.sparse_solve.bounded_sparse): the
independent balances of a set of held flows found by a walk of the flowsheet's graph, and a
class flow the balances empty held with its class instead of a solve that cannot start."""

import warnings

import numpy as np
import pytest
from scipy import sparse

from tromplab.circuit import sparse_solve
from tromplab.circuit.simulation import lab_survey, large_plant


@pytest.fixture(scope="module")
def plant():
    """The 6-node plant of 20 classes with four minerals on every stream (900 unknowns)."""
    truth = large_plant(2, 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the truth's grade of an empty class is 0/0 (no assay drawn)
        survey = lab_survey(truth, np.random.default_rng(40), flows={"fresh_feed": 0.02})
    problem, _ = sparse_solve.build_sparse_problem(truth.flowsheet, survey)
    return truth.flowsheet, survey, problem


@pytest.mark.parametrize("share_free", [0.2, 0.5, 0.8])
def test_the_walk_keeps_as_many_balances_as_the_rank_and_they_are_independent(plant, share_free):
    """Against the rank of the dense matrix (numpy's SVD), on random sets of free unknowns."""
    _, _, problem = plant
    rng = np.random.default_rng(7)
    free = np.sort(rng.choice(problem.A.shape[1], int(share_free * problem.A.shape[1]), replace=False))
    A = problem.A[:, free].tocsr()
    rows = np.flatnonzero(np.diff(A.indptr) > 0)
    dependent = sparse_solve._dependent_balances(A[rows])
    kept = np.delete(rows, dependent)
    rank = np.linalg.matrix_rank(A[rows].toarray())
    assert dependent.size > 0 or share_free == 0.8  # the sets of few free unknowns leave balances dependent
    assert kept.size == rank == np.linalg.matrix_rank(A[kept].toarray())


def test_constraints_other_than_balances_take_the_pivoted_qr():
    """A row that is not a balance (a flow in three rows, or two entries of one sign) has no walk."""
    three_rows = sparse.csr_matrix(np.array([[1.0, 1.0], [-1.0, 0.0], [1.0, -1.0]]))
    same_sign = sparse.csr_matrix(np.array([[1.0, 0.0], [1.0, 1.0]]))
    assert sparse_solve._dependent_balances(three_rows) is None
    assert sparse_solve._dependent_balances(same_sign) is None


def test_a_class_flow_the_balances_empty_is_held_with_its_class(plant):
    """The fresh feed's and the mill discharge's class 5 held: the sump's balance puts the cyclone
    feed's class 5 at 0 (to rounding), its assays ratios of rounding errors at the start."""
    flowsheet, survey, problem = plant
    n, index = problem.n_classes, flowsheet.stream_index
    start = sparse_solve.sparse_solids_first_start(flowsheet, survey, problem)
    active = np.zeros(start.size, dtype=bool)
    active[[index["fresh_feed"] * n + 5, index["discharge_1"] * n + 5]] = True
    current = sparse_solve._held(problem, active)
    free = np.setdiff1d(np.arange(start.size), current.held)
    v0 = sparse_solve.projected_start(current, start, free)
    assert abs(v0[index["cyclone_feed_1"] * n + 5]) < 1e-12 * np.abs(v0).max()
    emptied = sparse_solve._emptied_by_balances(current, v0)
    assert np.flatnonzero(emptied).tolist() == [index["cyclone_feed_1"] * n + 5]
    held = sparse_solve._held(problem, active | emptied)
    free = np.setdiff1d(np.arange(start.size), held.held)
    v, success, _, _ = sparse_solve.solve_sparse(held, start, free=free)
    assert success and np.all(np.isfinite(v)) and np.all(v[list(held.held)] == 0.0)
