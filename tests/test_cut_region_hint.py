"""Default filters that remove the cut region are named in one message; the classes they
leave out are summarised in one line per experiment, the full list in left_out.csv."""

import pandas as pd

import tromplab
from tromplab.cli import main

from .conftest import ROOT

GAS_CYCLONE = ROOT / "tests" / "data" / "gas_cyclone_cut_in_low_feed_classes_um.csv"


def test_the_loader_says_when_the_feed_share_filter_removes_the_cut_region():
    (balance,) = tromplab.read_lab(GAS_CYCLONE)
    around_cut = [note for note in balance.notes if "every class around the cut" in note]
    assert len(around_cut) == 1 and "min_feed_share = 0.2 %" in around_cut[0]
    assert balance.left_out_summary() == "3 class(es) left out: pan-1, 1-2, 2-4 um (feed share below the limit: 3)"
    (kept,) = tromplab.read_lab(GAS_CYCLONE, min_feed_share=0.0)
    assert not [note for note in kept.notes if "around the cut" in note] and kept.left_out_summary() == ""


def test_the_command_names_its_option_and_lists_the_classes_in_a_file(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fit", str(GAS_CYCLONE), "-o", str(out), "--figures", "none", "--formulas", "plitt"]) == 0
    said = capsys.readouterr().err
    assert "--min-feed-share = 0.2 %" in said and "min_feed_share" not in said
    assert said.count("left out") == 2  # the cut-region warning and one summary line, not one line per class
    listed = pd.read_csv(out / "left_out.csv")
    assert listed["size_upper"].tolist() == [1.0, 2.0, 4.0] and listed["row"].tolist() == [7, 8, 9]
    assert listed["reason"].str.startswith("feed share").all()


def test_an_ordinary_lab_table_gets_no_cut_region_note():
    for balance in tromplab.read_lab(ROOT / "datasets" / "double_deck_screen_decks_lab.csv"):
        assert not [note for note in balance.notes if "around the cut" in note]
