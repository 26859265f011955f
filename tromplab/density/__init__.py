"""Density partition of gravity separators: Tromp curves by relative density.

The curves (partition to the sinks against relative density, with the cut density
``rho50``, the probable error ``Ep`` and the imperfection ``I = Ep / (rho50 - 1)``) are
declared in :mod:`tromplab.density.registry`; tracer counts, float-sink analyses and
partitions are read by :mod:`tromplab.density.readers`, fitted by
:mod:`tromplab.density.fitting` (binomial maximum likelihood, least squares) and
:func:`fit_density` returns a :class:`~tromplab.density.results.DensityResult` whose
``save(DIR)`` writes what ``tromplab density fit FILE -o DIR`` writes (:func:`fit_density_to_folder`
does both in one go, and streams a large campaign to disk unit by unit, as the command does); :func:`predict_density`
returns a :class:`~tromplab.density.prediction.DensityPrediction` whose ``save(FILE)`` writes
what ``tromplab density predict WASHABILITY -o FILE`` writes.
"""

from .fitting import DensityCurveFit, fit_density_curve
from .prediction import DensityPrediction, predict_density
from .readers import DensitySample, read_density
from .registry import (
    DENSITY_CURVES,
    LIMIT_CURVES,
    PLAIN_CURVES,
    DensityCurve,
    DensityIndices,
    density_registry_table,
    get_density_curve,
    select_density_curves,
)
from .results import DensityResult, fit_density
from .streamed import DensityFolder, fit_density_to_folder

__all__ = [
    "DENSITY_CURVES",
    "LIMIT_CURVES",
    "PLAIN_CURVES",
    "DensityCurve",
    "DensityIndices",
    "DensityCurveFit",
    "DensityPrediction",
    "DensityFolder",
    "DensityResult",
    "DensitySample",
    "fit_density",
    "fit_density_to_folder",
    "fit_density_curve",
    "predict_density",
    "read_density",
    "density_registry_table",
    "get_density_curve",
    "select_density_curves",
]
