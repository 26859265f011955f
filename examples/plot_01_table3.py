"""
Table 2 -> Table 3 of Shuvalov et al. (2018)
============================================

The paper screens nine formulas with Fisher's F in ten industrial experiments (its Table 2)
and ranks them (its Table 3). ``tromplab.rank_formulas`` recomputes the ranking from the
published F values.
"""
