"""Plot functions: take ax=None, return the Axes, draw what they say; nothing styled on import."""

import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from numpy.testing import assert_allclose  # noqa: E402

from tromplab import plotting, sieve  # noqa: E402
from tromplab.curves import fit_formula  # noqa: E402
from tromplab.formulas import FORMULAS, get_formula  # noqa: E402
from tromplab.points import TrompPoints  # noqa: E402
from tromplab.workbench import fit_experiments  # noqa: E402

SIZES = np.geomspace(10, 400, 10)


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def bench():
    rng = np.random.default_rng(0)
    runs = [TrompPoints(f"run{i}", SIZES, np.clip(get_formula("plitt")(SIZES, 80 + 20 * i, 2.5) + rng.normal(0, 0.02, 10), 0, 1))
            for i in range(2)]  # fmt: skip
    return fit_experiments(runs)


def test_importing_tromplab_styles_and_plots_nothing():
    code = "import sys, tromplab, tromplab.plotting, tromplab.report, tromplab.cli; print('matplotlib.pyplot' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "False"


def test_tromp_fits_draws_every_formula_and_the_band(bench):
    fits = bench.fits_of("run0")
    ax = plotting.plot_tromp_fits(fits)
    labels = [line.get_label() for line in ax.get_lines()]
    assert sum(label.startswith("(") for label in labels) == len(FORMULAS)
    assert "measured" in labels
    assert len(ax.collections) == 1  # the band of the best fit
    assert ax.get_xscale() == "log"
    _, axes = plt.subplots()
    assert plotting.plot_tromp_fits(fits, ax=axes, log_size=False, band=False) is axes and axes.get_xscale() == "linear"
    chosen = bench.best_fit("run0")
    other = next(f for f in fits if f is not chosen)
    widths = {line.get_label().split(",")[0]: line.get_linewidth() for line in plotting.plot_tromp_fits(fits, best=other).get_lines()}
    assert widths[f"({other.formula.equation}) {other.formula.id}"] > widths[f"({chosen.formula.equation}) {chosen.formula.id}"]


def test_inadequate_fits_are_dashed():
    points = TrompPoints("x", SIZES[:5], [0.9, 0.2, 0.8, 0.1, 0.0])
    fits = [fit_formula(points, f) for f in FORMULAS[:3]]
    ax = plotting.plot_tromp_fits(fits, band=False)
    styles = {line.get_label(): line.get_linestyle() for line in ax.get_lines()}
    assert any("inadequate" in label and style == "--" for label, style in styles.items())


def test_curve_band_contains_the_fit_and_narrows_with_less_noise():
    rng = np.random.default_rng(1)
    noisy = fit_formula(TrompPoints("n", SIZES, get_formula("plitt")(SIZES, 80, 2.5) + rng.normal(0, 0.03, 10)), "plitt")
    quiet = fit_formula(TrompPoints("q", SIZES, get_formula("plitt")(SIZES, 80, 2.5) + rng.normal(0, 0.003, 10)), "plitt")
    grid = np.geomspace(20, 300, 30)
    low, high = plotting.curve_band(noisy, grid)
    assert np.all(low <= noisy.predict(grid) + 1e-12) and np.all(noisy.predict(grid) <= high + 1e-12)
    quiet_low, quiet_high = plotting.curve_band(quiet, grid)
    assert np.mean(quiet_high - quiet_low) < 0.3 * np.mean(high - low)


def test_residuals_heatmap_and_ranking(bench):
    ax = plotting.plot_residuals(bench.fits_of("run1"))
    first = ax.get_lines()[0]
    fit = bench.fits_of("run1")[0]
    assert_allclose(first.get_ydata(), fit.points.partition_fine - fit.predict(fit.points.size))
    table = bench.fits_table()
    heat = plotting.plot_f_heatmap(table)
    texts = [t.get_text() for t in heat.texts]
    assert len(texts) == 18 and all(t.rstrip("*") for t in texts)
    assert "F_crit" in heat.get_xticklabels()[0].get_text()
    bars = plotting.plot_ranking(bench.ranking_table())
    assert len(bars.patches) == 9


def test_equal_slope_families_and_the_ks_kf_relation():
    ax = plotting.plot_equal_slope_family(-0.4)
    hoffmann = next(line for line in ax.get_lines() if "molerus_hoffmann" in line.get_label())
    y = hoffmann.get_ydata()
    assert y[-1] > y.min() + 0.03  # (4) rises again at slope -0.4 (Fig. 2)
    relation = plotting.plot_plitt_lognormal_relation()
    corrected, printed = relation.get_lines()
    assert_allclose(corrected.get_ydata()[[0, -1]], [2.2568, 0.7523], atol=1e-3)  # ks 1..3 <-> kf 2.25..0.75
    assert not np.allclose(printed.get_ydata(), corrected.get_ydata())


def test_sieve_figures():
    curves = sieve.geometric_probability_curves(2.0, 1.6, [0.5, 1.0], np.linspace(0.8, 2.0, 5))
    assert len(plotting.plot_geometric_probability(curves).get_lines()) == 2
    speeds = np.linspace(0.1, 0.5, 20)
    ax = plotting.plot_residue_and_efficiency(speeds, [speeds, speeds**2], 100 * speeds)
    assert len(ax.get_lines()) == 2
    design = sieve.design_bin(12, 1.6, 0.9)
    ax = plotting.plot_distance_densities(12, [30, design.c, 7], bin_edges=(design.x1, design.x2))
    assert len(ax.get_lines()) == 3 and len(ax.patches) == 1
