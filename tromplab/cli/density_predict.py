"""``tromplab density predict WASHABILITY --curve normal --rho50 1.55 --ep 0.035 -o pred.csv``.

The products a density separator with a given partition curve makes of a feed of known
washability: yield and ash of floats and sinks, the theoretical yield at the same ash and
the organic efficiency (:mod:`tromplab.density.washability`), one row per feed and cut
density; with ``--target-ash`` the cut density giving floats of that ash.  The Python face
is :func:`tromplab.density.predict_density`, whose result's ``save(output, table=...)`` writes
the same files, byte for byte (this module parses, calls it, saves and prints).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

from ..options import DEFAULT_SUM_TOLERANCE_PCT, PLAIN_DENSITY_CURVES
from ..validation import check_cut_density, check_non_negative, check_percent, check_positive, check_share, cli_type

#: The curves ``--curve`` offers: the registry's ids, the plain curves then their variants with limits.
PREDICT_CURVES = PLAIN_DENSITY_CURVES + tuple(f"{curve}_limits" for curve in PLAIN_DENSITY_CURVES)


# --- command line ----------------------------------------------------------------------------
def add_predict_parser(density_commands) -> None:
    """Register ``predict`` on the sub-command parsers of ``tromplab density``."""
    predict = density_commands.add_parser(
        "predict",
        help="yield and ash of floats and sinks, theoretical yield and organic efficiency of a feed's washability "
        "under a partition curve (docs/density.md)",
    )
    predict.add_argument("washability", type=Path, help="washability CSV: density_lower, density_upper, mass_pct, ash_pct "
                         "[, density_mean, test]")  # fmt: skip
    predict.add_argument("-o", "--output", type=Path, default=Path("prediction.csv"),
                         help="prediction CSV, one row per feed and cut density (default: prediction.csv)")  # fmt: skip
    predict.add_argument("--curve", choices=PREDICT_CURVES, default="normal",
                         help="partition curve of the registry (default normal); --light-limit/--heavy-limit select its "
                         "variant with limits")  # fmt: skip
    cut = predict.add_mutually_exclusive_group(required=True)
    cut.add_argument("--rho50", type=cli_type(check_cut_density, "--rho50"), nargs="+", metavar="RHO50",
                     help="cut density (relative density, above 1); several give one row each")  # fmt: skip
    cut.add_argument("--target-ash", dest="target_ash_pct", type=cli_type(check_percent, "--target-ash"), nargs="+", metavar="ASH_PCT",
                     help="floats ash per cent sought: the cut density giving it is found (Brent's method)")  # fmt: skip
    predict.add_argument("--ep", type=cli_type(check_positive, "--ep"), required=True,
                         help="probable error Ep = (rho75 - rho25)/2, relative density units")  # fmt: skip
    predict.add_argument("--light-limit", type=cli_type(check_share, "--light-limit"), default=None,
                         help="partition to sinks of the lightest material, in [0, 0.25) (default 0)")  # fmt: skip
    predict.add_argument("--heavy-limit", type=cli_type(check_share, "--heavy-limit"), default=None,
                         help="partition to sinks of the heaviest material, in (0.75, 1] (default 1)")  # fmt: skip
    predict.add_argument("--table", type=Path, default=None,
                         help="also write the washability table (cumulative floats and sinks, near-gravity material) "
                         "to this CSV")  # fmt: skip
    predict.add_argument("--sum-tolerance", dest="sum_tolerance_pct", type=cli_type(check_non_negative, "--sum-tolerance"),
                         default=DEFAULT_SUM_TOLERANCE_PCT,
                         help=f"allowed deviation of mass_pct totals from 100 (default {DEFAULT_SUM_TOLERANCE_PCT:g})")  # fmt: skip
    predict.add_argument("--float-lower-density", type=cli_type(check_positive, "--float-lower-density"), default=None,
                         help="lower bound of the open float fraction (default: the width of its neighbour)")  # fmt: skip
    predict.add_argument("--sink-upper-density", type=cli_type(check_positive, "--sink-upper-density"), default=None,
                         help="upper bound of the open sink fraction (default: the width of its neighbour)")  # fmt: skip
    predict.set_defaults(
        run=_run_predict,
        imports=(
            "tromplab.density.prediction",
            "tromplab.density.washability",
            "tromplab.density.registry",
            "tromplab.output.csv_parts",
            "scipy.optimize",
        ),
    )


def _run_predict(args) -> int:
    from ..density.prediction import check_prediction_files, predict_density

    check_prediction_files(args.output, args.table, source=args.washability)  # before the input is read
    result = predict_density(
        args.washability, curve=args.curve, rho50=args.rho50, ep=args.ep, light_limit=args.light_limit,
        heavy_limit=args.heavy_limit, target_ash_pct=args.target_ash_pct, sum_tolerance_pct=args.sum_tolerance_pct,
        float_lower_density=args.float_lower_density, sink_upper_density=args.sink_upper_density,
    )  # fmt: skip
    written = result.save(args.output, table=args.table)
    print(console_report(result, written))
    return 3 if result.predictions["floats_yield_pct"].isna().any() else 0  # 3: some predictions failed (notes say why)


def console_report(result, written: dict) -> str:
    """What the command prints: the predictions (of a :class:`~tromplab.density.prediction.DensityPrediction`)
    and the files ``written``."""
    shown = ["test", "curve", "rho50", "ep", "floats_yield_pct", "floats_ash_pct", "sinks_ash_pct", "organic_efficiency_pct"]
    table = result.predictions[shown].to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-")
    notes = _grouped_notes(result.predictions, written)
    return "\n".join([table, *notes, "", "Wrote:", *(f"  {path}" for path in written.values())])


def _grouped_notes(predictions, written: dict) -> list[str]:
    """The notes of the predictions, a note that repeats over rows once with its count and first
    tests (:func:`tromplab.notices.grouped_lines`); every one is in the predictions file."""
    from ..notices import Notice, grouped_lines

    said = [Notice(str(row.test), row.note) for row in predictions.itertuples() if isinstance(row.note, str) and row.note]
    listed_in = next(iter(written), "the predictions file")  # the predictions CSV is written first
    tests = len(set(predictions["test"]))
    lines = grouped_lines(said, total=tests, noun="tests", listed_in=listed_in)
    return [textwrap.fill(f"note {line}" if line.startswith("(") else f"note: {line}", width=98) for line in lines]
