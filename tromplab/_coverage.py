"""Coverage of tromplab's confidence intervals on seeded synthetic experiments.

Not part of the public API: shared by ``benchmarks/coverage.py`` (the full study, several
hundred replicates per case) and ``tests/test_coverage.py`` (a smaller seeded run), so both
measure the very same thing.  Each replicate draws a known curve at fixed sizes with
Gaussian noise (not clipped to [0, 1], so the noise is the model's), fits the formula that
generated it, makes the intervals tromplab reports (:func:`tromplab.uncertainty.interval_table`)
and records whether each interval contains the true value, computed from the generating
parameters with the same ``delta_max`` as the fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .curves import fit_formula
from .formulas import get_formula
from .indices import curve_indices
from .points import TrompPoints
from .uncertainty import interval_table

#: Quantities whose coverage is measured: the corrected cut and the indices made on a
#: transformed scale (log for Ep, logit for eta and eps / (x_max - 1)).
COVERED = ("d_cut", "ep", "eta", "epsilon")


@dataclass(frozen=True)
class Case:
    """One synthetic design: a formula, its true curve, the number of sizes and the noise."""

    formula: str
    slope: float  # slope of the true curve at the cut, partition per relative size (negative)
    n_points: int
    noise: float = 0.02
    d_cut: float = 80.0

    @property
    def label(self) -> str:
        return f"{self.formula} n={self.n_points} slope={self.slope:g} noise={self.noise:g}"

    @property
    def sizes(self) -> np.ndarray:
        return self.d_cut * np.geomspace(0.25, 4.0, self.n_points)

    @property
    def shape(self) -> float:
        formula = get_formula(self.formula)
        return float(formula.clip_shape(formula.shape_for_slope(self.slope)))


#: The designs of the study: four of the nine formulas, 8-12 sizes, noise 0.02.
CASES = (
    Case("plitt", -1.0, 10),
    Case("rosin_rammler", -0.6, 8),
    Case("lognormal", -1.5, 12),
    Case("lynch", -1.0, 10),
)


def true_values(case: Case) -> dict[str, float]:
    """The covered quantities of the generating curve (``delta_max`` = the largest size)."""
    found = curve_indices(case.formula, case.d_cut, case.shape, delta_max=float(case.sizes.max()))
    return {"d_cut": case.d_cut, **{name: float(getattr(found, name)) for name in COVERED if name != "d_cut"}}


def coverage_run(case: Case, replicates: int, *, seed: int = 0, level: float = 0.95, profile: bool = False) -> pd.DataFrame:
    """One row per replicate and covered quantity: ``replicate, quantity, truth, value, low,
    high, method, covered`` (``covered`` nan when no interval could be made).

    ``profile`` makes the parameter intervals by profile likelihood as ``tromplab fit --ci``
    does (slower); without it they are the Wald intervals on the log scale that ``fit`` falls
    back to.  The indices' intervals are the delta method on the transformed scale either way.
    """
    rng = np.random.default_rng(seed)
    formula = get_formula(case.formula)
    truth = true_values(case)
    clean = formula(case.sizes, case.d_cut, case.shape)
    rows = []
    for replicate in range(replicates):
        points = TrompPoints(f"r{replicate}", case.sizes, clean + rng.normal(0.0, case.noise, case.n_points))
        fit = fit_formula(points, formula)
        if not fit.success:
            continue
        table = interval_table(fit, level=level, profile=profile).set_index("quantity")
        for quantity in COVERED:
            low, high = table.loc[quantity, "low"], table.loc[quantity, "high"]
            made = np.isfinite(low) and np.isfinite(high)
            rows.append(
                {
                    "replicate": replicate,
                    "quantity": quantity,
                    "truth": truth[quantity],
                    "value": table.loc[quantity, "value"],
                    "low": low,
                    "high": high,
                    "method": table.loc[quantity, "method"],
                    "covered": float(low <= truth[quantity] <= high) if made else np.nan,
                }
            )
    return pd.DataFrame(rows)


def coverage_table(runs: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Coverage per case and quantity: ``case, quantity, method, replicates, coverage, missed_low,
    missed_high`` (shares of the replicates with an interval; missed_low: the interval lies
    below the truth)."""
    rows = []
    for label, run in runs.items():
        for quantity, group in run.groupby("quantity", sort=False):
            made = group[group["covered"].notna()]
            rows.append(
                {
                    "case": label,
                    "quantity": quantity,
                    "method": "/".join(sorted(set(made["method"]))),
                    "replicates": len(made),
                    "coverage": made["covered"].mean(),
                    "missed_low": (made["high"] < made["truth"]).mean(),
                    "missed_high": (made["low"] > made["truth"]).mean(),
                }
            )
    return pd.DataFrame(rows)
