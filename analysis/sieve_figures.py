"""Figures of the sieve-classifier papers: P_g against D/l for several shape factors
(kinetics paper, Fig. 3), residue shares and efficiency of two fractions against the
relative-speed amplitude, and the distance densities of three fractions on the bottom
deck of a 12-deck classifier with the collecting bin.

Usage: ``python analysis/sieve_figures.py [--outdir analysis/output]``
"""

from _common import output_arguments, save

import numpy as np
import seaborn as sns

from tromplab.classifiers import sieve
from tromplab.output.plotting import plot_distance_densities, plot_geometric_probability, plot_residue_and_efficiency

HOLE, HALF_CELL, LENGTH, PITCH = 2.0, 1.6, 1.6, 0.0032  # mm, mm, m, m (kinetics paper's example)
FRACTIONS = {"2.5 x 1.5 mm": ((2.5, 1.5), (0.148, 0.051)), "2.0 x 1.5 mm": ((2.0, 1.5), (0.185, 0.069))}


def main(argv=None):
    args = output_arguments(__doc__, argv)
    sns.set_theme(style="whitegrid")
    curves = sieve.geometric_probability_curves(HOLE, HALF_CELL, [0.25, 0.5, 0.75, 1.0], np.linspace(0.75, 2.5, 36))
    save(plot_geometric_probability(curves), args.outdir / "sieve_pg_family.png")
    speeds = np.linspace(0.1, 0.5, 200)
    residues = []
    for (length, width), (v_k, sigma) in FRACTIONS.values():
        p = sieve.geometric_probability(HOLE, length, width, HALF_CELL) * sieve.velocity_probability(speeds, v_k, sigma)
        residues.append(sieve.residue_share(p, LENGTH, PITCH))
    efficiency = sieve.sieve_efficiency(residues[0], residues[1])
    save(
        plot_residue_and_efficiency(speeds, residues, efficiency, labels=list(FRACTIONS)),
        args.outdir / "sieve_residue_efficiency.png",
    )
    design = sieve.design_bin(12, 1.6, 0.9)
    labels = [
        "finer fraction (C = 30, illustrative)",
        f"target fraction (C = {design.c:.2f})",
        "coarser fraction (C = 7, illustrative)",
    ]
    ax = plot_distance_densities(12, [30.0, design.c, 7.0], bin_edges=(design.x1, design.x2), labels=labels, x_max=2.6)
    save(ax, args.outdir / "sieve_distance_densities.png")


if __name__ == "__main__":
    main()
