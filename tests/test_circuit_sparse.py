"""The sparse path of large flowsheets (tromplab.circuit.sparse_solve) against the dense path.

Both paths solve the same weighted least squares; forced through each (the size threshold
monkeypatched), a survey gives the same balance and the same tables: flows, assays, sds and
tests to 1e-9 relative (of the value, or of its column's largest for a value at rounding of 0),
except where the problem's conditioning leaves the dense path's pseudo-inverse fewer digits (the
four-mineral plant's smallest variances: there the sparse covariance is shown to solve its
defining equations to rounding and the dense one not).
"""

import warnings

import numpy as np
import pandas as pd
import pytest

from tromplab.circuit import path_choice, reconcile, sparse_factor, sparse_solve
from tromplab.circuit.outputs import balance_tables
from tromplab.circuit.simulation import lab_survey, large_plant


def _survey(blocks: int, classes: int, minerals: bool):
    truth = large_plant(blocks, classes)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the truth's grade of an empty class is 0/0 (no assay drawn)
        survey = lab_survey(truth, np.random.default_rng(40), flows={"fresh_feed": 0.02}, **({} if minerals else {"assayed": ()}))
    return truth.flowsheet, survey


def _both_paths(monkeypatch, flowsheet, survey, tables: bool = True) -> dict:
    """``{"sparse": (balance, tables), "dense": (balance, tables)}``, each path forced."""
    out = {}
    for path, threshold in (("sparse", 1), ("dense", 10**9)):
        monkeypatch.setattr(path_choice, "SPARSE_FLOWSHEET_UNKNOWNS", threshold)
        balance = reconcile(flowsheet, survey)
        out[path] = balance, balance_tables(balance) if tables else None
    assert sparse_solve.is_sparse(out["sparse"][0].problem) and not sparse_solve.is_sparse(out["dense"][0].problem)
    return out


def _assert_tables_agree(sparse_tables: dict, dense_tables: dict, rtol: float = 1e-9) -> None:
    """Every table equal: text exactly, numbers to ``rtol`` of themselves or of the column's largest
    (of the reconciled values' for an adjustment).
    The design table's order among candidates of equal reduction (to rounding) is free: compared by key."""
    assert sparse_tables.keys() == dense_tables.keys()
    for name, dense in dense_tables.items():
        sparse = sparse_tables[name]
        if name == "design":
            keys = ["stream", "measurement", "quantity"]
            sparse, dense = (t.drop(columns="rank").sort_values(keys).reset_index(drop=True) for t in (sparse, dense))
        assert list(sparse.columns) == list(dense.columns) and len(sparse) == len(dense), name
        for column in dense.columns:
            a, b = sparse[column], dense[column]
            if pd.api.types.is_numeric_dtype(b) and not pd.api.types.is_bool_dtype(b):
                a, b = a.to_numpy(float), b.to_numpy(float)
                # an adjustment (reconciled - measured) is at rounding of the values it is the difference of
                scale = dense["reconciled"] if column == "adjustment" else dense[column]
                atol = rtol * np.nanmax(np.abs(scale.to_numpy(float)), initial=0.0) + _cancellation(name, column, dense, b, rtol)
                assert np.array_equal(np.isnan(a), np.isnan(b)), f"{name}.{column}: other NaN"
                off = np.abs(a - b) > atol + rtol * np.abs(b)
                assert not off.any(), f"{name}.{column}: {a[off][:3]} against {b[off][:3]}"
            else:
                assert (a.astype(str).to_numpy() == b.astype(str).to_numpy()).all(), f"{name}.{column}"


#: Differences of variances agree to this share of the larger: the dense path's pseudo-inverse
#: keeps 2e-9 of a measurement's variance on the assayed plants (its predicted variances moved by
#: that much from one process to another, the sparse path's not).
VARIANCE_DIGITS = 1e-8


