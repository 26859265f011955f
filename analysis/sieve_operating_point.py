"""Multi-criteria choice of the mean transport speed of one sieve (kinetics paper's example):
capacity against efficiency under the 8 % purity limit, with the Pareto-front figure.

Usage: ``python analysis/sieve_operating_point.py [--outdir analysis/output]``
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import seaborn as sns  # noqa: E402

from tromplab.choice import choose, sieve_speed_problem  # noqa: E402
from tromplab.plotting import plot_pareto  # noqa: E402
from tromplab.reproduce import write_table  # noqa: E402

OUTPUT = Path(__file__).resolve().parent / "output"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--outdir", type=Path, default=OUTPUT)
    args = parser.parse_args(argv)
    result = choose(sieve_speed_problem(), floor_second=80.0, share_of_first=0.8)
    for label, optimum in [("max Q with E >= 80 %", result.best_first), ("max E with Q >= 80 % of max", result.best_second),
                           ("compromise (max-min)", result.compromise)]:  # fmt: skip
        p = optimum.point
        print(f"{label:>28}: V = {p['V']:.4f} m/s, Q = {p['Q']:.0f} kg/h, E = {p['E']:.2f} %")
    print("Printed compromise: E = 89.64 %, Q = 1340 kg/h (reproduced by max Q at the purity limit; see docs/errata.md)")
    sns.set_theme(style="whitegrid")
    ax = plot_pareto(result)
    ax.set_xlabel("capacity Q, kg/h")
    ax.set_ylabel("efficiency E, %")
    figure = args.outdir / "sieve_pareto.png"
    args.outdir.mkdir(parents=True, exist_ok=True)
    ax.figure.tight_layout()
    ax.figure.savefig(figure, dpi=120)
    plt.close(ax.figure)
    print(f"Wrote {write_table(result.pareto, args.outdir, 'sieve_pareto.csv')}")
    print(f"Wrote {figure}")


if __name__ == "__main__":
    main()
