"""``density fit`` streamed unit by unit (tromplab.density.streamed): the same files, byte for
byte, as the results kept in memory and saved; no more than a few units held at once; nothing
half-written when a run is interrupted."""

import filecmp
import gc
import inspect
import os
import weakref
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tromplab.cli import main
from tromplab.density import fit_density, fit_density_to_folder, results, streamed
from tromplab.density.simulation import simulate_tracer_test
from tromplab.output.csv_parts import write_csv
from tromplab.output.spooled import SpooledTables, unit_table
from tromplab.parallel import streaming

TRACERS = Path(__file__).resolve().parents[1] / "datasets" / "density_tracers_dmc_by_size_synthetic.csv"
#: Tests per unit in these tests: a campaign of 30 tests is 8 units, as 1,000 tests are of 128.
UNIT = 4


def _campaign(tests: int = 30, *, seed: int = 3) -> pd.DataFrame:
    """Tracer tests of 9 densities, some overdispersed-looking (few tracers) and some tracers
    lost (notes), and one test the curves cannot be fitted to (no tracer sinks: every fit fails)."""
    rng = np.random.default_rng(seed)
    frames = []
    for number in range(tests):
        rho50, ep = rng.uniform(1.45, 1.75), rng.uniform(0.02, 0.08)
        densities = np.round(np.linspace(rho50 - 3 * ep, rho50 + 3 * ep, 9), 3)
        frames.append(simulate_tracer_test("normal", {"rho50": rho50, "ep": ep}, densities, placed=int(rng.integers(8, 40)),
                                           retrieval=0.95, rng=rng, test=f"t{number:03d}"))  # fmt: skip
    frames[7] = frames[7].assign(floats=frames[7]["floats"] + frames[7]["sinks"], sinks=0)  # nothing sinks: no curve
    return pd.concat(frames, ignore_index=True)


@pytest.fixture
def small_units(monkeypatch):
    monkeypatch.setattr(results, "TESTS_PER_UNIT", UNIT)


def _same_folders(one, other) -> None:
    names = sorted(os.listdir(one))
    assert names == sorted(os.listdir(other))
    _, mismatch, errors = filecmp.cmpfiles(one, other, names, shallow=False)
    assert (mismatch, errors) == ([], [])


@pytest.mark.parametrize(
    "options",
    [
        {"figures": "none"},
        {"figures": "none", "ci": 0.9},
        {"figures": "auto", "ci": 0.95, "curves": "plain"},  # above the figure limit: one overview
        {"figures": "none", "jobs": 2, "curves": "normal,logistic_limits"},
    ],
    ids=["plain", "intervals", "overview", "two-workers"],
)
def test_a_streamed_campaign_writes_the_files_of_the_results_kept_in_memory(options, small_units, tmp_path):
    table = _campaign()
    figures = options.pop("figures")
    kept = fit_density(table, **options)
    kept.save(tmp_path / "memory", figures=figures)
    result, written = fit_density_to_folder(table, tmp_path / "streamed", figures=figures, stream=True, **options)
    assert isinstance(result, streamed.DensityFolder)
    assert list(written) == list(kept.save(tmp_path / "again", figures=figures))  # the same files in the same order
    _same_folders(tmp_path / "memory", tmp_path / "streamed")
    assert result.report() == kept.report()
    assert result.unfitted() == kept.unfitted() == ["t007"]
    assert list(result.notices()) == kept.notices()
    assert result.tests == 30 and result.notes == len(kept.notices())


def test_a_partition_table_streams_the_files_of_its_least_squares_fits(small_units, tmp_path):
    rng = np.random.default_rng(5)
    rows = []
    for number in range(9):
        density = np.linspace(1.3, 1.9, 7)
        share = np.clip(1 / (1 + np.exp(-(density - 1.6) / 0.05)) + rng.normal(0, 0.02, 7), 0, 1)
        rows.append(pd.DataFrame({"test": f"=p{number}", "density": density, "partition_sinks": share}))  # a defended name
    table = pd.concat(rows, ignore_index=True)
    fit_density(table, ci=0.9).save(tmp_path / "memory", figures="none")
    result, _ = fit_density_to_folder(table, tmp_path / "streamed", figures="none", ci=0.9, stream=True)
    assert isinstance(result, streamed.DensityFolder)
    _same_folders(tmp_path / "memory", tmp_path / "streamed")


def test_a_table_with_size_fractions_or_a_workbook_is_kept_in_memory(tmp_path):
    result, _ = fit_density_to_folder(TRACERS, tmp_path / "sizes", figures="none", stream=True)
    assert isinstance(result, results.DensityResult)
    result, _ = fit_density_to_folder(_campaign(), tmp_path / "excel", figures="none", excel=True, stream=True)
    assert isinstance(result, results.DensityResult)


def test_the_command_streams_a_large_campaign_and_says_what_it_says_in_memory(small_units, tmp_path, monkeypatch, capsys):
    path = tmp_path / "campaign.csv"
    _campaign().to_csv(path, index=False)
    outputs = {}
    for name, threshold in (("memory", 10**9), ("streamed", 10)):
        monkeypatch.setattr(streaming, "STREAM_THRESHOLD", threshold)
        code = main(["density", "fit", str(path), "-o", str(tmp_path / name), "--figures", "none", "--ci", "0.9"])
        said = capsys.readouterr()
        outputs[name] = (code, said.out.replace(str(tmp_path / name), "OUT"), said.err)
    assert outputs["memory"] == outputs["streamed"]
    code, out, err = outputs["streamed"]
    assert code == 3 and "no curve could be fitted to: t007" in out  # reported, and every other test fitted
    assert "30 tests" in err
    _same_folders(tmp_path / "memory", tmp_path / "streamed")


