"""The weights of Tromp points (tromplab.loading.weights): one weighting for the lab and the
circuit paths, a partition variance that matches simulation, no class taken as exact, and a
note when a few classes carry most of the weight."""

import io
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tromplab import TrompPoints, curve_indices, fit_formula
from tromplab.circuit import ErrorModel, read_flowsheet, reconcile
from tromplab.circuit.simulation import (
    CircuitTruth,
    classes_from_edges,
    lab_survey,
    plitt_partition_to_fines,
    rosin_rammler_shares,
)
from tromplab.cli import main
from tromplab.errors import OptionError
from tromplab.loading.lab import LabOptions, read_lab
from tromplab.loading.weights import (
    concentration_note,
    partition_variance,
    partition_weights,
    weight_concentration,
    weight_notes,
)
from tromplab.options import (
    DEFAULT_ABSOLUTE_ERROR,
    DEFAULT_PARTITION_FLOOR,
    DEFAULT_RELATIVE_ERROR,
    WEIGHT_CONCENTRATION_SHARE,
)

from .conftest import write

CYCLONE_SHEET = "stream,from,to,product\nfeed,,cyclone,\noverflow,cyclone,,fine\nunderflow,cyclone,,coarse\n"
LOWER = np.array([300, 212, 150, 106, 75, 53, 38, np.nan])
UPPER = np.array([np.nan, 300, 212, 150, 106, 75, 53, 38])
FEED = np.array([0.14, 0.11, 0.12, 0.12, 0.11, 0.10, 0.07, 0.23])
#: A hydrocyclone's partition to the overflow: nothing of the top class reaches the overflow.
PARTITION = np.array([0.0, 0.004, 0.06, 0.30, 0.58, 0.80, 0.90, 0.96])


def _exact_node():
    """Feed, overflow and underflow shares of one hydrocyclone that balance exactly (not rounded)."""
    y = float(np.sum(FEED * PARTITION))
    return FEED, FEED * PARTITION / y, FEED * (1 - PARTITION) / (1 - y)


def _lab_table(feed, fine, coarse) -> pd.DataFrame:
    return pd.DataFrame(
        {"size_lower_um": LOWER, "size_upper_um": UPPER, "feed_frac": feed, "overflow_frac": fine, "underflow_frac": coarse}
    )


def _survey(feed, fine, coarse) -> pd.DataFrame:
    frames = [
        pd.DataFrame({"stream": stream, "size_lower_um": LOWER, "size_upper_um": UPPER, "retained_frac": values})
        for stream, values in (("feed", feed), ("overflow", fine), ("underflow", coarse))
    ]
    return pd.concat(frames, ignore_index=True)


def test_one_node_gives_the_same_weights_and_fits_by_the_lab_and_the_circuit_path():
    shares = _exact_node()
    (lab_balance,) = read_lab(_lab_table(*shares), weighting="error-model")
    lab = lab_balance.to_points()
    (circuit,) = reconcile(pd.read_csv(io.StringIO(CYCLONE_SHEET)), _survey(*shares)).to_points()
    np.testing.assert_allclose(lab.size, circuit.size, rtol=1e-12)
    np.testing.assert_allclose(lab.partition_fine, circuit.partition_fine, atol=1e-10)
    np.testing.assert_allclose(lab.weight, circuit.weight, rtol=1e-10, atol=1e-10)
    assert not np.allclose(lab.weight, 1.0)  # a weighting, not the unweighted fit
    for formula in ("plitt", "rosin_rammler", "whiten"):
        by_lab, by_circuit = fit_formula(lab, formula), fit_formula(circuit, formula)
        assert by_lab.success and by_circuit.success
        np.testing.assert_allclose(by_lab.d_cut, by_circuit.d_cut, rtol=1e-6)
        np.testing.assert_allclose(by_lab.shape, by_circuit.shape, rtol=1e-6)


def test_the_weighting_has_one_name_on_both_faces(tmp_path, capsys):
    path = write(tmp_path, _lab_table(*_exact_node()).to_csv(index=False), "lab.csv")
    out = tmp_path / "points.csv"
    assert main(["points", str(path), "-o", str(out), "--weighting", "error-model"]) == 0
    written = pd.read_csv(out)
    (balance,) = read_lab(path, weighting="error-model")
    np.testing.assert_allclose(written["weight"], balance.points_table()["weight"], rtol=1e-12)
    with pytest.raises(OptionError, match="weighting"):
        read_lab(path, weighting="precision")
    capsys.readouterr()
    assert main(["points", str(path), "-o", str(out), "--weighting", "precision"]) == 2
    assert "--weighting" in capsys.readouterr().err


