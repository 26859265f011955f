"""The batch engine of the density fits against its oracles: statsmodels' GLM, the previous
one-fit-at-a-time path (tests/density_fitting_before_batch.py), scipy.stats, a brute-force profile."""

import math

import numpy as np
import pandas as pd
import pytest
import scipy.optimize
import scipy.special
import scipy.stats
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.density import fit_density, read_density
from tromplab.density import results as density_results
from tromplab.density.batch import TracerStack, fit_glm
from tromplab.density.fitting import fit_density_curves
from tromplab.density.registry import DENSITY_CURVES, PLAIN_CURVES, get_density_curve
from tromplab.density.simulation import simulate_tracer_test
from tromplab.statistics import distributions as dist

from . import density_fitting_before_batch as before
from .conftest import write
from .glm_oracle import statsmodels_glm

BUNDLED = "datasets/density_tracers_dmc_by_size_synthetic.csv"
DENSITIES = np.round(np.arange(1.40, 1.71, 0.03), 2)
#: statsmodels' GLM run to convergence (no tolerance: all its iterations): its default stops at a change of the deviance of
#: 1e-8, which leaves the parameters of the probit and cloglog links about 1e-6 from the maximum.
STATSMODELS_TIGHT = {"tol": 0.0, "maxiter": 300}


def tracer_sets() -> list:
    """The bundled test (4 size fractions), simulated tests of each curve family, one with real
    limits, one overdispersed, and counts near separation (two mixed densities)."""
    rng = np.random.default_rng(7)
    tables = [
        simulate_tracer_test("logistic", {"rho50": 1.55, "ep": 0.04}, DENSITIES, rng=rng, test="logistic"),
        simulate_tracer_test("gompertz", {"rho50": 1.6, "ep": 0.03}, DENSITIES, rng=rng, test="gompertz"),
        simulate_tracer_test(
            "gompertz_limits",
            {"rho_c": 1.55, "ep_c": 0.04, "light_limit": 0.06, "heavy_limit": 0.92},
            DENSITIES,
            rng=rng,
            test="limits",
        ),  # fmt: skip
        pd.DataFrame(
            {
                "test": "overdispersed",
                "density": DENSITIES[:8],
                "sinks": [0, 6, 2, 15, 8, 25, 20, 30],
                "floats": [30, 24, 28, 15, 22, 5, 10, 0],
            }
        ),  # fmt: skip
        pd.DataFrame(
            {
                "test": "near_separation",
                "density": [1.4, 1.45, 1.5, 1.55, 1.6, 1.65],
                "sinks": [0, 0, 3, 27, 30, 30],
                "floats": [30, 30, 27, 3, 0, 0],
            }
        ),  # fmt: skip
    ]
    samples = read_density(BUNDLED)
    for table in tables:
        samples += read_density(table)
    return samples


@pytest.mark.parametrize("curve", PLAIN_CURVES, ids=[curve.id for curve in PLAIN_CURVES])
@pytest.mark.slow
def test_batch_glm_is_statsmodels_glm_to_1e8(curve):
    samples = tracer_sets()
    stack = TracerStack.of([(s.used["density"].to_numpy(float), s.used["sinks"].to_numpy(float),
                             s.used["recovered"].to_numpy(float)) for s in samples])  # fmt: skip
    batch = fit_glm(stack, curve.form)
    assert batch.converged.all()
    for row, sample in enumerate(samples):
        oracle = statsmodels_glm(curve, sample, **STATSMODELS_TIGHT)
        assert_allclose(batch.params[row], oracle.params, rtol=1e-8, err_msg=sample.label)
        assert_allclose(batch.deviance[row], oracle.deviance, rtol=1e-8, err_msg=sample.label)
        assert_allclose(batch.covariance[row], oracle.cov_params(), rtol=1e-8, err_msg=sample.label)