def test_a_streamed_run_holds_a_few_units_at_a_time_not_the_campaign(small_units, tmp_path, monkeypatch):
    """The samples and fits alive in the main process after each unit: at most the units in
    flight (one being fitted, in this process), where the run kept in memory holds them all."""
    made = []  # weak references to every sample and fit made
    fit_unit = results.fit_unit

    def counted(options, unit):
        fits = fit_unit(options, unit)
        made.extend(weakref.ref(item) for item in [*unit, *fits])
        return fits

    monkeypatch.setattr(streamed, "fit_unit", counted)
    monkeypatch.setattr(results, "fit_unit", counted)
    most = []

    def progress(done, total, label):
        gc.collect()
        most.append(sum(ref() is not None for ref in made))

    table = _campaign(40)
    fit_density_to_folder(table, tmp_path / "streamed", figures="none", stream=True, progress=progress)
    per_unit = UNIT * (1 + 6)  # the samples and their six curves' fits
    assert len(most) == 10 and max(most) <= per_unit
    kept = fit_density(table, progress=progress)
    assert most[-1] == 40 * 7 and len(kept.fits) == 240  # in memory: every one


def test_an_interrupted_run_leaves_the_folder_as_it_was_and_no_scratch(small_units, tmp_path):
    table = _campaign()
    out = tmp_path / "out"
    fit_density_to_folder(table.iloc[:50], out, figures="none", stream=True)
    before = {name: (out / name).read_bytes() for name in os.listdir(out)}

    def interrupt(done, total, label):
        if done >= 3 * UNIT:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        fit_density_to_folder(table, out, figures="none", stream=True, progress=interrupt)
    assert {name: (out / name).read_bytes() for name in os.listdir(out)} == before
    assert sorted(os.listdir(tmp_path)) == ["out"]  # no scratch or staging folder left beside it
    with pytest.raises(KeyboardInterrupt):
        fit_density_to_folder(table, tmp_path / "new", figures="none", stream=True, progress=interrupt)
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_units_typed_differently_join_into_the_text_of_the_whole_table(tmp_path):
    units = [
        pd.DataFrame({"test": ["a", "b"], "rank": [1, 2], "ok": [True, False]}),
        pd.DataFrame({"test": ["c"], "rank": [np.nan], "ok": [np.nan]}),  # floats, objects
        pd.DataFrame({"test": ["=d"], "rank": [3], "ok": [True]}),
        pd.DataFrame({"test": pd.Series([], dtype=object), "rank": pd.Series([], dtype=float), "ok": []}),
    ]
    carriage = [*units[:2], pd.DataFrame({"test": ["e\rf"], "rank": [4], "ok": [False]})]
    for case, frames in (("typed", units), ("carriage", carriage), ("alike", [units[0], units[2]])):
        with SpooledTables(tmp_path / case) as spool:
            for number, frame in enumerate(frames):
                spool.keep("table", number, unit_table(frame))
            spool.writer("table")(tmp_path / f"{case}-joined.csv")
        write_csv(pd.concat([frame for frame in frames if len(frame)], ignore_index=True), tmp_path / f"{case}-whole.csv")
        assert (tmp_path / f"{case}-joined.csv").read_bytes() == (tmp_path / f"{case}-whole.csv").read_bytes(), case
    assert not any(name.startswith(".") for name in os.listdir(tmp_path))  # the scratch folders are gone


def test_the_function_s_keywords_are_the_command_s_options():
    from tromplab.cli import build_parser

    parser = build_parser()
    for word in ("density", "fit"):
        parser = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction").choices[word]
    dests = {action.dest for action in parser._actions if action.option_strings}
    beside = {"data", "sheet", "sep", "decimal", "client", "progress", "stream"}  # stream: as fit_to_folder's
    keywords = set(inspect.signature(fit_density_to_folder).parameters) - beside
    assert keywords <= dests and keywords >= set(inspect.signature(fit_density).parameters) - beside


@pytest.mark.slow
def test_a_campaign_streamed_from_a_local_dask_cluster_writes_the_files_of_one_process(small_units, tmp_path):
    pytest.importorskip("distributed", reason="the dask extra (pip install 'tromplab[dask]') is not installed")
    table = _campaign()
    fit_density(table, ci=0.9, curves="plain").save(tmp_path / "memory", figures="none")
    result, _ = fit_density_to_folder(table, tmp_path / "dask", figures="none", ci=0.9, curves="plain", dask="local",
                                      stream=True)  # fmt: skip
    assert isinstance(result, streamed.DensityFolder)
    _same_folders(tmp_path / "memory", tmp_path / "dask")


def test_bad_input_in_a_late_test_ends_a_streamed_run_as_it_ends_one_in_memory(small_units, tmp_path, monkeypatch, capsys):
    table = _campaign()
    table.loc[table.index[table["test"] == "t021"][2], "sinks"] = -1  # found when that test's unit is made
    path = tmp_path / "bad.csv"
    table.to_csv(path, index=False)
    said = {}
    for name, threshold in (("memory", 10**9), ("streamed", 10)):
        monkeypatch.setattr(streaming, "STREAM_THRESHOLD", threshold)
        code = main(["density", "fit", str(path), "-o", str(tmp_path / name), "--figures", "none"])
        said[name] = (code, capsys.readouterr().err)
    assert said["memory"] == said["streamed"] and said["memory"][0] != 0
    assert "negative count" in said["memory"][1]
    assert sorted(os.listdir(tmp_path)) == ["bad.csv"]  # nothing written, no scratch left
