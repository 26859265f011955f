"""Markov-chain layer model (paper 001; spec section 7)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from tromplab.classifiers.layer import LayerModel, fit_layer_model
from tromplab.cli import main

from .conftest import reference_rows

PUBLISHED = LayerModel(diffusion=0.005, segregation=0.026, passage=0.21)
START = [0.5] * 4


@pytest.mark.parametrize("row", reference_rows("layer_published.csv"), ids=lambda r: f"step {r.step}")
def test_published_extraction_without_locking(row):
    assert_allclose(PUBLISHED.simulate(START, 300).extraction[int(row.step) - 1], row.extraction, atol=row.atol)


def test_mass_is_conserved_and_concentrations_stay_in_range():
    run = LayerModel(0.05, 0.2, 0.1).simulate([0.9, 0.1, 0.5, 0.3, 0.7], 500)
    initial_total = 0.9 + 0.1 + 0.5 + 0.3 + 0.7
    assert_allclose(run.concentrations.sum(axis=1) + run.extraction * initial_total, initial_total, rtol=1e-12)
    assert run.concentrations.min() >= 0 and run.concentrations.max() <= 1
    assert np.all(np.diff(run.extraction) >= 0)


def test_transition_matrix_is_column_stochastic():
    """Without passage the fines only move between cells: the total stays."""
    run = LayerModel(0.1, 0.3, 0.0).simulate([0.2, 0.4, 0.6], 50)
    assert_allclose(run.concentrations.sum(axis=1), 1.2, rtol=1e-13)
    assert run.extraction[-1] == 0


def test_first_lock_near_step_200_needs_a_threshold_near_0022():
    assert PUBLISHED.simulate(START, 300).first_lock is None
    first = {
        eps: LayerModel(0.005, 0.026, 0.21, lock_threshold=eps).simulate(START, 300).first_lock for eps in (0.01, 0.022, 0.03)
    }
    assert first[0.022] == pytest.approx(200, abs=5)
    assert first[0.01] > 240 and first[0.03] < 190


def test_locking_slows_the_passage_by_the_square_root_rule():
    run = LayerModel(0.005, 0.026, 0.21, lock_threshold=0.022).simulate(START, 300)
    k = run.first_lock  # step after which vf = vf0 sqrt(3/4)
    bottom_before = run.concentrations[k, -1]
    gained = run.extraction[k + 1] - run.extraction[k]
    model = LayerModel(0.005, 0.026, 0.21)
    after_move = model._transition(run.concentrations[k].copy(), 1)
    assert_allclose(gained * 2.0, after_move[-1] * 0.21 * np.sqrt(3 / 4), rtol=1e-12)
    assert bottom_before > 0


#: The published run (d, v0, vf0 of paper 001; 4 cells at 50 %) with a lock threshold of 0.02,
#: over the 600 steps of the paper's Fig. 3.
LOCKING = dict(diffusion=0.005, segregation=0.026, passage=0.21, lock_threshold=0.02)


def _lock_steps(run) -> list[int]:
    """Step at which the first, second, ... cell locked."""
    return [int(np.flatnonzero(run.locked >= count)[0]) + 1 for count in range(1, run.locked.max() + 1)]


@pytest.mark.parametrize("constant, steps", [(False, [206, 261, 293]), (True, [206, 260, 292])], ids=["fig3b", "fig3a"])
def test_lock_steps_of_the_published_run_with_threshold_002(constant, steps):
    """Paper 001 (text under Fig. 5): 'at k = 200 (40 s) the layer is one cell thinner'; the threshold
    is not stated. With 0.02 the three upper cells lock at steps 206, 261 and 293 (computed: the
    paper gives only the first, about 200); with a constant passage the later locks come one step
    earlier (the bottom cell passes more, the cells above empty sooner)."""
    run = LayerModel(**LOCKING, constant_passage=constant).simulate(START, 600)
    assert _lock_steps(run) == steps


def test_figure_3a_constant_passage_after_a_lock():
    """Paper 001, Fig. 3: kinetics at constant (a) and variable (b) passage. The text: almost the same
    at the start, then the variable passage slows the process noticeably; the figure's axes end at
    k = 600 and extraction 1, where both curves end (the only readable values of the figure)."""
    variable = LayerModel(**LOCKING).simulate(START, 600)
    constant = LayerModel(**LOCKING, constant_passage=True).simulate(START, 600)
    first = variable.first_lock
    assert constant.first_lock == first == 206
    assert_array_equal(constant.extraction[:first], variable.extraction[:first])  # one model until a cell locks
    later = slice(first + 1, None)
    assert np.all(constant.extraction[later] > variable.extraction[later] - 1e-15)
    assert_allclose((constant.extraction - variable.extraction).max(), 0.00424, atol=5e-6)  # largest gap 0.42 % at k = 297
    assert constant.extraction[599] > 1 - 1e-9 and variable.extraction[599] > 1 - 1e-9
    # the step after the first lock passes vf0 of the bottom cell (Fig. 3a), not vf0 sqrt(3/4) (Fig. 3b)
    after_move = LayerModel(0.005, 0.026, 0.21)._transition(constant.concentrations[first - 1].copy(), 1)
    assert_allclose(constant.extraction[first] - constant.extraction[first - 1], after_move[-1] * 0.21 / 2.0, rtol=1e-12)


def test_layer_command_takes_the_constant_passage_of_figure_3a(tmp_path, capsys):
    out = tmp_path / "fig3a.csv"
    options = ["layer", "simulate", "--lock-threshold", "0.02", "--steps", "600", "-o", str(out)]
    assert main([*options, "--constant-passage"]) == 0
    written = np.loadtxt(out, delimiter=",", skiprows=1, usecols=-2)
    assert_allclose(written, LayerModel(**LOCKING, constant_passage=True).simulate(START, 600).extraction, rtol=1e-12)
    assert main(options) == 0
    variable = np.loadtxt(out, delimiter=",", skiprows=1, usecols=-2)
    assert (written - variable).max() > 4e-3  # the option changed the run
    assert "first cell locked at step 206" in capsys.readouterr().out


@pytest.mark.parametrize("cells, low, high", [(4, 1.15, 1.25), (16, 1.9, 2.1)])
def test_twice_as_many_steps_only_for_thick_layers(cells, low, high):
    """'Nonlinear needs ~2x the steps of linear to reach 80 %' (d = v0 = 0.2, vf = 0.02): 1.20 at 4 cells."""
    linear = LayerModel(0.2, 0.2, 0.02, nonlinear=False).simulate([0.5] * cells, 5000).steps_to_reach(0.8)
    nonlinear = LayerModel(0.2, 0.2, 0.02).simulate([0.5] * cells, 5000).steps_to_reach(0.8)
    assert low <= nonlinear / linear <= high


def test_table_has_one_row_per_step():
    table = PUBLISHED.simulate(START, 10).table(step_seconds=0.2)
    assert list(table.columns) == ["step", "time", "C_1", "C_2", "C_3", "C_4", "extraction", "locked"]
    assert_allclose(table["time"].iloc[-1], 2.0)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(diffusion=0.4, segregation=0.3, passage=0.1), "exceeds 1"),
        (dict(diffusion=-0.1, segregation=0.3, passage=0.1), "diffusion must lie in"),
    ],
)
def test_bad_parameters(kwargs, message):
    with pytest.raises(ValueError, match=message):
        LayerModel(**kwargs)


def test_bad_initial_state():
    with pytest.raises(ValueError, match="one initial concentration per cell"):
        PUBLISHED.simulate(0.5, 10)
    with pytest.raises(ValueError, match="must lie in"):
        PUBLISHED.simulate([0.5, 1.5], 10)


@pytest.mark.slow
def test_identification_round_trip_with_noise():
    steps = np.arange(10, 301, 10)
    truth = PUBLISHED.simulate(START, 300).extraction[steps - 1]
    exact = fit_layer_model(steps, truth, initial=START)
    assert_allclose([exact.model.diffusion, exact.model.segregation, exact.model.passage], [0.005, 0.026, 0.21], rtol=1e-6)
    noisy = truth + np.random.default_rng(0).normal(0, 0.005, truth.size)
    fit = fit_layer_model(steps, noisy, initial=START).fit
    for name, value in [("diffusion", 0.005), ("segregation", 0.026), ("passage", 0.21)]:
        assert abs(fit.values[name] - value) < 3 * fit.stderr[name]


@pytest.mark.slow
def test_identification_of_the_lock_threshold():
    steps = np.arange(10, 301, 10)
    truth = LayerModel(0.005, 0.026, 0.21, lock_threshold=0.022).simulate(START, 300).extraction[steps - 1]
    fit = fit_layer_model(steps, truth, initial=START, fit_threshold=True)
    assert fit.fit.success
    assert_allclose([fit.model.diffusion, fit.model.segregation, fit.model.passage], [0.005, 0.026, 0.21], rtol=0.02)
    assert fit.fit.ssr < 1e-8
    # thresholds that lock the cell at the same step as 0.022 are equivalent
    run = LayerModel(0.005, 0.026, 0.21, lock_threshold=fit.model.lock_threshold).simulate(START, 300)
    assert run.first_lock == LayerModel(0.005, 0.026, 0.21, lock_threshold=0.022).simulate(START, 300).first_lock
    assert np.isinf(fit.profile["lock_threshold"].iloc[-1])  # 'never locks' was tried too
