"""``tromplab plant predict | optimize | evaluate``: a coal-washing plant's products, its best cuts, a tested separation.

The library is :mod:`tromplab.plant`; this module registers the ``plant`` command and its
sub-commands on the CLI's parser and runs them through :func:`tromplab.plant.predict` and
:meth:`tromplab.plant.PlantPrediction.save`, :func:`tromplab.plant.optimize` and
:meth:`tromplab.plant.PlantOptimum.save`, :func:`tromplab.plant.evaluate` and
:meth:`tromplab.plant.evaluation.SeparationEvaluation.save` (what the Python API writes, byte for byte).
The parser needs only the light modules imported here; the library is imported when a
sub-command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..options import DEFAULT_SUM_TOLERANCE_PCT, PLAIN_DENSITY_CURVES
from ..output.outputs import check_output_folder
from ..validation import check_count, check_non_negative, check_percent, check_positive, check_probability, check_seed, cli_type
from .startup import EXIT_OK, print_usage, progress_bars

#: What ``plant predict`` imports when it runs (imported before it starts, under the CLI's signal handling).
PREDICT_IMPORTS = ("tromplab.plant", "tromplab.plant.plotting", "tromplab.output.plotting", "scipy.special")
#: Defaults of the options, written out so that building the parser imports no numerical library (a test checks them).
DEFAULT_CI, DEFAULT_DRAWS, MAX_DRAWS, MAX_PARTICLES = 0.95, 2000, 200_000, 10**12


def add_plant_command(commands) -> argparse.ArgumentParser:
    """Register ``tromplab plant`` with its sub-commands; returns the ``plant`` parser."""
    plant = commands.add_parser("plant", help="a coal-washing plant: washability by size fraction, a device per size fraction "
                                "(docs/plant.md)")  # fmt: skip
    sub = plant.add_subparsers(dest="plant_command", metavar="SUBCOMMAND", parser_class=type(plant))
    _add_predict(sub)
    _add_optimize(sub)
    _add_evaluate(sub)
    plant.set_defaults(run=lambda args: print_usage(plant))
    return plant


def _add_predict(sub) -> None:
    predict = sub.add_parser(
        "predict",
        help="clean-coal yield, ash, theoretical yield, organic efficiency and misplaced material of each size fraction "
        "and of the plant, with intervals from the curves' uncertainty",
        description="Predict the products of every size fraction's device and of the blended plant product and write "
        "products.csv, devices.csv, summary.txt, yield_ash.png and partition.png into the output folder.",
    )
    _add_inputs(predict)
    predict.add_argument("--washability-particles", type=cli_type(check_count, "--washability-particles", maximum=MAX_PARTICLES),
                         default=None, metavar="N", help="add the sampling error of the washability analyses to the "
                         "intervals: each size fraction's analysis made on a sample of N particles (Dirichlet draws of the "
                         "density fractions' masses; default: the washability taken as exact)")  # fmt: skip
    predict.set_defaults(run=run_plant_predict, imports=PREDICT_IMPORTS)


def _add_optimize(sub) -> None:
    optimize = sub.add_parser(
        "optimize",
        help="the cut densities that give the most clean coal at a product ash of at most --target-ash "
        "(equal incremental ash), optionally with a probability --confidence under the curves' uncertainty",
        description="Find the cut density of every size fraction's device that maximises the plant's clean coal at a "
        "clean-coal ash of at most --target-ash, within the bounds of the plant table, and write cuts.csv and the files "
        "of `plant predict` at those cuts into the output folder.",
    )
    _add_inputs(optimize)
    optimize.add_argument("--target-ash", dest="target_ash_pct", type=cli_type(check_percent, "--target-ash"), required=True, metavar="ASH_PCT",
                          help="clean-coal ash per cent not to exceed (the contract ash)")  # fmt: skip
    optimize.add_argument("--confidence", type=cli_type(check_probability, "--confidence"), default=None, metavar="P",
                          help="maximise the expected clean coal subject to P(ash <= target) >= P under the curves' "
                          "uncertainty (needs their standard deviations or covariance)")  # fmt: skip
    optimize.set_defaults(run=run_plant_optimize, imports=PREDICT_IMPORTS + ("scipy.optimize",))


def _add_evaluate(sub) -> None:
    evaluate = sub.add_parser(
        "evaluate",
        help="a tested separation in the standard form: partition coefficients, cut density, Ep, imperfection, "
        "yield and ash errors, organic efficiency, misplaced and near-gravity material (ISO 923)",
        description="Evaluate every test of FILE - two-product float-sink analyses with ash, tracer counts with the "
        "feed's --washability, or three-product analyses (clean, middlings, reject) with ash, each cut on its own feed - and "
        "write evaluation.csv, fractions.csv, tracers.csv (tracer tests) and summary.txt into the output folder.",
    )
    evaluate.add_argument("file", type=Path, help="float-sink table: test, density_lower, density_upper, [feed_pct,] "
                          "floats_pct, sinks_pct with feed_ash_pct or floats_ash_pct and sinks_ash_pct; or tracer counts: "
                          "test, density, placed, sinks, floats; or a three-product table: ..., clean_pct, middlings_pct, "
                          "reject_pct [, clean_yield, middlings_yield] with ash (docs/plant.md)")  # fmt: skip
    evaluate.add_argument("--washability", type=Path, default=None, metavar="WASH",
                          help="washability of the feed of the tracer tests (density_lower, density_upper, mass_pct, "
                          "ash_pct; one table, or one per test named after the test or its size fraction)")  # fmt: skip
    evaluate.add_argument("-o", "--outdir", type=Path, default=Path("results/evaluation"),
                          help="output folder, replaced as a whole when the run succeeds (default: results/evaluation)")  # fmt: skip
    evaluate.add_argument("--curve", choices=PLAIN_DENSITY_CURVES, default="normal",
                          help="the partition curve fitted for rho50, Ep and the imperfection (default normal)")  # fmt: skip
    evaluate.add_argument("--floats-yield", type=cli_type(check_probability, "--floats-yield"), default=None, metavar="Y",
                          help="mass share of the feed to the floats (estimated from three analyses when not given)")  # fmt: skip
    evaluate.add_argument("--sum-tolerance", dest="sum_tolerance_pct", type=cli_type(check_non_negative, "--sum-tolerance"), default=DEFAULT_SUM_TOLERANCE_PCT,
                          help=f"allowed deviation of each analysis from 100 (default {DEFAULT_SUM_TOLERANCE_PCT:g})")  # fmt: skip
    evaluate.set_defaults(run=run_plant_evaluate, imports=("tromplab.plant.evaluation", "statsmodels.api", "scipy.optimize"))


def _add_inputs(command) -> None:
    """The inputs and the interval options both sub-commands take."""
    command.add_argument("washability", type=Path, help="washability by size fraction: size_fraction, fraction_pct, "
                         "density_lower, density_upper, mass_pct, ash_pct [, density_mean, <quality>_pct]")  # fmt: skip
    command.add_argument("plant", type=Path, nargs="?", default=None, help="plant table: size_fraction, device, curve, rho50, "
                         "ep or imperfection [, rho50_sd, ep_sd, rho50_min, rho50_max]; or give --curves-from")  # fmt: skip
    command.add_argument("-o", "--outdir", type=Path, default=Path("results/plant"),
                         help="output folder, replaced as a whole when the run succeeds (default: results/plant)")  # fmt: skip
    command.add_argument("--curves-from", type=Path, default=None, metavar="DIR",
                         help="a `tromplab density fit` results folder: each size fraction's best curve with its covariance "
                         "(matched by size fraction), in place of PLANT")  # fmt: skip
    command.add_argument("--ci", type=cli_type(check_probability, "--ci"), default=DEFAULT_CI, metavar="LEVEL",
                         help=f"level of the percentile intervals (default {DEFAULT_CI:g})")  # fmt: skip
    command.add_argument("--draws", type=cli_type(check_count, "--draws", minimum=0, maximum=MAX_DRAWS), default=DEFAULT_DRAWS,
                         help=f"parameter draws of the parametric bootstrap of the curves (default {DEFAULT_DRAWS})")  # fmt: skip
    command.add_argument("--seed", type=cli_type(check_seed, "--seed"), default=0, help="seed of the draws (default 0)")
    command.add_argument("--sum-tolerance", dest="sum_tolerance_pct", type=cli_type(check_non_negative, "--sum-tolerance"), default=DEFAULT_SUM_TOLERANCE_PCT,
                         help=f"allowed deviation of fraction_pct and mass_pct totals from 100 (default {DEFAULT_SUM_TOLERANCE_PCT:g})")  # fmt: skip
    command.add_argument("--float-lower-density", type=cli_type(check_positive, "--float-lower-density"), default=None,
                         help="lower bound of the open float fractions (default: symmetric about a mean density, else the "
                         "neighbour's width)")  # fmt: skip
    command.add_argument("--sink-upper-density", type=cli_type(check_positive, "--sink-upper-density"), default=None,
                         help="upper bound of the open sink fractions (default: as for --float-lower-density)")  # fmt: skip


def _input_options(args) -> dict:
    check_output_folder(args.outdir, inputs=[p for p in (args.washability, args.plant, args.curves_from) if p is not None])
    return {"curves_from": args.curves_from, "ci": args.ci, "draws": args.draws, "seed": args.seed,
            "sum_tolerance_pct": args.sum_tolerance_pct, "float_lower_density": args.float_lower_density,
            "sink_upper_density": args.sink_upper_density}  # fmt: skip


def _finish(result, outdir) -> int:
    written = result.save(outdir)
    print(result.report())
    print("\nWrote:")
    for path in written.values():
        print(f"  {path}")
    return EXIT_OK


def run_plant_predict(args) -> int:
    """Run ``tromplab plant predict``: read, predict, write the folder, print the report and the files written."""
    from ..plant import predict

    options = _input_options(args)
    with progress_bars(quiet=args.quiet) as progress:
        result = predict(args.washability, args.plant, washability_particles=args.washability_particles, progress=progress,
                         **options)  # fmt: skip
    return _finish(result, args.outdir)


def run_plant_optimize(args) -> int:
    """Run ``tromplab plant optimize``: read, find the cuts, write the folder, print the report and the files written."""
    from ..plant import optimize

    options = _input_options(args)
    with progress_bars(quiet=args.quiet) as progress:
        result = optimize(args.washability, args.plant, target_ash_pct=args.target_ash_pct, confidence=args.confidence,
                          progress=progress, **options)  # fmt: skip
    return _finish(result, args.outdir)


def run_plant_evaluate(args) -> int:
    """Run ``tromplab plant evaluate``: read the tests (and the tracer tests' washability), evaluate them, write the
    folder, print the report."""
    from ..plant import evaluate

    check_output_folder(args.outdir, inputs=[p for p in (args.file, args.washability) if p is not None])
    result = evaluate(args.file, curve=args.curve, floats_yield=args.floats_yield, washability=args.washability,
                      sum_tolerance_pct=args.sum_tolerance_pct)  # fmt: skip
    return _finish(result, args.outdir)
