"""Regenerate the figures of Shuvalov et al. (2018): the equal-slope families (Fig. 1 at
slope -0.5, Fig. 2 at -0.4), the ks-kf relation (Fig. 3, corrected form), and the F
heatmap and ranking chart of Tables 2 and 3.

Usage: ``python analysis/shuvalov2018_figures.py [--outdir analysis/output]``
"""

from _common import ROOT, output_arguments, save

import matplotlib.pyplot as plt
import seaborn as sns

from tromplab.curves.formulas import get_formula
from tromplab.output.plotting import plot_equal_slope_family, plot_f_heatmap, plot_plitt_lognormal_relation, plot_ranking
from tromplab.curves.ranking import rank_formulas, read_f_table


def main(argv=None):
    args = output_arguments(__doc__, argv)
    sns.set_theme(style="whitegrid")
    save(plot_equal_slope_family(-0.5), args.outdir / "fig1_equal_slope_-0.5.png")
    save(plot_equal_slope_family(-0.4), args.outdir / "fig2_equal_slope_-0.4.png")
    save(plot_plitt_lognormal_relation(), args.outdir / "fig3_ks_kf.png")
    table = read_f_table(ROOT / "datasets" / "shuvalov2018_table2_F.csv", use_given_marks=False)
    table["formula"] = [get_formula(eq).id for eq in table["equation"]]
    table["success"] = True
    _, ax = plt.subplots(figsize=(10, 5))
    save(plot_f_heatmap(table, ax=ax), args.outdir / "table2_F_heatmap.png")
    ranking = rank_formulas(table, key="formula")
    save(plot_ranking(ranking), args.outdir / "table3_ranking.png")


if __name__ == "__main__":
    main()
