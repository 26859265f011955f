"""``tromplab trend``: monitor a classifier over surveys with control charts and change flags."""

from __future__ import annotations

from pathlib import Path

from ..output.outputs import check_output_folder
from ..validation import check_probability, cli_type
from .option_groups import READERS, lab_options
from .printing import print_notices
from .startup import print_result, progress_bars


def add_trend(commands, groups) -> None:
    trend = commands.add_parser(
        "trend", parents=[groups["lab"]], help="monitor a classifier over surveys: control charts and change flags"
    )
    trend.add_argument("input", type=Path, help="Tromp points or a lab table with a 'date' (or 'survey') column")
    trend.add_argument("-o", "--outdir", type=Path, default=Path("results/trend"), help="output folder (default: results/trend)")
    trend.add_argument("--formula", default=None, help="formula id (default: the best-ranked of the nine over all surveys)")
    trend.add_argument(
        "--baseline",
        default=None,
        help="baseline period: the first N surveys, or a date range FROM:TO (default: the first half, at most 8)",
    )
    trend.add_argument(
        "--alpha",
        type=cli_type(check_probability, "--alpha"),
        default=0.01,
        help="significance level of the change flags (default 0.01)",
    )
    trend.add_argument("--size-unit", default="", help="unit of the sizes, for the figure labels")
    trend.add_argument("--no-figures", action="store_true", help="do not draw figures")
    trend.set_defaults(run=_run_trend, imports=(*READERS, "tromplab.trend"))


def _run_trend(args) -> int:
    from ..loading.tables import check_input_file
    from ..trend import monitor_surveys, read_surveys

    check_input_file(args.input)
    check_output_folder(args.outdir, inputs=[args.input])
    surveys = read_surveys(args.input, lab_options(args))
    with progress_bars(
        quiet=args.quiet, unit="survey", stages=("tests", "charts"), units={"tests": "fit", "charts": "chart"}
    ) as progress:
        result = monitor_surveys(surveys, formula=args.formula, baseline=args.baseline, alpha=args.alpha, progress=progress)
        written = result.save(args.outdir, size_unit=args.size_unit, figures=not args.no_figures, progress=progress)
    print(result.report())
    print("\nWrote:")
    for path in written.values():
        print(f"  {path}")
    notices = result.notices()
    print_notices(notices, total=len(result.surveys), quiet=args.quiet, verbose=args.verbose, noun="surveys", intervals=True)
    if args.quiet:
        said = f", {len(notices)} warning(s) (warnings.csv)" if notices else ""
        print_result(f"tromplab trend: {len(result.surveys)} survey(s) charted{said}; results in {args.outdir}")
    return 0
