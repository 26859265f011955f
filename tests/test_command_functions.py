"""Every command is one Python function whose result's ``save()`` writes the command's files
(docs/architecture.md, "Commands as functions"): on the bundled data sets, the folder of the
command line is byte for byte the folder of the function's ``save()``, and its text files are
those the code wrote before the commands took one shape (digests recorded at 52a2c1d by
``python tests/command_cases.py --record``; figures compared between the two faces only).
"""

from __future__ import annotations

import inspect
import json
from pathlib import Path

import pytest

import tromplab
from tromplab import plant

from .command_cases import CASES, DATASETS, ROOT, digests, fresh_digests, run_command, write_inputs

RECORDED = json.loads((Path(__file__).parent / "data" / "command_digests.json").read_text(encoding="utf-8"))
SHEET, SURVEY = DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv"
WASHABILITY = DATASETS / "density_washability_synthetic.csv"
TRACERS = DATASETS / "density_tracers_dmc_by_size_synthetic.csv"
PLANT = DATASETS / "plant_washability_synthetic.csv", DATASETS / "plant_devices_synthetic.csv"

#: Each case through its Python function: ``(out, inputs) -> {file name: path}`` of ``save()``.
THROUGH_THE_API = {
    "fit lab table with intervals": lambda out, _: tromplab.fit_experiments(
        DATASETS / "double_deck_screen_decks_lab.csv", size_unit="mm", ci=0.95
    ).save(out),
    "fit lab table, extended, no figures": lambda out, _: tromplab.fit_experiments(
        DATASETS / "air_classifier_lab_synthetic.csv", extended=True
    ).save(out, figures="none"),
    "density fit with intervals": lambda out, _: tromplab.fit_density(TRACERS, ci=0.95).save(out),
    "density fit plain, no figures": lambda out, _: tromplab.fit_density(TRACERS, curves="plain").save(out, figures="none"),
    "density predict": lambda out, _: tromplab.predict_density(WASHABILITY, rho50=[1.45, 1.6], ep=0.05).save(
        out / "prediction.csv", table=out / "washability.csv"
    ),
    "density predict target ash": lambda out, _: tromplab.predict_density(
        WASHABILITY, target_ash_pct=[8, 12], ep=0.04, curve="logistic"
    ).save(out / "prediction.csv"),
    "circuit with fits": lambda out, _: tromplab.reconcile_circuit(SHEET, SURVEY, fit=True).save(out),
    "circuit excluded, no figures": lambda out, _: tromplab.reconcile_circuit(
        SHEET, SURVEY, exclude="screen_feed:flow", weighting="feed-share"
    ).save(out, figures=False),
    "circuit design of a survey": lambda out, _: tromplab.design_circuit(SHEET, SURVEY).save(out),
    "circuit design simulated": lambda out, _: tromplab.design_circuit(SHEET).save(out),
    "trend": lambda out, _: tromplab.monitor_surveys(DATASETS / "classifier_trend_surveys.csv").save(out),
    "trend no figures": lambda out, _: tromplab.monitor_surveys(DATASETS / "classifier_trend_surveys.csv", alpha=0.05).save(
        out, figures=False
    ),
    "plant predict": lambda out, _: plant.predict(*PLANT, draws=300, seed=5).save(out),
    "plant optimize": lambda out, _: plant.optimize(*PLANT, target_ash_pct=10, draws=200).save(out),
    "plant evaluate": lambda out, inputs: plant.evaluate(inputs / "float_sink_test.csv").save(out),
}


def test_every_case_has_its_python_function_and_its_recorded_digests():
    assert set(THROUGH_THE_API) == set(CASES) == set(RECORDED)
    commands = {" ".join(arg for arg in CASES[name][:2] if not arg.startswith(("datasets/", "{"))) for name in CASES}
    assert commands >= {"fit", "density fit", "density predict", "circuit design", "trend", "plant predict",
                        "plant optimize", "plant evaluate"}  # fmt: skip
    assert any(CASES[name][0] == "circuit" and CASES[name][1] != "design" for name in CASES)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_the_command_writes_what_its_function_saves_and_what_it_wrote_before(name, tmp_path, monkeypatch):
    assert fresh_digests(name, tmp_path / "fresh") == RECORDED[name]
    monkeypatch.chdir(ROOT)  # the API reads the data sets by the relative names the command line is given
    inputs = write_inputs(tmp_path / "inputs")
    assert run_command(name, tmp_path / "cli", inputs) == RECORDED[name]["exit"]
    cli = digests(tmp_path / "cli", text_only=False)
    (tmp_path / "api").mkdir()
    written = THROUGH_THE_API[name](tmp_path / "api", inputs)
    assert sorted(Path(path).name for path in written.values()) == sorted(file for file in cli if not file.startswith("."))
    assert digests(tmp_path / "api", text_only=False) == cli


#: The command functions and the keywords each takes beside the command's option names: the
#: error model's options of ``circuit`` travel as one ``ErrorModel`` (``errors``), the trend's
#: evaluation settings (``level``, ``lam``, ``width``, ``consecutive``) are the benchmark's, a
#: running Dask client (``client``) is the API's form of ``--scheduler``, and ``progress`` is the
#: API's form of the bars the command line draws.
FUNCTIONS = {
    ("density", "fit"): (tromplab.fit_density, {"data", "sheet", "sep", "decimal", "client", "progress"}),
    ("density", "predict"): (tromplab.predict_density, {"washability"}),
    ("circuit",): (tromplab.reconcile_circuit, {"flowsheet", "measurements", "errors", "progress"}),
    ("circuit", "design"): (tromplab.design_circuit, {"flowsheet", "measurements", "errors", "progress"}),
    ("trend",): (tromplab.monitor_surveys, {"surveys", "level", "lam", "width", "consecutive", "progress"}),
}


@pytest.mark.parametrize("command", list(FUNCTIONS), ids=" ".join)
def test_a_function_s_keywords_are_its_command_s_options(command):
    from tromplab.cli import build_parser

    parser = build_parser()
    for word in command:
        parser = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction").choices[word]
    dests = {action.dest for action in parser._actions if action.option_strings}
    function, beside = FUNCTIONS[command]
    keywords = set(inspect.signature(function).parameters) - beside
    assert keywords and keywords <= dests, f"keywords that are not options of tromplab {' '.join(command)}: {keywords - dests}"


@pytest.mark.slow
def test_density_fit_on_a_local_dask_cluster_makes_the_fits_of_one_process(tmp_path, monkeypatch):
    pytest.importorskip("distributed", reason="the dask extra (pip install 'tromplab[dask]') is not installed")
    from tromplab.density import results

    monkeypatch.setattr(results, "TESTS_PER_UNIT", 2)  # the four size fractions in two units
    alone = tromplab.fit_density(TRACERS, ci=0.9, curves="plain")
    on_dask = tromplab.fit_density(TRACERS, ci=0.9, curves="plain", dask="local")
    assert alone.fits_table().to_csv() == on_dask.fits_table().to_csv()
    alone.save(tmp_path / "alone", figures="none")
    on_dask.save(tmp_path / "dask", figures="none")
    assert digests(tmp_path / "alone", text_only=True) == digests(tmp_path / "dask", text_only=True)