def test_statsmodels_default_tolerance_is_what_separated_the_previous_outputs():
    # why the previous fits.csv differs from the batch's in the 7th digit: statsmodels' default stop
    sample = read_density(BUNDLED)[1]
    curve = get_density_curve("gompertz")
    loose, tight = statsmodels_glm(curve, sample), statsmodels_glm(curve, sample, **STATSMODELS_TIGHT)
    assert 1e-9 < np.max(np.abs(loose.params / tight.params - 1)) < 1e-5


@pytest.fixture(scope="module")
def both_paths():
    """Every curve with 95 % intervals on every tracer set: the batch, and the previous path run to convergence."""
    samples = tracer_sets()
    # each test on its own scale (no file floor): the previous path fits one test at a time
    own_scale = dict.fromkeys(get_density_curve(curve).id for curve in DENSITY_CURVES)
    batch = fit_density_curves(samples, DENSITY_CURVES, ci=0.95, pooled=own_scale)
    settings = (before.PROFILE_XTOL, before.SLSQP_FTOL, before.SCALAR_XATOL, before.GLM_FIT_OPTIONS)
    before.PROFILE_XTOL, before.SLSQP_FTOL, before.SCALAR_XATOL, before.GLM_FIT_OPTIONS = 1e-12, 1e-16, 1e-12, STATSMODELS_TIGHT
    try:
        previous = [before.fit_density_curve(sample, curve, ci=0.95) for sample in samples for curve in DENSITY_CURVES]
    finally:
        before.PROFILE_XTOL, before.SLSQP_FTOL, before.SCALAR_XATOL, before.GLM_FIT_OPTIONS = settings
    return batch, previous


def _numbers(fit) -> dict:
    numbers = {**fit.params, "objective": fit.objective, "aic": fit.aic, "gof_p": fit.gof_p, "dispersion": fit.dispersion}
    for quantity, (low, high) in fit.intervals.items():
        numbers.update({f"{quantity}_low": low, f"{quantity}_high": high})
    return numbers


@pytest.mark.slow
def test_batch_equals_the_previous_path_run_to_convergence(both_paths):
    """Plain curves to 1e-8 (both reach the maximum; the Pearson dispersion to 5e-8), curves with
    limits to 1e-6 relative or absolute (SLSQP's own precision in the previous path, at ftol
    1e-16); the same successes, messages and notes."""
    batch, previous = both_paths
    compared = 0
    for new, old in zip(batch, previous):
        assert (new.sample.label, new.curve.id, new.success, new.message) == (
            old.sample.label,
            old.curve.id,
            old.success,
            old.message,
        )
        if not new.success:
            continue
        assert new.overdispersed == old.overdispersed and new.df_resid == old.df_resid
        new_numbers, old_numbers = _numbers(new), _numbers(old)
        if new.curve.has_limits and new.overdispersed:
            # four parameters on counts with 7 times the binomial variance: the profiles of Ep and I
            # have several minima, and each path follows its own warm starts; the fit itself must agree
            new_numbers = {name: value for name, value in new_numbers.items() if not name.endswith(("_low", "_high"))}
            old_numbers = {name: value for name, value in old_numbers.items() if not name.endswith(("_low", "_high"))}
        else:
            assert new.notes == old.notes
        assert new_numbers.keys() == old_numbers.keys()
        for name, value in new_numbers.items():
            rtol = 1e-6 if new.curve.has_limits else (5e-8 if name == "dispersion" else 1e-8)
            atol = 1e-6 if new.curve.has_limits else 1e-12  # a limit near 0 of the previous path is good to SLSQP's 1e-6
            assert_allclose(value, old_numbers[name], rtol=rtol, atol=atol, err_msg=f"{new.sample.label} {new.curve.id} {name}")
            compared += 1
    assert compared > 500


