"""Minerals by size: per-class assays reconciled with the size analyses of a circuit survey.

The truth is the simulated magnetite circuit of :func:`tromplab.circuit.simulation.mineral_circuit`
(a heavy mineral classified finer than the gangue); the surveys reach the reader as a lab
prints them (clipped at 0, rounded to 0.01 %).  The full-size study is
benchmarks/circuit_components.py.
"""

import numpy as np
import pandas as pd
import pytest

from tromplab.circuit import ErrorModel, read_survey, reconcile, reconcile_circuit
from tromplab.circuit.simulation import component_study, lab_survey, mineral_circuit, simulate_survey, survey_table
from tromplab.cli import build_parser, main
from tromplab.errors import InputError, OptionError
from tromplab.loading.points import read_points
from tromplab.output.plotting import offscreen_axes

MINERALS = ("magnetite", "pyrite")


@pytest.fixture(scope="module")
def truth():
    return mineral_circuit()


@pytest.fixture(scope="module")
def surveyed(truth):
    """One survey as a lab reports it (seed 11) and its balance: assays of every sampled stream."""
    survey = lab_survey(truth, np.random.default_rng(11), flows={"fresh_feed": 0.02})
    return survey, reconcile(truth.flowsheet, survey)


def _exact_table(truth, **options) -> pd.DataFrame:
    """The truth written as a survey table without noise or rounding."""
    drawn = simulate_survey(truth, np.random.default_rng(0), errors=ErrorModel(relative_error=0.0, absolute_error=1e-12,
                            assay_relative_error=0.0, assay_absolute_error=1e-12), **options)  # fmt: skip
    return survey_table(drawn, decimals=None)


def test_the_reader_takes_assays_as_fractions_with_the_error_model(truth):
    table = survey_table(simulate_survey(truth, np.random.default_rng(1)))
    errors = ErrorModel(assay_relative_error=0.1, assay_absolute_error=0.002, components={"pyrite": (0.2, 0.001)})
    survey = read_survey(table, truth.flowsheet, errors=errors)
    assert survey.components == MINERALS
    magnetite = survey.assays[survey.assays["component"] == "magnetite"]
    pyrite = survey.assays[survey.assays["component"] == "pyrite"]
    scarce = survey.assays_set_aside
    assert len(magnetite) + np.sum(scarce["component"] == "magnetite") == 4 * truth.classes.shape[0]
    assert len(pyrite) + np.sum(scarce["component"] == "pyrite") == 4 * truth.classes.shape[0]
    assert 0 < len(scarce) < 12  # the overflow's coarsest classes: too little material to assay
    shares = survey.shares.set_index(["stream", "class_index"])["value"]
    assert all(shares[(r.stream, r.class_index)] < 0.001 for r in scarce.itertuples())
    by_row = dict(zip(survey.shares["row"], table["assay_magnetite_pct"] / 100.0))  # the file row of each share
    np.testing.assert_allclose(magnetite["value"].to_numpy(), [by_row[row] for row in magnetite["row"]])
    np.testing.assert_allclose(magnetite["sd"], np.hypot(0.1 * magnetite["value"], 0.002))
    np.testing.assert_allclose(pyrite["sd"], np.hypot(0.2 * pyrite["value"], 0.001))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t: t.assign(assay_magnetite_pct=t["assay_magnetite_pct"].where(t.index != 3, 101.0)), "above 100"),
        (lambda t: t.assign(assay_magnetite_pct=t["assay_magnetite_pct"].where(t.index != 3, -0.5)), "negative assay"),
        (lambda t: t.rename(columns={"assay_pyrite_pct": "assay_solids_pct"}), "other than 'solids'"),
        (lambda t: pd.concat([t, t.iloc[[0]].assign(retained_pct=np.nan)], ignore_index=True), "twice"),
    ],
)
def test_bad_assays_are_refused_naming_the_row_and_column(truth, change, message):
    table = change(survey_table(simulate_survey(truth, np.random.default_rng(1))))
    with pytest.raises(InputError, match=message):
        read_survey(table, truth.flowsheet)


def test_an_assay_override_naming_no_assayed_component_is_refused(truth):
    table = survey_table(simulate_survey(truth, np.random.default_rng(1)))
    with pytest.raises(OptionError, match="galena"):
        read_survey(table, truth.flowsheet, errors=ErrorModel(components={"galena": (0.05, 0.001)}))


