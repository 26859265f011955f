"""Survey design and readable results of a circuit survey: ``tromplab circuit design`` (a survey
taken or simulated from the flowsheet), design.csv's predictions checked by reconciling again,
the measurements a candidate makes testable, observability.csv, the next steps, and the
console table of ``--fit``."""

import numpy as np
import pandas as pd
import pytest

from tromplab.circuit import ErrorModel, design_circuit, read_flowsheet, read_survey, reconcile
from tromplab.circuit.design import (
    DESIGN_COLUMNS,
    OBSERVABILITY_COLUMNS,
    observability_table,
    select_quantities,
    survey_with,
)
from tromplab.circuit.outputs import next_steps
from tromplab.circuit.planning import design_advice, simulated_survey
from tromplab.circuit.simulation import example_plant, grinding_circuit, lab_survey, simulate_survey, survey_table
from tromplab.cli import main
from tromplab.errors import OptionError

from .test_circuit import _grinding_circuit_with_water, _with_pct_solids

#: The columns the design table must start with (the rest are documented extras).
NAMED_COLUMNS = ["stream", "measurement", "quantity", "sd_before", "sd_after"]


def _files(tmp_path, truth, flows=None, seed=2):
    """The flowsheet and a simulated survey of ``truth`` as a lab reports it, written as CSV files."""
    sheet, survey = tmp_path / "sheet.csv", tmp_path / "survey.csv"
    truth.flowsheet.to_frame().to_csv(sheet, index=False)
    survey_table(simulate_survey(truth, np.random.default_rng(seed), flows=flows)).to_csv(survey, index=False)
    return sheet, survey


def _observed_sd(flowsheet, survey, quantity: str) -> float:
    """The sd of ``quantity`` after reconciling ``survey`` (the delta method at the new reconciled values)."""
    again = reconcile(flowsheet, survey)
    gradient = dict(select_quantities(again, [quantity]))[quantity]
    return float(np.sqrt(gradient @ again.covariance @ gradient))


@pytest.mark.slow
def test_the_design_command_ranks_candidates_and_its_top_one_delivers_the_predicted_sd(tmp_path, capsys):
    """design.csv has the named columns, ranked; the top candidate, added to the survey at its
    reconciled value with its stated error and reconciled again, gives the predicted sd within
    10 % (measured: within 0.1 %) and below the sd before."""
    truth = example_plant()
    sheet, survey = _files(tmp_path, truth, flows={"screen_feed": 0.02})
    out = tmp_path / "design"
    assert main(["circuit", "design", str(sheet), str(survey), "-o", str(out)]) == 0
    table = pd.read_csv(out / "design.csv", keep_default_na=False)
    assert list(table.columns[1:6]) == NAMED_COLUMNS and list(table.columns) == DESIGN_COLUMNS
    assert table["rank"].tolist() == list(range(1, len(table) + 1))
    assert table["reduction"].is_monotonic_decreasing
    top = table.iloc[0]
    balance = reconcile(sheet, survey)
    observed = _observed_sd(balance.flowsheet, survey_with(balance, top["stream"], top["measurement"]), top["quantity"])
    assert observed == pytest.approx(float(top["sd_after"]), rel=0.10)
    assert observed < float(top["sd_before"])
    assert f"1. {top['measurement']} of {top['stream']}" in capsys.readouterr().out