def test_a_limit_the_profile_does_not_reach_is_not_invented():
    """A test with real limits whose profile of Ep, for a curve with limits, stays below the
    chi-squared threshold down to the search's edge (the limits take the misplaced tracers, so a
    step fits nearly as well): no lower limit (the previous path reported 1.0048e-4, next to the
    edge 1e-4, and an imperfection limit of 9.1e-4). Checked by brute force: (rho50, l, h)
    re-optimised (l and h on a grid of 30 x 30) at Ep = 1e-4."""
    rng = np.random.default_rng(7)
    simulate_tracer_test("logistic", {"rho50": 1.55, "ep": 0.04}, DENSITIES, rng=rng)  # the draws before it
    table = simulate_tracer_test("gompertz_limits", {"rho_c": 1.55, "ep_c": 0.04, "light_limit": 0.06, "heavy_limit": 0.92},
                                 DENSITIES, rng=rng, test="limits")  # fmt: skip
    fit = fit_density_curves(read_density(table), ["normal_limits"], ci=0.95)[0]
    assert math.isnan(fit.intervals["ep"][0]) and "ep: the profile does not reach the lower limit within 0.0001" in fit.notes
    assert math.isnan(fit.intervals["imperfection"][0])
    used = fit.sample.used
    k, n, rho = (used[c].to_numpy(float) for c in ("sinks", "recovered", "density"))

    def deviance(params):
        p = np.clip(fit.curve.partition(rho, **params), 1e-300, 1 - 1e-16)
        return 2 * np.sum(scipy.special.xlogy(k, k / (n * p)) + scipy.special.xlogy(n - k, (n - k) / (n * (1 - p))))

    best = math.inf
    for light in np.linspace(0.0, 0.249, 30):
        for heavy in np.linspace(0.751, 1.0, 30):

            def at(cut, light=light, heavy=heavy):
                return deviance(fit.curve.from_indices(rho50=cut, ep=1e-4, light_limit=light, heavy_limit=heavy))

            best = min(best, scipy.optimize.minimize_scalar(at, bounds=(1.4, 1.7), method="bounded").fun)
    assert best - fit.objective < scipy.stats.chi2.ppf(0.95, 1)


def test_previous_path_as_shipped_agrees_within_its_own_tolerances():
    """The files before the batch (statsmodels' default stop, brentq to 1e-4 of the first step):
    the batch's numbers are within those tolerances of them."""
    sample = read_density(BUNDLED)[0]
    for curve in ("normal", "logistic_limits"):
        new = fit_density_curves([sample], [curve], ci=0.95)[0]
        old = before.fit_density_curve(sample, curve, ci=0.95)
        for quantity in ("rho50", "ep", "imperfection"):
            step = 0.25 * getattr(old.indices, "imperfection" if quantity == "imperfection" else "ep")
            assert_allclose(new.intervals[quantity], old.intervals[quantity], atol=2e-4 * step)
        assert_allclose(new.indices.ep, old.indices.ep, rtol=1e-5)


def test_distributions_are_scipy_stats_to_the_last_bit():
    rng = np.random.default_rng(3)
    q, df, x = rng.uniform(0.001, 0.999, 500), rng.integers(1, 60, 500), rng.uniform(0, 60, 500)
    assert np.array_equal(dist.chi2_ppf(q, df), scipy.stats.chi2.ppf(q, df))
    assert np.array_equal(dist.chi2_sf(x, df), scipy.stats.chi2.sf(x, df))
    assert np.array_equal(dist.f_ppf(q, 1, df), scipy.stats.f.ppf(q, 1, df))
    assert np.array_equal(dist.t_ppf(q, df), scipy.stats.t.ppf(q, df))
    assert np.array_equal(dist.norm_ppf(q), scipy.stats.norm.ppf(q)) and np.array_equal(dist.norm_isf(q), scipy.stats.norm.isf(q))
    n = rng.integers(1, 100, 500).astype(float)
    k, p = np.floor(rng.uniform(0, 1, 500) * (n + 1)), rng.uniform(1e-12, 1 - 1e-12, 500)
    assert np.array_equal(dist.binom_logpmf(k, n, p), scipy.stats.binom.logpmf(k, n, p))


