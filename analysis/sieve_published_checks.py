"""Recompute the published checks of both sieve-classifier papers and print them beside
the printed values (kinetics / identification paper and random-walk paper).

Usage: ``python analysis/sieve_published_checks.py [--outdir analysis/output]``
"""

import argparse
from pathlib import Path

import pandas as pd

from tromplab.reproduce import sieve_checks, write_table

OUTPUT = Path(__file__).resolve().parent / "output"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--outdir", type=Path, default=OUTPUT)
    args = parser.parse_args(argv)
    checks = sieve_checks()
    with pd.option_context("display.width", 200, "display.max_colwidth", 70):
        print(checks.to_string(index=False, float_format=lambda v: f"{v:.5g}"))
    print(f"\n{int(checks['agrees'].sum())} of {len(checks)} printed values reproduced; the others are explained in docs/errata.md")
    print(f"Wrote {write_table(checks, args.outdir, 'sieve_published_checks.csv')}")


if __name__ == "__main__":
    main()
