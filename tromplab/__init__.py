"""tromplab: separation (Tromp) curves of particle classifiers and sieve-classifier models.

Importing the package has no side effects: no plotting style, no files, no network.
"""

from ._version import __version__
from .curves import CurveFit, fit_formula
from .errors import InputError
from .formulas import FORMULAS, Formula, get_formula
from .indices import curve_indices
from .points import TrompPoints, read_points
from .ranking import rank_formulas
from .workbench import Workbench, fit_experiments

__all__ = [
    "__version__",
    "FORMULAS", "CurveFit", "Formula", "InputError", "TrompPoints", "Workbench", "curve_indices",
    "fit_experiments", "fit_formula", "get_formula", "rank_formulas", "read_points",
]  # fmt: skip