@pytest.mark.parametrize("measurement", ["solids flow", "size analysis", "repeat size analysis", "per cent solids"])
def test_each_kind_of_candidate_delivers_its_predicted_sd(measurement):
    """The best candidate of each kind (a flow, an analysis of the unsampled stream, a repeat,
    a per cent solids on the grinding circuit with water) gives the predicted sd within 10 %."""
    if measurement == "per cent solids":
        truth, sheet, _ = _grinding_circuit_with_water()
        table = _with_pct_solids(
            survey_table(simulate_survey(truth, np.random.default_rng(5))), {"cyclone_underflow": 74.0}, sd=1.0
        )
        table.loc[0, "solids_flow"] = 250.0
        balance = reconcile(sheet, table)
    else:
        truth = example_plant()
        sheet = truth.flowsheet
        balance = reconcile(sheet, lab_survey(truth, np.random.default_rng(2), flows={"screen_feed": 0.02}))
    design = balance.design_table()
    best = design[design["measurement"] == measurement].iloc[0]
    observed = _observed_sd(sheet, survey_with(balance, best["stream"], measurement), best["quantity"])
    assert observed == pytest.approx(best["sd_after"], rel=0.10)


def test_without_a_survey_the_advice_is_simulated_says_so_and_holds_on_the_simulated_survey(tmp_path):
    truth = grinding_circuit()
    sheet = tmp_path / "sheet.csv"
    truth.flowsheet.to_frame().to_csv(sheet, index=False)
    out = tmp_path / "design"
    assert main(["circuit", "design", str(sheet), "-o", str(out), "--flows", "fresh_feed"]) == 0
    summary = (out / "summary.txt").read_text(encoding="utf-8")
    assert "a survey simulated from the flowsheet" in summary and "Rosin-Rammler" in summary
    assert "solids flows measured on fresh_feed" in summary
    simulated = read_survey(out / "simulated_survey.csv", truth.flowsheet)  # the survey as a lab table, read back
    assert reconcile(truth.flowsheet, simulated).chi_square < 0.05  # at the expected values, rounded to 0.01 %: little to adjust
    advice = design_advice(truth.flowsheet, flows=["fresh_feed"])
    table = pd.read_csv(out / "design.csv")
    np.testing.assert_allclose(table["sd_after"], advice.table["sd_after"], rtol=1e-9)
    top = advice.table.iloc[0]
    observed = _observed_sd(truth.flowsheet, survey_with(advice.balance, top["stream"], top["measurement"]), top["quantity"])
    assert observed == pytest.approx(top["sd_after"], rel=0.10)


def test_the_simulated_separators_cut_at_their_feeds_geometric_mean_size():
    """The simulated plant's stated assumption: each separator's partition is 1/2 at the
    geometric mean size of its own feed (the fixed point, recycles included)."""
    truth = example_plant()
    survey, words = simulated_survey(truth.flowsheet)
    balance = reconcile(truth.flowsheet, survey)
    log_size = np.log(survey.classes["size"].to_numpy(float))
    for node in truth.flowsheet.separators:
        feed = sum(balance.class_flows[truth.flowsheet.stream_index[s]] for s in node.inputs)
        cut = np.exp(feed @ log_size / feed.sum())
        fine = balance.class_flows[truth.flowsheet.stream_index[node.fine]]
        fed = feed > 0
        phi = np.interp(np.log(cut), log_size[fed][::-1], (fine[fed] / feed[fed])[::-1])
        assert phi == pytest.approx(0.5, abs=0.05), node.name
    assert "cut at the geometric mean size of its feed" in words


def test_the_command_line_and_python_write_the_same_files(tmp_path):
    truth = example_plant()
    sheet, survey = _files(tmp_path, truth)
    assert main(["circuit", "design", str(sheet), str(survey), "-o", str(tmp_path / "cli"), "--quantity", "fine yield",
                 "--relative-error", "0.08"]) == 0  # fmt: skip
    design_circuit(sheet, survey, quantity=["fine yield"], errors=ErrorModel(relative_error=0.08)).save(tmp_path / "api")
    for name in ("design.csv", "observability.csv", "summary.txt"):
        assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "api" / name).read_bytes(), name
    table = pd.read_csv(tmp_path / "api" / "design.csv")
    assert set(table["quantity"]) == {"fine yield top_deck", "fine yield bottom_deck", "fine yield cyclone"}
    assert table["stated_error"].str.contains("8 % relative").any()


