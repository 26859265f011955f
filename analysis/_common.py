"""What every analysis script shares: its output folder option and figure saving."""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from tromplab.output.plotting import save_figure  # noqa: E402

OUTPUT = Path(__file__).resolve().parent / "output"
ROOT = Path(__file__).resolve().parent.parent


def output_arguments(doc: str, argv=None, extra=None):
    """Parse ``--outdir`` (default ``analysis/output``, created) and any ``extra(parser)`` options."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--outdir", type=Path, default=OUTPUT)
    if extra is not None:
        extra(parser)
    args = parser.parse_args(argv)
    args.outdir.mkdir(parents=True, exist_ok=True)
    return args


def save(ax, path):
    save_figure(ax, path)
    print(f"Wrote {path}")