def _cancellation(name: str, column: str, table: pd.DataFrame, values: np.ndarray, rtol: float):
    """The tolerance of a quantity that is a difference of variances, to :data:`VARIANCE_DIGITS`
    of the larger: an adjustment's variance is the measurement's less the reconciled value's (its
    sd and the tests read it: relative to the measurement's variance, ``1 / redundancy`` of their
    own), a result's shift per sd is a share of the result's sd.  0 for every other column."""
    rtol = VARIANCE_DIGITS
    if name == "adjustments" and column in ("adjustment_sd", "standardised", "gross_error", "gross_error_sd",
                                            "measurement_test", "p_value"):  # fmt: skip
        redundancy = (table["adjustment_sd"].to_numpy(float) / table["sd"].to_numpy(float)) ** 2
        return rtol * np.abs(values) / np.where(redundancy > 0, redundancy, np.inf)
    if name == "worth" and column in ("redundancy", "variance_share"):
        return rtol
    if name == "worth" and column == "shift_per_sd":
        return rtol * table["result_sd"].to_numpy(float)
    return 0.0


def test_ordinary_surveys_keep_the_dense_path():
    """The bundled example and the reference surveys stay below the threshold: their path and bytes are the former ones."""
    from pathlib import Path

    from tromplab.circuit import read_flowsheet, read_survey

    root = Path(__file__).resolve().parents[1]
    sheet = read_flowsheet(root / "datasets" / "circuit_example_flowsheet.csv")
    surveys = [
        root / "datasets" / "circuit_example_survey.csv",
        *sorted((root / "tests/data/circuit_reference/inputs").glob("*.csv")),
    ]
    for path in surveys:
        survey = read_survey(path, sheet)
        assert path_choice.unknown_count(sheet, survey) < path_choice.SPARSE_FLOWSHEET_UNKNOWNS / 2, path.name
        assert not path_choice.takes_sparse_path(sheet, survey)
    assert not sparse_solve.is_sparse(reconcile(sheet, read_survey(surveys[0], sheet)).problem)


def test_the_30_node_plant_takes_the_sparse_path_with_its_stages_reported():
    flowsheet, survey = _survey(10, 20, minerals=False)
    assert path_choice.takes_sparse_path(flowsheet, survey)
    stages = []
    balance = reconcile(flowsheet, survey, progress=lambda done, total, label: stages.append(label))
    assert sparse_solve.is_sparse(balance.problem) and balance.success
    assert stages[:3] == ["reconciliation: round 1", "reconciliation: round 2", "reconciliation: round 3"]
    held_stages = [label for label in stages if label.startswith("reconciliation: bounds, ")]
    assert balance.at_bound and held_stages and held_stages[0].endswith(" flows held")  # the bounds' sets reported
    assert balance.dof == balance.problem.W.shape[0] - balance.decomposition.rank > 0


def test_a_small_plant_with_minerals_forced_sparse_gives_the_dense_balance_and_tables(monkeypatch):
    """A 6-node plant of 8 classes with four minerals (360 unknowns), both paths: every table."""
    flowsheet, survey = _survey(2, 8, minerals=True)
    paths = _both_paths(monkeypatch, flowsheet, survey)
    (sparse, sparse_tables), (dense, dense_tables) = paths["sparse"], paths["dense"]
    assert sparse.at_bound == dense.at_bound and sparse.dof == dense.dof and sparse.success and dense.success
    np.testing.assert_allclose(sparse._unknowns, dense._unknowns, rtol=1e-9, atol=1e-12 * np.abs(dense._unknowns).max())
    _assert_tables_agree(sparse_tables, dense_tables)


