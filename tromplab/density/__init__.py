"""Density partition of gravity separators: Tromp curves by relative density.

The curves (partition to the sinks against relative density, with the cut density
``rho50``, the probable error ``Ep`` and the imperfection ``I = Ep / (rho50 - 1)``) are
declared in :mod:`tromplab.density.curves`.
"""

from .curves import (
    DENSITY_CURVES,
    LIMIT_CURVES,
    PLAIN_CURVES,
    DensityCurve,
    DensityIndices,
    density_registry_table,
    get_density_curve,
    select_density_curves,
)

__all__ = [
    "DENSITY_CURVES",
    "LIMIT_CURVES",
    "PLAIN_CURVES",
    "DensityCurve",
    "DensityIndices",
    "density_registry_table",
    "get_density_curve",
    "select_density_curves",
]
