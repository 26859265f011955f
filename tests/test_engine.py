"""The batched engine reaches the single fit's optimum; workers, Dask and the CLI's scale options."""

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab import workbench
from tromplab._synthetic import synthetic
from tromplab.cli import main
from tromplab.curves import engine
from tromplab.curves.curve_fit import fit_formula
from tromplab.curves.engine import check_bootstrap_request, fit_formula_batch, refit_resamples
from tromplab.curves.formulas import ALL_FORMULAS, FORMULAS, get_formula, is_batchable, shuvalov_break, shuvalov_breaks
from tromplab.loading.points import TrompPoints
from tromplab.parallel import fanout
from tromplab.workbench import fit_experiments, worker

BATCHABLE = [f for f in ALL_FORMULAS if is_batchable(f)]


EXPERIMENTS = [synthetic(seed) for seed in range(18)]  # two curves of each of the nine formulas


def test_every_formula_is_batched_except_curves_with_two_extras():
    assert {f.id for f in ALL_FORMULAS if not is_batchable(f)} == {f.id for f in ALL_FORMULAS if len(f.extras) >= 2}
    assert all(is_batchable(f) for f in FORMULAS)


@pytest.mark.slow
@pytest.mark.parametrize("formula", BATCHABLE, ids=[f.id for f in BATCHABLE])
def test_batched_optimum_is_at_least_the_single_fit_optimum(formula):
    batch = fit_formula_batch(EXPERIMENTS, formula)
    for batched, points in zip(batch, EXPERIMENTS):
        single = fit_formula(points, formula)
        assert batched.success and single.success
        assert batched.fit.ssr <= single.fit.ssr * (1 + 1e-8) + 1e-14, points.experiment
        if batched.fit.ssr >= single.fit.ssr * (1 - 1e-6):  # same optimum: same parameters and errors
            for name in batched.fit.names:
                assert_allclose(batched.fit.values[name], single.fit.values[name], rtol=2e-3, atol=1e-6, err_msg=name)
            assert_allclose(batched.indices.eta, single.indices.eta, rtol=1e-3)
            if np.isfinite(single.fit.stderr["d_cut"]) and not single.fit.at_bound:
                assert_allclose(batched.fit.stderr["d_cut"], single.fit.stderr["d_cut"], rtol=0.05)
        kinds = [[w.split(" ")[0] for w in fit.warnings] for fit in (batched, single)]  # the same checks fire
        assert kinds[0] == kinds[1] or batched.fit.ssr < single.fit.ssr * (1 - 1e-6)


def test_the_fit_of_11_never_compares_structured_arrays(monkeypatch):
    # numpy promotes structured dtypes in Python code and turns an exception raised there (a
    # Ctrl-C landing in it) into "TypeError: Cannot compare structured arrays": seen as exit 70
    # instead of 130 when a run was interrupted during the fits of (11)
    import numpy._core._internal as numpy_internal

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(numpy_internal, "_promote_fields", interrupted)
    fits = fit_formula_batch(EXPERIMENTS[:4], get_formula("shuvalov"))
    assert all(fit.success for fit in fits)


@pytest.mark.parametrize("formula_id", ["luckie_austin", "shuvalov"])
def test_piecewise_optimum_is_not_above_a_dense_search(formula_id):
    # (10) and (11) have kinks; the reference is a dense grid in (ln d_cut, shape), not the single fit
    formula = get_formula(formula_id)
    points = [synthetic(seed) for seed in (7, 8, 16, 17)]
    for fit in fit_formula_batch(points, formula):
        shapes = np.geomspace(*formula.shape_bounds, 300)
        cuts = np.exp(np.linspace(np.log(fit.points.size[0] / 2), np.log(fit.points.size[-1] * 2), 300))
        best = np.inf
        for shape in shapes[::3]:  # every cut at once per shape (x broadcast over cuts x sizes)
            curves = formula.phi(fit.points.size[None, :] / cuts[::3, None], shape, **fit.context)
            best = min(best, float(np.min(np.sum((curves - fit.points.partition_fine) ** 2, axis=1))))
        assert fit.fit.ssr <= best * (1 + 1e-9)


@pytest.mark.parametrize("kr", [0.1, 0.7, 2.0, 5.0, 30.0])
def test_vectorised_break_points_match_the_scalar_solver(kr):
    for efficiency in (0.45, 0.5, 0.6, 0.75, 0.9, 0.99):
        try:
            expected = shuvalov_break(kr, efficiency)
        except ValueError:  # no break point: the nearer end
            expected = 1.0 if efficiency < 0.5 else 0.0
        assert_allclose(shuvalov_breaks(kr, efficiency), expected, atol=1e-12)