def test_a_result_or_stream_the_survey_lacks_is_refused_in_the_words_of_each_face(tmp_path, capsys):
    truth = example_plant()
    sheet, survey = _files(tmp_path, truth)
    out = tmp_path / "out"
    assert main(["circuit", "design", str(sheet), str(survey), "-o", str(out), "--quantity", "recovery cyclone"]) == 2
    assert "--quantity names 'recovery cyclone', not a result of this survey" in capsys.readouterr().err
    assert main(["circuit", "design", str(sheet), "-o", str(out), "--sampled", "cyclone_feed,nowhere"]) == 2
    assert "--sampled names 'nowhere', not a stream of the flowsheet" in capsys.readouterr().err
    assert not out.exists()  # nothing written
    with pytest.raises(OptionError, match="^quantity names 'recovery cyclone'"):
        design_circuit(sheet, survey, quantity="recovery cyclone")
    with pytest.raises(OptionError, match="^sampled describes a survey to simulate"):
        design_circuit(sheet, survey, sampled=["oversize"])


def test_a_candidate_makes_testable_what_the_reconciliation_then_tests():
    """A measurement listed in makes_testable has no measurement test in the survey and gets one
    once the candidate is added; the candidate itself is testable when it says so."""
    truth = grinding_circuit()
    balance = reconcile(truth.flowsheet, lab_survey(truth, np.random.default_rng(2), flows={"fresh_feed": 0.02}))
    design = balance.design_table()
    row = design[design["n_made_testable"] > 0].iloc[0]
    before = balance.adjustments_table().set_index("measurement")["measurement_test"]
    again = reconcile(truth.flowsheet, survey_with(balance, row["stream"], row["measurement"]))
    after = again.adjustments_table().set_index("measurement")["measurement_test"]
    for name in row["makes_testable"].split("; "):
        assert np.isnan(before[name]) and np.isfinite(after[name]), name
    assert (design.loc[design["n_made_testable"] == 0, "makes_testable"] == "").all()


def test_the_first_flow_on_a_survey_scaled_by_a_basis_changes_no_relative_sd():
    """Without a measured flow the flows are relative to a feed of 100; the first flow measured
    replaces that basis, so design.csv predicts no change, and reconciling again agrees."""
    truth = grinding_circuit()
    balance = reconcile(truth.flowsheet, lab_survey(truth, np.random.default_rng(4)))
    assert balance.basis
    design = balance.design_table()
    flows = design[design["measurement"] == "solids flow"]
    assert len(flows) and (flows["reduction"] == 0).all() and (flows["sd_after"] == flows["sd_before"]).all()
    assert not flows["testable"].any()
    # the rounding of the updates is no reduction: none below 1e-12, none negative, none above 1
    reduction = design["reduction"]
    assert ((reduction == 0) | (reduction >= 1e-12)).all() and (reduction <= 1).all()
    row = flows.iloc[0]
    observed = _observed_sd(truth.flowsheet, survey_with(balance, row["stream"], "solids flow"), row["quantity"])
    assert observed == pytest.approx(row["sd_before"], rel=0.01)


def test_observability_names_what_would_determine_an_unobservable_water_flow():
    """The mill water of a grinding circuit whose fresh feed has no per cent solids is not
    observable; observability.csv names that per cent solids, and measuring it makes it so."""
    truth, sheet, _ = _grinding_circuit_with_water()
    pct = {"cyclone_feed": 55.0, "cyclone_overflow": 33.0, "cyclone_underflow": 74.0}
    table = _with_pct_solids(survey_table(simulate_survey(truth, np.random.default_rng(5))), pct, sd=1.0)
    balance = reconcile(sheet, table)
    found = observability_table(balance)
    assert list(found.columns) == OBSERVABILITY_COLUMNS
    mill = found[(found["stream"] == "mill_water") & (found["quantity"] == "water flow")].iloc[0]
    assert mill["observable"] == "no" and "per cent solids of fresh_feed" in mill["made_observable_by"]
    assert (found.loc[found["quantity"] == "solids flow", "observable"] == "relative to the basis").all()
    water = balance.water_table().set_index("stream")
    seen = found[(found["quantity"] == "water flow") & (found["observable"] == "yes")].set_index("stream")
    np.testing.assert_allclose(seen["reconciled"], water.loc[seen.index, "water_flow"], rtol=1e-6)
    again = reconcile(sheet, survey_with(balance, "fresh_feed", "per cent solids"))
    assert (observability_table(again).query("quantity == 'water flow'")["observable"] == "yes").all()
    assert "the survey leaves" in next_steps(balance)[0] and "per cent solids of fresh_feed" in next_steps(balance)[0]


