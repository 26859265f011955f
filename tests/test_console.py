"""The console a person reads: a warning that repeats across experiments is printed
once per kind with its count and first names, every occurrence is in ``warnings.csv``;
``--quiet`` prints errors and a one-line result, ``-v`` every occurrence."""

import re
import types
import warnings

import numpy as np
import pandas as pd
import pytest

from tromplab.cli import main
from tromplab.curves.measured import unbracketed_cut
from tromplab.errors import YieldWarning
from tromplab.loading.lab import read_experiments
from tromplab.loading.points import TrompPoints
from tromplab.notices import WARNING_KINDS, Notice, code_of, grouped_lines, notice_table, regroup_warnings
from tromplab.workbench import data_notes

EXPERIMENTS, GAPPED_EVERY = 240, 3  # a third of the batch measured with no size near its cut
TWO_FORMULAS = ["--formulas", "plitt,lognormal"]  # the notes concern the data, not the formulas


def lab_batch_file(path) -> set:
    """A points file of 240 experiments as a lab gives it (sizes to 4 digits, partitions to 3
    decimals): Plitt curves with cuts 40-120 um and noise 0.01 on 8 sizes from 10 to 320 um;
    every third experiment has no size within a factor 2.2 of its cut.  Returns the names of the
    experiments whose cut the points, as read back, do not bracket."""
    rng = np.random.default_rng(41)
    sizes = np.geomspace(10, 320, 8)
    lines = ["experiment,size,partition_fine"]
    for i in range(EXPERIMENTS):
        cut, sharpness = rng.uniform(40, 120), rng.uniform(2, 4)
        measured = sizes[(sizes < cut / 2.2) | (sizes > cut * 2.2)] if i % GAPPED_EVERY == 0 else sizes
        phi = np.clip(1 / (1 + (measured / cut) ** sharpness) + rng.normal(0, 0.01, measured.size), 0, 1)
        lines += [f"exp{i:03d},{size:.4g},{p:.3f}" for size, p in zip(measured, phi)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    table = pd.read_csv(path)  # what the reader sees: the rounded values
    return {
        name
        for name, rows in table.groupby("experiment")
        if unbracketed_cut(TrompPoints(name, rows["size"].to_numpy(), rows["partition_fine"].to_numpy()))
    }


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    folder = tmp_path_factory.mktemp("batch")
    unbracketed = lab_batch_file(folder / "batch.csv")
    return folder, unbracketed


def _run(capsys, *arguments) -> tuple[int, str, str]:
    code = main(list(arguments))
    printed = capsys.readouterr()
    return code, printed.out, printed.err


def test_the_batch_has_a_third_of_unbracketed_cuts(batch):
    _, unbracketed = batch
    assert len(unbracketed) == EXPERIMENTS // GAPPED_EVERY
    assert all(int(name[3:]) % GAPPED_EVERY == 0 for name in unbracketed)


@pytest.mark.slow
def test_240_experiments_print_at_most_20_lines_and_every_occurrence_is_in_warnings_csv(batch, capsys):
    folder, unbracketed = batch
    out = folder / "default"
    code, printed, err = _run(capsys, "fit", str(folder / "batch.csv"), "-o", str(out), "--no-figures", "--size-unit", "um")
    assert code == 0
    lines = err.splitlines()
    assert len(lines) <= 20, err
    said = " ".join(lines)
    assert f"{len(unbracketed)} of {EXPERIMENTS} experiments: the cut is not bracketed by the data" in said
    assert "(exp000, exp003, exp006 and 77 more; every one in warnings.csv)" in said
    assert "interval" not in said  # no intervals were asked for: the console does not speak of them
    table = pd.read_csv(out / "warnings.csv", keep_default_na=False)
    assert list(table.columns) == ["experiment", "formula", "code", "message"]
    cut = table[table["code"] == "cut-not-bracketed"]
    assert set(cut["experiment"]) == unbracketed and len(cut) == len(unbracketed)
    assert (cut["formula"] == "").all() and cut["message"].str.startswith("the cut is not bracketed by the data (").all()
    assert not cut["message"].str.contains("interval").any()
    assert "warnings.csv" in printed  # among the files written


@pytest.mark.slow
def test_quiet_prints_only_the_one_line_result_and_verbose_every_occurrence(batch, capsys):
    folder, unbracketed = batch
    quiet = _run(capsys, "fit", str(folder / "batch.csv"), "-o", str(folder / "q"), "--no-figures", "--quiet", *TWO_FORMULAS)
    assert quiet[0] == 0 and len(quiet[2].splitlines()) <= 3
    assert (
        quiet[1]
        == f"tromplab fit: 240 experiment(s) fitted, {len(unbracketed)} warning(s) (warnings.csv); results in {folder / 'q'}\n"
    )
    assert len(pd.read_csv(folder / "q" / "warnings.csv")) == len(unbracketed)
    verbose = _run(capsys, "fit", str(folder / "batch.csv"), "-o", str(folder / "v"), "--no-figures", "-v", *TWO_FORMULAS)
    shown = [line for line in verbose[2].splitlines() if line.startswith("warning (exp")]
    assert {line.split(")")[0].removeprefix("warning (") for line in shown} == unbracketed


@pytest.mark.slow
def test_intervals_are_spoken_of_only_when_asked_for(batch, capsys):
    folder, unbracketed = batch
    code, _, err = _run(capsys, "fit", str(folder / "batch.csv"), "-o", str(folder / "ci"), "--no-figures", "--ci", "0.9",
                        *TWO_FORMULAS)  # fmt: skip
    assert code == 0 and len(err.splitlines()) <= 20
    assert "no interval is given for them" in " ".join(err.split())
    table = pd.read_csv(folder / "ci" / "warnings.csv")
    assert table["message"].str.contains("no interval is given for d_cut").sum() == len(unbracketed)


@pytest.mark.slow  # compares with the folder test_quiet_prints_only_the_one_line_result_and_verbose_every_occurrence writes
def test_the_api_writes_the_same_warnings_csv(batch, tmp_path):
    import tromplab

    folder, unbracketed = batch
    bench = tromplab.fit_experiments(tromplab.read_experiments(folder / "batch.csv"), formulas=["plitt", "lognormal"])
    assert set(bench.warnings_table()["experiment"]) == unbracketed
    bench.save(tmp_path / "api", figures="none")
    assert (tmp_path / "api" / "warnings.csv").read_bytes() == (folder / "q" / "warnings.csv").read_bytes()


def test_every_kind_of_note_the_library_makes_has_its_code():
    sizes = [10.0, 20.0, 40.0, 80.0, 160.0]
    rising = data_notes(TrompPoints("rising", sizes, [0.05, 0.2, 0.6, 0.9, 0.97]))
    below = data_notes(TrompPoints("below", sizes, [0.2, 0.1, 0.05, 0.02, 0.01]), intervals=True)
    assert [code_of(note) for note in rising] == ["partition-rises-with-size"]
    assert [code_of(note) for note in below] == ["cut-not-bracketed"]
    codes = [kind.code for kind in WARNING_KINDS]
    assert len(set(codes)) == len(codes)


def test_a_kind_met_once_keeps_its_words_and_unknown_kinds_group_by_their_words():
    once = grouped_lines([Notice("a", "the measured cut is ambiguous: anywhere from 1 to 3")], total=5, labelled=True)
    assert once == ["warning (a): the measured cut is ambiguous: anywhere from 1 to 3"]
    other = [Notice(f"e{i}", f"odd value {i}.5 seen") for i in range(5)] + [Notice("z", "another thing")]
    lines = grouped_lines(other, total=9)
    assert lines == ["5 of 9 experiments: odd value ... seen (e0, e1, e2 and 2 more; every one in warnings.csv)",
                     "(z): another thing"]  # fmt: skip
    four = grouped_lines(other[:4], total=4, listed_in="")  # "and 1 more" would take its name's place
    assert four == ["4 of 4 experiments: odd value ... seen (e0, e1, e2, e3; -v prints every one)"]


def test_the_scale_notes_of_density_intervals_have_their_kinds_and_chi2_stays_a_word():
    from tromplab.density.dispersion import PooledDispersion
    from tromplab.density.fitting import _scale_note

    def fit(dispersion, pooled):
        return types.SimpleNamespace(dispersion=dispersion, df_resid=10, pooled=pooled)

    own = _scale_note(fit(1.3, None), 0.95)
    pooled = _scale_note(fit(1.05, PooledDispersion(1.4, 400, 40)), 0.95)
    assert [code_of(own), code_of(pooled)] == ["quasi-binomial-intervals", "quasi-binomial-intervals-pooled"]
    notices = [Notice(f"t{i}", own if i % 2 else pooled, "normal") for i in range(6)]
    lines = grouped_lines(notices, total=6, noun="tests", labelled=True)
    assert len(lines) == 2 and all(line.startswith("note: 3 of 6 tests: the intervals use the") for line in lines)
    assert all("chi2/df" in line and "..." not in line for line in lines)
    unknown = grouped_lines([Notice(f"t{i}", f"Pearson chi2/df = {i}.5 seen") for i in range(3)], total=3)
    assert unknown == ["3 of 3 experiments: Pearson chi2/df = ... seen (t0, t1, t2; every one in warnings.csv)"]


def test_warnings_csv_names_are_defended_against_formula_injection(tmp_path):
    from tromplab.output.csv_parts import write_csv

    write_csv(notice_table([Notice("=cmd|' /C calc'!A0", "the cut is not bracketed by the data (x)")]), tmp_path / "w.csv")
    text = (tmp_path / "w.csv").read_text(encoding="utf-8")
    assert "\n=cmd" not in text and "cmd|" in text


def test_the_api_warns_once_per_kind_of_a_contradicted_yield(tmp_path):
    lab = "datasets/double_deck_screen_decks_lab.csv"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found = read_experiments(lab, fine_yield=0.5)  # contradicts both decks' size data
    said = [str(w.message) for w in caught if issubclass(w.category, YieldWarning)]
    assert len(said) == 1 and "2 of 2 experiments: the stated fine yield contradicts the size data" in said[0]
    assert "deck_20mesh, deck_65mesh" in said[0] and caught[0].filename == __file__  # points at the caller
    assert all(any("contradicts" in note for note in b.notes) for b in found.balances)  # each one kept


def test_regrouped_warnings_pass_other_warnings_through():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with regroup_warnings(YieldWarning) as subjects:
            for name in ("a", "b"):
                subjects.begin(name)
                warnings.warn("file.csv: the stated fine yield 0.5 contradicts the size data", YieldWarning, stacklevel=1)
                warnings.warn(f"unrelated {name}", UserWarning, stacklevel=1)
    assert [w.category for w in caught] == [UserWarning, UserWarning, YieldWarning]


def test_the_docs_list_every_code_with_its_level():
    from tromplab.notices import OTHER, level_of

    from .conftest import ROOT

    page = (ROOT / "docs" / "columns.md").read_text(encoding="utf-8")
    for code in [kind.code for kind in WARNING_KINDS] + [OTHER]:
        assert f"| `{code}` | {level_of(code)} |" in page, code


@pytest.mark.slow
def test_trend_writes_its_warnings_and_prints_each_kind_once(tmp_path, capsys):
    from .conftest import ROOT

    series = ROOT / "datasets" / "classifier_trend_surveys.csv"
    arguments = ["trend", str(series), "--formula", "plitt_bypass", "--size-unit", "um", "--no-figures"]
    assert main([*arguments, "-o", str(tmp_path / "trend")]) == 0
    err = capsys.readouterr().err
    said = pd.read_csv(tmp_path / "trend" / "warnings.csv")
    assert list(said.columns) == ["survey", "formula", "code", "message"] and len(said) >= 1
    assert (said["formula"] == "plitt_bypass").all()
    for row in said.itertuples():  # each kind once: here every kind is met once, so each whole
        assert f"warning ({row.survey}, plitt_bypass): {row.message}" in " ".join(err.split())
    assert main([*arguments, "-o", str(tmp_path / "quiet"), "--quiet"]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == "" and quiet.out.startswith(f"tromplab trend: 24 survey(s) charted, {len(said)} warning(s)")


@pytest.mark.slow
def test_density_fit_groups_the_notes_of_its_tests(tmp_path, capsys):
    from .conftest import ROOT

    tracers = ROOT / "datasets" / "density_tracers_dmc_by_size_synthetic.csv"
    assert main(["density", "fit", str(tracers), "-o", str(tmp_path / "density"), "--curves", "normal"]) == 0
    err = " ".join(capsys.readouterr().err.split())
    said = pd.read_csv(tmp_path / "density" / "warnings.csv")
    assert list(said.columns) == ["test", "curve", "code", "message"]
    lost = said[said["code"] == "tracers-lost"]
    assert len(lost) == 4 and lost["message"].str.match(r"\d+ of 480 tracers lost").all()
    assert "note: 4 of 4 tests: some tracers were lost and are not counted (dmc_tracers (2-4 mm)," in err


@pytest.mark.slow
def test_density_predict_says_a_repeated_note_once(tmp_path, capsys):
    from .conftest import ROOT

    washability = ROOT / "datasets" / "density_washability_synthetic.csv"
    out = tmp_path / "pred.csv"
    code = main(["density", "predict", str(washability), "-o", str(out), "--target-ash", "1", "2", "3", "4", "--ep", "0.05"])
    printed = capsys.readouterr().out
    notes = pd.read_csv(out)["note"].dropna()
    assert code == 3 and len(notes) >= 3  # several targets no cut density reaches
    assert printed.count("no cut density") == 1 and f"({notes.size} times)" in printed and "every one in pred.csv" in printed


@pytest.mark.slow
def test_report_prints_each_kind_once(tmp_path, capsys):
    sizes = [10.0, 20.0, 40.0, 80.0, 160.0, 320.0]
    gapped = [0.99, 0.98, 0.96, 0.04, 0.02, 0.01]  # falls across the band between two sizes
    rows = [
        f"e{i},{s:g},{p:.3f}" for i in range(4) for s, p in zip(sizes, gapped if i % 2 else [0.95, 0.85, 0.6, 0.3, 0.1, 0.03])
    ]
    (tmp_path / "points.csv").write_text("experiment,size,partition_fine\n" + "\n".join(rows) + "\n", encoding="utf-8")
    assert main(["report", str(tmp_path / "points.csv"), "-o", str(tmp_path / "r.html"), "--formulas", "plitt"]) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "warning: 2 of 4 experiments: the cut is not bracketed by the data" in err and "(e1, e3; -v prints every one)" in err


@pytest.mark.slow
def test_circuit_prints_the_notes_of_its_separators_once_per_kind(tmp_path, capsys, monkeypatch):
    from tromplab.workbench.result import Workbench

    from .conftest import ROOT

    def unbracketed_everywhere(bench):  # the example's cuts are bracketed: say every separator's is not
        return [Notice(name, "the cut is not bracketed by the data (a gap)") for name in bench.experiments]

    monkeypatch.setattr(Workbench, "notices", unbracketed_everywhere)
    sheet, survey = ROOT / "datasets" / "circuit_example_flowsheet.csv", ROOT / "datasets" / "circuit_example_survey.csv"
    assert main(["circuit", str(sheet), str(survey), "-o", str(tmp_path / "circuit"), "--fit", "--no-figures"]) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert re.search(r"warning: (\d+) of \1 separators: the cut is not bracketed by the data", err), err
    assert "every one in warnings.csv" in err
    listed = pd.read_csv(tmp_path / "circuit" / "warnings.csv")
    assert list(listed.columns) == ["separator", "formula", "code", "message"]
    # every separator's note, plus the weights of the cyclone's points (the bundled example's one)
    unbracketed = listed[listed["code"] == "cut-not-bracketed"]
    assert sorted(unbracketed["separator"]) == ["bottom_deck", "cyclone", "top_deck"]


def test_grouped_warnings_keep_the_digits_of_names_and_group_by_the_numbers():
    from tromplab.output.display import grouped_warnings

    said = [
        ("deck_2", "plitt2", "x50 of run-3 not bracketed: cut at 0.4mm (p = 0.003)"),
        ("deck_7", "plitt2", "x50 of run-3 not bracketed: cut at 0.55mm (p = 2e-05)"),
        ("deck_7", "lynch", "x50 of run-4 not bracketed: cut at 0.6mm (p = 0.1)"),  # another name: another kind
    ]
    assert grouped_warnings(said) == [
        "x50 of run-3 not bracketed: cut at ...mm (p = ...) (2 fits): deck_2: plitt2 (0.4, 0.003); deck_7: plitt2 (0.55, 2e-05)",
        "deck_7, lynch: x50 of run-4 not bracketed: cut at 0.6mm (p = 0.1)",
    ]
