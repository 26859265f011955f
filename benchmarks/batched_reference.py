"""Benchmark floor: a bare batched Levenberg-Marquardt in numpy against tromplab's fits.

The floor the engine is measured against: for the seven smooth paper formulas, (3)-(9) (the
piecewise (10) and (11) need the engine's kink handling), every experiment of a padded batch
is fitted at once with nothing but arithmetic:

* start: the best point of a grid of 21 shapes (slopes at the cut from -0.02 to -20) times 24
  log-spaced cuts over the measured sizes;
* Levenberg-Marquardt in ``(ln d_cut, shape)`` on all rows together: forward-difference
  Jacobians, the 2 x 2 damped normal equations solved in closed form, steps clipped to the
  engine's bounds, a row ends when an accepted step gains less than 1e-13 (relative) or its
  damping passes 1e12; at most 200 iterations;
* no result objects, covariance, indices or checks.

Measured in the same run on the same experiments: the reference; tromplab's engine on the same
seven formulas (``engine.fit_formula_batch``: its grid, starts, polish, covariance and result
records); and ``workbench.fit_chunk`` (the whole work of a chunk: also the indices, residual
diagnostics, screen and warnings). Reported: seconds, and the share of fits where the reference
ends more than 1e-6 (relative) above or below tromplab's sum of squares.

    python benchmarks/batched_reference.py --experiments 1024
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from scaling import experiments  # noqa: E402

from tromplab.curves.batched import PaddedPoints  # noqa: E402
from tromplab.curves.engine import fit_formula_batch  # noqa: E402
from tromplab.curves.formulas import FORMULAS  # noqa: E402
from tromplab.curves.parameters import D_CUT_RANGE_FACTOR  # noqa: E402
from tromplab.workbench import fit_chunk  # noqa: E402

SMOOTH = [f for f in FORMULAS if not f.piecewise]
SLOPES = -np.geomspace(0.02, 20.0, 21)
CUTS = 24
ITERATIONS = 200


def _ssr(formula, data, log_cut, shape):
    """Weighted sums of squares of parameter rows (broadcast against the experiments' points)."""
    with np.errstate(all="ignore"):
        x = data.size / np.exp(log_cut)[..., None]
        residual = data.root_weight * (formula.phi(x, shape[..., None]) - data.observed)
        value = np.sum(residual**2, axis=-1)
    return np.where(np.isfinite(value), value, np.inf), residual


def reference_fit(formula, data: PaddedPoints) -> np.ndarray:
    """Sums of squares at the reference's optimum, one per experiment."""
    low_cut, high_cut = data.cut_bounds(D_CUT_RANGE_FACTOR)
    low_shape, high_shape = formula.shape_bounds
    shapes = np.array(sorted({formula.clip_shape(formula.shape_for_slope(s)) for s in SLOPES}))
    real = data.root_weight > 0
    span = np.log(np.where(real, data.size, np.inf).min(axis=1)), np.log(np.where(real, data.size, -np.inf).max(axis=1))
    cuts = span[0][:, None] + np.linspace(0.0, 1.0, CUTS) * (span[1] - span[0])[:, None]  # (E, C)
    grid, _ = _ssr(
        formula,
        PaddedPoints(data.size[:, None, None], data.observed[:, None, None], data.root_weight[:, None, None], data.n),
        np.broadcast_to(cuts[:, None, :], (len(data), shapes.size, CUTS)),
        np.broadcast_to(shapes[None, :, None], (len(data), shapes.size, CUTS)),
    )
    best = grid.reshape(len(data), -1).argmin(axis=1)
    log_cut = cuts[np.arange(len(data)), best % CUTS]
    shape = shapes[best // CUTS]
    ssr, residual = _ssr(formula, data, log_cut, shape)
    damping = np.full(len(data), 1e-3)
    alive = np.isfinite(ssr)
    for _ in range(ITERATIONS):
        if not alive.any():
            break
        step_cut, step_shape = 1.5e-8, 1.5e-8 * np.maximum(np.abs(shape), 1.0)
        jac_cut = (_ssr(formula, data, log_cut + step_cut, shape)[1] - residual) / step_cut
        jac_shape = (_ssr(formula, data, log_cut, shape + step_shape)[1] - residual) / step_shape[:, None]
        a, b, c = np.sum(jac_cut**2, -1), np.sum(jac_cut * jac_shape, -1), np.sum(jac_shape**2, -1)
        g1, g2 = np.sum(jac_cut * residual, -1), np.sum(jac_shape * residual, -1)
        a_d, c_d = a * (1 + damping), c * (1 + damping)
        det = a_d * c_d - b * b
        with np.errstate(all="ignore"):
            d_cut = np.where(det != 0, -(c_d * g1 - b * g2) / det, 0.0)
            d_shape = np.where(det != 0, -(a_d * g2 - b * g1) / det, 0.0)
        trial_cut = np.clip(log_cut + np.nan_to_num(d_cut), low_cut, high_cut)
        trial_shape = np.clip(shape + np.nan_to_num(d_shape), low_shape, high_shape)
        trial_ssr, trial_residual = _ssr(formula, data, trial_cut, trial_shape)
        accepted = alive & (trial_ssr < ssr)
        gain = np.where(accepted, (ssr - trial_ssr) / np.maximum(ssr, 1e-300), 0.0)
        log_cut, shape = np.where(accepted, trial_cut, log_cut), np.where(accepted, trial_shape, shape)
        residual = np.where(accepted[:, None], trial_residual, residual)
        ssr = np.where(accepted, trial_ssr, ssr)
        damping = np.where(accepted, np.maximum(damping / 3.0, 1e-12), damping * 4.0)
        alive &= ~((accepted & (gain < 1e-13)) | (~accepted & (damping > 1e12)))
    return ssr


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=1024)
    args = parser.parse_args(argv)
    batch = experiments(args.experiments)
    data = PaddedPoints.from_points(batch)
    reference_fit(SMOOTH[0], PaddedPoints.from_points(batch[:8]))  # warm-up
    start = time.perf_counter()
    reference = {f.id: reference_fit(f, data) for f in SMOOTH}
    reference_seconds = time.perf_counter() - start
    start = time.perf_counter()
    engine = {f.id: np.array([fit.fit.ssr for fit in fit_formula_batch(batch, f)]) for f in SMOOTH}
    engine_seconds = time.perf_counter() - start
    start = time.perf_counter()
    fit_chunk(batch, formulas=tuple(f.id for f in SMOOTH), alpha=0.05, delta_max=None)
    chunk_seconds = time.perf_counter() - start
    above = below = 0
    for formula_id, found in reference.items():
        relative = (found - engine[formula_id]) / np.maximum(engine[formula_id], 1e-300)
        above += int(np.sum(relative > 1e-6))
        below += int(np.sum(relative < -1e-6))
    fits = len(batch) * len(SMOOTH)
    print(f"{args.experiments} experiments x {len(SMOOTH)} smooth formulas ({fits} fits)")
    print(f"  bare batched reference:   {reference_seconds:6.2f} s  1.00 x")
    print(f"  tromplab engine:          {engine_seconds:6.2f} s  {engine_seconds / reference_seconds:.2f} x")
    print(f"  tromplab chunk (all work): {chunk_seconds:5.2f} s  {chunk_seconds / reference_seconds:.2f} x")
    print(
        f"  reference above tromplab's sum of squares (> 1e-6): {above} ({above / fits:.2%}); below: {below} ({below / fits:.2%})"
    )


if __name__ == "__main__":
    main()