def test_an_unsampled_stream_is_observable_with_its_sd():
    truth = example_plant()
    balance = reconcile(truth.flowsheet, lab_survey(truth, np.random.default_rng(2), flows={"screen_feed": 0.02}))
    found = observability_table(balance).set_index(["stream", "quantity"])
    row = found.loc[("top_deck_undersize", "size distribution")]
    assert row["observable"] == "yes" and row["reconciled_sd"] == pytest.approx(balance.share_sd[2].max(), rel=1e-6)
    flow = found.loc[("cyclone_feed", "solids flow")]
    assert flow["reconciled"] == pytest.approx(balance.flows[5]) and flow["reconciled_sd"] == pytest.approx(balance.flow_sd[5])


@pytest.mark.slow
def test_the_console_names_the_next_steps_and_prints_the_fits_as_tromplab_fit_does(tmp_path, capsys):
    truth = example_plant()
    drawn = simulate_survey(truth, np.random.default_rng(3), flows={"screen_feed": 0.01, "oversize": 0.05, "middlings": 0.05,
                            "cyclone_overflow": 0.05}, gross=("middlings", -1, -8.0))  # fmt: skip
    sheet, survey = tmp_path / "sheet.csv", tmp_path / "survey.csv"
    truth.flowsheet.to_frame().to_csv(sheet, index=False)
    survey_table(drawn).to_csv(survey, index=False)
    assert main(["circuit", str(sheet), str(survey), "-o", str(tmp_path / "out"), "--fit", "--no-figures"]) == 0
    printed = capsys.readouterr().out
    steps = printed.split("\nNext:\n")[1].split("\n\n")[0]
    assert steps.startswith("  1. check the measurement(s) the serial elimination names (middlings:flow")
    assert "--exclude middlings:flow" in steps and "  2. for the next survey, add the" in steps
    assert "Experiment cyclone (n = " in printed and "ranked by F (highest first)" in printed  # the fit command's table
    assert "sizes (d50, d50c) in um" in printed
    summary = (tmp_path / "out" / "summary.txt").read_text(encoding="utf-8")
    assert summary.count("\nnext: ") == 2
    assert read_flowsheet(sheet).stream_names == truth.flowsheet.stream_names


# --- the flowsheet figure ----------------------------------------------------------------------
#: A flowsheet that crowds a figure: two feeds into one node, a feed into a later node, long
#: names, and a recycle back over two columns.
CROWDED = pd.DataFrame({
    "stream": ["new_feed_from_the_crusher_line", "second_feed", "primary_cyclone_feed", "primary_overflow_to_flotation",
               "primary_underflow", "secondary_feed_long_name", "secondary_fines", "secondary_coarse_back_to_mill"],
    "from": ["", "", "mill", "cyclone_1", "cyclone_1", "", "screen", "screen"],
    "to": ["mill", "mill", "cyclone_1", "", "screen", "screen", "", "mill"],
    "product": ["", "", "ground", "fine", "coarse", "", "fine", "coarse"],
})  # fmt: skip


