"""One battery over every public result class (in the spirit of scikit-learn's ``check_estimator``).

Each class in :data:`REGISTRY` has a factory that builds a real instance from bundled data
and the names its report and notebook view must show.  The battery checks the contract of
:mod:`tromplab.results_contract`: the ``Attributes`` block, ``summary()``, ``report()``,
``_repr_html_()``, ``to_frame()``, ``save()`` (the files of the command, all or nothing),
pickling with the version stamped and checked.  A discovery test fails when a public result
class is missing from the registry.
"""

from __future__ import annotations

import dataclasses
import filecmp
import functools
import html.parser
import importlib
import inspect
import pickle
import pkgutil
import re
import warnings
from typing import NamedTuple

import numpy as np
import pandas as pd
import pytest

import tromplab
from tromplab import results_contract
from tromplab._version import __version__
from tromplab.circuit import CircuitBalance, CircuitResult, read_flowsheet, read_survey, reconcile, reconcile_circuit
from tromplab.circuit.planning import DesignAdvice, design_advice
from tromplab.classifiers import choice, layer, pulp, sieve
from tromplab.cli import main
from tromplab.curves.curve_fit import CurveFit
from tromplab.curves.indices import CurveIndices
from tromplab.density import DensityCurveFit, DensityPrediction, DensityResult, fit_density, predict_density
from tromplab.density.washability import Prediction, Washability, partition_curve, read_washability
from tromplab.errors import InconsistentVersionWarning
from tromplab.loading.lab import MassBalance
from tromplab.plant import PlantOptimum, PlantPrediction, SeparationEvaluation, evaluate, optimize
from tromplab.plant import predict as predict_plant
from tromplab.results_contract import ResultContract
from tromplab.statistics.compare import ExtraSumOfSquares, SharedFit
from tromplab.statistics.uncertainty import Bootstrap
from tromplab.trend import TrendResult, monitor_surveys, read_surveys
from tromplab.workbench import Workbench

from .conftest import DATASETS

#: A name that breaks HTML unless escaped: the notebook views must show it as text.
HOSTILE = "<b>&x"
DECK = DATASETS / "double_deck_screen_decks_lab.csv"
TRACERS = DATASETS / "density_tracers_dmc_by_size_synthetic.csv"
SURVEYS = DATASETS / "classifier_trend_surveys.csv"
SIZES = [10.0, 20, 40, 80, 160, 320]


class Entry(NamedTuple):
    build: object  # () -> instance (cached)
    shows: tuple[str, ...]  # what report() and _repr_html_() must name (the fitted thing, the user's names)


REGISTRY: dict[type, Entry] = {}


def registered(cls: type, *shows: str):
    """Register the decorated factory for ``cls``; it is built once per test session."""

    def decorate(factory):
        REGISTRY[cls] = Entry(functools.cache(factory), shows)
        return factory

    return decorate


def _points(name: str, shares) -> tromplab.TrompPoints:
    return tromplab.TrompPoints(name, SIZES, shares)


FIRST = [0.98, 0.93, 0.70, 0.30, 0.08, 0.01]
SECOND = [0.99, 0.95, 0.62, 0.18, 0.03, 0.01]


@registered(CurveFit, HOSTILE, "plitt")
def _curve_fit():
    return tromplab.fit_formula(_points(HOSTILE, FIRST), "plitt")


@registered(Workbench, HOSTILE, "plitt")
def _workbench():
    return tromplab.fit_experiments([_points(HOSTILE, FIRST), _points("second", SECOND)], formulas=["plitt", "lognormal"])


@registered(SharedFit, HOSTILE, "plitt")
def _shared_fit():
    return tromplab.shared_fit([_points(HOSTILE, FIRST), _points("second", SECOND)], "plitt")


@registered(CurveIndices, "d_cut", "ep")
def _curve_indices():
    return _curve_fit().indices


@registered(ExtraSumOfSquares, "F =")
def _extra_sum_of_squares():
    points = _points(HOSTILE, FIRST)
    return tromplab.nested_f_test(tromplab.fit_formula(points, "plitt"), tromplab.fit_formula(points, "plitt_bypass"))


@registered(Bootstrap, "residuals", "d_cut")
def _bootstrap():
    return tromplab.bootstrap(_curve_fit(), n=20, seed=1)


@registered(MassBalance, "deck_20mesh", "fine yield")
def _mass_balance():
    return tromplab.read_lab(DECK)[0]