def test_vectorised_break_points_solve_their_equation_to_rounding():
    """x_a phi_5(x_a) + int_{x_a}^1 phi_5 = eta_exp within a few units of rounding over the whole
    shape range, also where the left side is flat (x_a near 0), where steps in x_a stalled."""
    from tromplab.curves.formulas import rosin_rammler, rosin_rammler_area

    kr, efficiency = (grid.ravel() for grid in np.meshgrid(np.geomspace(0.05, 40.0, 60), np.linspace(0.5, 0.999, 60)))
    x_a = shuvalov_breaks(kr, efficiency)
    solvable = efficiency < rosin_rammler_area(0.0, 1.0, kr)
    left = x_a * rosin_rammler(x_a, kr) + rosin_rammler_area(x_a, 1.0, kr)
    assert solvable.sum() > 1000
    assert np.all((x_a >= 0.0) & (x_a <= 1.0))
    assert np.abs(left - efficiency)[solvable].max() < 5e-15
    assert np.all(x_a[~solvable] == 0.0)


def test_engine_fit_becomes_an_lmfit_result_with_the_same_optimum():
    fit = fit_formula_batch(EXPERIMENTS[:1], "plitt")[0]
    assert fit.fit.raw is None
    polished = fit.with_lmfit()
    assert polished.fit.raw is not None and polished.fit.minimizer is not None
    assert_allclose(polished.fit.ssr, fit.fit.ssr, rtol=1e-8)
    assert_allclose(polished.fit.values["d_cut"], fit.d_cut, rtol=1e-4)


def test_too_few_points_give_a_failed_fit_and_the_batch_goes_on():
    short = TrompPoints("short", [10.0, 20.0], [0.8, 0.2])
    fits = fit_formula_batch([short, EXPERIMENTS[1]], "plitt_bypass")
    assert not fits[0].success and "3 parameters" in fits[0].message
    assert fits[1].success


def test_batched_bootstrap_refits_match_single_refits():
    fit = fit_formula(EXPERIMENTS[4], "lognormal")
    rng = np.random.default_rng(1)
    samples = [
        TrompPoints("b", fit.points.size, np.clip(fit.predict(fit.points.size) + rng.normal(0, 0.02, fit.points.n), 0, 1))
        for _ in range(12)
    ]
    batched = refit_resamples(fit, samples)
    for refit, sample in zip(batched, samples):
        single = fit_formula(sample, fit.formula, global_search=False, starts=[dict(fit.fit.values)])
        assert refit.fit.ssr <= single.fit.ssr * (1 + 1e-8) + 1e-14
        assert_allclose(refit.d_cut, single.d_cut, rtol=1e-4)
        assert_allclose(refit.indices.ep, single.indices.ep, rtol=1e-3)


def test_absurd_bootstrap_is_refused_before_work():
    assert check_bootstrap_request(1000, n_fits=9) < 60
    with pytest.raises(ValueError, match="more than the 100,000 resamples"):
        check_bootstrap_request(10_000_000, n_fits=1)
    with pytest.raises(ValueError, match="refits"):
        check_bootstrap_request(50_000, n_fits=9 * 1000)


def _write(tmp_path, experiments):
    path = tmp_path / "points.csv"
    frames = [p.to_frame() for p in experiments]
    pd.concat([f if "weight" in f else f.assign(weight=1.0) for f in frames]).to_csv(path, index=False)
    return path


@pytest.mark.slow
def test_output_is_byte_identical_whatever_the_number_of_workers(tmp_path, monkeypatch):
    monkeypatch.setattr(fanout, "CHUNK_SIZE", 4)  # several chunks from a small batch
    path = _write(tmp_path, EXPERIMENTS[:10])
    outputs = {}
    for jobs in (1, 2):
        out = tmp_path / f"jobs{jobs}"
        assert main(["fit", str(path), "-o", str(out), "--jobs", str(jobs), "--no-figures", "--formulas", "plitt,11"]) == 0
        outputs[jobs] = {name: (out / name).read_bytes() for name in ("fits.csv", "ranking.csv", "averages.csv")}
    assert outputs[1] == outputs[2]


