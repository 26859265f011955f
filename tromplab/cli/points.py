"""``tromplab points`` (a lab table turned into Tromp points with diagnostics) and ``tromplab
balance`` (the yield estimate and mass-balance table of a lab table)."""

from __future__ import annotations

from pathlib import Path

from ..output.outputs import check_output_file, write_files
from .option_groups import READERS, add_partition_to, lab_options
from .printing import print_balance_notes


def add_points(commands, groups) -> None:
    points = commands.add_parser(
        "points", parents=[groups["lab"], groups["water"]], help="turn a lab table into Tromp points with diagnostics"
    )
    points.add_argument("input", type=Path, help="lab table (CSV or .xlsx)")
    points.add_argument("-o", "--output", type=Path, required=True, help="Tromp points CSV to write")
    add_partition_to(points)
    points.set_defaults(run=_run_points, imports=(*READERS, "tromplab.output.views", "tromplab.output.csv_parts"))


def _run_points(args) -> int:
    import pandas as pd

    from ..loading.lab import read_lab
    from ..loading.tables import check_input_file
    from ..output.views import partition_view

    check_input_file(args.input)
    check_output_file(args.output, inputs=[args.input])
    balances = read_lab(args.input, lab_options(args))
    table = pd.concat(
        [b.points_table(weight_by_feed_share=args.weight_by_feed_share, unit_in_names=True) for b in balances], ignore_index=True
    )
    table = partition_view(table, args.partition_to)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    from ..output.csv_parts import write_csv

    written = write_files({args.output.name: lambda p: write_csv(table, p)}, args.output.parent)
    print_balance_notes(balances)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
    print(f"\nWrote: {written[args.output.name]}")
    return 0


def add_balance(commands, groups) -> None:
    balance = commands.add_parser("balance", parents=[groups["lab"]], help="yield estimate and mass-balance table of a lab table")
    balance.add_argument("input", type=Path, help="lab table (CSV or .xlsx)")
    add_partition_to(balance)
    balance.set_defaults(run=_run_balance, imports=(*READERS, "tromplab.output.views"))


def _run_balance(args) -> int:
    from ..loading.lab import PARTITION_METHOD_TEXT, read_lab
    from ..loading.tables import check_input_file
    from ..output.views import balance_view

    check_input_file(args.input)
    balances = read_lab(args.input, lab_options(args))
    print_balance_notes(balances)
    for balance in balances:
        estimate = balance.yield_estimate
        print(
            f"Experiment {balance.experiment}: fine yield {balance.fine_yield:.4f} ({balance.yield_source}); "
            f"partition from {PARTITION_METHOD_TEXT[balance.partition_method]}"
        )
        if estimate is not None:
            print(
                f"  least-squares estimate from the three streams: {estimate.value:.4f} +/- {estimate.stderr:.4f} "
                f"(standard error, {estimate.n_classes} classes); coarse yield {1 - estimate.value:.4f}"
            )
        table = balance_view(balance.classes, args.partition_to, adjusted=True)
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
        print()
    return 0
