"""The Python API and the command line are two faces of one library: ``fit_experiments``
with the options of ``tromplab fit`` as keywords, then ``bench.save(DIR)``, writes the same
files as the command, byte for byte."""

import filecmp

import pandas as pd
import pytest

import tromplab
from tromplab.cli import main
from tromplab.errors import OptionError

from .conftest import DATASETS

DECK = DATASETS / "double_deck_screen_decks_lab.csv"
TABLES = ("fits.csv", "ranking.csv", "averages.csv")


@pytest.mark.slow
@pytest.mark.parametrize(
    ("options", "keywords"),
    [
        ([], {}),
        (["--ci", "0.95"], {"ci": 0.95}),
        (["--ci", "0.9", "--partition-to", "coarse", "--extended"], {"ci": 0.9, "partition_to": "coarse", "extended": True}),
        (["--bootstrap", "30", "--seed", "4", "--rank-by", "aicc"], {"bootstrap": 30, "seed": 4, "rank_by": "aicc"}),
    ],
)
def test_save_writes_what_the_command_writes(tmp_path, options, keywords):
    command = tmp_path / "command"
    assert main(["fit", str(DECK), "--size-unit", "mm", "--figures", "best", "-q", "-o", str(command), *options]) == 0
    bench = tromplab.fit_experiments(tromplab.read_experiments(DECK), size_unit="mm", **keywords)
    written = bench.save(tmp_path / "api", figures="best")
    assert sorted(written) == sorted(p.name for p in command.iterdir() if not p.name.startswith("."))
    for name in written:
        assert filecmp.cmp(command / name, tmp_path / "api" / name, shallow=False), name


def test_interval_and_partition_options_reach_the_fits_table():
    hydrocyclone = DATASETS.parent / "tests" / "data" / "hydrocyclone_size_class_um.csv"  # a cut its points bracket
    bench = tromplab.fit_experiments(tromplab.read_experiments(hydrocyclone), ci=0.95, partition_to="coarse", formulas=["plitt"])
    fits = bench.fits_table()
    assert {"d_cut_low", "d_cut_high", "slope_coarse"} <= set(fits.columns) and "slope" not in fits.columns
    assert (fits["slope_coarse"] > 0).all()
    assert (fits["d_cut_low"] < fits["d_cut"]).all() and (fits["d_cut"] < fits["d_cut_high"]).all()


def test_workbook_only_when_the_folder_is_an_excel_file(tmp_path):
    bench = tromplab.fit_experiments(tromplab.read_experiments(DECK), size_unit="mm", formulas=["plitt", "lognormal"])
    written = bench.save(tmp_path / "results.xlsx")
    assert list(written) == ["results.xlsx"]
    sheets = pd.read_excel(written["results.xlsx"], sheet_name=None)
    assert {"fits", "ranking", "averages", "balance", "points"} <= set(sheets)


@pytest.mark.parametrize(
    ("keywords", "option", "flag"),
    [
        ({"formulas": "plitt,nonsense"}, "formulas", "--formulas"),
        ({"ci": 1.5}, "ci", "--ci"),
        ({"bootstrap": -1}, "bootstrap", "--bootstrap"),
        ({"bootstrap_method": "jackknife"}, "bootstrap_method", "--bootstrap-method"),
        ({"rank_by": "bic"}, "rank_by", "--rank-by"),
    ],
)
def test_the_same_option_is_refused_by_both_faces_in_their_own_words(tmp_path, capsys, keywords, option, flag):
    with pytest.raises(OptionError) as refused:
        tromplab.fit_experiments(tromplab.read_experiments(DECK), **keywords)
    assert refused.value.option == option
    value = str(next(iter(keywords.values())))
    assert main(["fit", str(DECK), "-o", str(tmp_path / "out"), flag, value]) == 2
    said = capsys.readouterr().err
    assert flag in said and not (tmp_path / "out").exists()


def test_save_refuses_an_unknown_figure_choice(tmp_path):
    bench = tromplab.fit_experiments(tromplab.read_experiments(DECK), formulas=["plitt"])
    with pytest.raises(OptionError, match="figures must be one of auto, all, best, none"):
        bench.save(tmp_path / "out", figures="some")
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_intervals_are_made_on_the_workers_and_do_not_depend_on_them(monkeypatch):
    from tromplab._synthetic import synthetic
    from tromplab.statistics.uncertainty import interval_columns

    monkeypatch.setattr(tromplab.parallel.fanout, "CHUNK_SIZE", 3)  # four chunks of experiments from ten
    experiments = [synthetic(seed) for seed in range(10)]
    options = {"formulas": ["plitt", "lognormal"], "ci": 0.9, "bootstrap": 8, "seed": 3}
    serial, parallel = (tromplab.fit_experiments(experiments, jobs=jobs, **options) for jobs in (1, 2))
    whole = interval_columns(list(serial.fits), level=0.9, n_bootstrap=8, seed=3)
    assert serial.intervals.to_csv(index=False) == parallel.intervals.to_csv(index=False) == whole.to_csv(index=False)


@pytest.mark.slow
def test_the_figures_of_the_results_folder_are_the_same_drawn_by_two_workers(tmp_path, monkeypatch):
    """Workbench.save(jobs=) and tromplab fit --jobs draw the per-experiment figures on the
    workers, FIGURE_CHUNK experiments at a time: every file is the same for 1 and 2 workers."""
    from tromplab._synthetic import synthetic
    from tromplab.output import folder

    monkeypatch.setattr(folder, "FIGURE_CHUNK", 2)  # three chunks from five experiments
    bench = tromplab.fit_experiments([synthetic(seed) for seed in range(5)], formulas=["plitt", "lognormal"])
    bench.save(tmp_path / "one", figures="all", jobs=1)
    bench.save(tmp_path / "two", figures="all", jobs=2)
    pictures = sorted(p.name for p in (tmp_path / "one").glob("*.png"))
    assert len(pictures) == 5
    match, mismatch, errors = filecmp.cmpfiles(
        tmp_path / "one", tmp_path / "two", pictures + ["figures.csv", "fits.csv"], shallow=False
    )
    assert not mismatch and not errors
