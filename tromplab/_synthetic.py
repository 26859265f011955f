"""Seeded synthetic Tromp curves shared by the engine tests and the benchmarks.

Not part of the public API: it exists so that ``tests/test_engine.py`` and
``benchmarks/fit_robustness.py`` (and the benchmarks importing it) draw the very same curves
instead of keeping two copies of the generator in step.
"""

import numpy as np

from tromplab.curves.curve_fit import fit_formula
from tromplab.curves.formulas import FORMULAS, get_formula
from tromplab.curves.indices import curve_indices
from tromplab.loading.points import TrompPoints
from tromplab.statistics.uncertainty import interval_table


def synthetic(seed: int, weighted: bool = True) -> TrompPoints:
    """A noisy curve of one of the nine formulas (8-12 sizes, slope -0.3 to -2, noise 0.01-0.03).

    Parameters
    ----------
    seed : int
        Seed of the random generator; ``seed % 9`` picks the true formula.
    weighted : bool, optional
        When true, every fifth seed (``seed % 5 == 0``) gets point weights drawn from 0.5-2;
        the benchmarks pass false to time unweighted fits against bare lmfit.

    Returns
    -------
    TrompPoints
        The experiment named ``s<seed>``, partition numbers clipped to [0, 1].
    """
    rng = np.random.default_rng(seed)
    truth = FORMULAS[seed % len(FORMULAS)]
    n = int(rng.integers(8, 13))
    d_cut = float(rng.uniform(20, 200))
    sizes = d_cut * np.geomspace(rng.uniform(0.1, 0.4), rng.uniform(2.5, 6), n)
    shape = truth.clip_shape(truth.shape_for_slope(-rng.uniform(0.3, 2.0)))
    context = {"measured_efficiency": 0.75} if truth.context_from_efficiency else {}
    phi = truth(sizes, d_cut, shape, **context) + rng.normal(0, rng.uniform(0.01, 0.03), n)
    weight = rng.uniform(0.5, 2.0, n) if weighted and seed % 5 == 0 else None
    return TrompPoints(f"s{seed}", sizes, np.clip(phi, 0, 1), weight)


#: Designs of the interval coverage study: a true curve (cut 80, slope about -0.8 at the cut)
#: measured at 10 sizes from 20 to 320 with normal noise of 0.02 on the partition.
COVERAGE_SIZES = np.geomspace(20.0, 320.0, 10)
COVERAGE_TRUTH = {"plitt": 3.2, "rosin_rammler": 2.3, "lognormal": 0.52}
COVERAGE_QUANTITIES = ("d_cut", "shape", "slope", "eta", "epsilon", "d25", "d75", "ep")


def interval_coverage(
    formula: str,
    replicates: int,
    *,
    level: float = 0.95,
    noise: float = 0.02,
    profile: bool = False,
    first_seed: int = 0,
    shape: float | None = None,
    clip: bool = False,
):
    """Share of seeded replicates whose interval covers the true value, per quantity.

    Each replicate draws the partition of the true curve (:data:`COVERAGE_TRUTH`) at
    :data:`COVERAGE_SIZES` plus normal noise, fits the same formula and makes the intervals
    of :func:`tromplab.statistics.uncertainty.interval_table` (parameters by profile likelihood when
    ``profile``, else Wald on the log scale; indices by the delta method on their
    transformed scale). The true indices come from the generating parameters at the same
    ``delta_max`` (the largest size).  ``shape`` replaces the true shape of
    :data:`COVERAGE_TRUTH`; ``clip`` clips the noisy partition to [0, 1], as measured
    partition numbers are (where the true curve is near 0 or 1 the clipped noise is no longer
    normal, and the intervals cover less: see docs/uncertainty.md).

    Returns
    -------
    pandas.DataFrame
        One row per quantity: ``formula, quantity, method, replicates, covered, coverage,
        missing`` (``missing``: replicates without an interval, left out of the share).
    """
    import pandas as pd

    curve = get_formula(formula)
    shape = COVERAGE_TRUTH[formula] if shape is None else float(shape)
    delta_max = float(COVERAGE_SIZES[-1])
    truth = _true_quantities(curve, shape, delta_max)
    counts = {q: [0, 0, 0] for q in COVERAGE_QUANTITIES}  # covered, made, missing
    methods = {q: set() for q in COVERAGE_QUANTITIES}
    for seed in range(first_seed, first_seed + replicates):
        rng = np.random.default_rng(seed)
        partition = curve(COVERAGE_SIZES, 80.0, shape) + rng.normal(0.0, noise, COVERAGE_SIZES.size)
        if clip:
            partition = np.clip(partition, 0.0, 1.0)
        fit = fit_formula(TrompPoints(f"coverage-{seed}", COVERAGE_SIZES, partition), curve, delta_max=delta_max)
        if not fit.success:
            for q in COVERAGE_QUANTITIES:
                counts[q][2] += 1
            continue
        table = interval_table(fit, level=level, profile=profile).set_index("quantity")
        _count_covered(table.rename(index={curve.shape_name: "shape"}), truth, counts, methods)
    return pd.DataFrame(
        [
            {
                "formula": formula,
                "quantity": q,
                "method": "/".join(sorted(methods[q])),
                "replicates": made,
                "covered": covered,
                "coverage": covered / made if made else np.nan,
                "missing": missing,
            }
            for q, (covered, made, missing) in counts.items()
        ]
    )


def _true_quantities(curve, shape: float, delta_max: float) -> dict:
    """The true value of every quantity of :data:`COVERAGE_QUANTITIES` for the generating curve."""
    true_indices = curve_indices(curve, 80.0, shape, delta_max=delta_max)
    return {"d_cut": 80.0, "shape": shape, **{q: getattr(true_indices, q) for q in COVERAGE_QUANTITIES[2:]}}


def _count_covered(table, truth: dict, counts: dict, methods: dict) -> None:
    """Add one replicate's intervals (``table`` by quantity) to ``counts`` (covered, made,
    missing per quantity) and the methods that made them."""
    for q in COVERAGE_QUANTITIES:
        low, high = table.loc[q, "low"], table.loc[q, "high"]
        if np.isfinite(low) and np.isfinite(high):
            counts[q][0] += bool(low <= truth[q] <= high)
            counts[q][1] += 1
            methods[q].add(table.loc[q, "method"])
        else:
            counts[q][2] += 1