def test_two_spellings_of_the_feed_share_weighting_agree_and_two_weightings_are_refused(tmp_path, capsys):
    assert LabOptions(weighting="feed-share") == LabOptions(weight_by_feed_share=True)
    with pytest.raises(OptionError, match="weighting is 'error-model' and weight_by_feed_share is set too"):
        LabOptions(weight_by_feed_share=True, weighting="error-model")
    path = write(tmp_path, _lab_table(*_exact_node()).to_csv(index=False), "lab.csv")
    both = ["--weight-by-feed-share", "--weighting", "error-model"]
    assert main(["points", str(path), "-o", str(tmp_path / "points.csv"), *both]) == 2
    assert "--weighting is 'error-model' and --weight-by-feed-share is set too" in capsys.readouterr().err


@pytest.mark.parametrize("phi, share", [(0.5, 0.25), (0.9, 0.1), (0.98, 0.2)])
def test_the_partition_variance_is_that_of_the_partition_computed_from_noisy_products(phi, share):
    """Delta method checked by simulation: product shares drawn from the error model at the
    shares the partition implies, the partition recomputed as y b / (y b + (1 - y) c)."""
    y, r, e = 0.6, 0.05, 0.001
    fine, coarse = share * phi / y, share * (1 - phi) / (1 - y)
    rng = np.random.default_rng(7)
    b = fine + np.hypot(r * fine, e) * rng.standard_normal(400_000)
    c = coarse + np.hypot(r * coarse, e) * rng.standard_normal(400_000)
    simulated = np.std(y * b / (y * b + (1 - y) * c))
    predicted = np.sqrt(partition_variance([phi], [share], y, floor=0.0))[0]
    np.testing.assert_allclose(predicted, simulated, rtol=0.03)


def test_a_class_all_in_one_product_does_not_take_most_of_the_weight():
    """The top class's overflow share is 0: the error model alone gives it a variance from the
    absolute error only; the floor keeps the heaviest two classes below the share of the
    inverse variance of the reconciled partition."""
    balance = reconcile(pd.read_csv(io.StringIO(CYCLONE_SHEET)), _survey(*_exact_node()))
    part = balance.partition_table()
    reconciled = weight_concentration(1.0 / part["partition_sd"].to_numpy() ** 2)
    default = weight_concentration(balance.points_table()["weight"])
    without_floor = weight_concentration(
        partition_weights("error-model", part["partition_fine"], part["feed_share"], part["fine_yield"].iloc[0], floor=0.0)
    )
    assert reconciled.share > 0.55 and without_floor.share > 0.55
    assert default.share < WEIGHT_CONCENTRATION_SHARE
    assert DEFAULT_PARTITION_FLOOR > 0


def test_a_note_names_the_classes_that_carry_most_of_the_weight(tmp_path, capsys):
    feed = np.array([0.40, 0.38, 0.05, 0.05, 0.04, 0.04, 0.02, 0.02])
    y = float(np.sum(feed * PARTITION))
    table = _lab_table(feed, feed * PARTITION / y, feed * (1 - PARTITION) / (1 - y))
    (balance,) = read_lab(table, weighting="feed-share")
    (note,) = [n for n in balance.notes if "of the weight" in n]
    assert note.startswith("2 of 8 classes (300-top um, 212-300 um) carry 78 % of the weight")
    (unweighted,) = read_lab(table)
    assert not any("of the weight" in n for n in unweighted.notes)
    path = write(tmp_path, table.to_csv(index=False), "lab.csv")
    assert main(["points", str(path), "-o", str(tmp_path / "points.csv"), "--weighting", "feed-share"]) == 0
    assert "carry 78 % of the weight" in capsys.readouterr().err.replace("\n", " ")
    points = balance.points_table(unit_in_names=True)
    assert weight_notes(points) == [f"note ({balance.experiment}): {note}"]


def test_the_concentration_threshold_needs_enough_classes():
    assert concentration_note([5.0, 1.0, 1.0], ["a", "b", "c"]) is None  # three classes: two always carry much
    assert concentration_note([1.0] * 8, list("abcdefgh")) is None
    assert "2 of 4 classes (a, b)" in concentration_note([3.0, 2.0, 0.5, 0.5], list("abcd"))


