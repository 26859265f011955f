"""``tromplab rank``: rank formulas from a table of F values (the paper's Table 2 to Table 3)."""

from __future__ import annotations

from pathlib import Path

from ..options import DEFAULT_ALPHA
from ..output.outputs import check_output_folder, write_files
from ..validation import check_probability, cli_type
from .option_groups import READERS


def add_rank(commands) -> None:
    rank = commands.add_parser("rank", help="rank formulas from a table of F values (Table 2 -> Table 3)")
    rank.add_argument("table", type=Path, help="CSV with experiment, equation, F and n or F_crit [, adequate]")
    rank.add_argument(
        "-o", "--outdir", type=Path, default=Path("results"), help="output folder for ranking.csv (default: results)"
    )
    rank.add_argument(
        "--alpha",
        type=cli_type(check_probability, "--alpha"),
        default=DEFAULT_ALPHA,
        help="significance level for F_crit from n, in (0, 1)",
    )
    rank.add_argument("--computed-adequacy", action="store_true", help="ignore an 'adequate' column and use F > F_crit")
    rank.set_defaults(run=_run_rank, imports=("tromplab.curves.ranking", *READERS, "tromplab.output.csv_parts"))


def _run_rank(args) -> int:
    from ..curves.ranking import rank_formulas, read_f_table
    from ..loading.tables import check_input_file
    from ..output.csv_parts import write_csv

    check_input_file(args.table)
    check_output_folder(args.outdir, inputs=[args.table])
    table = read_f_table(args.table, alpha=args.alpha, use_given_marks=not args.computed_adequacy)
    ranking = rank_formulas(table)
    written = write_files({"ranking.csv": lambda p: write_csv(ranking, p)}, args.outdir)
    print(ranking.to_string(index=False))
    print(f"\nWrote: {written['ranking.csv']}")
    return 0
