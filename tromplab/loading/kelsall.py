"""The Kelsall correction of a hydrocyclone's partition for the water split.

In a hydrocyclone a share ``Rf`` of the feed water reports to the underflow (the coarse
product), and with it the same share of every size of fine particle, unclassified.
Kelsall (1953) removes it from the actual partition to the underflow ``Y``:

.. math::

    Y' = \\frac{Y - R_f}{1 - R_f}

(Napier-Munn et al. 1996, ch. 12).  tromplab's partition is to the fines, ``phi = 1 - Y``,
so the corrected partition to the fines is ``phi' = 1 - Y' = phi / (1 - Rf)``.  The lab
loader adds it to the points table when a water recovery is given; the fitted bypass is
compared with the water recovery in :mod:`tromplab.statistics.hydrocyclone`.

References
----------
Kelsall D.F. (1953). A further study of the hydraulic cyclone. Chem. Eng. Sci. 2, 254-272.
Napier-Munn T.J., Morrell S., Morrison R.D., Kojovic T. (1996). Mineral Comminution
Circuits: their operation and optimisation. JKMRC, Brisbane.
"""

from __future__ import annotations

from ..validation import check_water_recovery


def kelsall_corrected(partition_fine, water_recovery: float):
    """Kelsall-corrected partition to the fines, ``phi / (1 - Rf)``.

    Parameters
    ----------
    partition_fine : array_like
        Actual partition to the fine product (overflow), 0..1.
    water_recovery : float
        Share of the feed water reporting to the underflow, in [0, 1).

    Returns
    -------
    same type as ``partition_fine``
        The corrected partition to the fines, ``1 - Y'`` with ``Y' = (Y - Rf)/(1 - Rf)``
        the corrected partition to the underflow.  Not clipped: a value above 1 means the
        class went to the overflow more than its water did (measurement error, or water
        recovery overstated), and is left visible.

    Examples
    --------
    >>> import numpy as np
    >>> kelsall_corrected(np.array([0.7, 0.35]), 0.3).round(3).tolist()
    [1.0, 0.5]
    """
    water_recovery = check_water_recovery(water_recovery, "water_recovery")
    return partition_fine / (1.0 - water_recovery)