@pytest.mark.slow
def test_on_simulated_surveys_the_default_weights_no_longer_let_two_classes_move_the_cut():
    """benchmarks/circuit_weights.py in small: lab-reported surveys of one hydrocyclone (Plitt's
    corrected curve of the simulation), fitted with the registry's log-logistic ``plitt`` (a
    curve of another form, as most ranked formulas are): the former weights (1/sd^2 of the
    reconciled partition) put Ep 10-15 % off, the default within a third of that (200 surveys:
    14.6 % and 5.6 % RMSE)."""
    edges = [38, 53, 75, 106, 150, 212, 300]
    classes = classes_from_edges(edges)
    phi = plitt_partition_to_fines(classes["size"], 100.0, 2.5)
    feed = 100.0 * rosin_rammler_shares(edges, 150.0, 1.0)
    sheet = read_flowsheet(pd.read_csv(io.StringIO(CYCLONE_SHEET)))
    truth = CircuitTruth(sheet, classes, np.vstack([feed, feed * phi, feed * (1 - phi)]), partitions={"cyclone": phi})
    true_ep = curve_indices("rosin_rammler_bypass", 100.0, 2.5, delta_max=600.0, bypass=0.0).ep
    rng = np.random.default_rng(11)
    errors, shares = {"former": [], "default": []}, {"former": [], "default": []}
    for _ in range(12):
        balance = reconcile(sheet, lab_survey(truth, rng))
        part = balance.partition_table()  # the rows of points_table, in the same order
        used = part["used"].to_numpy()
        former = 1.0 / part["partition_sd"].to_numpy()[used] ** 2
        default = balance.points_table()["weight"].to_numpy()[used]
        for name, weight in (("former", former / former.mean()), ("default", default)):
            points = TrompPoints("cyclone", part["size"].to_numpy()[used], part["partition_fine"].to_numpy()[used], weight)
            fit = fit_formula(points, "plitt", delta_max=600.0)
            errors[name].append(fit.indices.ep / true_ep - 1.0)
            shares[name].append(weight_concentration(weight).share)
    rmse = {name: np.sqrt(np.mean(np.square(values))) for name, values in errors.items()}
    assert rmse["former"] > 0.08 and rmse["default"] < rmse["former"] / 2
    assert np.median(shares["former"]) > WEIGHT_CONCENTRATION_SHARE > np.median(shares["default"])


@pytest.mark.slow
def test_tromplab_circuit_says_when_two_classes_carry_most_of_the_weight(tmp_path, capsys):
    feed = np.array([0.40, 0.38, 0.05, 0.05, 0.04, 0.04, 0.02, 0.02])  # two classes hold most of the feed
    y = float(np.sum(feed * PARTITION))
    write(tmp_path, CYCLONE_SHEET, "sheet.csv")
    _survey(feed, feed * PARTITION / y, feed * (1 - PARTITION) / (1 - y)).to_csv(tmp_path / "survey.csv", index=False)
    out = tmp_path / "out"
    assert main(["circuit", str(tmp_path / "sheet.csv"), str(tmp_path / "survey.csv"), "-o", str(out)]) == 0
    printed = capsys.readouterr().err
    (note,) = weight_notes(pd.read_csv(out / "points.csv"))
    assert note.startswith("note (cyclone): 2 of 8 classes (300-top um, 212-300 um) carry")
    said = note.replace("note (cyclone): ", "warning (cyclone): ", 1)  # on standard error, as the fit says it
    assert " ".join(said.split()) in " ".join(printed.split())  # the console wraps it at 98 columns
    assert note in (out / "summary.txt").read_text(encoding="utf-8")
    listed = pd.read_csv(out / "warnings.csv", keep_default_na=False)  # every occurrence, in the results folder
    assert listed.to_dict("records") == [
        {"separator": "cyclone", "formula": "", "code": "weight-concentrated", "message": note.split(": ", 1)[1]}
    ]


