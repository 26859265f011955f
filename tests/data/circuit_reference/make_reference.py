"""Write the reference outputs of ``tromplab circuit`` and ``tromplab circuit design`` that
tests/test_circuit_speed.py compares the current implementation with.

Provenance: the outputs in this folder were first written by this script at commit ed84263 of
tromplab (the implementation before the factor-once / low-rank-update rewrite), with
OPENBLAS_NUM_THREADS=1 (``worth.csv`` gzip-compressed).  They were written again on branch
circuit-kkt when the least squares became deterministic (Gauss-Newton in numpy instead of
MINPACK, whose result depended on memory left by earlier allocations; the error model's rounds
to 1e-10 instead of 1e-6; near-tied measurement tests ranked by file row).  Against ed84263's
files: example, example_options, water and design_simulated agree to 1e-8 relative,
design_survey to 1e-9, design_simulated_flows to 1e-12; the assayed surveys, which ed84263 did
not reproduce between runs (flows moved by 1e-4), moved by 1e-7 in their flows and their three
tied magnetite suspects are now listed by row (the serial elimination names cyclone_feed's, not
cyclone_underflow's; their tests agree to 2e-8).  The inputs (``inputs/``) are derived from the bundled example
(datasets/circuit_example_*.csv) as the functions below say.  Run from the repository root:

    OPENBLAS_NUM_THREADS=1 python tests/data/circuit_reference/make_reference.py
"""

import gzip
import os
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
#: The inputs as the commands are given them, relative to this folder (the summaries name them).
FLOWSHEET = "../../../datasets/circuit_example_flowsheet.csv"
SURVEY = "../../../datasets/circuit_example_survey.csv"
CYCLONE_STREAMS = ("cyclone_feed", "cyclone_overflow", "cyclone_underflow")


def assayed_example(*, per_stream: bool, seed: int = 40) -> pd.DataFrame:
    """The bundled survey with a magnetite assay on the three cyclone streams: one value per
    class, or one value per stream written on each of its rows (as labs often report it).

    The true grades: 3 % in the coarsest to 6 % in the finest class of the cyclone feed
    (example_plant's class flows), the magnetite classified on Plitt's curve at d50c 60 um
    (m 2.5, bypass 0.2); each assay drawn with sd sqrt((0.05 a)^2 + 0.0005^2), clipped at 0 and
    rounded to 0.01 %."""
    from tromplab.circuit.simulation import example_plant, plitt_partition_to_fines

    table = pd.read_csv(HERE / SURVEY, comment="#")
    truth = example_plant()
    sheet, m = truth.flowsheet, truth.class_flows
    size = truth.classes["size"].to_numpy(float)
    feed, fine, coarse = (sheet.stream_index[s] for s in CYCLONE_STREAMS)
    mineral_feed = np.linspace(0.03, 0.06, size.size) * m[feed]
    phi = plitt_partition_to_fines(size, 60.0, 2.5, bypass=0.2)
    mineral = {feed: mineral_feed, fine: phi * mineral_feed, coarse: (1 - phi) * mineral_feed}
    rng = np.random.default_rng(seed)
    column = np.full(len(table), np.nan)
    for s in (feed, fine, coarse):
        rows = np.flatnonzero(table["stream"].to_numpy() == sheet.stream_names[s])
        with np.errstate(invalid="ignore", divide="ignore"):
            grade = mineral[s].sum() / m[s].sum() if per_stream else np.where(m[s] > 0, mineral[s] / m[s], 0.0)
        drawn = grade + np.hypot(0.05 * grade, 0.0005) * rng.standard_normal(np.shape(grade))
        column[rows] = np.round(100 * np.clip(drawn, 0.0, None), 2)  # a scalar fills every row of the stream
    table["assay_magnetite_pct"] = column
    return table


def with_pct_solids() -> pd.DataFrame:
    """The bundled survey with per cent solids measured on the three cyclone streams (on each
    stream's first row): 58 % feed, 36 % overflow, 74 % underflow, sd 1 point by default."""
    table = pd.read_csv(HERE / SURVEY, comment="#")
    table["pct_solids"] = np.nan
    for stream, value in zip(CYCLONE_STREAMS, (58.0, 36.0, 74.0)):
        table.loc[table.index[table["stream"] == stream][0], "pct_solids"] = value
    return table


CIRCUIT_CASES = {
    "example": (SURVEY, []),
    "example_options": (SURVEY, ["--relative-error", "0.08", "--error-model-at", "measured", "--exclude", "oversize:+19000"]),
    "assay_class": ("inputs/assay_class.csv", []),
    "assay_stream": ("inputs/assay_stream.csv", []),
    "water": ("inputs/water.csv", []),
}
DESIGN_CASES = {
    "design_simulated": [],
    "design_simulated_flows": [
        "--flows",
        "screen_feed",
        "--sampled",
        "screen_feed,oversize,middlings,undersize,cyclone_feed,cyclone_overflow,cyclone_underflow",
    ],
    "design_survey": [SURVEY, "--quantity", "partition", "--quantity", "fine yield", "--quantity", "circulating load"],
}


def run(name: str, outdir) -> int:
    """Run case ``name`` (from this folder: the inputs are named relative to it) into ``outdir``."""
    from tromplab.cli import main as tromplab

    if name in CIRCUIT_CASES:
        survey, options = CIRCUIT_CASES[name]
        return tromplab(["circuit", FLOWSHEET, survey, "-o", str(outdir), "--no-figures", "-q", *options])
    return tromplab(["circuit", "design", FLOWSHEET, *DESIGN_CASES[name], "-o", str(outdir), "-q"])


def main() -> None:
    os.chdir(HERE)
    inputs = HERE / "inputs"
    inputs.mkdir(exist_ok=True)
    assayed_example(per_stream=False).to_csv(inputs / "assay_class.csv", index=False)
    assayed_example(per_stream=True).to_csv(inputs / "assay_stream.csv", index=False)
    with_pct_solids().to_csv(inputs / "water.csv", index=False)
    for name in [*CIRCUIT_CASES, *DESIGN_CASES]:
        assert run(name, HERE / name) == 0, name
        worth = HERE / name / "worth.csv"
        if worth.exists():  # the largest table, stored compressed (the test reads it back as text)
            Path(f"{worth}.gz").write_bytes(gzip.compress(worth.read_bytes(), mtime=0))
            worth.unlink()


if __name__ == "__main__":
    main()
