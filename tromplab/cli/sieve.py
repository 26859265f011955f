"""``tromplab sieve identify | pg | bin``: sieve classifiers (velocity laws identified from
residues, the geometric probability of passing a hole, the collecting-bin design)."""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import OptionError, ResultError
from ..output.outputs import check_output_file, write_files
from ..validation import MAX_DECKS, check_count, check_probability, check_range, cli_type
from .option_groups import READERS
from .startup import EXIT_OK, EXIT_PARTIAL

#: Lengths of ``sieve pg`` (any one unit): only their ratios matter, and within this range
#: their squares and ratios stay normal floating-point numbers.
SIEVE_LENGTHS = {"low": 1e-100, "high": 1e100}


#: Sieve length of ``sieve bin`` (any unit): the design scales with it; beyond this range the
#: normal approximation's root is no longer bracketed in floating point.
BIN_LENGTHS = {"low": 1e-6, "high": 1e6}


#: What ``sieve bin`` prints, in words (its numbers carry the unit of --length, here "L-unit").
BIN_LEGEND = (
    "x1, x2: start and end of the collecting bin along the bottom deck, measured from the deck's start (x2 = the sieve\n"
    "length); C: the passage intensity coefficient (passages through the decks form a Poisson stream of intensity\n"
    "C x along the deck); L-unit: the unit --length was given in (m for a length in metres)."
)


def add_sieve(commands) -> None:
    sieve = commands.add_parser("sieve", help="sieve classifiers: identification, geometric probability, bin design")
    sieve_commands = sieve.add_subparsers(dest="sieve_command", metavar="SIEVE_COMMAND", required=True)
    identify = sieve_commands.add_parser("identify", help="identify Vk and sigma from residues at several speed regimes")
    identify.add_argument("data", type=Path, help="CSV: sieve, fraction, relative_speed, residue, sieve_length, cell_pitch, P_g")
    identify.add_argument(
        "-o",
        "--output",
        type=Path,
        default=Path("results/velocity_laws.csv"),
        help="CSV of the identified laws (default: results/velocity_laws.csv)",
    )
    identify.add_argument("--two-sided", action="store_true", help="two-sided velocity probability (random-walk paper)")
    identify.add_argument(
        "--level", type=cli_type(check_probability, "--level"), default=0.95, help="confidence level of the intervals, in (0, 1)"
    )
    identify.set_defaults(run=_run_sieve_identify, imports=("tromplab.classifiers.sieve", *READERS, "tromplab.output.csv_parts"))
    _add_sieve_pg(sieve_commands)
    _add_sieve_bin(sieve_commands)


def _add_sieve_pg(sieve_commands) -> None:
    pg = sieve_commands.add_parser("pg", help="geometric probability of a particle passing a round hole")
    pg.add_argument("--hole", type=cli_type(check_range, "--hole", **SIEVE_LENGTHS), required=True, help="hole diameter D")
    pg.add_argument("--length", type=cli_type(check_range, "--length", **SIEVE_LENGTHS), required=True, help="particle length l")
    pg.add_argument(
        "--width",
        type=cli_type(check_range, "--width", **SIEVE_LENGTHS),
        required=True,
        help="particle width d (shape factor d/l)",
    )
    pg.add_argument(
        "--cell-width",
        type=cli_type(check_range, "--cell-width", **SIEVE_LENGTHS),
        required=True,
        help="cell width 2b across the transport direction",
    )
    pg.add_argument(
        "--method",
        choices=("auto", "closed", "quadrature"),
        default="auto",
        help="closed form, quadrature, or auto: the closed form where it is valid (default)",
    )
    pg.set_defaults(run=_run_sieve_pg, imports=("tromplab.classifiers.sieve",))


def _add_sieve_bin(sieve_commands) -> None:
    bin_ = sieve_commands.add_parser("bin", help="collecting-bin position on the bottom deck for a required recovery")
    bin_.add_argument(
        "--decks",
        type=cli_type(check_count, "--decks", maximum=MAX_DECKS),
        required=True,
        help=f"number of decks m, 1 to {MAX_DECKS}",
    )
    bin_.add_argument(
        "--length", type=cli_type(check_range, "--length", **BIN_LENGTHS), required=True, help="sieve length L (= x2)"
    )
    bin_.add_argument(
        "--recovery",
        type=cli_type(check_probability, "--recovery"),
        required=True,
        help="required recovery g* of the target fraction, in (0, 1)",
    )
    bin_.set_defaults(run=_run_sieve_bin, imports=("tromplab.classifiers.sieve",))


