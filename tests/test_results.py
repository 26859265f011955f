"""Result objects you can read: reprs, summaries, reports, batch views, saving and loading."""

import json
import pickle
import re

import matplotlib
import numpy as np
import pandas as pd
import pytest

import tromplab
from tromplab.curves.curve_fit import FIT_COLUMNS
from tromplab.errors import InputError
from tromplab.loading.points import TrompPoints
from tromplab.statistics.uncertainty import AVERAGED_QUANTITIES

matplotlib.use("Agg")

SIZES = np.array([1.0, 2, 4, 8, 16, 32, 64])


def _points(name, d_cut, ks, noise, seed):
    rng = np.random.default_rng(seed)
    phi = 1 / (1 + (SIZES / d_cut) ** ks) + rng.normal(0, noise, SIZES.size)
    return TrompPoints(name, SIZES, np.clip(phi, 0, 1), source="synthetic")


@pytest.fixture(scope="module")
def bench():
    experiments = [_points("run1", 8.0, 2.5, 0.01, 1), _points("run2", 12.0, 1.8, 0.01, 2)]
    return tromplab.fit_experiments(experiments, formulas=["plitt", "lognormal", "rosin_rammler"])


def test_fit_repr_is_one_short_line_with_the_numbers(bench):
    fit = bench.fits[0]
    text = repr(fit)
    assert "\n" not in text and len(text) < 200
    assert text.startswith("<CurveFit plitt (7) on 'run1': ")
    assert f"d_cut={fit.d_cut:.4g}" in text and f"ks={fit.shape:.4g}" in text
    assert ("(adequate)" in text) == fit.screen.adequate
    assert "<table>" in fit._repr_html_() and f"{fit.d_cut:.5g}" in fit._repr_html_()


def test_fit_summary_is_the_fits_table_row(bench):
    fit = bench.fits[1]
    summary = fit.summary()
    assert list(summary.columns) == [c for c in FIT_COLUMNS if c != "rank"]
    row = bench.fits_table().iloc[1]
    for column in ("d_cut", "shape", "F", "eta", "ep", "aicc"):
        assert summary.loc[0, column] == pytest.approx(row[column])


def test_fit_report_holds_parameters_screen_indices_diagnostics_and_warnings(bench):
    fit = bench.fits[0]
    text = fit.report(profile=False)
    for section in ("[[Fit]]", "[[Parameters]]", "[[Fisher screen]]", "[[Indices]]", "[[Diagnostics]]", "[[Warnings]]"):
        assert section in text
    table = tromplab.interval_table(fit, profile=False).set_index("quantity")
    d_cut_line = next(line for line in text.splitlines() if line.strip().startswith("d_cut"))
    numbers = [float(v) for v in re.findall(r"-?\d+\.?\d*(?:e[-+]?\d+)?", d_cut_line.split("=", 1)[1])]
    np.testing.assert_allclose(numbers[:4], table.loc["d_cut", ["value", "stderr", "low", "high"]].astype(float), rtol=1e-4)
    assert f"F_crit = {fit.screen.F_crit:.5g}" in text
    assert f"= {fit.indices.ep:.5g}".replace(" ", "") in text.replace(" ", "")


def test_failed_fit_still_reads():
    from tromplab.curves.curve_fit import CurveFit
    from tromplab.curves.fitting import ParameterFit

    points = TrompPoints("flat", [1.0, 2.0, 3.0], [0.5, 0.5, 0.5])
    formula = tromplab.get_formula("plitt")
    fit = CurveFit(formula, points, ParameterFit.failed(formula.parameters(points.size), 3, "fit failed from every start: x"))
    assert repr(fit) == "<CurveFit plitt (7) on 'flat': failed: fit failed from every start: x>"
    assert "success = False: fit failed from every start: x" in fit.report()
    assert fit.summary().loc[0, "success"] == False  # noqa: E712


