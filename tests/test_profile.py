"""The batched profile likelihood (curves.batched.profile_limits) against an independent profile
and against lmfit's conf_interval, on the bundled lab layouts (real and textbook data).

The independent profile: for a two-parameter formula, the other parameter is re-optimised by a
dense grid across its bounds and a bounded scalar minimisation around the best grid point
(scipy), so it finds the lower branch where the profile has two.
"""

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy import optimize, stats

from tromplab.curves.engine import fit_formula_batch
from tromplab.curves.formulas import FORMULAS, is_batchable
from tromplab.curves.intervals import batched_profile_intervals, profile_intervals
from tromplab.loading.lab import read_experiments

from .conftest import DATASETS

DATA = Path(__file__).resolve().parent / "data"
LAYOUTS = [DATA / "hydrocyclone_size_class_um.csv", DATA / "gas_cyclone_classes_above_cut_um.csv",
           DATA / "points_size_um.csv", DATASETS / "double_deck_screen_decks_lab.csv"]  # fmt: skip
TWO_PARAMETER = [f for f in FORMULAS if f.n_params == 2 and is_batchable(f)]
LEVEL = 0.95


def _experiments():
    return [points for path in LAYOUTS for points in read_experiments(path).points]


def _independent_profile(fit, name: str, value: float) -> float:
    """Sum of squares with ``name`` held at ``value``, the other parameter re-optimised globally."""
    formula, points = fit.formula, fit.points
    weight = np.ones(points.n) if points.weight is None else points.weight / points.weight.mean()
    other = next(n for n in fit.fit.names if n != name)
    spec = {s.name: s for s in formula.parameters(points.size)}[other]

    def ssr(free: float) -> float:
        values = {name: value, other: free}
        with np.errstate(all="ignore"):
            phi = formula(points.size, values["d_cut"], values[formula.shape_name], **fit.context)
        total = float(np.sum(weight * (phi - points.partition_fine) ** 2))
        return total if np.isfinite(total) else np.inf

    grid = np.geomspace(max(spec.lower, 1e-9 * spec.upper), spec.upper, 300)
    values = np.array([ssr(g) for g in grid])
    k = int(np.argmin(values))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    polished = optimize.minimize_scalar(ssr, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12 * hi})
    return min(values[k], polished.fun)


def _limits():
    """(fit, name, batched limit, lmfit limit, target sum of squares) for every finite limit."""
    experiments = _experiments()
    out = []
    for formula in TWO_PARAMETER:
        fits = [
            fit
            for fit in fit_formula_batch(experiments, formula)
            if fit.success and not fit.fit.at_bound and fit.fit.ssr > 1e-10  # an exact fit leaves no level to resolve
        ]
        batched = batched_profile_intervals(fits, LEVEL)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reference = [fit.with_lmfit().fit.profile_intervals(LEVEL) for fit in fits]
        for fit, ours, theirs in zip(fits, batched, reference):
            free = fit.points.n - 2
            target = fit.fit.ssr * (1.0 + stats.f.ppf(LEVEL, 1, free) / free)
            for name in fit.fit.names:
                for k in range(2):
                    out.append((fit, name, ours[name][k], theirs[name][k], target))
    return out


@pytest.fixture(scope="module")
def limits():
    return _limits()


def test_every_batched_limit_is_where_the_independent_profile_reaches_the_level(limits):
    finite = [row for row in limits if np.isfinite(row[2])]
    assert len(finite) > 100
    for fit, name, value, _, target in finite:
        gap = target - fit.fit.ssr
        found = _independent_profile(fit, name, value)
        assert abs(found - target) <= 1e-6 * gap, (fit.formula.id, fit.experiment, name, value, (found - target) / gap)


def test_where_lmfit_finds_the_level_the_batched_limit_is_the_same(limits):
    """lmfit's conf_interval stops at 5e-5 (relative) and, on these layouts, misses the level
    on a few limits (its point is short of the level there: checked by the same independent
    profile); where its limit is right, the batched one agrees to 2e-4."""
    checked = 0
    for fit, name, ours, theirs, target in limits:
        if not np.isfinite(theirs):
            continue
        gap = target - fit.fit.ssr
        if abs(_independent_profile(fit, name, theirs) - target) > 1e-3 * gap:
            continue  # lmfit's limit is not where the profile reaches the level
        checked += 1
        assert ours == pytest.approx(theirs, rel=2e-4), (fit.formula.id, fit.experiment, name)
    assert checked > 100


def test_one_fit_and_a_batch_give_the_same_profile_intervals():
    experiments = _experiments()[:4]
    fits = fit_formula_batch(experiments, "plitt")
    batched = batched_profile_intervals(fits, LEVEL)
    for fit, together in zip(fits, batched):
        alone = profile_intervals(fit, LEVEL)
        for name in fit.fit.names:
            np.testing.assert_allclose(alone[name], together[name], rtol=1e-9)
