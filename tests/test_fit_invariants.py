"""Fit-level invariants on generated experiments: scaling the sizes scales the
cut sizes and their intervals and changes nothing else; row order changes nothing;
swapping the fine and coarse products of a lab table gives 1 - partition and, read as a
partition to the coarse product, the same fits.  docs/reliability.md states the tolerances."""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from tromplab import fit_experiments, read_experiments
from tromplab.errors import InputError
from tromplab.statistics.uncertainty import interval_columns
from tromplab.workbench import data_notes

from .strategies import lab_tables, tromp_experiments

# deterministic (derandomize) and bounded: each example fits two to four batches of nine formulas
FIT_SETTINGS = settings(deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])

#: Columns in size units: multiplied by the scale factor.
SIZE_COLUMNS = ("d_cut", "d50", "d50c", "d25", "d75", "ep", "ep_c")
#: Dimensionless columns: unchanged.
UNCHANGED_COLUMNS = ("shape", "slope", "eta", "epsilon", "imperfection", "imperfection_c", "bypass", "fishhook", "x_break",
                     "F", "F_crit", "ssr", "aic", "aicc", "bic")  # fmt: skip
#: Relative tolerance of the invariants.  The optimiser works on relative sizes and stops at
#: its own tolerance, so the optimum moves by up to ~1e-6 with the units (largest seen:
#: 1.2e-6 on d_cut over 300 generated experiments).
RTOL = 1e-5
#: Absolute tolerance of the dimensionless results (shapes, efficiencies, slopes, bypass):
#: a shape near 0 (7.8e-4 seen) moves by 1.4e-8 with the data's last digits.
ATOL = 1e-7
#: Standard errors and intervals come from a forward-difference Jacobian at the optimum, so
#: they move with the optimum's last digits: up to 4e-4 seen on an ill-conditioned fit (a
#: curve levelling off at a plateau).  Before the step in ln d_cut was made absolute
#: (engine.py) it followed |ln d_cut|, which depends on the unit, and moved them by 1 %.
RTOL_DERIVED = 5e-3


#: A curve through every point (sum of squares below this; partitions are 0..1, so residuals
#: below 1e-6) has no unique optimum: ssr is rounding noise (0 or 1e-35), so F is inf or 1e32,
#: and on step-like data (a lab table whose classes go 0, 0, 1) any cut between two classes
#: and any shape up to its bound fit, so the optimiser's path decides d_cut (2 % seen at
#: sizes of 1e-9).  Such fits are compared only in that both runs find a curve through
#: every point; they are not ranked against each other.
EXACT_SSR = 1e-12
#: A number in a warning (replaced before warnings are compared across units).
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?"


def _fits_to_rounding(fits: pd.DataFrame) -> pd.Series:
    return fits["ssr"] < EXACT_SSR


def _assert_same_results(reference, other, scale: float = 1.0, rtol: float = RTOL, unpinned=None) -> None:
    """Sizes scaled by ``scale``, everything else equal, to :data:`RTOL`; fits through every
    point (:data:`EXACT_SSR`) only checked to be such in both."""
    through_every_point = _fits_to_rounding(reference) | _fits_to_rounding(other)
    for fits in (reference, other):  # a curve through every point, or a failed fit, on both sides
        chosen = fits.loc[through_every_point]
        assert ((chosen["ssr"] < 1e3 * EXACT_SSR) | ~chosen["success"]).all()
    # a fit that says a parameter is not determined by the data (a flat valley: formula (11) on
    # three classes found cuts 3.6 % apart at sums of squares equal to 1e-9) has no unique
    # optimum, and the warning's threshold may fall either side of a standard error that moves
    # with the unit by 5e-3
    exact = through_every_point | (_says(reference, "not determined") | _says(other, "not determined")).to_numpy()
    if unpinned is not None:
        exact = exact | unpinned
    assert (other.loc[~exact, "success"] == reference.loc[~exact, "success"]).all()
    for column in SIZE_COLUMNS:
        assert_allclose(other.loc[~exact, column] / scale, reference.loc[~exact, column], rtol=rtol, err_msg=column)
    for column in UNCHANGED_COLUMNS:
        if column in reference:
            atol = 0.0 if column in ("F", "F_crit", "ssr", "aic", "aicc", "bic") else ATOL  # scores: relative only
            assert_allclose(other.loc[~exact, column], reference.loc[~exact, column], rtol=rtol, atol=atol, err_msg=column)
    _assert_same_ranks(reference[~exact], other[~exact])
    # the same warnings, numbers aside (a cut size in another unit): found a d_cut of 7e-10 "at
    # its bound 7e-12" when the bound test had numpy.isclose's absolute tolerance
    for column in ("warnings", "extrapolated"):
        words = [
            fits.loc[~exact, column].fillna("").astype(str).str.replace(NUMBER, "#", regex=True) for fits in (reference, other)
        ]
        assert words[1].equals(words[0]), column


