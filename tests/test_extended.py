"""Curves with bypass and fish-hook; nested tests; shared fits across experiments; diagnostics; weights."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.curves.curve_fit import fit_formula
from tromplab.curves.formulas import EXTENDED_FORMULAS, get_formula, whiten_beta_star
from tromplab.loading.points import TrompPoints
from tromplab.statistics.compare import DEFAULT_MARGIN, nested_f_test, shared_fit
from tromplab.workbench import fit_experiments

SIZES = np.geomspace(10, 400, 12)
X = np.geomspace(1e-3, 1e3, 500)


@pytest.mark.parametrize("formula", EXTENDED_FORMULAS, ids=[f.id for f in EXTENDED_FORMULAS])
def test_extended_curves_are_declared_and_reduce_to_their_paper_formula(formula):
    assert formula.family == "extended" and formula.citation and formula.extras
    base = get_formula(formula.nests)
    shape = base.shape_for_slope(-0.6)
    without = {extra.name: 0.0 for extra in formula.extras}
    assert_allclose(formula.phi(X, shape, **without), base.phi(X, shape), atol=1e-12)
    with_bypass = formula.phi(X, shape, **{**without, "bypass": 0.2})
    assert_allclose(with_bypass, 0.8 * base.phi(X, shape), atol=1e-12)
    assert np.all((with_bypass >= 0) & (with_bypass <= 1))


def test_whiten_beta_star_keeps_the_corrected_cut():
    for alpha, beta in [(2.0, 0.5), (5.0, 1.0), (10.0, 2.0)]:
        star = whiten_beta_star(alpha, beta)
        assert_allclose(get_formula("whiten").phi(1.0, alpha, fishhook=beta), 0.5, atol=1e-12)
        assert star > 0
    curve = get_formula("whiten").phi(X, 5.0, bypass=0.3, fishhook=1.0)
    assert curve.max() > 0.7  # the fish-hook: the fines partition rises above C = 1 - bypass


def test_bypass_is_recovered_and_the_nested_test_detects_it():
    formula = get_formula("plitt_bypass")
    rng = np.random.default_rng(2)
    points = TrompPoints("b", SIZES, formula(SIZES, 80, 2.5, bypass=0.15) + rng.normal(0, 0.01, SIZES.size))
    full, reduced = fit_formula(points, formula), fit_formula(points, "plitt")
    assert_allclose(full.extras["bypass"], 0.15, atol=0.03)
    assert full.screen.n_params == 3
    test = nested_f_test(reduced, full)
    assert test.needed() and test.p_value < 1e-4


def test_nested_test_does_not_ask_for_a_bypass_that_is_not_there():
    rng = np.random.default_rng(3)
    points = TrompPoints("p", SIZES, get_formula("plitt")(SIZES, 80, 2.5) + rng.normal(0, 0.01, SIZES.size))
    test = nested_f_test(fit_formula(points, "plitt"), fit_formula(points, "plitt_bypass"))
    assert not test.needed()
    with pytest.raises(ValueError, match="does not nest"):
        nested_f_test(fit_formula(points, "lognormal"), fit_formula(points, "plitt_bypass"))


def test_extended_curves_stay_out_of_the_paper_ranking_by_default():
    rng = np.random.default_rng(4)
    points = TrompPoints("p", SIZES, get_formula("plitt")(SIZES, 80, 2.5) + rng.normal(0, 0.01, SIZES.size))
    bench = fit_experiments([points], formulas="paper,extended")
    assert set(bench.fits_table()["formula"]) >= {"whiten", "plitt_bypass"}
    assert "whiten" not in set(bench.ranking_table()["formula"])
    ranked = fit_experiments([points], formulas="paper,extended", rank_extended=True).ranking_table()
    assert "whiten" in set(ranked["formula"])


def shifted(d_cut, ks, seed, name):
    rng = np.random.default_rng(seed)
    phi = get_formula("plitt")(SIZES, d_cut, ks) + rng.normal(0, 0.01, SIZES.size)
    return TrompPoints(name, SIZES, np.clip(phi, 0, 1))


def test_shared_shape_test_detects_a_change_of_sharpness_only():
    same = shared_fit([shifted(80, 2.5, 1, "a"), shifted(120, 2.5, 2, "b")], "plitt")
    assert not same.test.needed()
    changed = shared_fit([shifted(80, 2.5, 1, "a"), shifted(100, 4.0, 3, "c")], "plitt")
    assert changed.test.needed() and changed.test.p_value < 1e-6
    table = same.table()
    assert list(table["experiment"]) == ["a", "b"]
    assert_allclose(table["d_cut_joint"], [80, 120], rtol=0.03)


def test_shared_cut_size():
    result = shared_fit([shifted(80, 2.5, 1, "a"), shifted(80, 4.0, 2, "b")], "plitt", shared="d_cut")
    assert not result.test.needed()
    assert_allclose(result.fit.values["d_cut"], 80, rtol=0.03)


def test_compare_command(tmp_path, capsys):
    import pandas as pd

    frame = pd.concat([shifted(80, 2.5, 1, "a").to_frame(), shifted(100, 4.0, 3, "c").to_frame()])
    path = tmp_path / "two.csv"
    frame.to_csv(path, index=False)
    assert main(["compare", str(path), "--formula", "plitt"]) == 0
    assert "the experiments differ in ks: their estimates differ by" in capsys.readouterr().out
    assert main(["compare", str(path), "--experiments", "a,zzz"]) == 1
    assert "unknown experiment(s) zzz" in capsys.readouterr().err


def _plitt_run(ks, seed, noise, name, d_cut=80.0, count=30):
    sizes = np.geomspace(20, 400, count)
    rng = np.random.default_rng(seed)
    return TrompPoints(name, sizes, get_formula("plitt")(sizes, d_cut, ks) + rng.normal(0, noise, count))


def test_a_tiny_p_value_with_estimates_within_the_margin_is_equal_within_the_margin():
    """The shapes ks 2.50 against 2.52 on 30 points with noise 2e-4: the F test tells them apart
    (p ~ 1e-32), but they differ by 0.8 %, less than the default margin of 1 %."""
    result = shared_fit([_plitt_run(2.5, 1, 2e-4, "a"), _plitt_run(2.52, 2, 2e-4, "b", d_cut=100.0)], "plitt")
    separate = [fit.fit.values["ks"] for fit in result.separate]
    assert_allclose(result.relative_difference, (max(separate) - min(separate)) / result.fit.values["ks"], rtol=1e-12)
    assert 0.005 < result.relative_difference < DEFAULT_MARGIN == 0.01
    assert result.test.p_value < 1e-20
    assert result.verdict() == "equal within the margin"
    assert result.conclusion().startswith("the experiments are equal within the margin in ks: their estimates differ by 0.")
    assert "although the F test tells them apart" in result.conclusion()
    assert result.verdict(margin=0.005) == "differ"


def test_no_difference_detected_but_estimates_beyond_the_margin_is_undecided():
    """Six noisy points each (noise 0.05): ks 2.5 against 3.0 is not detected (p ~ 0.6), yet the
    estimates differ by 15 %: the data cannot tell whether the runs are equal."""
    result = shared_fit([_plitt_run(2.5, 1, 0.05, "a", count=6), _plitt_run(3.0, 2, 0.05, "b", count=6)], "plitt")
    assert not result.test.needed() and result.relative_difference > 0.1
    assert result.verdict() == "undecided"
    assert "the data cannot tell whether the experiments are equal" in result.conclusion()
    assert result.verdict(margin=0.2) == "equal within the margin"


def test_compare_command_takes_a_margin(tmp_path, capsys):
    import pandas as pd

    frame = pd.concat([_plitt_run(2.5, 1, 2e-4, "a").to_frame(), _plitt_run(2.52, 2, 2e-4, "b", d_cut=100.0).to_frame()])
    path = tmp_path / "close.csv"
    frame.to_csv(path, index=False)
    assert main(["compare", str(path)]) == 0
    assert "the experiments are equal within the margin in ks" in capsys.readouterr().out
    assert main(["compare", str(path), "--margin", "0.001"]) == 0
    assert "the experiments differ in ks" in capsys.readouterr().out
    assert main(["compare", str(path), "--margin", "1.5"]) == 2
    assert "--margin" in capsys.readouterr().err


def test_systematic_residuals_are_flagged_even_when_adequate():
    """Plitt fitted to a curve with a 25 % bypass passes F but misses the plateau systematically."""
    sizes = np.geomspace(5, 500, 20)
    points = TrompPoints("s", sizes, get_formula("plitt_bypass")(sizes, 80, 3.0, bypass=0.25))
    fit = fit_formula(points, "plitt")
    assert fit.screen.adequate
    assert fit.diagnostics.systematic
    assert any("residuals are systematic" in w for w in fit.warnings)


def test_equal_weights_change_nothing_and_feed_share_weights_are_used(tmp_path):
    rng = np.random.default_rng(5)
    phi = get_formula("lognormal")(SIZES, 90, 0.9) + rng.normal(0, 0.02, SIZES.size)
    plain = fit_formula(TrompPoints("p", SIZES, phi), "plitt")
    equal = fit_formula(TrompPoints("p", SIZES, phi, weight=np.full(SIZES.size, 7.0)), "plitt")
    assert_allclose([equal.d_cut, equal.screen.F, equal.fit.ssr], [plain.d_cut, plain.screen.F, plain.fit.ssr], rtol=1e-8)
    weighted = fit_formula(TrompPoints("p", SIZES, phi, weight=np.linspace(0.1, 3, SIZES.size)), "plitt")
    weights = np.linspace(0.1, 3, SIZES.size)
    weights /= weights.mean()
    mean = np.average(phi, weights=weights)
    assert_allclose(weighted.screen.s0_sq, np.sum(weights * (phi - mean) ** 2) / (SIZES.size - 1))
    from tromplab.loading.lab import LabOptions, read_experiments

    from .conftest import DATASETS

    points, _ = read_experiments(DATASETS / "double_deck_screen_decks_lab.csv", LabOptions(weight_by_feed_share=True))
    assert_allclose(points[0].weight.sum(), 1.0, atol=1e-3)
