"""False-alarm rate and detection delay of the monitoring rule of tromplab.trend.

Draws seeded survey series from tromplab.trend.simulate_surveys: ``--series`` series
without any change (false alarms) and as many with the bundled design's two changes
(a bypass step at survey 13, a cut drifting by 4 % per survey from survey 19), runs
tromplab.trend.monitor_surveys on each (formula plitt_bypass, default baseline: the
first 8 surveys, alpha 0.01), and evaluates the rule at several EWMA limit widths L
on the same fits.  Results are printed and written to benchmarks/output/trend_false_alarms.csv;
docs/trend.md states them.

    python benchmarks/trend_false_alarms.py --series 200 --workers 2
"""

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab.trend import EWMA_L, SeriesDesign, flag_changes, monitor_surveys, simulate_surveys, surveys_from_frame

WIDTHS = (3.0, 3.5, EWMA_L, 4.0)
NO_CHANGE = SeriesDesign(bypass_step_at=None, drift_from=None)
CHANGES = SeriesDesign()


def charted(seed: int, design: SeriesDesign):
    """The charted values, p_baseline and baseline of one seeded series."""
    result = monitor_surveys(surveys_from_frame(simulate_surveys(design, seed=seed)), formula="plitt_bypass", consecutive=False)
    table = result.table
    values = {q: g["value"].to_numpy() for q, g in table.groupby("quantity", sort=False)}
    p_baseline = table.drop_duplicates("survey")["p_baseline"].to_numpy()
    return values, p_baseline, result.baseline


def evaluate(seed: int) -> list[dict]:
    rows = []
    null = charted(10_000 + seed, NO_CHANGE)
    change = charted(20_000 + seed, CHANGES)
    step, drift = CHANGES.bypass_step_at, CHANGES.drift_from
    for width in dict.fromkeys(WIDTHS):
        _, _, changed, points = flag_changes(*null, width=width)
        after = len(changed) - max(null[2]) - 1
        _, alarms, changed_c, points_c = flag_changes(*change, width=width)
        found = np.flatnonzero(points_c)
        before_step = found[found < step]
        step_hits = found[(found >= step) & (found < drift)]
        cut_alarm = np.flatnonzero(alarms["d_cut"] & changed_c)
        cut_hits = cut_alarm[cut_alarm >= drift]
        rows.append(
            {
                "seed": seed,
                "L": width,
                "null_any_change_point": bool(points.any()),
                "null_flagged_surveys": int(changed.sum()),
                "null_monitored_surveys": after,
                "change_false_before_step": len(before_step) > 0,
                "step_delay": step_hits[0] - step if step_hits.size else np.nan,
                "drift_delay": cut_hits[0] - drift if cut_hits.size else np.nan,
            }
        )
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--series", type=int, default=200)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--outdir", type=Path, default=Path(__file__).resolve().parent / "output")
    args = parser.parse_args(argv)
    with ProcessPoolExecutor(args.workers) as pool:
        rows = [row for chunk in pool.map(evaluate, range(args.series)) for row in chunk]
    table = pd.DataFrame(rows)
    args.outdir.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.outdir / "trend_false_alarms.csv", index=False)
    summary = table.groupby("L").agg(
        series=("seed", "size"),
        false_alarm_series=("null_any_change_point", "mean"),
        false_alarm_per_survey=("null_flagged_surveys", "sum"),
        monitored=("null_monitored_surveys", "sum"),
        false_before_step=("change_false_before_step", "mean"),
        step_detected=("step_delay", lambda d: d.notna().mean()),
        step_delay_mean=("step_delay", "mean"),
        step_delay_max=("step_delay", "max"),
        drift_detected=("drift_delay", lambda d: d.notna().mean()),
        drift_delay_mean=("drift_delay", "mean"),
        drift_delay_median=("drift_delay", "median"),
        drift_delay_max=("drift_delay", "max"),
    )
    summary["false_alarm_per_survey"] = summary["false_alarm_per_survey"] / summary.pop("monitored")
    print(summary.to_string(float_format=lambda v: f"{v:.3f}"))
    print(f"\nWrote {args.outdir / 'trend_false_alarms.csv'}")


if __name__ == "__main__":
    main()
