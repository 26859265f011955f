"""``tromplab circuit``: a plant survey reconciled over its flowsheet, the partition curves of
every separator (the work is in :mod:`tromplab.circuit_command`)."""

from __future__ import annotations

from pathlib import Path

from ..options import (
    DEFAULT_ABSOLUTE_ERROR,
    DEFAULT_ALPHA,
    DEFAULT_FLOW_RELATIVE_ERROR,
    DEFAULT_PCT_SOLIDS_SD,
    DEFAULT_RELATIVE_ERROR,
    ERROR_MODEL_POINTS,
)
from ..validation import (
    check_pct_solids_sd,
    check_positive_relative_error,
    check_probability,
    check_relative_error,
    check_share_sd,
    cli_type,
)
from .startup import EXIT_OK


def _add_circuit_command(commands) -> None:
    """``tromplab circuit FLOWSHEET MEASUREMENTS -o DIR [--fit]`` (the work is in circuit_command)."""
    circuit = commands.add_parser(
        "circuit", help="reconcile a plant survey over its flowsheet; partition curves of every separator (docs/circuit.md)"
    )
    circuit.add_argument("flowsheet", type=Path, help="flowsheet CSV: stream, from, to, product")
    circuit.add_argument("measurements", type=Path, help="survey CSV: stream, size classes, retained_pct [, solids_flow]")
    circuit.add_argument(
        "-o", "--outdir", type=Path, default=Path("results/circuit"), help="output folder (default: %(default)s)"
    )
    circuit.add_argument("--fit", action="store_true", help="also fit the nine formulas and the extended curves per separator")
    circuit.add_argument("--size-unit", default=None, help="unit of the sizes when the size columns carry none")
    circuit.add_argument("--no-figures", action="store_true", help="do not draw the figures")
    circuit.add_argument("--exclude", default="", metavar="STREAM[:WHAT],...",
                         help="leave measurements out: a stream, or STREAM:flow, STREAM:pct_solids, STREAM:CLASS "
                         "(e.g. cyclone_feed:-150+75); what the elimination proposes")  # fmt: skip
    errors = circuit.add_argument_group("error model (where the survey table gives none)")
    errors.add_argument("--relative-error", type=cli_type(check_relative_error, "--relative-error"),
                        default=DEFAULT_RELATIVE_ERROR, help="relative error of a measured share, 0..1 (default %(default)s)")  # fmt: skip
    errors.add_argument("--absolute-error", type=cli_type(check_share_sd, "--absolute-error"), default=DEFAULT_ABSOLUTE_ERROR,
                        help="absolute error of a share, as a fraction of the stream, 0..0.5 (default %(default)s)")  # fmt: skip
    errors.add_argument("--flow-relative-error", type=cli_type(check_positive_relative_error, "--flow-relative-error"),
                        default=DEFAULT_FLOW_RELATIVE_ERROR,
                        help="relative error of a measured solids flow, (0, 1] (default %(default)s)")  # fmt: skip
    errors.add_argument("--pct-solids-sd", type=cli_type(check_pct_solids_sd, "--pct-solids-sd"), default=DEFAULT_PCT_SOLIDS_SD,
                        help="sd of a per cent solids, percentage points, (0, 50] (default %(default)s)")  # fmt: skip
    errors.add_argument("--error-model-at", choices=ERROR_MODEL_POINTS, default=ERROR_MODEL_POINTS[0],
                        help="evaluate the error model at the reconciled values (iterated) or at the measured ones "
                        "(default %(default)s)")  # fmt: skip
    tests = circuit.add_argument_group("tests")
    tests.add_argument("--alpha", type=cli_type(check_probability, "--alpha"), default=DEFAULT_ALPHA,
                       help="level of the chi-square and measurement tests, in (0, 1) (default %(default)s)")  # fmt: skip
    circuit.set_defaults(run=_run_circuit, imports=("tromplab.circuit", "tromplab.circuit_command"))


def _run_circuit(args) -> int:
    from ..circuit import ErrorModel
    from ..circuit_command import console_report, run_circuit

    errors = ErrorModel(relative_error=args.relative_error, absolute_error=args.absolute_error,
                        flow_relative_error=args.flow_relative_error, pct_solids_sd=args.pct_solids_sd,
                        evaluated_at=args.error_model_at)  # fmt: skip
    run = run_circuit(args.flowsheet, args.measurements, args.outdir, fit=args.fit, errors=errors, alpha=args.alpha,
                      size_unit=args.size_unit, figures=not args.no_figures, exclude=args.exclude)  # fmt: skip
    print(console_report(run))
    return EXIT_OK