@registered(CircuitBalance, "circuit_example_survey", "streams")
def _circuit_balance():
    sheet = read_flowsheet(DATASETS / "circuit_example_flowsheet.csv")
    return reconcile(sheet, read_survey(DATASETS / "circuit_example_survey.csv", sheet))


@registered(CircuitResult, "circuit_example_survey", "streams")
def _circuit_result():
    return reconcile_circuit(DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv", fit=True)


@registered(DesignAdvice, "circuit_example_survey", "size analysis")
def _design_advice():
    return design_advice(DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv")


@registered(TrendResult, "plitt", "surveys")
def _trend():
    return monitor_surveys(read_surveys(SURVEYS), formula="plitt")


@registered(DensityResult, "normal")
def _density():
    return fit_density(TRACERS, curves="normal,logistic")


@registered(DensityCurveFit, "normal")
def _density_curve_fit():
    return _density().fits[0]


@registered(Washability, "fractions")
def _washability():
    return read_washability(DATASETS / "density_washability_synthetic.csv")[0]


@registered(Prediction, "floats", "sinks")
def _prediction():
    return _washability().predict(partition_curve("normal", rho50=1.55, ep=0.05)[1])


@registered(DensityPrediction, "density_washability_synthetic", "floats_yield_pct")
def _density_prediction():
    return predict_density(DATASETS / "density_washability_synthetic.csv", rho50=[1.5, 1.6], ep=0.05)


PLANT_WASH = DATASETS / "plant_washability_synthetic.csv"
PLANT_DEVICES = DATASETS / "plant_devices_synthetic.csv"


@registered(PlantPrediction, "dm_vessel", "clean_yield_pct")
def _plant_prediction():
    return predict_plant(PLANT_WASH, PLANT_DEVICES, draws=200)


@registered(PlantOptimum, "dm_vessel", "incremental_ash_pct")
def _plant_optimum():
    return optimize(PLANT_WASH, PLANT_DEVICES, target_ash_pct=10, draws=200)


PLANT_TEST = pd.DataFrame({"test": [HOSTILE] * 3, "density_lower": [None, 1.4, 1.6], "density_upper": [1.4, 1.6, None],
                           "feed_pct": [50, 25, 25], "floats_pct": [75, 20.8333, 4.1667], "sinks_pct": [12.5, 31.25, 56.25],
                           "feed_ash_pct": [10, 30, 70]})  # fmt: skip


@registered(SeparationEvaluation, HOSTILE, "organic_efficiency_pct")
def _separation_evaluation():
    return evaluate(PLANT_TEST)


@registered(layer.LayerFit, "Layer model", "diffusion")
def _layer_fit():
    table = pd.read_csv(DATASETS / "layer_extraction_example.csv", comment="#")
    return layer.fit_layer_model(table["step"].to_numpy(), table["extraction"].to_numpy(), initial=[0.5] * 4)


@registered(pulp.PulpFit, "Pulp screen", "beta")
def _pulp_fit():
    table = pd.read_csv(DATASETS / "pulp_screen_productivity_example.csv", comment="#")
    return pulp.fit_pulp_screen(table["applied_pressure"], table["frequency"], table["productivity"])


@registered(sieve.VelocityLaw, "Velocity law", "v_k")
def _velocity_law():
    speeds = np.array([0.18, 0.22, 0.26, 0.30, 0.34, 0.38])
    residues = sieve.residue_share(0.15 * sieve.velocity_probability(speeds, 0.25, 0.06), 1.0, 0.01)
    return sieve.identify_velocity_law(speeds, residues, geometric_prob=0.15, sieve_length=1.0, cell_pitch=0.01)


@registered(sieve.Dependence, "l / D", "a")
def _dependence():
    lengths = np.array([2.0, 2.25, 2.5, 2.75])
    return sieve.fit_dependence(np.full(4, 2.0), lengths, 0.1 * (lengths / 2.0) ** 1.5, form="a * (l / D) ** b")


@registered(sieve.BinDesign, "recovery 0.9", "x1")
def _bin_design():
    return sieve.design_bin(12, 1.6, 0.9)


@registered(choice.ChoiceResult, "Pareto", "compromise")
def _choice():
    return choice.choose(choice.sieve_speed_problem(), floor_second=80.0, share_of_first=0.8)


CLASSES = sorted(REGISTRY, key=lambda cls: cls.__name__)


def instance(cls):
    return REGISTRY[cls].build()


# --- the Attributes block ---------------------------------------------------------------------
def documented_attributes(cls) -> set[str]:
    """Names in the numpydoc ``Attributes`` section of the class docstring (``a, b : type`` lines)."""
    lines = inspect.cleandoc(cls.__doc__ or "").splitlines() + [""]
    headings = [i for i in range(len(lines) - 1) if lines[i] and set(lines[i + 1]) == {"-"}]
    starts = [i for i in headings if lines[i] == "Attributes"]
    if not starts:
        return set()
    end = next((i for i in headings if i > starts[0]), len(lines))
    names = set()
    for line in lines[starts[0] + 2 : end]:
        if line and not line.startswith(" "):
            names.update(name.strip() for name in line.split(" : ")[0].split(","))
    return names


def public_attributes(cls) -> set[str]:
    """Public dataclass fields and properties of ``cls`` (its methods are documented on their own)."""
    names = {field.name for field in dataclasses.fields(cls) if not field.name.startswith("_")}
    for klass in cls.__mro__:
        for name, value in vars(klass).items():
            if not name.startswith("_") and isinstance(value, property | functools.cached_property):
                names.add(name)
    return names


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
def test_attributes_block_lists_the_public_attributes(cls):
    documented = documented_attributes(cls)
    assert documented, f"{cls.__name__} has no numpydoc Attributes block"
    assert public_attributes(cls) <= documented, f"undocumented: {sorted(public_attributes(cls) - documented)}"
    assert documented <= public_attributes(cls), f"documented but missing: {sorted(documented - public_attributes(cls))}"


# --- the verbs ----------------------------------------------------------------------------------
@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
def test_follows_the_contract(cls):
    assert issubclass(cls, ResultContract)
    assert cls.summary is not ResultContract.summary, "summary() is each class's own"


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
@pytest.mark.slow
def test_summary_is_a_non_empty_table(cls):
    summary = instance(cls).summary()
    assert isinstance(summary, pd.DataFrame) and len(summary) > 0 and len(summary.columns) > 0


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
@pytest.mark.slow
def test_to_frame_is_a_table(cls):
    table = instance(cls).to_frame()
    assert isinstance(table, pd.DataFrame) and len(table.columns) > 0


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
@pytest.mark.slow
def test_report_is_text_naming_what_was_fitted(cls):
    text = instance(cls).report()
    assert isinstance(text, str) and text.strip()
    for name in REGISTRY[cls].shows:
        assert name in text, f"report() does not name {name!r}"


class _Tags(html.parser.HTMLParser):
    """Counts open and close tags of the elements that must be closed, and the text shown."""

    CLOSED = ("table", "tr", "td", "th", "div", "p", "b", "thead", "tbody")

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.depth: dict[str, int] = {}
        self.text = []

    def handle_starttag(self, tag, attrs):
        if tag in self.CLOSED:
            self.depth[tag] = self.depth.get(tag, 0) + 1

    def handle_endtag(self, tag):
        if tag in self.CLOSED:
            self.depth[tag] = self.depth.get(tag, 0) - 1
            assert self.depth[tag] >= 0, f"</{tag}> without <{tag}>"

    def handle_data(self, data):
        self.text.append(data)


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
def test_html_view_is_a_table_with_escaped_names(cls):
    markup = instance(cls)._repr_html_()
    assert "<table" in markup
    tags = _Tags()
    tags.feed(markup)
    tags.close()
    assert all(depth == 0 for depth in tags.depth.values()), tags.depth
    shown = "".join(tags.text)
    for name in REGISTRY[cls].shows:
        assert name in shown, f"the notebook view does not show {name!r}"
    if HOSTILE in REGISTRY[cls].shows:
        assert HOSTILE not in markup and html.escape(HOSTILE, quote=False) in markup


# --- pickling -----------------------------------------------------------------------------------
def _other_version(data: bytes) -> bytes:
    """``data`` with the version stamp changed to another version of the same length."""
    other = __version__[:-1] + ("1" if __version__[-1] != "1" else "2")
    stamp = results_contract.VERSION_KEY.encode()
    assert stamp in data and __version__.encode() in data
    return data.replace(__version__.encode(), other.encode())


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
def test_pickle_round_trip_keeps_the_summary(cls):
    result = instance(cls)
    with warnings.catch_warnings():
        warnings.simplefilter("error", InconsistentVersionWarning)
        copy = pickle.loads(pickle.dumps(result))
    pd.testing.assert_frame_equal(copy.summary(), result.summary())


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
def test_a_pickle_from_another_version_warns(cls):
    data = _other_version(pickle.dumps(instance(cls)))
    with warnings.catch_warnings(record=True) as caught:  # nested results warn too, each for itself
        warnings.simplefilter("always")
        copy = pickle.loads(data)
    found = [w.message for w in caught if isinstance(w.message, InconsistentVersionWarning)]
    assert any(w.result_class == cls.__name__ and w.saved_version != __version__ for w in found), found
    assert isinstance(copy.summary(), pd.DataFrame)


def test_a_pickle_without_a_stamp_loads_quietly(monkeypatch):
    result = _curve_fit()
    monkeypatch.setattr(ResultContract, "__getstate__", lambda self: dict(self.__dict__))  # as before the stamp
    data = pickle.dumps(result)
    monkeypatch.undo()
    assert results_contract.VERSION_KEY.encode() not in data
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        copy = pickle.loads(data)
    pd.testing.assert_frame_equal(copy.summary(), result.summary())


# --- save: the files of the command, all or nothing -------------------------------------------
def _fit_command(folder):
    assert main(["fit", str(DECK), "--formulas", "plitt,lognormal", "--figures", "best", "-q", "-o", str(folder)]) == 0


def _fit_api(folder):
    bench = tromplab.fit_experiments(tromplab.read_experiments(DECK), formulas=["plitt", "lognormal"])
    return bench, bench.save(folder, figures="best")


def _density_command(folder):
    assert main(["density", "fit", str(TRACERS), "--curves", "normal", "-o", str(folder)]) == 0


def _density_api(folder):
    result = fit_density(TRACERS, curves="normal")
    return result, result.save(folder)


def _plant_command(folder):
    assert main(["plant", "predict", str(PLANT_WASH), str(PLANT_DEVICES), "--draws", "200", "-o", str(folder)]) == 0


def _plant_api(folder):
    return _plant_prediction(), _plant_prediction().save(folder)


def _optimum_command(folder):
    command = [
        "plant",
        "optimize",
        str(PLANT_WASH),
        str(PLANT_DEVICES),
        "--target-ash",
        "10",
        "--draws",
        "200",
        "-o",
        str(folder),
    ]
    assert main(command) == 0


def _optimum_api(folder):
    return _plant_optimum(), _plant_optimum().save(folder)


def _evaluation_command(folder):
    PLANT_TEST.to_csv(folder.parent / "plant_test.csv", index=False)
    assert main(["plant", "evaluate", str(folder.parent / "plant_test.csv"), "-o", str(folder)]) == 0


def _evaluation_api(folder):
    return _separation_evaluation(), _separation_evaluation().save(folder)


def _trend_command(folder):
    assert main(["trend", str(SURVEYS), "--formula", "plitt", "-o", str(folder)]) == 0


def _trend_api(folder):
    return _trend(), _trend().save(folder)


def _circuit_command(folder):
    sheet, survey = DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv"
    assert main(["circuit", str(sheet), str(survey), "-o", str(folder)]) == 0


def _circuit_api(folder):
    return _circuit_balance(), _circuit_balance().save(folder)


def _circuit_fit_command(folder):
    sheet, survey = DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv"
    assert main(["circuit", str(sheet), str(survey), "--fit", "-o", str(folder)]) == 0


def _circuit_fit_api(folder):
    return _circuit_result(), _circuit_result().save(folder)


def _prediction_command(folder):
    command = ["density", "predict", str(DATASETS / "density_washability_synthetic.csv"), "--rho50", "1.5", "1.6", "--ep",
               "0.05", "-o", str(folder / "prediction.csv"), "--table", str(folder / "washability.csv")]  # fmt: skip
    assert main(command) == 0


def _prediction_api(folder):
    return _density_prediction(), _density_prediction().save(folder / "prediction.csv", table=folder / "washability.csv")


def _design_command(folder):
    sheet, survey = DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv"
    assert main(["circuit", "design", str(sheet), str(survey), "-o", str(folder)]) == 0


def _design_api(folder):
    return _design_advice(), _design_advice().save(folder)


#: Classes with ``save``: the command writing the same folder, and the same through the API.
SAVES = {
    DesignAdvice: (_design_command, _design_api),
    CircuitBalance: (_circuit_command, _circuit_api),
    CircuitResult: (_circuit_fit_command, _circuit_fit_api),
    DensityPrediction: (_prediction_command, _prediction_api),
    Workbench: (_fit_command, _fit_api),
    DensityResult: (_density_command, _density_api),
    TrendResult: (_trend_command, _trend_api),
    PlantPrediction: (_plant_command, _plant_api),
    PlantOptimum: (_optimum_command, _optimum_api),
    SeparationEvaluation: (_evaluation_command, _evaluation_api),
}


#: The main file of each command: what ``to_frame()`` returns.
MAIN_FILES = {
    DesignAdvice: "design.csv",
    CircuitBalance: "flows.csv",
    CircuitResult: "flows.csv",
    DensityPrediction: "prediction.csv",
    Workbench: "fits.csv",
    DensityResult: "fits.csv",
    TrendResult: "trend.csv",
    PlantPrediction: "products.csv",
    PlantOptimum: "cuts.csv",
    SeparationEvaluation: "evaluation.csv",
}


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls.__name__)
def test_save_only_where_a_command_writes_a_folder(cls):
    assert hasattr(cls, "save") == (cls in SAVES), "save(directory) writes what a command writes; SAVES lists them"


@pytest.mark.slow
@pytest.mark.parametrize("cls", list(SAVES), ids=lambda cls: cls.__name__)
def test_save_writes_what_the_command_writes(cls, tmp_path, capsys):
    command, api = SAVES[cls]
    command(tmp_path / "command")
    capsys.readouterr()
    result, written = api(tmp_path / "api")
    assert written and sorted(written) == sorted(p.name for p in (tmp_path / "command").iterdir() if not p.name.startswith("."))
    for name in written:
        assert filecmp.cmp(tmp_path / "command" / name, tmp_path / "api" / name, shallow=False), name
    main_file = pd.read_csv(written[MAIN_FILES[cls]], nrows=0)
    assert list(result.to_frame().columns) == list(main_file.columns), f"to_frame() is {MAIN_FILES[cls]}"


#: Where a save is made to fail half-way: the second figure, or (a result without figures) the second table.
FAILING_WRITER = {DesignAdvice: ("tromplab.output.csv_parts", "write_csv"),
                  SeparationEvaluation: ("tromplab.output.csv_parts", "write_csv")}  # fmt: skip


#: Results whose command writes files, not a folder: each file is replaced in one step, on its own.
FILES_NOT_FOLDER = {DensityPrediction}


@pytest.mark.parametrize("cls", sorted(set(SAVES) - FILES_NOT_FOLDER, key=lambda cls: cls.__name__), ids=lambda cls: cls.__name__)
@pytest.mark.slow
def test_save_writes_nothing_half(cls, tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    owner, name = FAILING_WRITER.get(cls, (Figure, "savefig"))
    owner = importlib.import_module(owner) if isinstance(owner, str) else owner
    written = getattr(owner, name)

    def fail_second(*args, **kwargs):  # the first file is written, the second fails
        fail_second.calls += 1
        if fail_second.calls > 1:
            raise OSError("disk full")
        return written(*args, **kwargs)

    fail_second.calls = 0
    monkeypatch.setattr(owner, name, fail_second)
    with pytest.raises(OSError, match="disk full"):
        SAVES[cls][1](tmp_path / "out")
    assert fail_second.calls > 1
    assert list(tmp_path.iterdir()) == [], "a failed save leaves no folder and no temporary files"


# --- discovery: no public result class outside the battery ----------------------------------------
#: Public classes with a verb of the contract, or returned by a public function, that are not
#: results: why each is left out of the battery.
NOT_RESULTS = {
    "tromplab.loading.points.TrompPoints": "input data (read_points): to_frame() is the points table",
    "tromplab.circuit.flowsheet.Flowsheet": "input (read_flowsheet): the circuit's description",
    "tromplab.circuit.measurements.Survey": "input (read_survey): the measurements",
    "tromplab.density.readers.DensitySample": "input (read_density): one test's data",
    "tromplab.density.streamed.DensityFolder": "what a streamed density fit wrote (fit_density_to_folder): its tables "
    "are the folder's files, its fits are not kept",
    "tromplab.loading.lab_options.LabOptions": "options of read_lab",
    "tromplab.curves.formulas.Formula": "a registry record",
    "tromplab.curves.parameters.Parameter": "a registry record",
    "tromplab.density.registry.DensityCurve": "a registry record",
    "tromplab.plant.inputs.SizeFraction": "input (read_plant_washability): one size fraction's washability",
    "tromplab.plant.inputs.Device": "input (read_plant): one device's curve",
    "tromplab.plant.optimization.CutResponse": "a working record of the optimiser (one fraction's response to its cut)",
    "tromplab.plant.optimization.CutSolution": "a working record of the optimiser (the cuts and the multiplier)",
    "tromplab.output.report.Report": "a document being built (build_report): html() and markdown() are its outputs",
    "tromplab.output.export.Export": "an export file being built: its writers are the command's",
    "tromplab.trend.Survey": "input (read_surveys): one dated survey",
    "tromplab.loading.tables.Table": "a table being read",
    "tromplab.workbench.store.FitStore": "where a Workbench reads its fits: save() writes the Workbench's folder",
    "tromplab.workbench.store.FitsInMemory": "a Workbench's store (FitStore): save() writes the Workbench's folder",
    "tromplab.workbench.store.FitsOnDisk": "a streamed Workbench's store (FitStore): save() copies its folder",
    "tromplab.loading.lab.Experiments": "a named pair (points, balances) of read_experiments",
    "tromplab.workbench.worker.FittedChunk": "what a worker sends back to fit_experiments",
    "tromplab.results_contract.ResultContract": "the contract's mixin itself",
}


def _package_classes():
    """Every class defined in a module of tromplab, by qualified name."""
    found = {}
    for module in pkgutil.walk_packages(tromplab.__path__, "tromplab."):
        if module.name.endswith("__main__"):
            continue
        loaded = importlib.import_module(module.name)
        for value in vars(loaded).values():
            if inspect.isclass(value) and value.__module__ == module.name and not value.__name__.startswith("_"):
                found[f"{value.__module__}.{value.__qualname__}"] = value
    return found


def _public_functions():
    """The functions of ``tromplab.__all__`` and of the subpackages' ``__all__``."""
    functions = [getattr(tromplab, name) for name in tromplab.__all__]
    for package in ("circuit", "density", "workbench", "plant"):
        module = importlib.import_module(f"tromplab.{package}")
        functions += [getattr(module, name) for name in module.__all__]
    return [function for function in functions if inspect.isfunction(function)]


def _returned_classes(function) -> set[type]:
    annotation = inspect.signature(function).return_annotation
    names = re.findall(
        r"[A-Za-z_][A-Za-z_0-9.]*", annotation if isinstance(annotation, str) else getattr(annotation, "__name__", "")
    )
    classes = {function.__globals__.get(name.split(".")[-1]) for name in names}
    return {cls for cls in classes if inspect.isclass(cls) and cls.__module__.startswith("tromplab")}


def test_every_public_result_class_is_in_the_battery():
    classes = _package_classes()
    verbs = ("summary", "report", "to_frame", "_repr_html_", "save")
    candidates = {name for name, cls in classes.items() if any(hasattr(cls, verb) for verb in verbs)}
    for function in _public_functions():
        candidates |= {f"{cls.__module__}.{cls.__qualname__}" for cls in _returned_classes(function)}
    registered_names = {f"{cls.__module__}.{cls.__qualname__}" for cls in REGISTRY}
    missing = sorted(candidates - registered_names - set(NOT_RESULTS))
    assert not missing, f"public result classes outside the battery (add a factory, or a reason to NOT_RESULTS): {missing}"
    assert set(NOT_RESULTS) <= set(classes), f"stale entries: {sorted(set(NOT_RESULTS) - set(classes))}"


def test_summary_means_a_table_everywhere():
    """No class of the package keeps a ``summary`` that is not the contract's (a table)."""
    for name, cls in _package_classes().items():
        if hasattr(cls, "summary") and name not in NOT_RESULTS:
            assert issubclass(cls, ResultContract), name


@pytest.mark.slow
def test_workbench_report_with_a_path_is_deprecated(tmp_path):
    with pytest.warns(FutureWarning, match="write_report"):
        written = _workbench().report(tmp_path / "report.html")
    assert "report.html" in written and written["report.html"].read_text(encoding="utf-8").startswith("<!")
