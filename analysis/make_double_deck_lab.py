"""Express each deck of the double-deck screen exercise as its own classifier.

Reads ``datasets/double_deck_screen_20_65mesh_exercise.csv`` (three products P, M, Q of a
20-mesh over 65-mesh screen, with their published masses) and writes the lab table
``datasets/double_deck_screen_decks_lab.csv`` with two experiments:

* ``deck_20mesh``: feed = the feed; coarse = P; fine = everything through the 20-mesh
  deck, i.e. M and Q together (:func:`tromplab.loading.lab.mix_streams`), fine yield = yM + yQ;
* ``deck_65mesh``: feed = M and Q together; coarse = M; fine = Q; fine yield = yQ/(yM + yQ).

Usage: ``python analysis/make_double_deck_lab.py [--output PATH]``
"""

import argparse
from pathlib import Path

import pandas as pd

from tromplab.loading.lab import mix_streams

ROOT = Path(__file__).resolve().parent.parent
SOURCE = ROOT / "datasets" / "double_deck_screen_20_65mesh_exercise.csv"
TARGET = ROOT / "datasets" / "double_deck_screen_decks_lab.csv"
# Stream masses published with the exercise (kg of 1000 kg feed), solved there from the balance.
MASS_P, MASS_M, MASS_Q = 736.0758, 221.9141, 42.01009
HEADER = """\
# Lab table: the two decks of the double-deck screen exercise, each as its own classifier.
# Derived by analysis/make_double_deck_lab.py from double_deck_screen_20_65mesh_exercise.csv (see that
#   file for the source: a worked spreadsheet exercise whose feed is McCabe, Smith & Harriott's quartz
#   analysis, Table 28.2). Regenerate with: python analysis/make_double_deck_lab.py
# deck_20mesh: feed = F; coarse = P (on 20 mesh); fine = M and Q mixed by their masses (through 20 mesh).
# deck_65mesh: feed = M and Q mixed; coarse = M (on 65 mesh); fine = Q (through 65 mesh).
# fine_yield: from the published stream masses P = 736.0758, M = 221.9141, Q = 42.01009 kg (F = 1000 kg).
# Units: sizes in mm (Tyler apertures); stream columns are mass % per class (sums 99.99-100.01 as printed).
# The 65-mesh deck's fine product holds much +20-mesh material (strong misplacement): a textbook
#   exercise, not a plant survey.
"""


def build(source: Path = SOURCE) -> pd.DataFrame:
    data = pd.read_csv(source, comment="#")
    total = MASS_P + MASS_M + MASS_Q
    y_m, y_q = MASS_M / total, MASS_Q / total
    through_20, yield_20 = mix_streams([data["M_pct"], data["Q_pct"]], [y_m, y_q])
    bounds = {"size_lower_mm": data["lower_mm"], "size_upper_mm": data["upper_mm"]}
    deck_20 = pd.DataFrame(
        {
            "experiment": "deck_20mesh",
            **bounds,
            "feed_pct": data["feed_pct"],
            "fine_pct": 100 * through_20,
            "coarse_pct": data["P_pct"],
            "fine_yield": yield_20,
        }
    )
    deck_65 = pd.DataFrame(
        {
            "experiment": "deck_65mesh",
            **bounds,
            "feed_pct": 100 * through_20,
            "fine_pct": data["Q_pct"],
            "coarse_pct": data["M_pct"],
            "fine_yield": y_q / yield_20,
        }
    )
    return pd.concat([deck_20, deck_65], ignore_index=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=TARGET)
    args = parser.parse_args(argv)
    table = build()
    args.output.write_text(HEADER + table.to_csv(index=False, float_format="%.6g", lineterminator="\n"))
    print(f"Wrote {args.output}")


if __name__ == "__main__":
    main()