def _run_sieve_identify(args) -> int:
    from ..classifiers.sieve import identify_from_table
    from ..loading.tables import check_input_file, read_table
    from ..output.csv_parts import write_csv

    check_input_file(args.data)
    check_output_file(args.output, inputs=[args.data])
    laws = identify_from_table(read_table(args.data), two_sided=args.two_sided, level=args.level)
    written = write_files({args.output.name: lambda p: write_csv(laws, p)}, args.output.parent)
    view = laws[["sieve", "fraction", "n_regimes", "v_k", "v_k_stderr", "sigma", "sigma_stderr", "success"]]
    print(view.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
    failed = laws.loc[~laws["success"].astype(bool), ["sieve", "fraction", "message"]]
    for sieve, fraction, message in failed.itertuples(index=False):
        print(f"  not identified: sieve {sieve}, fraction {fraction}: {message}")
    print(f"\nWrote: {written[args.output.name]}")
    if len(failed):  # a partial result, as failed fits are: written, and said on stderr with exit 3
        print(f"{len(failed)} of {len(laws)} sieve fraction(s) not identified (success False in {args.output})", file=sys.stderr)
        return EXIT_PARTIAL
    return EXIT_OK


def _run_sieve_pg(args) -> int:
    from ..classifiers.sieve import closed_form_valid, geometric_probability

    if args.width > args.length:
        raise OptionError(
            "--width", f"must not exceed --length ({args.width:g} > {args.length:g}): the shape factor d/l is at most 1"
        )
    value = geometric_probability(args.hole, args.length, args.width, args.cell_width / 2, method=args.method)
    if not 0.0 <= value <= 1.0:  # also nan
        raise ResultError(f"the geometric probability came out as {value!r}, outside 0..1")
    closed = closed_form_valid(args.hole, args.length, args.width, args.cell_width / 2)
    print(
        f"P_g = {value:.6f}  (D = {args.hole:g}, l = {args.length:g}, d = {args.width:g}, d/l = {args.width / args.length:.3g}, "
        f"2b = {args.cell_width:g}; closed form {'valid' if closed else 'not valid: quadrature'})"
    )
    return 0


def _run_sieve_bin(args) -> int:
    import numpy as np

    from ..classifiers.sieve import design_bin, distance_moments

    failed = []
    for method in ("exact", "normal"):
        try:
            design = design_bin(args.decks, args.length, args.recovery, method=method)
        except ValueError as error:  # the root of the recovery equation is not bracketed
            failed.append(f"{method}: no bin position found ({error})")
            continue
        # the normal approximation places the bin by its own distribution: only the exact
        # method must reach the required recovery, both must place the bin on the deck
        exact_enough = method != "exact" or abs(design.recovery - args.recovery) < 1e-6
        if not (np.isfinite([design.c, design.x1, design.recovery]).all() and exact_enough and 0.0 <= design.x1 <= design.x2):
            failed.append(
                f"{method}: the bin position {design.x1:.4g} (deck length {design.x2:g}) gives a recovery of "
                f"{design.recovery:.4g}, not the required {args.recovery:.15g}"
            )
            continue
        print(
            f"{method:>6}: C = {design.c:.4f} per L-unit², x1 = {design.x1:.4f} L-units, x2 = {design.x2:.4g} L-units, "
            f"recovery in the bin = {design.recovery:.4f}"
        )
        if method == "exact":
            mean, variance = distance_moments(args.decks, design.c)
            moments = f"exact mean distance on deck {args.decks}: {mean:.4f} L-units, standard deviation {np.sqrt(variance):.4f} L-units"
    if len(failed) == 2:
        raise ResultError("; ".join(failed))
    if not failed[:1] or not failed[0].startswith("exact"):
        print(moments)
    print(BIN_LEGEND)
    if failed:
        raise ResultError(failed[0])
    return 0
