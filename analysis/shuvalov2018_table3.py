"""Regenerate Table 3 of Shuvalov et al. (2018) from its Table 2 and print it beside the
published table, with the differing cells marked.

Usage: ``python analysis/shuvalov2018_table3.py [--computed-adequacy] [--outdir analysis/output]``
"""

from _common import ROOT, output_arguments

import pandas as pd

from tromplab.reproduce import shuvalov_table3, write_table


def add_options(parser):
    parser.add_argument("--computed-adequacy", action="store_true", help="adequacy from F > F_crit instead of Table 3's marks")


def main(argv=None):
    args = output_arguments(__doc__, argv, add_options)
    table = shuvalov_table3(
        ROOT / "datasets" / "shuvalov2018_table2_F.csv",
        ROOT / "datasets" / "shuvalov2018_table3_ranks.csv",
        use_given_marks=not args.computed_adequacy,
    )
    marks = "computed from Table 2" if args.computed_adequacy else "as printed in Table 3"
    print(f"Table 3 recomputed (adequacy {marks}); 'published_*' columns are the printed values.")
    with pd.option_context("display.width", 250):
        print(table[["equation", "points", "published_points", "place", "published_place", "differences"]].to_string(index=False))
    name = "table3_computed_adequacy.csv" if args.computed_adequacy else "table3_printed_marks.csv"
    print(f"Wrote {write_table(table, args.outdir, name)}")


if __name__ == "__main__":
    main()
