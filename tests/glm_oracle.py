"""statsmodels' binomial GLM of a plain density curve on a tracer sample: the oracle the batch
GLM (tromplab.density.batch) and the fits built on it are compared with."""

from __future__ import annotations

import warnings

import numpy as np


def statsmodels_glm(curve, sample, **options):
    """The fitted ``sm.GLM`` of ``curve``'s link on ``sample``'s recovered tracers (``options``: of ``fit``)."""
    import statsmodels.api as sm

    links = {"probit": sm.families.links.Probit, "logit": sm.families.links.Logit, "cloglog": sm.families.links.CLogLog}
    used = sample.used
    k, n = used["sinks"].to_numpy(float), used["recovered"].to_numpy(float)
    exog = np.column_stack([np.ones(len(k)), used["density"].to_numpy(float)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sm.GLM(np.column_stack([k, n - k]), exog, family=sm.families.Binomial(link=links[curve.link]())).fit(**options)
