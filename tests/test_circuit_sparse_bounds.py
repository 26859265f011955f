"""The bounds stage of the sparse path (tromplab.circuit.sparse_solve.bounded_sparse): the
independent balances of a set of held flows found by a walk of the flowsheet's graph (or a
regularised sparse LU where a row is not a balance), a class flow the balances empty held with
its class instead of a solve that cannot start, and the bounded end itself: inside the bounds and
the grades, the balances kept, no lower sum of squares within reach of a quadratic programme at
it, and lower than the dense path's active set's."""

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


def test_a_regularised_lu_finds_the_rows_a_pivoted_qr_drops():
    """A block of balances with a mill's total row and rows made dependent (sums of others): the
    rows it drops leave an independent set of the block's rank (numpy's SVD), each dropped row in
    their span; a block without dependence drops nothing."""
    rng = np.random.default_rng(3)
    flows, nodes = 40, 15
    incidence = np.zeros((nodes, flows))
    for k in range(flows):
        a, b = rng.choice(nodes, 2, replace=False)
        incidence[a, k], incidence[b, k] = 1.0, -1.0
    total = incidence[:5].sum(axis=0)  # a row that is not a balance of the graph: a sum of five
    block = sparse.csr_matrix(np.vstack([incidence, total, incidence[7] + incidence[9]]))
    dropped = sparse_solve._dependent_rows_of_block(block)
    kept = np.delete(np.arange(block.shape[0]), dropped)
    dense = block.toarray()
    rank = np.linalg.matrix_rank(dense)
    assert kept.size == rank == np.linalg.matrix_rank(dense[kept]) and dropped.size == block.shape[0] - rank >= 2
    independent = sparse.csr_matrix(dense[kept])
    assert sparse_solve._dependent_rows_of_block(independent).size == 0


@pytest.fixture(scope="module")
def bounded(plant):
    """The plant reconciled (forced sparse), the unbounded solution, and its bounded flows."""
    flowsheet, survey, problem = plant
    v, success, _, _ = sparse_solve.solve_sparse(problem, sparse_solve.sparse_solids_first_start(flowsheet, survey, problem))
    assert success
    return problem, v, sparse_solve.bounded_sparse(problem, v)


def _sum_of_squares(problem, v, held):
    active = np.zeros(v.size, dtype=bool)
    active[list(held)] = True
    residual = sparse_solve._whitened(sparse_solve._held(problem, active), v)
    return float(residual @ residual)


def test_the_bounded_end_keeps_the_balances_the_bounds_and_the_grades(bounded):
    problem, fitted, result = bounded
    v = result.v
    solids = problem.n_streams * problem.n_classes
    grades = v[solids:].reshape(problem.n_components, solids) / np.where(v[:solids] > 0, v[:solids], np.inf)
    assert result.settled and result.held and np.any(fitted < 0)  # the bounds at work
    assert np.all(v >= 0.0) and grades.max() <= 1.0 + 1e-12
    assert np.abs(problem.A @ v - problem.b).max() <= 1e-10 * np.abs(v).max()
    assert np.all(v[list(result.held)] == 0.0)


def test_no_quadratic_programme_at_the_bounded_end_lowers_its_sum_of_squares(bounded):
    """The linearised problem at the end, under the bounds, the grades and the held flows, from a
    fresh interior point: its optimum is the end (to 1e-9 of the sum of squares)."""
    from tromplab.circuit.bounded_qp import bounded_least_squares

    problem, _, result = bounded
    v = result.v
    solids = problem.n_streams * problem.n_classes
    emptied = np.zeros(v.size, dtype=bool)
    emptied[:solids] = np.isin(np.arange(solids), result.held) & (v[:solids] == 0.0)
    current = sparse_solve._held(problem, emptied)
    free = np.setdiff1d(np.arange(v.size), current.held)
    J = (current.W @ current.jacobian(v)).tocsc()[:, free].tocsr()
    residual = sparse_solve._whitened(current, v)
    A, b, _ = sparse_solve.free_constraints(current, free)
    qp = bounded_least_squares(J, J @ v[free] - residual, A, b, sparse_solve._grade_rows(current, free)[0], v[free])
    model = J @ (qp.x - v[free]) + residual
    assert qp.converged and float(model @ model) >= (1.0 - 1e-9) * float(residual @ residual)


def test_the_bounded_end_is_below_the_dense_active_set_s(bounded):
    """The dense path's rule (one flow released per solve, a grade unbounded) ends higher on this
    plant, with grades up to 17: 332.01 against 329.77 (the error model of the survey's values)."""
    from tromplab.circuit.problem import bounded_solution, build_problem

    problem, fitted, result = bounded
    truth = large_plant(2, 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        survey = lab_survey(truth, np.random.default_rng(40), flows={"fresh_feed": 0.02})
    dense_problem, _ = build_problem(truth.flowsheet, survey)
    held, v = bounded_solution(dense_problem, fitted)
    solids = problem.n_streams * problem.n_classes
    assert (v[solids:].reshape(problem.n_components, solids) / np.where(v[:solids] > 0, v[:solids], np.inf)).max() > 10
    assert _sum_of_squares(problem, result.v, result.held) < _sum_of_squares(problem, v, held) - 2.0


def test_polishes_that_leave_the_bounds_leave_the_iterate_inside_them(plant, bounded, monkeypatch):
    """Every polish refused (as where degenerate bounds make the held solve leave them): after
    two, the interior point's iterate stands, inside the bounds and on the balances."""
    problem, fitted, result = bounded
    monkeypatch.setattr(sparse_solve, "_polished", lambda *args: None)
    stood = sparse_solve.bounded_sparse(problem, fitted)
    assert stood.settled and np.all(stood.v >= 0.0) and np.all(stood.v[list(stood.held)] == 0.0)
    assert np.abs(problem.A @ stood.v - problem.b).max() <= 1e-8 * np.abs(stood.v).max()
    assert _sum_of_squares(problem, stood.v, stood.held) == pytest.approx(
        _sum_of_squares(problem, result.v, result.held), rel=1e-6
    )


def test_an_interior_point_that_does_not_converge_is_said(bounded, monkeypatch):
    from tromplab.circuit import bounded_qp

    problem, fitted, _ = bounded
    monkeypatch.setattr(bounded_qp, "ITERATIONS", 2)
    stopped = sparse_solve.bounded_sparse(problem, fitted)
    assert not stopped.settled and stopped.message == "the bounds' quadratic programme did not converge"
    assert np.all(stopped.v >= 0.0)  # the last iterate inside the bounds (the start)
