"""A workbench reads its fits through one interface (:class:`tromplab.workbench.FitStore`), held
in memory or read back from a streamed folder: both implementations offer every question of
the interface and answer them alike."""

import inspect
import pickle

import pandas as pd
import pytest

from tromplab._synthetic import synthetic
from tromplab.loading.points import TrompPoints
from tromplab.workbench import FitsInMemory, FitsOnDisk, FitStore, fit_experiments, fit_to_folder

QUESTIONS = sorted(name for name, value in vars(FitStore).items() if inspect.isfunction(value) and not name.startswith("_"))


def test_the_interface_asks_what_the_workbench_needs():
    assert QUESTIONS == sorted([
        "averages_read", "best_formula", "experiment_rows", "experiments", "failed_fits", "fits_by_experiment",
        "fits_of", "fits_table", "n_successful", "ranking", "save", "standings", "top_rows",
    ])  # fmt: skip


@pytest.mark.parametrize("store", [FitsInMemory, FitsOnDisk])
def test_each_store_answers_every_question_with_the_interface_s_parameters(store):
    for name in QUESTIONS:
        asked = list(inspect.signature(getattr(FitStore, name)).parameters)
        assert list(inspect.signature(getattr(store, name)).parameters) == asked, name


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """One batch kept in memory and streamed (two experiments the screen cannot judge among them)."""
    data = [synthetic(seed, weighted=False) for seed in range(30)]
    data.insert(5, TrompPoints("two_points", [10.0, 40.0], [0.9, 0.2]))
    folder = tmp_path_factory.mktemp("stores")
    options = {"formulas": "plitt,lognormal,shuvalov", "ci": 0.9, "figures": "none"}
    kept, _ = fit_to_folder(data, folder / "memory", stream=False, **options)
    streamed, _ = fit_to_folder(data, folder / "streamed", stream=True, **options)
    return kept, streamed, folder


def test_a_streamed_and_a_kept_batch_answer_alike(both):
    kept, streamed, folder = both
    assert isinstance(kept.store, FitsInMemory) and isinstance(streamed.store, FitsOnDisk)
    assert streamed.store.experiments() == kept.store.experiments()
    assert streamed.store.n_successful() == kept.store.n_successful()
    assert streamed.store.failed_fits() == kept.store.failed_fits()
    for experiment in kept.experiments[:3] + kept.experiments[-2:]:
        assert streamed.store.best_formula(experiment) == kept.store.best_formula(experiment)
        assert [f.fit.values for f in streamed.store.fits_of(experiment)] == [
            f.fit.values for f in kept.store.fits_of(experiment)
        ]
        assert streamed.verdicts(experiment) == kept.verdicts(experiment)
    pd.testing.assert_frame_equal(streamed.store.ranking(), kept.store.ranking())
    assert kept.store.standings(kept.equations) is None  # the kept batch's standings come from its ranking
    pd.testing.assert_frame_equal(
        streamed.store.standings(streamed.equations), kept.ranking_table()[["equation", "formula", "points", "place"]]
    )
    # the streamed batch reads the averages it wrote (as a CSV reader types them); the kept one makes them
    assert kept.store.averages_read(0.9) is None and streamed.store.averages_read(0.95) is None
    pd.testing.assert_frame_equal(streamed.store.averages_read(0.9), pd.read_csv(folder / "memory" / "averages.csv"))


def test_an_old_pickle_without_a_store_loads_into_an_in_memory_store():
    points = [synthetic(seed, weighted=False) for seed in range(3)]
    bench = fit_experiments(points, formulas="plitt,lognormal", alpha=0.1)
    state = bench.__getstate__()
    del state["store"]
    settings = state.pop("settings")  # the layout before the settings were one record
    state.update(alpha=settings.alpha, rank_by=settings.rank_by, ci=settings.ci, partition_to=settings.partition_to)
    old = object.__new__(type(bench))
    old.__setstate__(state)
    assert isinstance(old.store, FitsInMemory) and old.store.bench is old
    assert old.alpha == 0.1 and old.settings.alpha == 0.1
    pd.testing.assert_frame_equal(old.fits_table(), bench.fits_table())
    again = pickle.loads(pickle.dumps(bench))
    assert again.store.bench is again
    pd.testing.assert_frame_equal(again.ranking_table(), bench.ranking_table())