@pytest.mark.parametrize(
    "options",
    [{"assay_absolute_error": 0.6}, {"assay_relative_error": 1.5}, {"assay_relative_error": 0.0, "assay_absolute_error": 0.0},
     {"components": {"pyrite": (0.05,)}}, {"components": {"pyrite": (0.05, 0.9)}}],
)  # fmt: skip
def test_assay_errors_out_of_range_are_refused(options):
    with pytest.raises(OptionError):
        ErrorModel(**options)


def test_exact_data_give_the_true_partition_of_every_mineral(truth):
    survey = read_survey(_exact_table(truth), truth.flowsheet)
    balance = reconcile(truth.flowsheet, survey)
    assert balance.chi_square < 1e-6  # against about 33 on its 33 degrees of freedom with noise
    partition = balance.partition_table()
    for mineral in MINERALS:
        rows = partition[partition["component"] == mineral]
        np.testing.assert_allclose(rows["partition_fine"], truth.component_partitions[("cyclone", mineral)], atol=1e-6)
    scale = truth.flows[0] / balance.flows[0]  # flows per 100 of the fresh feed
    np.testing.assert_allclose(balance.component_flows * scale, truth.component_flows, rtol=1e-6, atol=1e-6)


def test_each_mineral_balances_per_class_at_the_cyclone_and_in_total_at_the_mill(surveyed, truth):
    _, balance = surveyed
    index = truth.flowsheet.stream_index
    flows = balance.component_flows
    feed, over, under, fresh = (index[s] for s in ("cyclone_feed", "cyclone_overflow", "cyclone_underflow", "fresh_feed"))
    np.testing.assert_allclose(flows[:, feed], flows[:, over] + flows[:, under], atol=1e-8)
    np.testing.assert_allclose(flows[:, fresh].sum(axis=1) + flows[:, under].sum(axis=1), flows[:, feed].sum(axis=1))
    assert not np.allclose(flows[:, fresh] + flows[:, under], flows[:, feed], atol=1e-3)  # the mill grinds: not per class


def test_each_separators_partition_per_mineral_is_within_its_uncertainty_of_the_truth(surveyed, truth):
    """Acceptance: a survey with per-class assays of two minerals gives the cyclone's partition
    per mineral within its stated uncertainty of the simulated truth."""
    _, balance = surveyed
    partition = balance.partition_table()
    for mineral in MINERALS:
        rows = partition[(partition["experiment"] == "cyclone") & (partition["component"] == mineral)]
        used = rows["used"].astype(bool).to_numpy()
        assert used.sum() >= 8
        z = (rows["partition_fine"].to_numpy() - truth.component_partitions[("cyclone", mineral)]) / rows["partition_sd"]
        assert np.all(np.abs(z[used]) < 3.0), (mineral, z[used])
    recoveries = balance.components_table()
    assert list(recoveries["component"]) == list(MINERALS) and recoveries["determined"].all()
    for row in recoveries.itertuples():
        k = truth.components.index(row.component)
        over, under = truth.flowsheet.stream_index["cyclone_overflow"], truth.flowsheet.stream_index["cyclone_underflow"]
        true = truth.component_flows[k, over].sum() / truth.component_flows[k][[over, under]].sum()
        assert row.recovery_fine_low <= true <= row.recovery_fine_high
        assert 0.0 <= row.recovery_fine_low < row.recovery_fine < row.recovery_fine_high <= 1.0


def test_the_heavy_mineral_reports_to_the_underflow_finer_than_the_solids(surveyed):
    _, balance = surveyed
    partition = balance.partition_table()
    solids = partition[partition["component"] == "solids"]["partition_fine"].to_numpy()
    magnetite = partition[partition["component"] == "magnetite"]["partition_fine"].to_numpy()
    middle = slice(4, 9)  # 150 um down to 20 um, around the cuts
    assert np.all(magnetite[middle] < solids[middle])


def test_a_separator_assayed_in_one_product_only_leaves_the_mineral_undetermined(truth):
    table = survey_table(simulate_survey(truth, np.random.default_rng(3), flows={"fresh_feed": 0.02},
                                         assayed=("cyclone_overflow",)))  # fmt: skip
    balance = reconcile(truth.flowsheet, read_survey(table, truth.flowsheet))
    partition = balance.partition_table()
    minerals = partition[partition["component"] != "solids"]
    determined = minerals["partition_fine"].notna().to_numpy()
    # none in the overflow: zero to the rounding of the linear algebra, whose last bits follow
    # the memory alignment of the arrays (3.5e-7 was seen in one whole-suite run, 0.0 alone)
    assert determined.sum() <= 2 and np.all(np.abs(minerals["partition_fine"].to_numpy()[determined]) < 1e-5)
    flags = minerals["flag"][~determined]
    assert (flags != "").all() and flags.str.contains("not determined").mean() > 0.9  # the rest: outside 0..1
    components = balance.components_table()
    assert not components["determined"].any() and components["recovery_fine"].isna().all()
    solids = partition[partition["component"] == "solids"]
    assert solids["partition_fine"].notna().sum() >= 8


