"""Seeded synthetic Tromp curves shared by the engine tests and the benchmarks.

Not part of the public API: it exists so that ``tests/test_engine.py`` and
``benchmarks/fit_robustness.py`` (and the benchmarks importing it) draw the very same curves
instead of keeping two copies of the generator in step.
"""

import numpy as np

from tromplab.formulas import FORMULAS
from tromplab.points import TrompPoints


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
