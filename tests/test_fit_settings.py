"""The settings of a batch fit are one record (:class:`tromplab.validation.FitSettings`): every
field reachable from the command line and from the API, with the same default, checked once."""

import dataclasses
import inspect

import numpy as np
import pytest

from tromplab.cli import build_parser
from tromplab.errors import OptionError
from tromplab.loading.points import TrompPoints
from tromplab.validation import FitSettings
from tromplab.workbench import fit_experiments, fit_to_folder, fit_with_settings

#: Keywords of fit_experiments that are not settings: the input and two run-time objects.
NOT_SETTINGS = {"experiments", "client", "progress"}


def unreachable_settings(record, namespace, signature: inspect.Signature) -> list[str]:
    """Every field of ``record`` the command line (``namespace``: ``tromplab fit``'s parsed
    defaults) or the API (``signature``: of fit_experiments) does not know, or knows with
    another default; and every API keyword that is no field."""
    problems = []
    for field in dataclasses.fields(record):
        expected_cli = field.metadata.get("cli_default", field.default)
        if not hasattr(namespace, field.name):
            problems.append(f"{field.name}: no option of tromplab fit")
        elif getattr(namespace, field.name) != expected_cli:
            problems.append(f"{field.name}: the command line's default {getattr(namespace, field.name)!r} != {expected_cli!r}")
        parameter = signature.parameters.get(field.name)
        if parameter is None:
            problems.append(f"{field.name}: no keyword of fit_experiments")
        elif parameter.default != field.default:
            problems.append(f"{field.name}: the API's default {parameter.default!r} != {field.default!r}")
    names = {field.name for field in dataclasses.fields(record)}
    problems += [
        f"{name}: a keyword of fit_experiments but no setting" for name in set(signature.parameters) - names - NOT_SETTINGS
    ]
    return problems


def fit_defaults():
    return build_parser().parse_args(["fit", "points.csv"])


def test_every_setting_is_an_option_of_the_command_line_and_a_keyword_of_the_api_with_the_same_default():
    assert unreachable_settings(FitSettings, fit_defaults(), inspect.signature(fit_experiments)) == []


def test_the_check_names_a_setting_the_command_line_or_the_api_does_not_know():
    # the check above must fail for an option declared in the record alone
    grown = dataclasses.make_dataclass(
        "Grown", [("new_option", float, dataclasses.field(default=0.5))], bases=(FitSettings,), frozen=True
    )
    assert unreachable_settings(grown, fit_defaults(), inspect.signature(fit_experiments)) == [
        "new_option: no option of tromplab fit",
        "new_option: no keyword of fit_experiments",
    ]
    defaults = fit_defaults()
    defaults.alpha = 0.1
    assert unreachable_settings(FitSettings, defaults, inspect.signature(fit_experiments)) == [
        "alpha: the command line's default 0.1 != 0.05"
    ]


def test_the_command_line_options_become_the_record_field_by_field():
    args = build_parser().parse_args(
        ["fit", "points.csv", "--alpha", "0.1", "--ci", "0.9", "--rank-by", "aicc", "--jobs", "2", "--extended", "--seed", "7"]
    )
    settings = FitSettings.from_options(args)
    assert settings == FitSettings(alpha=0.1, ci=0.9, rank_by="aicc", jobs=2, extended=True, seed=7)
    assert FitSettings.from_options(args, ci=None).ci is None


@pytest.mark.parametrize(
    ("keywords", "option"),
    [
        ({"alpha": 1.5}, "alpha"),
        ({"ci": 0.0}, "ci"),
        ({"jobs": -1}, "jobs"),
        ({"seed": -3}, "seed"),
        ({"rank_by": "ssr"}, "rank_by"),
        ({"bootstrap_method": "wild"}, "bootstrap_method"),
        ({"bootstrap": 10**9}, "bootstrap"),
        ({"partition_to": "middlings"}, "partition_to"),
        ({"water_recovery": 1.0}, "water_recovery"),
    ],
)
def test_a_wrong_setting_is_refused_when_the_record_is_made_naming_the_option(keywords, option):
    with pytest.raises(OptionError) as raised:
        FitSettings(**keywords)
    assert raised.value.option == option


def test_the_record_is_frozen_and_keeps_a_list_of_formulas_as_a_tuple():
    settings = FitSettings(formulas=["plitt", "lognormal"])
    assert settings.formulas == ("plitt", "lognormal")
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.alpha = 0.1


def test_the_workbench_and_its_workers_hold_the_record_the_api_made(tmp_path):
    points = TrompPoints("run", [10, 20, 40, 80, 160], np.array([0.98, 0.91, 0.62, 0.21, 0.04]))
    bench = fit_experiments([points], formulas=["plitt", "lognormal"], alpha=0.1, rank_by="aicc", partition_to="coarse")
    assert bench.settings == FitSettings(formulas=("plitt", "lognormal"), alpha=0.1, rank_by="aicc", partition_to="coarse")
    assert (bench.alpha, bench.rank_by, bench.partition_to) == (0.1, "aicc", "coarse")
    assert all(fit.options.alpha == 0.1 for fit in bench.fits)  # the worker's fits were screened at the record's alpha
    again = fit_with_settings([points], bench.settings)
    assert again.fits_table().equals(bench.fits_table())
    streamed, _ = fit_to_folder([points], tmp_path / "out", settings=bench.settings, figures="none")
    assert streamed.settings is bench.settings


def test_fit_to_folder_refuses_an_unknown_keyword_and_keywords_beside_a_record(tmp_path):
    points = TrompPoints("run", [10, 20, 40, 80, 160], np.array([0.98, 0.91, 0.62, 0.21, 0.04]))
    with pytest.raises(TypeError, match="unexpected keyword argument.*: colour"):
        fit_to_folder([points], tmp_path / "out", colour="red")
    with pytest.raises(TypeError, match="not both: alpha"):
        fit_to_folder([points], tmp_path / "out", settings=FitSettings(), alpha=0.1)