@pytest.mark.slow
def test_workbench_views(bench, tmp_path):
    text = repr(bench)
    assert len(text) < 400 and "2 experiments x 3 formulas, 6 fits" in text
    assert bench._repr_html_().count("<tr") == len(bench.ranking_table()) + 1  # header + one row per formula
    assert not hasattr(bench, "ranking")  # ranking_table only
    summary = bench.summary()  # one row per experiment, its top-ranked fit
    assert list(summary["experiment"]) == ["run1", "run2"] and list(summary["formula"]) == ["plitt", "lognormal"]
    averages = bench.averages()
    assert set(averages["experiment"]) == {"run1", "run2"} and set(averages["quantity"]) == set(AVERAGED_QUANTITIES)
    ax = bench.plot("run2")
    assert ax.get_title().endswith("run2") and len(ax.lines) >= 4  # three curves, the points, the cut marker
    with pytest.raises(KeyError, match="no experiment 'run3'"):
        bench.plot("run3")
    written = bench.write_report(tmp_path / "report.html")
    html = written["report.html"].read_text()
    assert "run1" in html and "synthetic" in html and "<img" in html


def test_save_and_load_round_trip(bench, tmp_path):
    bench.save(tmp_path / "batch", reloadable=True)
    loaded = tromplab.load(tmp_path / "batch")
    pd.testing.assert_frame_equal(loaded.fits_table(), bench.fits_table())
    pd.testing.assert_frame_equal(loaded.ranking_table(), bench.ranking_table())
    assert (loaded.alpha, loaded.rank_by, [f.id for f in loaded.formulas]) == (
        bench.alpha,
        bench.rank_by,
        [f.id for f in bench.formulas],
    )
    saved_points = pd.read_csv(tmp_path / "batch" / "points.csv")
    assert list(saved_points["experiment"].unique()) == ["run1", "run2"]
    np.testing.assert_array_equal(
        saved_points.loc[saved_points.experiment == "run1", "partition_fine"], bench.fits[0].points.partition_fine
    )
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "batch" / "ranking.csv"), bench.ranking_table(), check_dtype=False)
    again = pickle.loads(pickle.dumps(loaded))
    pd.testing.assert_frame_equal(again.fits_table(), bench.fits_table())


def test_load_refuses_another_major_version_and_missing_files(bench, tmp_path):
    bench.save(tmp_path / "batch", reloadable=True)
    manifest = json.loads((tmp_path / "batch" / "manifest.json").read_text())
    manifest["tromplab_version"] = "9.0.0"
    (tmp_path / "batch" / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(InputError, match=r"saved by tromplab 9\.0\.0, this is tromplab .*major versions differ"):
        tromplab.load(tmp_path / "batch")
    with pytest.raises(InputError, match="not a saved tromplab batch"):
        tromplab.load(tmp_path)


def test_the_python_page_lists_the_public_api_and_help_does_too():
    from .conftest import ROOT

    section = (ROOT / "docs" / "python.md").read_text()
    listed = re.findall(r"^- `([\w]+)`: ", section, flags=re.MULTILINE)
    assert listed == list(tromplab.__all__)
    for name in tromplab.__all__:
        assert hasattr(tromplab, name)
        assert f"- ``{name}``: " in tromplab.__doc__
        line = next(line for line in tromplab.__doc__.splitlines() if line.startswith(f"- ``{name}``: "))
        assert len(line.split(": ", 1)[1]) > 10, f"{name} has no one-line summary"


@pytest.mark.slow
def test_readme_five_lines_run(tmp_path, monkeypatch):
    from .conftest import ROOT

    readme = (ROOT / "README.md").read_text()
    code = readme.split("## Python\n", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    assert len(code.strip().splitlines()) == 5
    monkeypatch.chdir(tmp_path)
    code = code.replace('"datasets/', f'"{ROOT}/datasets/')
    namespace = {}
    exec(compile(code, "README", "exec"), namespace)  # noqa: S102 - the README's own example
    assert (tmp_path / "report.html").exists()
    assert list(namespace["bench"].ranking_table()["place"])[0] == 1
