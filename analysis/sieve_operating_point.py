"""Multi-criteria choice of the mean transport speed of one sieve (kinetics paper's example):
capacity against efficiency under the 8 % purity limit, with the Pareto-front figure.

Usage: ``python analysis/sieve_operating_point.py [--outdir analysis/output]``
"""

from _common import output_arguments, save

import seaborn as sns

from tromplab.classifiers.choice import choose, sieve_speed_problem
from tromplab.output.plotting import plot_pareto
from tromplab.reproduce import write_table


def main(argv=None):
    args = output_arguments(__doc__, argv)
    result = choose(sieve_speed_problem(), floor_second=80.0, share_of_first=0.8)
    for label, optimum in [
        ("max Q with E >= 80 %", result.best_first),
        ("max E with Q >= 80 % of max", result.best_second),
        ("compromise (max-min)", result.compromise),
    ]:
        p = optimum.point
        print(f"{label:>28}: V = {p['V']:.4f} m/s, Q = {p['Q']:.0f} kg/h, E = {p['E']:.2f} %")
    print("Printed compromise: E = 89.64 %, Q = 1340 kg/h (reproduced by max Q at the purity limit; see docs/errata.md)")
    sns.set_theme(style="whitegrid")
    ax = plot_pareto(result)
    ax.set_xlabel("capacity Q, kg/h")
    ax.set_ylabel("efficiency E, %")
    print(f"Wrote {write_table(result.pareto, args.outdir, 'sieve_pareto.csv')}")
    save(ax, args.outdir / "sieve_pareto.png")


if __name__ == "__main__":
    main()
