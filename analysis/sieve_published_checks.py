"""Recompute the published checks of both sieve-classifier papers and print them beside
the printed values (kinetics / identification paper and random-walk paper).

Usage: ``python analysis/sieve_published_checks.py [--outdir analysis/output]``
"""

from _common import output_arguments

import pandas as pd

from tromplab.reproduce import sieve_checks, write_table


def main(argv=None):
    args = output_arguments(__doc__, argv)
    checks = sieve_checks()
    with pd.option_context("display.width", 200, "display.max_colwidth", 70):
        print(checks.to_string(index=False, float_format=lambda v: f"{v:.5g}"))
    counts = checks["agreement"].value_counts()
    print(
        f"\nOf {len(checks)} printed values, {counts.get('agrees', 0)} agree at the printed precision, "
        f"{counts.get('last digit', 0)} are one unit off in the last printed digit and {counts.get('differs', 0)} differ; "
        "docs/errata.md explains each difference"
    )
    print(f"Wrote {write_table(checks, args.outdir, 'sieve_published_checks.csv')}")


if __name__ == "__main__":
    main()