def test_wilson_intervals_are_statsmodels_to_the_last_bit():
    from statsmodels.stats.proportion import proportion_confint

    from tromplab.density.fitting import wilson_interval

    rng = np.random.default_rng(4)
    n = rng.integers(1, 200, 1000)
    k = rng.integers(0, n + 1)
    for level in (0.8, 0.95, 0.99):
        expected = proportion_confint(k, n, alpha=1 - level, method="wilson")
        assert all(np.array_equal(a, b) for a, b in zip(wilson_interval(k, n, level=level), expected))


def campaign(tests: int) -> pd.DataFrame:
    rng = np.random.default_rng(11)
    frames = [
        simulate_tracer_test(
            "normal", {"rho50": rng.uniform(1.45, 1.7), "ep": rng.uniform(0.02, 0.06)}, DENSITIES, rng=rng, test=f"t{i:02d}"
        )  # fmt: skip
        for i in range(tests)
    ]
    return pd.concat(frames, ignore_index=True)


@pytest.mark.slow
def test_units_and_workers_give_the_same_fits_as_one_batch(monkeypatch):
    table = campaign(5)
    whole = fit_density(table, ci=0.95, curves="normal,logistic_limits").fits_table()
    monkeypatch.setattr(density_results, "TESTS_PER_UNIT", 2)
    seen = []
    in_units = fit_density(table, ci=0.95, curves="normal,logistic_limits", progress=lambda *a: seen.append(a[:2]))
    assert seen == [(2, 5), (4, 5), (5, 5)]
    on_workers = fit_density(table, ci=0.95, curves="normal,logistic_limits", jobs=2)
    # the rows of a test do not depend on its company in the batch beyond the last digits of the minimisers
    for other in (in_units.fits_table(), on_workers.fits_table()):
        assert (other["test"] == whole["test"]).all() and (other["notes"] == whole["notes"]).all()
        numeric = whole.select_dtypes("number").columns
        assert_allclose(other[numeric].to_numpy(float), whole[numeric].to_numpy(float), rtol=1e-9, atol=1e-12)
    assert all(fit.sample is sample for fit, sample in zip(on_workers.fits[::2], on_workers.samples))


@pytest.mark.parametrize("figures", ["none", "auto", "all", "best"])
@pytest.mark.slow
def test_figures_choice_decides_the_figures_written_by_the_command_and_the_api(tmp_path, figures):
    path = write(tmp_path, campaign(3).to_csv(index=False), "tracers.csv")
    assert main(["density", "fit", str(path), "-o", str(tmp_path / "cli"), "--figures", figures, "-q"]) == 0
    fit_density(path).save(tmp_path / "api", figures=figures)
    cli = sorted(p.name for p in (tmp_path / "cli").iterdir())
    assert cli == sorted(p.name for p in (tmp_path / "api").iterdir())
    pictures = [name for name in cli if name.endswith(".png")]
    assert len(pictures) == (0 if figures == "none" else 3)
    assert ("figures.csv" in cli) == (figures != "none")
    for name in cli:
        assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "api" / name).read_bytes() or name.endswith(".png")


def test_auto_figures_above_the_limit_draw_one_overview(tmp_path, monkeypatch):
    monkeypatch.setattr(density_results, "AUTO_FIGURE_LIMIT", 2)
    written = fit_density(campaign(3), ci=0.95, curves="normal").save(tmp_path / "out")
    assert "overview.png" in written and "figures.csv" not in written
    assert not [name for name in written if name.startswith("density_")]


def test_unknown_figures_choice_is_an_option_error(tmp_path):
    from tromplab.errors import OptionError

    with pytest.raises(OptionError, match="figures"):
        fit_density(campaign(1)).save(tmp_path / "out", figures="some")


def test_a_result_pickled_after_its_tables_were_made_gives_the_same_tables():
    import pickle

    result = fit_density(campaign(2), curves="normal,normal_limits")
    table, report = result.fits_table(), result.report()  # fills the caches keyed by the objects' ids
    loaded = pickle.loads(pickle.dumps(result))
    assert loaded.fits_table().equals(table) and loaded.report() == report
    assert loaded.best(loaded.samples[1]) is not None