def test_the_textbook_table_gives_the_same_weights_by_both_paths_to_its_rounding():
    """tests/data/hydrocyclone_size_class_um.csv balances to its printed 1e-6: the lab path and
    the one-node survey agree on the weights to that order."""
    textbook = Path(__file__).resolve().parent / "data" / "hydrocyclone_size_class_um.csv"
    lab = pd.read_csv(textbook, comment="#")
    survey = pd.concat(
        [
            pd.DataFrame({"stream": stream, "size_class_um": lab["size_class_um"], "retained_pct": lab[f"{stream}_pct"]})
            for stream in ("feed", "overflow", "underflow")
        ],
        ignore_index=True,
    )
    (circuit,) = reconcile(pd.read_csv(io.StringIO(CYCLONE_SHEET)), survey).to_points()
    (by_lab,) = read_lab(textbook, weighting="error-model")
    np.testing.assert_allclose(by_lab.to_points().weight, circuit.weight, atol=1e-6)


def test_the_circuit_weights_follow_the_error_model_of_each_product():
    shares = _exact_node()
    errors = ErrorModel(streams={"overflow": (0.02, 0.0005)})
    balance = reconcile(pd.read_csv(io.StringIO(CYCLONE_SHEET)), _survey(*shares), errors=errors)
    part = balance.partition_table()
    expected = partition_weights(
        "error-model",
        part["partition_fine"],
        part["feed_share"],
        part["fine_yield"].iloc[0],
        part["used"],
        fine_error=(0.02, 0.0005),
        coarse_error=(DEFAULT_RELATIVE_ERROR, DEFAULT_ABSOLUTE_ERROR),
    )
    np.testing.assert_allclose(balance.points_table()["weight"], expected, rtol=1e-12)
    default = reconcile(pd.read_csv(io.StringIO(CYCLONE_SHEET)), _survey(*shares)).points_table()["weight"]
    assert not np.allclose(default, expected, rtol=1e-3)


def test_the_circuit_points_take_the_other_weightings_and_refuse_an_unknown_one():
    balance = reconcile(pd.read_csv(io.StringIO(CYCLONE_SHEET)), _survey(*_exact_node()))
    np.testing.assert_array_equal(balance.points_table(weighting="none")["weight"], np.ones(len(FEED)))
    np.testing.assert_allclose(balance.points_table(weighting="feed-share")["weight"], FEED, rtol=1e-9)
    (lab,) = read_lab(_lab_table(*_exact_node()), weighting="feed-share")
    np.testing.assert_allclose(balance.to_points(weighting="feed-share")[0].weight, lab.to_points().weight, rtol=1e-9)
    with pytest.raises(OptionError, match="weighting"):
        balance.points_table(weighting="precision")


@pytest.mark.parametrize("weighting", ["none", "feed-share", "error-model"])
@pytest.mark.slow
def test_the_circuit_command_takes_the_weighting_of_the_lab_path(tmp_path, capsys, weighting):
    from tromplab.circuit import reconcile_circuit

    from .conftest import DATASETS

    sheet, survey = DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv"
    assert main(["circuit", str(sheet), str(survey), "-o", str(tmp_path / "cli"), "--no-figures", "--weighting", weighting]) == 0
    capsys.readouterr()
    run = reconcile_circuit(sheet, survey, weighting=weighting)
    run.save(tmp_path / "api", figures=False)
    cli_points = (tmp_path / "cli" / "points.csv").read_bytes()
    assert cli_points == (tmp_path / "api" / "points.csv").read_bytes()
    points = pd.read_csv(tmp_path / "cli" / "points.csv")
    used = points[points["used"] == "yes"]
    expected = run.balance.points_table(weighting=weighting)
    assert np.allclose(used["weight"], expected.loc[expected["used"] == "yes", "weight"], rtol=1e-12)
    if weighting == "none":
        assert (used["weight"] == 1.0).all()
    else:
        assert used["weight"].std() > 0.01  # the classes are weighted unequally


def test_the_circuit_refuses_an_unknown_weighting_in_the_words_of_each_face(tmp_path, capsys):
    from tromplab.circuit import reconcile_circuit

    from .conftest import DATASETS

    sheet, survey = DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv"
    with pytest.raises(OptionError, match="weighting"):
        reconcile_circuit(sheet, survey, weighting="inverse")
    assert main(["circuit", str(sheet), str(survey), "-o", str(tmp_path / "cli"), "--weighting", "inverse"]) == 2
    assert "--weighting" in capsys.readouterr().err
    assert not (tmp_path / "cli").exists() and not (tmp_path / "api").exists()
