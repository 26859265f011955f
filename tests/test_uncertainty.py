"""Uncertainty of fits and indices, information criteria and model averaging."""

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.curves import fit_formula
from tromplab.formulas import FORMULAS, get_formula
from tromplab.points import TrompPoints
from tromplab.uncertainty import akaike_weights, bootstrap, interval_table, model_average

SIZES = np.geomspace(20, 400, 10)
PLITT = get_formula("plitt")


def experiment(seed, noise=0.02, d_cut=80.0, ks=2.5, name="e"):
    rng = np.random.default_rng(seed)
    return TrompPoints(name, SIZES, PLITT(SIZES, d_cut, ks) + rng.normal(0, noise, SIZES.size))


@pytest.mark.slow
def test_nominal_coverage_of_95_percent_intervals():
    """Over seeded synthetic experiments with a known curve, 95 % intervals cover the truth 90-99 % of the time."""
    wald = np.zeros(2)
    profile = np.zeros(2)
    runs, profiled_runs = 150, 60
    for seed in range(runs):
        fit = fit_formula(experiment(seed), PLITT).fit
        intervals = fit.confidence_intervals(0.95)
        wald += [intervals["d_cut"][0] <= 80 <= intervals["d_cut"][1], intervals["ks"][0] <= 2.5 <= intervals["ks"][1]]
        if seed < profiled_runs:
            intervals = fit.profile_intervals(0.95)
            profile += [intervals["d_cut"][0] <= 80 <= intervals["d_cut"][1], intervals["ks"][0] <= 2.5 <= intervals["ks"][1]]
    assert np.all((0.90 <= wald / runs) & (wald / runs <= 0.99)), wald / runs
    assert np.all((0.88 <= profile / profiled_runs) & (profile / profiled_runs <= 1.0)), profile / profiled_runs


def test_interval_table_reports_parameters_and_indices():
    fit = fit_formula(experiment(1), PLITT)
    table = interval_table(fit).set_index("quantity")
    assert list(table.index) == [
        "d_cut",
        "ks",
        "slope",
        "eta",
        "epsilon",
        "d25",
        "d75",
        "ep",
        "imperfection",
        "d50",
        "ep_c",
        "imperfection_c",
    ]
    assert set(table.loc[["d_cut", "ks"], "method"]) <= {"profile", "wald-log"}
    assert table.loc["slope", "method"] == "delta-neglog" and table.loc["eta", "method"] == "delta-logit"
    assert (table.loc["epsilon":, "method"] == "delta-log").all()
    assert (table["low"] < table["value"]).all() and (table["value"] < table["high"]).all()
    # the slope is -ks/4, so its delta-method error is exactly se(ks)/4
    assert_allclose(table.loc["slope", "stderr"], table.loc["ks", "stderr"] / 4, rtol=1e-5)


def test_delta_method_and_bootstrap_agree():
    fit = fit_formula(experiment(3), PLITT)
    delta = interval_table(fit, profile=False).set_index("quantity")
    boot = bootstrap(fit, n=300, seed=11).intervals().set_index("quantity")
    for quantity in ("d_cut", "eta", "ep"):
        assert_allclose(boot.loc[quantity, "stderr"], delta.loc[quantity, "stderr"], rtol=0.35)


def test_bootstrap_is_seeded_and_supports_cases():
    fit = fit_formula(experiment(4), PLITT)
    first, again = bootstrap(fit, n=30, seed=5), bootstrap(fit, n=30, seed=5)
    pd.testing.assert_frame_equal(first.samples, again.samples)
    assert not bootstrap(fit, n=30, seed=6).samples.equals(first.samples)
    cases = bootstrap(fit, n=30, seed=5, method="cases")
    assert cases.n_failed == 0 and len(cases.samples) == 30
    with pytest.raises(ValueError, match="'residuals' or 'cases'"):
        bootstrap(fit, n=10, method="jackknife")


def test_akaike_weights_and_information_criteria():
    assert_allclose(akaike_weights([3.0, 3.0, 5.0]).sum(), 1.0)
    fit = fit_formula(experiment(2), PLITT)
    criteria = fit.fit.information_criteria()
    n, k = SIZES.size, 3  # d_cut, ks and the error variance (Burnham & Anderson 2002, section 2.2)
    assert_allclose(criteria["aic"], n * np.log(fit.fit.ssr / n) + 2 * k)
    assert_allclose(criteria["aicc"] - criteria["aic"], 2 * k * (k + 1) / (n - k - 1))
    assert_allclose(criteria["bic"], n * np.log(fit.fit.ssr / n) + k * np.log(n))


