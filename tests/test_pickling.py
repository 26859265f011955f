"""Formula records and fit results travel through pickle (process pools, saved batches)."""

import pickle

import numpy as np
import pandas as pd
import pytest

import tromplab
from tromplab.curves.formulas import ALL_FORMULAS
from tromplab.loading.points import TrompPoints


@pytest.mark.parametrize("formula", ALL_FORMULAS, ids=lambda f: f.id)
def test_formula_records_pickle_by_id(formula):
    assert pickle.loads(pickle.dumps(formula)) is formula


def test_fit_and_batch_round_trip():
    points = TrompPoints("run", np.array([1.0, 2, 4, 8, 16, 32]), np.array([0.97, 0.9, 0.62, 0.3, 0.08, 0.02]))
    bench = tromplab.fit_experiments([points], formulas=["plitt", "lognormal", "shuvalov"])
    copy = pickle.loads(pickle.dumps(bench))
    pd.testing.assert_frame_equal(copy.fits_table(), bench.fits_table())
    pd.testing.assert_frame_equal(copy.ranking_table(), bench.ranking_table())
    fit = copy.fits[0]
    np.testing.assert_allclose(fit.predict(points.size), bench.fits[0].predict(points.size))