@pytest.mark.slow
def test_the_30_node_plant_solids_only_gives_the_dense_balance_and_tables(monkeypatch):
    flowsheet, survey = _survey(10, 20, minerals=False)
    paths = _both_paths(monkeypatch, flowsheet, survey)
    (sparse, sparse_tables), (dense, dense_tables) = paths["sparse"], paths["dense"]
    assert sparse.at_bound == dense.at_bound and len(sparse.at_bound) > 0  # the bounds' active set at work
    assert sparse.chi_square == pytest.approx(dense.chi_square, rel=1e-12)
    np.testing.assert_allclose(sparse.covariance, dense.covariance, rtol=0, atol=1e-12 * np.abs(dense.covariance).max())
    _assert_tables_agree(sparse_tables, dense_tables)


@pytest.mark.slow
def test_the_6_node_plant_with_four_minerals_gives_the_dense_balance_where_the_bounds_do_not_reach(monkeypatch):
    """20 classes, four minerals on every stream (900 unknowns, 20 directions no measurement
    sees): the unbounded least squares (its solution and chi-square to 1e-9, the well-conditioned
    measurement tests to 1e-6, the covariance: the sparse one solves its equations to rounding,
    the dense one to 1e-6 of them).  The bounded flows (and the sds evaluated at them) differ: the dense path's active set ends with grades up to 20 (a mineral
    flow 20 times its class's solids), the sparse path bounds every grade at 1 and still ends at
    a lower sum of squares (``test_circuit_sparse_bounds``)."""
    flowsheet, survey = _survey(2, 20, minerals=True)
    paths = _both_paths(monkeypatch, flowsheet, survey)
    (sparse, sparse_tables), (dense, dense_tables) = paths["sparse"], paths["dense"]
    assert sparse.dof == dense.dof and sparse.success and dense.success
    assert sparse.chi_square == pytest.approx(dense.chi_square, rel=1e-9)
    scale = np.abs(dense.fitted).max()
    np.testing.assert_allclose(sparse.fitted, dense.fitted, rtol=1e-9, atol=1e-12 * scale)
    well = dense_tables["worth"].drop_duplicates("measurement")["redundancy"].to_numpy() > 1e-2
    a, b = (t["measurement_test"].to_numpy(float)[well] for t in (sparse_tables["adjustments"], dense_tables["adjustments"]))
    np.testing.assert_allclose(a, b, rtol=1e-6)
    sparse_residual, dense_residual = (_covariance_residual(sparse, balance.covariance) for balance in (sparse, dense))
    assert sparse_residual < 1e-9 and sparse_residual < 1e-3 * dense_residual
    grades = dense.component_flows / np.where(dense.class_flows > 0, dense.class_flows, np.inf)[None]
    assert grades.max() > 10  # the dense path's end (why the flows are not compared)
    assert sparse.component_flows.max() > 0 and np.all(sparse.component_flows <= sparse.class_flows[None] * (1 + 1e-12))


def _covariance_residual(balance, covariance: np.ndarray) -> float:
    r"""The largest relative residual of the equations the columns :math:`c` of ``covariance``
    solve, :math:`J^T J c + A^T \lambda = e_k`, :math:`A c = 0`, :math:`Z^T c = 0` (``balance``:
    the sparse path's, whose :math:`J` and :math:`Z`, the directions no measurement sees, it holds),
    over a few columns."""
    from scipy import sparse
    from scipy.sparse import linalg as sparse_linalg

    problem, linearisation = balance.problem, balance.decomposition
    J, Z = linearisation.J, linearisation.unseen_unknowns
    constraints = sparse.vstack([problem.A, Z.T]).tocsr()
    worst = 0.0
    for k in np.linspace(0, covariance.shape[0] - 1, 9).astype(int):
        e = np.zeros(covariance.shape[0])
        e[k] = 1.0
        column = covariance[:, k]
        information = J.T @ (J @ column)
        multipliers = sparse_linalg.lsqr(constraints.T, e - information, atol=1e-15, btol=1e-15, iter_lim=20000)[0]
        residual = np.linalg.norm(e - information - constraints.T @ multipliers) / max(1.0, np.linalg.norm(information))
        worst = max(worst, residual, np.linalg.norm(constraints @ column) / np.abs(covariance).max())
    return worst


