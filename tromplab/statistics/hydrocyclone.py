"""Hydrocyclones: the fitted bypass against the measured water recovery.

In a hydrocyclone a share ``Rf`` of the feed water reports to the underflow, and with it the
same share of every size of fine particle, unclassified (the Kelsall correction,
:mod:`tromplab.loading.kelsall`).  The curves with bypass (``plitt_bypass``,
``lognormal_bypass``, ``whiten`` ...) model exactly this, ``phi = (1 - bypass) phi_c``: their
fitted bypass estimates the share the data say went to the underflow unclassified, which the
measured water recovery should match when the fines follow the water.

References
----------
Kelsall D.F. (1953). A further study of the hydraulic cyclone. Chem. Eng. Sci. 2, 254-272.
Napier-Munn T.J., Morrell S., Morrison R.D., Kojovic T. (1996). Mineral Comminution
Circuits: their operation and optimisation. JKMRC, Brisbane.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from ..curves.intervals import UNIT, transformed_interval
from ..validation import check_water_recovery

#: Confidence level of the bypass interval the water recovery is compared with.
BYPASS_CHECK_LEVEL = 0.95


def bypass_against_water_recovery(fits: Sequence, water_recovery: float, *, level: float = BYPASS_CHECK_LEVEL) -> pd.DataFrame:
    """The fitted bypass of each curve with bypass compared with the measured water recovery.

    Returns one row per fit with columns ``experiment, formula, water_recovery`` and
    ``water_recovery_check``: for a successful fit with a ``bypass`` parameter, a sentence
    saying whether ``water_recovery`` lies inside the ``level`` interval of the fitted
    bypass (Wald on the logit scale with the t quantile of the fit's degrees of freedom;
    a bypass on its bound of 0 gets the one-sided interval from 0); empty for the other
    fits.
    """

    water_recovery = check_water_recovery(water_recovery, "water_recovery")
    rows = []
    for fit in fits:
        row = {
            "experiment": fit.experiment,
            "formula": fit.formula.id,
            "water_recovery": water_recovery,
            "water_recovery_check": "",
        }
        if fit.success and "bypass" in fit.fit.values:
            value, se = fit.fit.values["bypass"], fit.fit.stderr.get("bypass", np.nan)
            dof = fit.points.n - len(fit.fit.names)
            if UNIT.inside(value):
                low, high = transformed_interval(value, se, stats.t.ppf(0.5 + level / 2, dof) if dof > 0 else np.nan, UNIT)
            else:  # on the edge: bypass 0 (the bound), the one-sided limit on the natural scale
                low = value
                high = value + stats.t.ppf(level, dof) * se if dof > 0 and np.isfinite(se) else np.nan
            row["water_recovery_check"] = _sentence(value, low, high, water_recovery, level)
        rows.append(row)
    return pd.DataFrame(rows, columns=["experiment", "formula", "water_recovery", "water_recovery_check"])


def _sentence(bypass: float, low: float, high: float, water_recovery: float, level: float) -> str:
    if not (np.isfinite(low) and np.isfinite(high)):
        return f"fitted bypass {bypass:.3f} (no interval) against water recovery {water_recovery:.3f}: cannot tell"
    fitted = f"fitted bypass {bypass:.3f} ({level:.0%} interval {low:.3f}-{high:.3f})"
    if low <= water_recovery <= high:
        return f"agrees: {fitted} contains the water recovery {water_recovery:.3f}"
    direction = "above" if bypass > water_recovery else "below"
    return (
        f"differs: {fitted} lies {direction} the water recovery {water_recovery:.3f}, so the finest particles did not "
        "report to the underflow in the water's proportion"
    )


def water_recovery_statements(fits: pd.DataFrame, experiment: str) -> list[str]:
    """The bypass checks of one experiment's rows of a fits table, one sentence per curve
    with bypass (``"plitt_bypass: agrees: ..."``); empty without ``water_recovery_check``."""
    if "water_recovery_check" not in fits.columns:
        return []
    rows = fits[(fits["experiment"] == experiment) & (fits["water_recovery_check"].fillna("") != "")]
    return [f"{formula}: {check}" for formula, check in rows[["formula", "water_recovery_check"]].itertuples(index=False)]
