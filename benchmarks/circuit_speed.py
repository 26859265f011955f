"""placeholder"""
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab.circuit.simulation import example_plant, plitt_partition_to_fines

DATASETS = Path(__file__).resolve().parent.parent / "datasets"
CYCLONE_STREAMS = ("cyclone_feed", "cyclone_overflow", "cyclone_underflow")
#: The mineral of the assayed example: magnetite, 6 % of the cyclone feed in the finest classes and
#: 3 % in the coarsest, classified at a finer cut than the solids (d50c 60 um against 110 um).
MINERAL = "magnetite"


def assayed_example_table(*, per_stream: bool, seed: int = 40) -> pd.DataFrame:
    """The bundled example survey with a magnetite assay on the three cyclone streams.

    ``per_stream=False``: one assay per class (the true grade of the example plant's cyclone
    streams, drawn with the default assay error model, rounded to 0.01 % as a lab prints it);
    ``per_stream=True``: one value per stream (its head grade, drawn and rounded the same way)
    written on every class row of the stream, as a lab that reports one assay per sample does.
    """
    table = pd.read_csv(DATASETS / "circuit_example_survey.csv", comment="#")
    truth = example_plant()
    sheet, m = truth.flowsheet, truth.class_flows
    size = truth.classes["size"].to_numpy(float)
    feed, fine, coarse = (sheet.stream_index[s] for s in CYCLONE_STREAMS)
    feed_grade = np.linspace(0.03, 0.06, size.size)  # coarse to fine
    mineral_feed = feed_grade * m[feed]
    phi = plitt_partition_to_fines(size, 60.0, 2.5, bypass=0.2)
    mineral = {feed: mineral_feed, fine: phi * mineral_feed, coarse: (1 - phi) * mineral_feed}
    rng = np.random.default_rng(seed)
    column = np.full(len(table), np.nan)
    for s in (feed, fine, coarse):
        rows = np.flatnonzero(table["stream"].to_numpy() == sheet.stream_names[s])
        with np.errstate(invalid="ignore", divide="ignore"):
            grade = mineral[s].sum() / m[s].sum() if per_stream else np.where(m[s] > 0, mineral[s] / m[s], 0.0)
        drawn = grade + np.hypot(0.05 * grade, 0.0005) * rng.standard_normal(np.shape(grade))
        column[rows] = np.round(100 * np.clip(drawn, 0.0, None), 2)  # a scalar fills every row
    table[f"assay_{MINERAL}_pct"] = column
    return table