def test_data_notes_come_back_from_the_workers_in_batch_order(monkeypatch):
    from tromplab.workbench import data_notes

    monkeypatch.setattr(fanout, "CHUNK_SIZE", 2)
    sizes = [10.0, 20.0, 40.0, 80.0, 160.0]
    rising = TrompPoints("rising", sizes, [0.05, 0.2, 0.6, 0.9, 0.97])
    above = TrompPoints("above", sizes, [0.99, 0.95, 0.85, 0.7, 0.6])
    batch = [EXPERIMENTS[0], rising, EXPERIMENTS[1], above, EXPERIMENTS[2]]
    expected = {p.experiment: data_notes(p) for p in batch if data_notes(p)}
    assert list(expected) == ["rising", "above"]
    for jobs in (1, 2):
        notes = fit_experiments(batch, formulas=["plitt"], jobs=jobs).notes
        assert notes == expected and list(notes) == list(expected)


def test_engine_and_single_fits_give_the_same_table():
    batched = fit_experiments(EXPERIMENTS[:6], formulas=["plitt", "luckie_austin"]).fits_table()
    single = fit_experiments(EXPERIMENTS[:6], formulas=["plitt", "luckie_austin"], single_fits=True).fits_table()
    assert list(batched["experiment"]) == list(single["experiment"])
    assert (batched["rank"].to_numpy() == single["rank"].to_numpy()).all()
    assert_allclose(batched["ssr"], single["ssr"], rtol=1e-6)
    assert_allclose(batched["d_cut"], single["d_cut"], rtol=1e-3)


def test_a_failing_engine_is_logged_and_falls_back_to_single_fits(monkeypatch, caplog):
    def broken_engine(*args, **kwargs):
        raise FloatingPointError("overflow in the Jacobian")

    monkeypatch.setattr(worker, "fit_formula_batch", broken_engine)
    with caplog.at_level("WARNING", logger="tromplab.workbench"):
        fits = fit_experiments(EXPERIMENTS[:3], formulas=["plitt", "luckie_austin"]).fits
    failures = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(failures) == 2
    assert "formula plitt for 3 experiment(s)" in failures[0] and "formula luckie_austin" in failures[1]
    assert all("FloatingPointError: overflow in the Jacobian" in message for message in failures)
    single = fit_experiments(EXPERIMENTS[:3], formulas=["plitt", "luckie_austin"], single_fits=True).fits
    assert all(fit.success for fit in fits) and len(fits) == 6
    for fit, expected in zip(fits, single):
        assert (fit.experiment, fit.formula.id) == (expected.experiment, expected.formula.id)
        assert fit.fit.ssr == expected.fit.ssr  # the same lmfit single fit, not the engine


@pytest.mark.slow
def test_dask_cluster_gives_the_serial_results(monkeypatch):
    distributed = pytest.importorskip("dask.distributed")
    dd = pytest.importorskip("dask.dataframe")
    monkeypatch.setattr(fanout, "CHUNK_SIZE", 3)
    experiments = EXPERIMENTS[:7]
    serial = fit_experiments(experiments, formulas=["plitt", "rosin_rammler"]).fits_table()
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            on_dask = fit_experiments(experiments, formulas=["plitt", "rosin_rammler"], client=client).fits_table()
    pd.testing.assert_frame_equal(on_dask, serial)
    frames = [p.to_frame() for p in experiments]
    frames = [f if "weight" in f else f.assign(weight=1.0) for f in frames]
    frame = dd.from_pandas(pd.concat(frames, ignore_index=True), npartitions=3)
    from_dask_frame = fit_experiments(frame, formulas=["plitt", "rosin_rammler"]).fits_table()
    pd.testing.assert_frame_equal(from_dask_frame.drop(columns="message"), serial.drop(columns="message"))


@pytest.mark.slow
def test_large_batches_get_one_overview_figure_and_parquet_tables(tmp_path):
    pytest.importorskip("pyarrow")
    experiments = [synthetic(seed) for seed in range(23)]  # more than the per-experiment figure limit
    path = _write(tmp_path, experiments)
    out = tmp_path / "out"
    assert main(["fit", str(path), "-o", str(out), "--formulas", "plitt", "--format", "parquet", "--jobs", "1"]) == 0
    assert (out / "overview.png").exists() and not list(out.glob("curves_*.png"))
    table = pd.read_parquet(out / "fits.parquet")
    assert len(table) == 23 and set(table["experiment"]) == {p.experiment for p in experiments}
    out_best = tmp_path / "best"
    few = _write(tmp_path, experiments[:3])
    assert main(["fit", str(few), "-o", str(out_best), "--formulas", "plitt,9", "--figures", "best", "--jobs", "1"]) == 0
    assert len(list(out_best.glob("curves_*.png"))) == 3


