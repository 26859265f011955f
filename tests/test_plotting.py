"""Plot functions: take ax=None, return the Axes, draw what they say; nothing styled on import."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from numpy.testing import assert_allclose  # noqa: E402

from tromplab.classifiers import sieve  # noqa: E402
from tromplab.curves.curve_fit import fit_formula  # noqa: E402
from tromplab.curves.formulas import FORMULAS, get_formula, select_formulas  # noqa: E402
from tromplab.loading.points import TrompPoints  # noqa: E402
from tromplab.output import plotting
from tromplab.workbench import fit_experiments  # noqa: E402

SIZES = np.geomspace(10, 400, 10)


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def bench():
    rng = np.random.default_rng(0)
    runs = [
        TrompPoints(f"run{i}", SIZES, np.clip(get_formula("plitt")(SIZES, 80 + 20 * i, 2.5) + rng.normal(0, 0.02, 10), 0, 1))
        for i in range(2)
    ]
    return fit_experiments(runs)


@pytest.mark.slow
def test_importing_tromplab_styles_and_plots_nothing():
    code = "import sys, tromplab, tromplab.output.plotting, tromplab.output.report, tromplab.cli; print('matplotlib.pyplot' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "False"


@pytest.mark.slow
def test_no_library_module_chooses_a_backend_or_a_style():
    # matplotlib.use, pyplot.switch_backend, style.use: the caller's choice (scripts, notebooks, tests)
    package = Path(plotting.__file__).resolve().parents[1]
    calls = [
        f"{path.relative_to(package)}:{node.lineno}"
        for path in sorted(package.rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in ("use", "switch_backend")
    ]
    assert calls == []


@pytest.mark.slow
def test_the_command_draws_with_agg_whatever_backend_is_configured(tmp_path):
    """The command's figures are pyplot-free Figures saved by Agg's PNG printer: no backend is
    loaded, so one that cannot load (a GUI backend on a server) does not matter."""
    points = tmp_path / "points.csv"
    rows = [f"E{k},{size:.3f},{value:.4f}" for k in range(2) for size, value in zip(SIZES, np.linspace(0.98, 0.03, 10))]
    points.write_text("experiment,size,partition_fine\n" + "\n".join(rows) + "\n", encoding="utf-8")
    code = (
        "import sys\nfrom tromplab.cli import main\n"
        f"code = main(['fit', {str(points)!r}, '-o', {str(tmp_path / 'out')!r}, '--figures', 'all'])\n"
        "print(code, 'matplotlib.pyplot' in sys.modules, 'matplotlib.backends.backend_agg' in sys.modules)\n"
    )
    env = {**os.environ, "MPLBACKEND": "module://no_such_backend"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert done.stdout.splitlines()[-1] == "0 False True", done.stderr
    figures = sorted((tmp_path / "out").glob("*.png"))
    assert [figure.name for figure in figures] == ["curves_E0.png", "curves_E1.png"]
    assert all(figure.read_bytes().startswith(b"\x89PNG") for figure in figures)


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
    widths = {
        line.get_label().split(",")[0]: line.get_linewidth() for line in plotting.plot_tromp_fits(fits, best=other).get_lines()
    }
    assert widths[f"({other.formula.equation}) {other.formula.id}"] > widths[f"({chosen.formula.equation}) {chosen.formula.id}"]


def test_inadequate_fits_are_faded_and_labelled():
    points = TrompPoints("x", SIZES[:5], [0.9, 0.2, 0.8, 0.1, 0.0])
    fits = [fit_formula(points, f) for f in FORMULAS[:3]]
    ax = plotting.plot_tromp_fits(fits, band=False)
    alphas = {line.get_label(): line.get_alpha() for line in ax.get_lines() if line.get_label().startswith("(")}
    assert any("inadequate" in label for label in alphas)
    assert all((alpha < 1) == ("inadequate" in label) for label, alpha in alphas.items())


def test_twelve_curves_get_distinct_colours_and_neighbouring_curves_distinct_line_styles():
    from matplotlib.colors import to_rgb

    rng = np.random.default_rng(3)
    points = TrompPoints("many", SIZES, np.clip(get_formula("plitt")(SIZES, 80, 2.5) + rng.normal(0, 0.02, 10), 0, 1))
    fits = [fit_formula(points, formula) for formula in select_formulas("paper,extended")]  # the nine and three extended
    assert len(fits) == 12
    ax = plotting.plot_tromp_fits(fits, band=False)
    curves = [line for line in ax.get_lines() if line.get_label().startswith("(")]
    assert len(curves) == 12
    colours = np.array([to_rgb(line.get_color()) for line in curves])
    distances = np.linalg.norm(colours[:, None] - colours[None], axis=-1)[np.triu_indices(12, 1)]
    assert distances.min() > 0.25  # every pair of curves told apart by colour (tab10 itself: 0.265)
    styles = [line.get_linestyle() for line in curves]
    assert all(a != b for a, b in zip(styles, styles[1:]))


def _tick_label_boxes(ax):
    figure = ax.figure
    figure.canvas.draw()  # the Agg renderer lays the labels out
    renderer = figure.canvas.get_renderer()
    low, high = ax.get_xlim()
    labels = [
        label
        for label in ax.get_xticklabels(which="both")
        if label.get_visible() and label.get_text() and low <= label.get_position()[0] <= high
    ]
    return [label.get_window_extent(renderer) for label in labels]


@pytest.mark.parametrize(
    "low, high", [(0.05, 5.0), (10.0, 320.0), (0.074, 4.7), (30.0, 45.0), (1.0, 1e5), (0.9, 1.3), (2e-3, 40.0)]
)
@pytest.mark.slow
def test_log_size_tick_labels_do_not_collide(low, high):
    sizes = np.geomspace(low, high, 8)
    points = TrompPoints("ticks", sizes, np.linspace(0.95, 0.05, 8))
    fits = [fit_formula(points, f) for f in ("plitt", "lognormal")]
    for ax in (plotting.plot_tromp_fits(fits, band=False), plotting.plot_residuals(fits)):
        boxes = _tick_label_boxes(ax)
        assert len(boxes) >= 2, "at least two labelled sizes"
        boxes.sort(key=lambda box: box.x0)
        for left, right in zip(boxes, boxes[1:]):
            assert left.x1 < right.x0, f"tick labels overlap on {low}..{high}"


def test_partition_to_coarse_draws_one_minus_phi(bench):
    fits = bench.fits_of("run0")
    fine = plotting.plot_tromp_fits(fits, band=False)
    coarse = plotting.plot_tromp_fits(fits, band=False, partition_to="coarse")
    measured = {ax: next(line for line in ax.get_lines() if line.get_label() == "measured") for ax in (fine, coarse)}
    assert_allclose(measured[coarse].get_ydata(), 1 - measured[fine].get_ydata())
    assert_allclose(coarse.get_lines()[0].get_ydata(), 1 - fine.get_lines()[0].get_ydata())
    assert coarse.get_ylabel() == "partition to coarse product"
    residual_fine = plotting.plot_residuals(fits)
    residual_coarse = plotting.plot_residuals(fits, partition_to="coarse")
    assert_allclose(residual_coarse.get_lines()[0].get_ydata(), -residual_fine.get_lines()[0].get_ydata(), atol=1e-12)
    with pytest.raises(ValueError, match="partition_to"):
        plotting.plot_tromp_fits(fits, partition_to="underflow")


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


def test_f_heatmap_of_a_wide_batch_labels_the_columns_seaborn_kept():
    # 45 experiments: seaborn labels every other column, and the F_crit labels must follow it
    # (a label per experiment raised "number of FixedLocator locations does not match")
    from tromplab._synthetic import synthetic

    bench = fit_experiments([synthetic(seed) for seed in range(45)], formulas=["plitt", "lognormal"])
    ax = plotting.plot_f_heatmap(bench.fits_table())
    ticks, labels = ax.get_xticks(), [label.get_text() for label in ax.get_xticklabels()]
    assert 1 < len(ticks) == len(labels) < 45
    for tick, label in zip(ticks, labels):
        assert label.startswith(f"s{int(tick)}\nF_crit ")
