r"""Ranking of the curves fitted to one sample: AIC, or quasi-AIC when the tracer counts are overdispersed.

Curves are ranked by Akaike's criterion.  When the tracer counts of a sample are
overdispersed (the Pearson test of its most general curve rejects at 5 %), the binomial
log-likelihood overstates the information in the data and the binomial AIC favours curves
with more parameters; they are then ranked by the quasi-AIC of Burnham & Anderson (2002,
sect. 2.5): :math:`\mathrm{QAIC} = -2 \log L / \hat c + 2 (p + 1)`, with one variance
inflation factor :math:`\hat c` for every curve of the sample, the Pearson
:math:`X^2 / df` of its most general curve (the most parameters; the lowest deviance among
those), and ``p + 1`` counting :math:`\hat c` as a parameter.  A difference below 2 is
reported as the data not telling the curves apart, as for AIC.

References
----------
.. [BurnhamAnderson2002] Burnham K.P., Anderson D.R. (2002). *Model Selection and Multimodel
   Inference*, 2nd ed. Springer, New York (sect. 2.5: overdispersed count data, QAIC).
"""

from __future__ import annotations

import math

from .fitting import DensityCurveFit

#: The criterion's name in the notes when the quasi-AIC ranks a sample.
QUASI_AIC = "QAIC"


def variance_inflation(fits: list[DensityCurveFit]) -> float:
    r""":math:`\hat c` of one sample's fits: the Pearson dispersion of its most general overdispersed binomial fit, else NaN."""
    done = [fit for fit in fits if fit.success and fit.method == "binomial"]
    if not done:
        return math.nan
    general = min(done, key=lambda fit: (-fit.curve.n_params, fit.objective))
    return general.dispersion if general.overdispersed and general.dispersion > 1 else math.nan


def quasi_aic(fit: DensityCurveFit, inflation: float) -> float:
    """QAIC of a binomial ``fit`` with the variance inflation ``inflation`` (NaN when it is NaN)."""
    if not (fit.success and fit.method == "binomial" and math.isfinite(inflation)):
        return math.nan
    parameters = fit.curve.n_params
    return (fit.aic - 2 * parameters) / inflation + 2 * (parameters + 1)


def rank_fits(fits: list[DensityCurveFit]) -> list[tuple[DensityCurveFit, int, str]]:
    """Rank the successful fits of one sample by AIC (QAIC when overdispersed); say when the best are closer than 2.

    Returns
    -------
    list of (fit, rank, note)
        In the order given; rank 0 for a failed fit.
    """
    inflation = variance_inflation(fits)
    criterion = {id(fit): quasi_aic(fit, inflation) if math.isfinite(inflation) else fit.aic for fit in fits}
    name = QUASI_AIC if math.isfinite(inflation) else "AIC"
    done = sorted((fit for fit in fits if fit.success), key=lambda fit: criterion[id(fit)])
    ranks = {id(fit): i + 1 for i, fit in enumerate(done)}
    close = [fit for fit in done if criterion[id(fit)] - criterion[id(done[0])] < 2.0] if done else []
    tie = ""
    if len(close) > 1:
        tie = f"the data cannot tell {', '.join(fit.curve.id for fit in close)} apart ({name} within 2 of the best)"
    ranked_by = ""
    if math.isfinite(inflation):
        ranked_by = f"ranked by QAIC (overdispersed: c-hat = {inflation:.3g}, the Pearson dispersion of the most general curve)"

    def note(fit):
        if not fit.success:
            return ""
        return "; ".join(part for part in (ranked_by, tie if fit in close else "") if part)

    return [(fit, ranks.get(id(fit), 0), note(fit)) for fit in fits]