def test_cli_refuses_an_absurd_bootstrap_before_fitting(tmp_path, capsys):
    path = _write(tmp_path, EXPERIMENTS[:1])
    assert (
        main(["fit", str(path), "-o", str(tmp_path / "o"), "--bootstrap", "10000000"]) == 2
    )  # usage: the parser refuses the count
    assert "100,000 resamples" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_11_finds_its_optimum_where_a_point_crosses_the_break():
    # a three-class step table (found by the lab-table scaling invariant): the optimum of (11)
    # sits where the finest point crosses the break, a ridge of kinks; before the search along
    # crossings the fits stopped up to 1 % above it, differently in each size unit
    from scipy.optimize import minimize_scalar

    from tromplab import read_experiments
    from tromplab.curves.measured import formula_context

    third = 100.0 / 3.0
    frame = pd.DataFrame(
        {
            "experiment": "step",
            "size_lower": [1.5e-6, 1e-6, np.nan],
            "size_upper": [np.nan, 1.5e-6, 1e-6],
            "feed_pct": [third, third, third],
            "fine_pct": [0.0, 0.0, 100.0],
            "coarse_pct": [400.0 / 9.0, 400.0 / 9.0, 100.0 / 9.0],
        }
    )
    formula = get_formula("shuvalov")
    found = []
    for scale in (1.0, 1e-3, 1e3):
        points = read_experiments(frame.assign(size_lower=frame["size_lower"] * scale, size_upper=frame["size_upper"] * scale))[0]
        (fit,) = fit_formula_batch(points, formula)
        found.append((fit.fit.values["d_cut"] / scale, fit.fit.ssr))
    points = read_experiments(frame)[0][0]
    efficiency = formula_context(formula, points)["measured_efficiency"]

    def on_crossing(kr):  # the finest point on the break: d_cut = size / x_a(kr); scalar root finding
        d_cut = points.size[0] / shuvalov_break(kr, efficiency)
        return float(np.sum((formula.phi(points.size / d_cut, kr, measured_efficiency=efficiency) - points.partition_fine) ** 2))

    independent = minimize_scalar(on_crossing, bounds=(5.0, 10.0), method="bounded", options={"xatol": 1e-10}).fun
    for d_cut, ssr in found:
        assert ssr <= independent * (1 + 1e-7)
        assert_allclose((d_cut, ssr), found[0], rtol=1e-6)


@pytest.mark.slow
def test_the_numbers_do_not_depend_on_how_the_batch_is_cut(monkeypatch):
    """Chunks of experiments with different numbers of points are padded to one width, so
    the fits and the profile intervals are the same bit for bit however the batch is cut
    (numpy's sums move in their last bits when a row gets more padding)."""
    experiments = [synthetic(seed) for seed in range(6)]
    experiments += [TrompPoints(f"short{seed}", p.size[:6], p.partition_fine[:6]) for seed, p in enumerate(experiments[:4])]
    assert len({p.n for p in experiments}) > 1
    options = {"formulas": ["plitt", "rosin_rammler", "11"], "ci": 0.9}
    whole = fit_experiments(experiments, **options)
    monkeypatch.setattr(fanout, "CHUNK_SIZE", 1)
    monkeypatch.setattr(fanout, "MAX_CHUNK_SIZE", 3)  # short ones alone in some chunks
    assert len(workbench.chunked(experiments, workers=1)) == 4
    cut = fit_experiments(experiments, **options)
    assert cut.fits_table().to_csv(index=False) == whole.fits_table().to_csv(index=False)
    assert cut.intervals.to_csv(index=False) == whole.intervals.to_csv(index=False)


def test_units_of_work_are_two_per_worker_within_their_limits():
    items = list(range(5000))
    sizes = lambda workers: [len(chunk) for chunk in workbench.chunked(items, workers=workers)]  # noqa: E731
    largest = workbench.MAX_CHUNK_SIZE
    assert sizes(1) == [1000] * 5  # as few units as the largest allows, of equal size
    assert max(sizes(1)) <= largest and sizes(2) == [834] * 5 + [5000 - 5 * 834]  # 6 units: 3 for each worker
    assert sizes(8) == [313] * 15 + [5000 - 15 * 313]  # 5,000 / 16, below the largest unit
    assert [len(c) for c in workbench.chunked(items[:1024], workers=2)] == [256] * 4
    assert [len(c) for c in workbench.chunked(items[:100], workers=2)] == [64, 36]  # never below CHUNK_SIZE
    assert sum(workbench.chunked(items[:777], workers=3), []) == items[:777]  # in order, nothing lost
    assert workbench.chunked([], workers=2) == []