def _cut_outside_the_sizes(fits: pd.DataFrame, experiments) -> np.ndarray:
    """Fits whose cut lies outside the measured sizes of their experiment: extrapolated, not
    pinned by the data (on four classes, a cut 100 times below the finest moved by 6e-5 with
    the unit and by 2e-4 with partitions changed by 1e-9), so left out of the comparisons."""
    smallest = {points.experiment: points.size.min() for points in experiments}
    largest = {points.experiment: points.size.max() for points in experiments}
    experiment = fits.index.get_level_values("experiment")
    inside = (fits["d_cut"] >= experiment.map(smallest)) & (fits["d_cut"] <= experiment.map(largest))
    return ~inside.to_numpy()


def _says(fits: pd.DataFrame, words: str) -> pd.Series:
    return fits["warnings"].fillna("").str.contains(words, regex=False)


def _fits(frame: pd.DataFrame) -> pd.DataFrame:
    experiments, _ = read_experiments(frame)
    return fit_experiments(experiments).fits_table().set_index(["experiment", "formula"]).sort_index()


def _assert_same_ranks(reference: pd.DataFrame, other: pd.DataFrame) -> None:
    """Ranks agree, except between formulas whose F tie within the ranking's tolerance
    (ranking.F_TIE_RTOL): a tie group may cut differently when F moves by rounding."""
    for experiment, group in reference.groupby(level="experiment"):
        ranks, others, scores = group["rank"], other.loc[group.index, "rank"], group["F"]
        for a in group.index:
            for b in group.index:
                if ranks[a] < ranks[b] and abs(scores[a] - scores[b]) > 1e-3 * abs(scores[a]):
                    assert others[a] < others[b], (experiment, a, b)


@pytest.mark.slow
@settings(FIT_SETTINGS, max_examples=12)
@given(frame=tromp_experiments(max_experiments=1), scale=st.sampled_from([1e-3, 25.4, 1e3]))
def test_scaling_the_sizes_scales_the_cut_sizes_and_nothing_else(frame, scale):
    reference = _fits(frame)
    scaled = _fits(frame.assign(size=frame["size"] * scale))
    _assert_same_results(reference, scaled, scale)
    exact = _fits_to_rounding(reference) | _fits_to_rounding(scaled)
    exact = exact | _says(reference, "not determined") | _says(scaled, "not determined")
    for column in ("adequate", "residuals"):
        assert scaled.loc[~exact, column].equals(reference.loc[~exact, column]), column
    # standard errors: relative to their value, or to the estimate when they are near 0
    assert_allclose(
        scaled.loc[~exact, "shape_stderr"], reference.loc[~exact, "shape_stderr"], rtol=RTOL_DERIVED, atol=1e-6, err_msg="shape"
    )
    assert_allclose(
        scaled.loc[~exact, "d_cut_stderr"] / scale,
        reference.loc[~exact, "d_cut_stderr"],
        rtol=RTOL_DERIVED,
        atol=1e-6 * reference["d_cut"].abs().max(),
        err_msg="d_cut_stderr",
    )
    if not exact.any():  # differences from the best AICc, which is rounding noise when one curve fits exactly
        assert_allclose(scaled["delta_aicc"], reference["delta_aicc"], atol=1e-6)
    # tests on the residuals: near-degenerate residuals move their p-values more than the fit (the
    # verdicts, compared above, do not change)
    for column in ("runs_p", "normality_p"):
        assert_allclose(scaled.loc[~exact, column], reference.loc[~exact, column], atol=1e-3, err_msg=column)


@pytest.mark.slow
@settings(FIT_SETTINGS, max_examples=3)
@given(frame=tromp_experiments(max_experiments=1), scale=st.sampled_from([1e-3, 25.4, 1e3]))
def test_scaling_the_sizes_scales_the_intervals_of_the_cut_sizes(frame, scale):
    """Delta and profile intervals of (5) Rosin-Rammler and (11) Shuvalov, which tie when
    (11)'s break lies below the data."""
    tables = []
    for sizes in (frame["size"], frame["size"] * scale):
        experiments, _ = read_experiments(frame.assign(size=sizes))
        bench = fit_experiments(experiments, formulas=["rosin_rammler", "shuvalov"])
        tables.append(interval_columns(bench.fits, level=0.95).set_index(["experiment", "formula"]))
    reference, scaled = tables
    for column in reference.columns:
        if column.endswith(("_low", "_high")):
            factor = scale if column.rsplit("_", 1)[0] in ("d_cut", "d25", "d75", "ep", "d50", "ep_c") else 1.0
            assert_allclose(scaled[column] / factor, reference[column], rtol=RTOL_DERIVED, atol=1e-12, err_msg=column)
        else:
            assert scaled[column].equals(reference[column]), column