@pytest.mark.slow
def test_the_30_node_plant_with_four_minerals_ends_inside_the_bounds_and_the_grades():
    """4,100 unknowns: the bounds settle (three quadratic programmes) at a chi-square of the held
    problem of 1,197.65 (the active-set rule of the dense path ended at 1,478.6 with 12 wrong-sign
    held flows and grades up to 25, docs/circuit.md), every grade at most 1, and the summary
    counts the class flows that emptied their class and would lower it if raised."""
    flowsheet, survey = _survey(10, 20, minerals=True)
    balance = reconcile(flowsheet, survey)
    assert sparse_solve.is_sparse(balance.problem) and balance.success
    assert np.all(balance.component_flows <= balance.class_flows[None] * (1 + 1e-12)) and balance.class_flows.min() >= 0
    v = balance._unknowns
    active = np.zeros(v.size, dtype=bool)
    active[list(balance.at_bound)] = True
    residual = sparse_solve._whitened(sparse_solve._held(balance.problem, active), v)
    assert float(residual @ residual) == pytest.approx(1197.65, rel=1e-5)
    assert balance.held_against_multipliers == balance.raisable_held == 4
    assert "4 of the flows held at 0 would lower the sum of squares if raised (each reached 0" in balance.report()


def _bounded_sum_of_squares(balance, problem) -> float:
    """The sum of squares of ``balance``'s bounded flows in the sparse ``problem`` (its held flows held)."""
    v = balance._unknowns
    active = np.zeros(v.size, dtype=bool)
    active[list(balance.at_bound)] = True
    residual = sparse_solve._whitened(sparse_solve._held(problem, active), v)
    return float(residual @ residual)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("blocks", "classes", "seed", "relation"),
    [(2, 10, 2, "equal"), (2, 16, 3, "lower"), (3, 12, 1, "lower"), (3, 12, 4, "grade-bound")],
)
def test_the_sparse_bounds_end_no_higher_than_the_dense_rule_unless_its_grades_exceed_1(
    monkeypatch, blocks, classes, seed, relation
):
    """Small plants with four minerals, both paths forced: where the dense rule's end has every
    grade at most 1 the sparse bounds end at its sum of squares or lower (the rule releases one
    flow at a time and stops at an end that is not the least; 260.16 against 251.45 on the second
    case); where it has a grade above 1 (1.96 on the last) the sparse end, bounded at 1, may be a
    little higher (measured over 20 such plants in docs/performance.md)."""
    truth = large_plant(blocks, classes)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        survey = lab_survey(truth, np.random.default_rng(seed), flows={"fresh_feed": 0.02})
    paths = _both_paths(monkeypatch, truth.flowsheet, survey, tables=False)
    sparse, dense = paths["sparse"][0], paths["dense"][0]
    problem = sparse.problem
    ends = _bounded_sum_of_squares(sparse, problem), _bounded_sum_of_squares(dense, problem)
    dense_grade = (dense.component_flows / np.where(dense.class_flows > 0, dense.class_flows, np.inf)[None]).max()
    assert np.all(sparse.component_flows <= sparse.class_flows[None] * (1 + 1e-12))
    if relation == "equal":
        assert ends[0] == pytest.approx(ends[1], rel=1e-9) and dense_grade <= 1
    elif relation == "lower":
        assert ends[0] < ends[1] - 1.0 and dense_grade <= 1
    else:
        assert dense_grade > 1 and ends[1] <= ends[0] <= ends[1] * (1 + 1e-4)