def _drawn_flowsheet(which):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from tromplab.circuit.plotting import figure_size, plot_flowsheet
    from tromplab.output.plotting import offscreen_axes

    if which == "crowded":
        subject = read_flowsheet(CROWDED)
    elif which == "water":
        truth, sheet, _ = _grinding_circuit_with_water()
        pct = {"fresh_feed": 90.0, "cyclone_feed": 55.0, "cyclone_overflow": 33.0, "cyclone_underflow": 74.0}
        subject = reconcile(sheet, _with_pct_solids(survey_table(simulate_survey(truth, np.random.default_rng(5))), pct, sd=1.0))
    else:
        truth = {"example": example_plant, "grinding": grinding_circuit}[which]()
        subject = reconcile(truth.flowsheet, lab_survey(truth, np.random.default_rng(2), flows={truth.flowsheet.feeds[0]: 0.02}))
    ax = offscreen_axes(figsize=figure_size(subject, "flowsheet"))
    plot_flowsheet(subject, ax=ax)
    FigureCanvasAgg(ax.figure).draw()
    return subject, ax


def _polyline_points(annotation, step: float = 1.0) -> np.ndarray:
    """Points every ``step`` pixels along the drawn arrow (its line and head), in display coordinates."""
    patch = annotation.arrow_patch
    path = patch.get_transform().transform_path(patch.get_path())
    points = []
    for line in path.to_polygons(closed_only=False):
        for a, b in zip(line[:-1], line[1:]):
            count = max(2, int(np.hypot(*(b - a)) / step) + 1)
            points.append(a + np.linspace(0.0, 1.0, count)[:, None] * (b - a))
    return np.vstack(points)


@pytest.mark.parametrize("which", ["example", "grinding", "water", "crowded"])
@pytest.mark.slow
def test_no_label_of_the_flowsheet_lies_over_a_box_an_arrow_or_another_label(which):
    """From the drawn bounding boxes (get_window_extent after the canvas is drawn): each label's
    extent meets no node box, no other label and no point of any arrow's line."""
    from tromplab.circuit.plotting import flowsheet_overlaps

    _, ax = _drawn_flowsheet(which)
    labels = [t for t in ax.texts if t.get_gid() == "label"]
    boxes = [t.get_bbox_patch().get_window_extent() for t in ax.texts if t.get_gid() == "node"]
    arrows = [a for a in ax.texts if a.get_gid() == "stream"]
    assert len(labels) == len(arrows) >= 4 and boxes
    extents = [label.get_window_extent() for label in labels]
    for k, extent in enumerate(extents):
        name = labels[k].get_text()
        assert not any(extent.overlaps(box) for box in boxes), name
        assert not any(extent.overlaps(other) for j, other in enumerate(extents) if j != k), name
        for arrow in arrows:
            points = _polyline_points(arrow)
            inside = (
                (points[:, 0] > extent.x0) & (points[:, 0] < extent.x1) & (points[:, 1] > extent.y0) & (points[:, 1] < extent.y1)
            )
            assert not inside.any(), name
    assert flowsheet_overlaps(ax) == []


def test_a_recycle_is_drawn_back_below_the_nodes_in_its_own_colour():
    from matplotlib.colors import to_hex

    from tromplab.circuit.plotting import RECYCLE_COLOUR, STREAM_COLOUR

    balance, ax = _drawn_flowsheet("example")
    arrows = [a for a in ax.texts if a.get_gid() == "stream"]
    colours = [to_hex(a.arrow_patch.get_edgecolor()) for a in arrows]
    names = balance.flowsheet.stream_names
    assert colours[names.index("cyclone_underflow")] == RECYCLE_COLOUR
    assert colours.count(RECYCLE_COLOUR) == 1 and colours.count(STREAM_COLOUR) == len(names) - 1
    recycle = _polyline_points(arrows[names.index("cyclone_underflow")])
    lowest_box = min(t.get_bbox_patch().get_window_extent().y0 for t in ax.texts if t.get_gid() == "node")
    assert recycle[:, 1].min() < lowest_box  # it runs back under the boxes, not through them
