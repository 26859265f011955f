"""Write the bundled monitoring series datasets/classifier_trend_surveys.csv.

24 weekly surveys of one classifier drawn by tromplab.trend.simulate_surveys with the
default tromplab.trend.SeriesDesign and seed 14: Plitt's curve with bypass (d_cut
150 um, ks 2.5, bypass 0.10) measured at 12 sizes from 38 to 850 um, with survey-to-
survey jitter (cut 1.5 %, bypass 0.005 standard deviation) and noise of 0.012 on every
partition number; the bypass steps up by 0.08 from survey S13 and the cut drifts up by
4 % per survey from S19.  Run from the repository root:

    python analysis/make_trend_series.py
"""

from pathlib import Path

from tromplab.trend import SeriesDesign, simulate_surveys

SEED = 14
OUT = Path(__file__).resolve().parent.parent / "datasets" / "classifier_trend_surveys.csv"


def main():
    design = SeriesDesign()
    frame = simulate_surveys(design, seed=SEED)
    header = [
        "# Synthetic monitoring series: 24 weekly surveys of one classifier (Tromp points with a date).",
        f"# Generator: analysis/make_trend_series.py (tromplab.trend.simulate_surveys, default SeriesDesign, seed {SEED}).",
        f"# Curve: plitt_bypass, d_cut {design.d_cut:g} um, ks {design.ks:g}, bypass {design.bypass:g}; sizes in um.",
        f"# Known changes: bypass + {design.bypass_step:g} from survey S{design.bypass_step_at + 1:02d}; cut + "
        f"{design.drift_per_survey:.0%} per survey from S{design.drift_from + 1:02d}.",
        f"# Noise: survey jitter of the cut {design.jitter_cut:.1%} and of the bypass {design.jitter_bypass:g} (sd); "
        f"{design.noise:g} on each partition number (clipped to 0..1, 5 decimals).",
        "# d_cut_true, bypass_true: the values each survey was drawn with (after jitter), for checking.",
    ]
    OUT.write_text("\n".join(header) + "\n" + frame.to_csv(index=False))
    print(f"Wrote {OUT}")


if __name__ == "__main__":
    main()