@pytest.mark.slow
def test_a_class_a_step_nearly_empties_is_emptied_instead_of_crawling_back():
    """Another survey of the plant (seed 41): its first step under the bounds shrinks an assayed
    class 2,500-fold and its assays, ratios of nearly nothing, made a chi-square of 5e6 where the
    step predicted 1,197; the halvings then took 17 steps.  The class emptied instead
    (``sparse_solve.EMPTYING``), the bounds settle in at most 10 steps."""
    truth = large_plant(10, 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        survey = lab_survey(truth, np.random.default_rng(41), flows={"fresh_feed": 0.02})
    labels = []
    balance = reconcile(truth.flowsheet, survey, progress=lambda done, total, label: labels.append(label))
    steps = [label for label in labels if label.startswith("reconciliation: bounds, step ")]
    assert balance.success and 2 <= len(steps) <= 10
    assert np.all(balance.component_flows <= balance.class_flows[None] * (1 + 1e-12))


@pytest.mark.slow
def test_a_large_survey_the_balances_cannot_determine_is_refused_as_on_the_dense_path():
    """Two streams of a cyclone without a size analysis: the sparse path sees the solids flows no
    measurement determines and hands over to the dense path, which names the streams."""
    from tromplab.errors import InputError

    flowsheet, survey = _survey(10, 20, minerals=False)
    blind = ("overflow_4", "underflow_4", "discharge_4")
    shares = survey.shares[~survey.shares["stream"].isin(blind)]
    closed = tuple(s for s in survey.closed_streams if s not in blind)
    from dataclasses import replace

    with pytest.raises(InputError, match="cannot determine"):
        reconcile(flowsheet, replace(survey, shares=shares, closed_streams=closed))


@pytest.mark.slow
def test_serial_elimination_on_a_large_flowsheet_stops_after_a_few_steps_and_says_so():
    """Each step of the serial elimination reconciles the survey again: on the sparse path it
    stops after LARGE_ELIMINATION_STEPS and the summary says why, rather than running for minutes."""
    from dataclasses import replace

    from tromplab.circuit import reconciliation

    flowsheet, survey = _survey(10, 20, minerals=False)
    shares = survey.shares.copy()
    for block in range(1, 11):  # ten gross errors of 15 sd, one per stage
        at = shares.index[(shares["stream"] == f"cyclone_feed_{block}") & (shares["class_index"] == 10)][0]
        shares.loc[at, "value"] += 15 * shares.loc[at, "sd"]
    balance = reconcile(flowsheet, replace(survey, shares=shares))
    assert sparse_solve.is_sparse(balance.problem) and balance.rejected
    table = balance.elimination_table()
    assert len(table) - 1 == reconciliation.LARGE_ELIMINATION_STEPS and table["p_value"].iloc[-1] <= balance.alpha
    assert f"serial elimination stopped after {reconciliation.LARGE_ELIMINATION_STEPS} steps" in balance.report()


def _factor_at(problem, v, near=None):
    return sparse_factor.AugmentedFactor(problem.W @ problem.jacobian(v), problem.A, near=near)


def test_a_step_through_the_last_factor_refined_equals_a_step_through_a_fresh_one():
    """Gauss-Newton steps and rounds reuse the last LU by iterative refinement: at a nearby point
    (the reuse taken) and at a far one (refinement stalls: a fresh LU), the step and the
    multipliers are the fresh factor's to rounding."""
    flowsheet, survey = _survey(2, 20, minerals=True)  # 900 unknowns, 20 unseen directions
    problem, _ = sparse_solve.build_sparse_problem(flowsheet, survey)
    v = sparse_solve.projected_start(problem, sparse_solve.sparse_solids_first_start(flowsheet, survey, problem))
    first = _factor_at(problem, v)
    assert first.unseen.shape[1] > 0  # directions no measurement sees: the pinned unknowns at work
    residual = problem.W @ (problem.predict(v) - problem.y)
    gradient = (problem.W @ problem.jacobian(v)).T @ residual
    for moved, reused in ((1e-4, True), (0.5, False)):
        w = v * (1.0 + moved * np.cos(np.arange(v.size)))
        near, fresh = _factor_at(problem, w, near=first), _factor_at(problem, w)
        assert near.lu is first.lu and near.refined
        step_near, step_fresh = near.step(residual), fresh.step(residual)
        assert near.refined == reused  # a far point: the refinement stalled and the system was factored
        np.testing.assert_allclose(step_near, step_fresh, rtol=0, atol=1e-10 * np.abs(step_fresh).max())
        mu_near, mu_fresh = near.multipliers(gradient), fresh.multipliers(gradient)
        np.testing.assert_allclose(mu_near, mu_fresh, rtol=0, atol=1e-9 * np.abs(mu_fresh).max())


def test_pinned_unknowns_give_the_covariance_of_the_unseen_directions_as_constraints():
    r"""The covariance with the unseen unknowns pinned and projected, :math:`\Pi C_p \Pi`, against
    the one with their directions :math:`Z^T` as constraint rows, computed densely:
    :math:`N (N^T J^T J N)^{-1} N^T` with :math:`N` an orthonormal null space of
    :math:`[A; Z^T]` (by the SVD of :math:`J N`, the dense path's way); and the step, the least squares under the same constraints."""
    from scipy import linalg

    flowsheet, survey = _survey(2, 20, minerals=True)  # 900 unknowns, 20 unseen directions
    problem, _ = sparse_solve.build_sparse_problem(flowsheet, survey)
    v = sparse_solve.projected_start(problem, sparse_solve.sparse_solids_first_start(flowsheet, survey, problem))
    factor = _factor_at(problem, v)
    Z = factor.unseen.toarray()
    assert Z.shape[1] > 0
    J = (problem.W @ problem.jacobian(v)).toarray()
    N = linalg.null_space(np.vstack([problem.A.toarray(), Z.T]))
    _, singular, right = np.linalg.svd(J @ N, full_matrices=False)  # J N of full column rank: no direction unseen is left
    half = N @ right.T / singular
    expected = half @ half.T
    np.testing.assert_allclose(factor.covariance(), expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    residual = problem.W @ (problem.predict(v) - problem.y)
    expected_step = -N @ np.linalg.lstsq(J @ N, residual, rcond=None)[0]
    np.testing.assert_allclose(factor.step(residual), expected_step, rtol=0, atol=1e-9 * np.abs(expected_step).max())


@pytest.mark.slow
def test_the_adjustments_figure_of_a_large_survey_shows_its_largest_tests():
    """The 30-node plant (solids only: 600-odd measurements): the figure shows the 150 largest
    measurement tests, in the table's order, says so in its title and stays 25 inches tall; a
    survey of the usual size shows every measurement (the bundled example's 78)."""
    from pathlib import Path

    from tromplab.circuit import plotting, read_flowsheet, read_survey
    from tromplab.output.plotting import offscreen_axes

    flowsheet, survey = _survey(10, 20, minerals=False)
    balance = reconcile(flowsheet, survey)
    table = balance.adjustments_table()
    shown = plotting._adjustments_shown(table)
    assert len(table) > plotting.ADJUSTMENTS_SHOWN == len(shown)
    tests = np.abs(table["measurement_test"].to_numpy(float))
    assert np.nanmin(np.abs(shown["measurement_test"].to_numpy(float))) >= np.sort(tests[np.isfinite(tests)])[-150]
    assert list(shown.index) == sorted(shown.index)
    ax = offscreen_axes(figsize=plotting.figure_size(balance, "adjustments"))
    plotting.plot_adjustments(balance, ax=ax)
    assert f"the 150 largest measurement tests of {len(table)}" in ax.get_title()
    assert plotting.figure_size(balance, "adjustments") == (8.0, 0.16 * 150 + 1.0)
    root = Path(__file__).resolve().parents[1]
    sheet = read_flowsheet(root / "datasets" / "circuit_example_flowsheet.csv")
    example = reconcile(sheet, read_survey(root / "datasets" / "circuit_example_survey.csv", sheet))
    assert len(plotting._adjustments_shown(example.adjustments_table())) == len(example.adjustments_table()) == 78