@pytest.mark.slow
@settings(FIT_SETTINGS, max_examples=6)
@given(frame=tromp_experiments(max_experiments=3), seed=st.integers(0, 2**32 - 1))
def test_row_order_changes_nothing(frame, seed):
    shuffled = frame.iloc[np.random.default_rng(seed).permutation(len(frame))]
    pd.testing.assert_frame_equal(_fits(shuffled), _fits(frame), check_exact=True)


@pytest.mark.slow
@settings(FIT_SETTINGS, max_examples=6)
@given(case=lab_tables())
def test_swapping_fine_and_coarse_gives_the_mirrored_partition_and_the_same_fits(case):
    """Each product's partition is computed from both products (partition_from="products"),
    so swapping the columns gives 1 - partition; read back as the partition to the coarse
    product, the swapped data give the original partition to fines, and the same fits."""
    swap = {column: column.replace("fine", "@").replace("coarse", "fine").replace("@", "coarse") for column in case.frame.columns}
    swapped_frame = case.frame.rename(columns=swap)
    if "coarse_yield" in swapped_frame:  # the stated yield is now the coarse product's
        swapped_frame = swapped_frame.rename(columns={"coarse_yield": "fine_yield"})
        swapped_frame["fine_yield"] = 1 - swapped_frame["fine_yield"]
    try:
        original, _ = read_experiments(case.frame)
    except InputError:
        return  # refused cleanly (test_hostile_inputs checks the refusals); nothing to compare
    swapped, _ = read_experiments(swapped_frame)
    mirrored = []
    for points, other in zip(original, swapped, strict=True):
        assert_allclose(other.size, points.size, rtol=1e-12)
        assert_allclose(other.partition_fine, 1 - points.partition_fine, atol=1e-9)
        assert other.delta_max == points.delta_max
        mirrored.append(
            pd.DataFrame({"experiment": other.experiment, "size": other.size, "partition_coarse": other.partition_fine})
        )
    # the swapped partition declared as the partition to the coarse product (a points file's
    # partition_coarse column); the top class bound (delta_max, which sets epsilon) carried over
    from_coarse, _ = read_experiments(pd.concat(mirrored, ignore_index=True))
    from_coarse = [replace(points, delta_max=other.delta_max) for points, other in zip(from_coarse, swapped, strict=True)]
    for points, other in zip(from_coarse, original, strict=True):
        assert_allclose(points.partition_fine, other.partition_fine, atol=1e-9)
    reference = fit_experiments(original).fits_table().set_index(["experiment", "formula"]).sort_index()
    mirrored_fits = fit_experiments(from_coarse).fits_table().set_index(["experiment", "formula"]).sort_index()
    # the mirrored partitions agree to 1e-9, not exactly: ill-conditioned fits of three or four
    # classes move by up to 2e-5 (seen on d_cut), so the tolerance here is 1e-4; a cut outside
    # the measured sizes (extrapolated, up to 100 times below them) is not pinned by the data
    # and moved by 2e-4, so it is left out
    # formula (11) rests on the measured cut; where the data note says it is ambiguous (a plateau
    # at 1/2) the last digits of the partitions decide its fit (tests/test_curves.py)
    ambiguous = {p.experiment for p in original if any("measured cut is ambiguous" in note for note in data_notes(p))}
    hanging = reference.index.get_level_values("experiment").isin(ambiguous) & (
        reference.index.get_level_values("formula") == "shuvalov"
    )
    unpinned = _cut_outside_the_sizes(reference, original) | hanging
    _assert_same_results(reference, mirrored_fits, rtol=1e-4, unpinned=unpinned)


@pytest.mark.slow
@settings(FIT_SETTINGS, max_examples=6)
@given(case=lab_tables(), scale=st.sampled_from([1e-3, 25.4, 1e3]))
def test_scaling_the_sieve_sizes_of_a_lab_table_scales_the_cut_sizes_and_nothing_else(case, scale):
    """The same lab table with its apertures in another unit: the same partitions at scaled
    sizes, so the fits of the points-level invariant above."""
    scaled_frame = case.frame.copy()
    for column in case.size_columns:
        scaled_frame[column] = scaled_frame[column] * scale
    try:
        original, _ = read_experiments(case.frame)
    except InputError:
        with pytest.raises(InputError):  # refused whatever the unit
            read_experiments(scaled_frame)
        return
    scaled, _ = read_experiments(scaled_frame)
    for points, other in zip(original, scaled, strict=True):
        assert_allclose(other.size, points.size * scale, rtol=1e-12)
        assert_allclose(other.partition_fine, points.partition_fine, rtol=1e-12, atol=0)
        assert other.largest_size == pytest.approx(points.largest_size * scale, rel=1e-12)  # delta_max or the largest size
    reference = fit_experiments(original).fits_table().set_index(["experiment", "formula"]).sort_index()
    other = fit_experiments(scaled).fits_table().set_index(["experiment", "formula"]).sort_index()
    _assert_same_results(reference, other, scale, unpinned=_cut_outside_the_sizes(reference, original))
