r"""The sampling error of the washability analysis: draws of each size fraction's density-fraction masses.

A washability analysis is made on a sample of the size fraction, so the mass shares of its
density fractions are those of a finite number of particles, not of the whole feed.  The
model (option ``washability_particles``, ``--washability-particles N``): the sample of each size
fraction holds :math:`N` particles, each falling into density fraction :math:`i` with the
feed's share :math:`m_i`, so the shares in the sample are multinomial,
:math:`\operatorname{Var}(\hat m_i) = m_i (1 - m_i) / N`.  The shares of the feed given the
analysis are drawn from the conjugate Dirichlet distribution

.. math::
    (m^*_1, \dots, m^*_k) \sim \operatorname{Dirichlet}(N \hat m_1, \dots, N \hat m_k)

(its variance :math:`\hat m_i (1 - \hat m_i)/(N + 1)`), independently between size fractions
and of the curves' draws; a density fraction with no mass keeps none; the ash of each density
fraction is kept as measured (its determination error is not modelled).  This is the particle-counting view of sampling on which Gy's
fundamental sampling error rests (Gy 1979; Wills & Finch 2016, ch. 3): for particles of one
size, :math:`N \approx M / (f \rho d^3)` for a sample of mass :math:`M`, particle density
:math:`\rho`, top size :math:`d` and shape factor :math:`f \approx 0.5` (a 100 kg sample of
50x12 mm coal of density 1.4 t/m3: :math:`100 / (0.5 \cdot 1400 \cdot 0.05^3) \approx 1{,}100`
particles).  Particles of unequal size make the effective :math:`N` smaller than the count.

References
----------
Gy, P. M. (1979). *Sampling of Particulate Materials: Theory and Practice*. Elsevier, Amsterdam.

Wills, B. A. & Finch, J. A. (2016). *Wills' Mineral Processing Technology*, 8th ed.,
Butterworth-Heinemann, ch. 3 (sampling; Gy's formula).
"""

from __future__ import annotations

import numpy as np

from .inputs import SizeFraction

#: Largest number of particles accepted for a washability sample (beyond it the error is nil).
MAX_PARTICLES = 10**12


def washability_mass_draws(fractions: list[SizeFraction], particles: int, draws: int, seed: int) -> list[np.ndarray]:
    """Per size fraction, ``(draws + 1, k)`` mass per cents of its density fractions: the analysis first, then the draws.

    Examples
    --------
    >>> from tromplab.density.washability import washability_from_arrays
    >>> fraction = SizeFraction("all", 100.0, washability_from_arrays([1.3, 1.4, 1.6], [1.4, 1.6, 2.0], [60, 30, 10], [4, 20, 70]))
    >>> (masses,) = washability_mass_draws([fraction], 400, 20000, seed=1)
    >>> masses[0].tolist(), round(float(masses[1:, 0].std()), 1)  # sd 100 x sqrt(0.6 x 0.4 / 401) = 2.45
    ([60.0, 30.0, 10.0], 2.4)
    >>> bool(np.allclose(masses.sum(axis=1), 100.0))
    True
    """
    generator = np.random.default_rng([seed, 1])  # a stream of its own: the curves' draws stay those of the seed
    result = []
    for fraction in fractions:
        mass = fraction.washability.mass_pct
        drawn = np.zeros((draws + 1, mass.size))
        drawn[0] = mass
        held = mass > 0
        if draws:
            drawn[1:, held] = 100.0 * generator.dirichlet(particles * mass[held] / mass[held].sum(), size=draws)
        result.append(drawn)
    return result