def test_without_assays_the_outputs_gain_only_the_component_column(truth):
    table = survey_table(simulate_survey(truth, np.random.default_rng(1))).drop(
        columns=["assay_magnetite_pct", "assay_pyrite_pct"]
    )
    balance = reconcile(truth.flowsheet, read_survey(table, truth.flowsheet))
    assert set(balance.partition_table()["component"]) == {"solids"}
    assert set(balance.points_table()["component"]) == {"solids"}
    assert balance.components_table().empty
    assert "component" not in balance.adjustments_table().columns


@pytest.mark.slow
def test_an_assay_can_be_left_out_and_the_elimination_names_it(truth):
    rng = np.random.default_rng(5)
    survey = lab_survey(truth, rng, flows={"fresh_feed": 0.02})
    assays = survey.assays.copy()
    slip = (assays["stream"] == "cyclone_underflow") & (assays["component"] == "magnetite") & (assays["class_index"] == 6)
    assays.loc[slip, "value"] += 12 * assays.loc[slip, "sd"]
    balance = reconcile(truth.flowsheet, survey.__class__(**{**survey.__dict__, "assays": assays}))
    assert balance.rejected
    first = balance.elimination_table().iloc[1]
    assert first["kind"] == "assay_magnetite_pct" and "magnetite assay" in first["measurement"]
    named = f"{first['stream']}:{first['kind']}:{first['size_class']}"
    again = reconcile(truth.flowsheet, survey.__class__(**{**survey.__dict__, "assays": assays}), exclude=[named])
    assert again.dof == balance.dof - 1 and again.chi_square < balance.chi_square


@pytest.mark.slow
def test_the_command_writes_the_components_and_fits_a_curve_per_separator_and_mineral(surveyed, truth, tmp_path):
    survey, _ = surveyed
    sheet = tmp_path / "flowsheet.csv"
    truth.flowsheet.to_frame().to_csv(sheet, index=False)
    table = tmp_path / "survey.csv"
    survey_table(simulate_survey(truth, np.random.default_rng(11), flows={"fresh_feed": 0.02})).to_csv(table, index=False)
    run = reconcile_circuit(sheet, table, fit=True)
    run.save(tmp_path / "out", figures=False)
    written = pd.read_csv(tmp_path / "out" / "components.csv")
    assert list(written["component"]) == list(MINERALS)
    points = read_points(tmp_path / "out" / "points.csv")
    assert [p.experiment for p in points] == ["cyclone", "cyclone:magnetite", "cyclone:pyrite"]
    ranked = run.bench.fits_table()
    assert set(ranked["experiment"]) == {"cyclone", "cyclone:magnetite", "cyclone:pyrite"}
    assert main(["fit", str(tmp_path / "out" / "points.csv"), "-o", str(tmp_path / "fit"), "--no-figures", "--formulas",
                 "plitt"]) == 0  # fmt: skip


def test_the_command_line_takes_the_assay_errors_with_the_api_defaults_and_ranges(tmp_path, capsys):
    args = build_parser().parse_args(["circuit", "sheet.csv", "survey.csv"])
    model = ErrorModel()
    assert (args.assay_relative_error, args.assay_absolute_error) == (model.assay_relative_error, model.assay_absolute_error)
    assert main(["circuit", "sheet.csv", "survey.csv", "-o", str(tmp_path / "out"), "--assay-absolute-error", "0.7"]) == 2
    assert "--assay-absolute-error: is at most 0.5" in capsys.readouterr().err


def test_the_partition_figure_draws_a_curve_per_separator_and_component(surveyed):
    _, balance = surveyed
    ax = balance.plot("partition", ax=offscreen_axes())
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert labels == ["cyclone:solids", "cyclone:magnetite", "cyclone:pyrite"]


@pytest.mark.slow
def test_the_intervals_of_the_mineral_partitions_cover_and_the_test_keeps_its_size(truth):
    """A small version of the study of docs/circuit.md (benchmarks/circuit_components.py)."""
    result = component_study(truth, 12, np.random.default_rng(2026), flows={"fresh_feed": 0.02})
    assert result.checked >= 12 * 2 * 9
    assert 0.90 <= result.coverage <= 0.99
    assert result.recovery_coverage >= 0.8
    assert result.rejected <= 3