def test_formula_11_reaches_the_basin_next_to_its_grid_starts(monkeypatch):
    """Synthetic experiment s7500: the points crossing (11)'s break cut the sum of squares into
    basins a few per cent wide in kr; the optimum (kr 2.30) lies in one that no start of the
    41-shape grid falls into (they end at kr 2.22 or 2.47, 1.4 % higher). The scan of shapes
    around the optimum (engine.scan_shapes_nearby) finds it, as a grid of 161 shapes does."""
    experiment = synthetic(7500, weighted=False)
    found = fit_formula_batch([experiment], "shuvalov")[0]
    monkeypatch.setattr(engine, "PIECEWISE_GRID_SLOPES", -np.geomspace(0.02, 20.0, 161))
    dense = fit_formula_batch([experiment], "shuvalov")[0]
    monkeypatch.setattr(engine, "scan_shapes_nearby", lambda problem, params, ssr, rows: (params, ssr, np.zeros(rows.size, int)))
    monkeypatch.setattr(engine, "PIECEWISE_GRID_SLOPES", -np.geomspace(0.02, 20.0, 41))
    without_scan = fit_formula_batch([experiment], "shuvalov")[0]
    assert found.fit.ssr <= dense.fit.ssr * (1 + 1e-9)
    assert without_scan.fit.ssr > 1.01 * found.fit.ssr  # the test sees the scan's work
    assert_allclose(found.shape, 2.2984, rtol=1e-3)


def test_a_batch_where_every_experiment_fails_keeps_the_column_types():
    """With no fit, the table is made of the failures alone (as before the rows were made on the
    workers): equation stays an integer column, for any number of workers."""
    tiny = [TrompPoints("a", [10.0, 20.0], [0.8, 0.2]), TrompPoints("b", [10.0, 20.0], [0.7, 0.1])]
    tables = [fit_experiments(tiny, formulas=["plitt", "lognormal"], jobs=jobs).fits_table() for jobs in (1, 2)]
    assert tables[0].to_csv(index=False) == tables[1].to_csv(index=False)
    assert str(tables[0]["equation"].dtype) == "int64" and not tables[0]["success"].any() and len(tables[0]) == 4


@pytest.mark.slow
def test_a_batch_leaves_no_object_frozen_out_of_garbage_collection(monkeypatch):
    """Results are kept out of the cyclic collector while a batch runs (gc.freeze); after the
    batch, whether it ends normally or with an error, every object is collectable again."""
    import gc

    monkeypatch.setattr(fanout, "CHUNK_SIZE", 2)
    monkeypatch.setattr(fanout, "MAX_CHUNK_SIZE", 2)
    frozen_during = []
    fit_chunk = workbench.fit_chunk

    def watched(experiments, **options):
        frozen_during.append(gc.get_freeze_count())
        return fit_chunk(experiments, **options)

    monkeypatch.setattr(worker, "fit_chunk", watched)
    assert gc.get_freeze_count() == 0
    bench = fit_experiments(EXPERIMENTS[:6], formulas=["plitt"], jobs=1)
    assert len(bench.fits) == 6 and gc.get_freeze_count() == 0
    # the later chunks ran with the earlier chunks' results (and the modules) frozen
    assert len(frozen_during) == 3 and all(count > 0 for count in frozen_during)
    assert frozen_during[2] > frozen_during[0]

    def broken(experiments, **options):
        raise RuntimeError("broken chunk")

    monkeypatch.setattr(worker, "fit_chunk", broken)
    with pytest.raises(RuntimeError, match="broken chunk"):
        fit_experiments(EXPERIMENTS[:6], formulas=["plitt"], jobs=1)
    assert gc.get_freeze_count() == 0

    # objects the process froze itself stay frozen, and the batch freezes nothing more
    monkeypatch.setattr(worker, "fit_chunk", fit_chunk)
    gc.freeze()
    try:
        owned = gc.get_freeze_count()
        fit_experiments(EXPERIMENTS[:6], formulas=["plitt"], jobs=1)
        # none unfrozen, none added (a frozen object that died meanwhile leaves the count)
        assert 0.99 * owned <= gc.get_freeze_count() <= owned
    finally:
        gc.unfreeze()