def test_model_average_weights_the_formulas():
    points = experiment(7)
    fits = [fit_formula(points, formula) for formula in FORMULAS]
    table = model_average(fits).set_index("quantity")
    weights = table.filter(like="weight_").iloc[0]
    assert_allclose(weights.sum(), 1.0)
    assert weights.idxmax() in ("weight_plitt", "weight_lognormal", "weight_molerus_hoffmann")
    d_cuts = [fit.d_cut for fit in fits]
    assert min(d_cuts) <= table.loc["d50c", "value"] <= max(d_cuts)
    assert table.loc["d50c", "stderr"] >= min(fit.fit.stderr["d_cut"] for fit in fits)
    assert_allclose(table.loc["d50", "value"], table.loc["d50c", "value"])  # no bypass: the actual cut is the corrected one
    with pytest.raises(ValueError, match="one experiment"):
        model_average([fits[0], fit_formula(experiment(8, name="other"), PLITT)])


def test_f_and_aicc_rankings_coincide_for_two_parameter_formulas():
    fits = [fit_formula(experiment(9), formula) for formula in FORMULAS]
    by_f = np.argsort([-fit.screen.F for fit in fits])
    by_aicc = np.argsort([fit.fit.information_criteria()["aicc"] for fit in fits])
    assert list(by_f) == list(by_aicc)


def test_fit_command_adds_interval_columns_and_averages(tmp_path, capsys):
    frame = pd.concat([experiment(s, name=f"run{s}").to_frame() for s in (1, 2)])
    path = tmp_path / "points.csv"
    frame.to_csv(path, index=False)
    out = tmp_path / "out"
    assert (
        main(
            [
                "fit",
                str(path),
                "-o",
                str(out),
                "--formulas",
                "plitt,lognormal",
                "--ci",
                "0.9",
                "--bootstrap",
                "20",
                "--no-figures",
            ]
        )
        == 0
    )
    fits = pd.read_csv(out / "fits.csv")
    for column in ("d_cut_low", "d_cut_high", "shape_low", "ep_high", "d_cut_boot_low", "eta_boot_high"):
        assert fits[column].notna().all(), column
    assert (fits["d_cut_low"] < fits["d_cut"]).all() and (fits["d_cut"] < fits["d_cut_high"]).all()
    averages = pd.read_csv(out / "averages.csv")
    assert set(averages["quantity"]) == {"d50", "d50c", "ep", "ep_c", "eta"} and set(averages["experiment"]) == {"run1", "run2"}
    assert main(["fit", str(path), "-o", str(out), "--ci", "1.5"]) == 2  # usage: the parser refuses the level


def test_bootstrap_alone_adds_only_bootstrap_columns(tmp_path):
    path = tmp_path / "points.csv"
    experiment(1).to_frame().to_csv(path, index=False)
    out = tmp_path / "out"
    assert main(["fit", str(path), "-o", str(out), "--formulas", "plitt", "--bootstrap", "5", "--no-figures"]) == 0
    columns = set(pd.read_csv(out / "fits.csv").columns)
    assert "d_cut_boot_low" in columns and "d_cut_low" not in columns


def test_model_averages_read_the_batched_indices_and_agree_with_the_one_by_one_delta_method():
    """Issue 11: the delta method of a chunk reads indices computed ahead on arrays; the averages
    agree with indices computed one fit and one step at a time (difference-quotient noise only)."""
    from numpy.testing import assert_allclose

    from tromplab._synthetic import synthetic
    from tromplab.uncertainty import batched_delta_indices, model_average
    from tromplab.workbench import fit_experiments

    bench = fit_experiments([synthetic(seed) for seed in (2, 7, 11)])
    for fits in bench.fits_by_experiment().values():
        one_by_one = model_average(fits)
        with batched_delta_indices(fits):
            batched = model_average(fits)
        assert list(batched["note"]) == list(one_by_one["note"])
        for column in ("value", "stderr", "low", "high"):
            assert_allclose(batched[column], one_by_one[column], rtol=1e-6, equal_nan=True)
