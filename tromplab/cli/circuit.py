"""``tromplab circuit FLOWSHEET MEASUREMENTS -o DIR [--fit]`` and ``tromplab circuit design
FLOWSHEET [SURVEY] -o DIR``: the parsers and the runs of the two commands, a thin layer over
their Python functions :func:`tromplab.circuit.reconcile_circuit` and
:func:`tromplab.circuit.design_circuit` (parse, call, save, print)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..options import (
    DEFAULT_ABSOLUTE_ERROR,
    DEFAULT_ALPHA,
    DEFAULT_ASSAY_ABSOLUTE_ERROR,
    DEFAULT_ASSAY_RELATIVE_ERROR,
    DEFAULT_FLOW_RELATIVE_ERROR,
    DEFAULT_PCT_SOLIDS_SD,
    DEFAULT_RELATIVE_ERROR,
    ERROR_MODEL_POINTS,
    WEIGHTINGS,
)
from ..output.outputs import check_output_folder
from ..validation import (
    check_assay_sd,
    check_pct_solids_sd,
    check_positive_relative_error,
    check_probability,
    check_relative_error,
    check_share_sd,
    cli_type,
)
from .printing import format_fits, print_notices
from .startup import EXIT_OK, print_result, stage_bars

#: What the circuit commands import when they run (before they start, under the CLI's signal
#: handling); the fits (``--fit``) and the figures add theirs (:func:`_imports`): lmfit and
#: matplotlib are a third of a second of start-up a run without them does not pay.  Neither
#: imports scipy's linear algebra, optimisation or sparse matrices unless a large flowsheet or
#: a bounded start needs them (:mod:`tromplab.circuit.linear_algebra`).
IMPORTS = (
    "tromplab.circuit",
    "tromplab.output.csv_parts",
)
#: The design advice's own (its simulated plant and survey draw on the formulas' records): a
#: survey reconciled without ``design`` does not pay for them (16 ms of its start-up, compiled).
DESIGN_IMPORTS = IMPORTS + ("tromplab.circuit.planning",)
#: The distributions of the tests ``circuit`` computes (``design`` computes none).
TEST_IMPORTS = ("scipy.special",)
FIT_IMPORTS = ("tromplab.workbench",)
FIGURE_IMPORTS = ("tromplab.output.plotting",)


def _imports(namespace) -> tuple[str, ...]:
    """The modules of this run of ``circuit`` (``design`` tests nothing, draws no figure and fits nothing)."""
    if getattr(namespace, "circuit_command", None) == "design":
        return DESIGN_IMPORTS
    fit = FIT_IMPORTS if getattr(namespace, "fit", False) else ()
    figures = () if getattr(namespace, "no_figures", False) else FIGURE_IMPORTS
    return IMPORTS + TEST_IMPORTS + fit + figures


_USAGE = (
    "tromplab circuit FLOWSHEET MEASUREMENTS [-o DIR] [--fit] [options]\n"
    "       tromplab circuit design FLOWSHEET [SURVEY] [-o DIR] [options]"
)


def add_circuit_command(commands) -> argparse.ArgumentParser:
    """Register ``tromplab circuit`` and ``tromplab circuit design``; returns the circuit parser."""
    circuit = commands.add_parser(
        "circuit",
        usage=_USAGE,
        help="reconcile a plant survey over its flowsheet; partition curves of every separator; "
        "'circuit design': what to measure next (docs/circuit.md)",
    )
    circuit.add_argument("flowsheet", type=Path, help="flowsheet CSV: stream, from, to, product")
    circuit.add_argument("measurements", type=Path, help="survey CSV: stream, size classes, retained_pct [, solids_flow]")
    circuit.add_argument(
        "-o", "--outdir", type=Path, default=Path("results/circuit"), help="output folder (default: %(default)s)"
    )
    circuit.add_argument("--fit", action="store_true", help="also fit the nine formulas and the extended curves per separator")
    circuit.add_argument("--weighting", choices=WEIGHTINGS, default="error-model",
                         help="the weights of points.csv and of --fit: the inverse variance of each class's partition "
                         "under the error model with a floor relative to its feed share (default), its feed share, or "
                         "none (as tromplab fit --weighting)")  # fmt: skip
    _add_survey_options(circuit)
    circuit.add_argument("--no-figures", action="store_true", help="do not draw the figures")
    _add_error_model_options(circuit)
    circuit.set_defaults(run=_run_circuit, imports=IMPORTS)
    sub = circuit.add_subparsers(
        dest="circuit_command", metavar="design", parser_class=type(circuit), required=False, prog=circuit.prog
    )
    design = sub.add_parser(
        "design",
        help="rank the measurements one could add (a flow, a size analysis, a repeat, a per cent solids) by the sd "
        "they would remove, from a survey taken or one simulated from the flowsheet",
        description="Write DIR/design.csv: every measurement one could add, with the predicted sd of each result "
        "named, ranked; with SURVEY at its reconciled values, without it at a survey simulated from the flowsheet.",
    )
    _add_design_options(design)
    _route_design(circuit, design)
    return circuit


def _add_survey_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--size-unit", default=None, help="unit of the sizes when the size columns carry none")
    parser.add_argument("--exclude", default="", metavar="STREAM[:WHAT],...",
                        help="leave measurements out: a stream, or STREAM:flow, STREAM:pct_solids, STREAM:CLASS "
                        "(e.g. cyclone_feed:-150+75); what the elimination proposes")  # fmt: skip


def _add_error_model_options(parser: argparse.ArgumentParser) -> None:
    errors = parser.add_argument_group("error model (where the survey table gives none)")
    errors.add_argument("--relative-error", type=cli_type(check_relative_error, "--relative-error"),
                        default=DEFAULT_RELATIVE_ERROR, help="relative error of a measured share, 0..1 (default %(default)s)")  # fmt: skip
    errors.add_argument("--absolute-error", type=cli_type(check_share_sd, "--absolute-error"), default=DEFAULT_ABSOLUTE_ERROR,
                        help="absolute error of a share, as a fraction of the stream, 0..0.5 (default %(default)s)")  # fmt: skip
    errors.add_argument("--flow-relative-error", type=cli_type(check_positive_relative_error, "--flow-relative-error"),
                        default=DEFAULT_FLOW_RELATIVE_ERROR,
                        help="relative error of a measured solids flow, (0, 1] (default %(default)s)")  # fmt: skip
    errors.add_argument("--pct-solids-sd", type=cli_type(check_pct_solids_sd, "--pct-solids-sd"), default=DEFAULT_PCT_SOLIDS_SD,
                        help="sd of a per cent solids, percentage points, (0, 50] (default %(default)s)")  # fmt: skip
    errors.add_argument("--assay-relative-error", type=cli_type(check_relative_error, "--assay-relative-error"),
                        default=DEFAULT_ASSAY_RELATIVE_ERROR,
                        help="relative error of a per-class assay, 0..1 (default %(default)s)")  # fmt: skip
    errors.add_argument("--assay-absolute-error", type=cli_type(check_assay_sd, "--assay-absolute-error"),
                        default=DEFAULT_ASSAY_ABSOLUTE_ERROR,
                        help="absolute error of an assay, as a fraction of the class's solids, 0..0.5 (default %(default)s)")  # fmt: skip
    errors.add_argument("--error-model-at", choices=ERROR_MODEL_POINTS, default=ERROR_MODEL_POINTS[0],
                        help="evaluate the error model at the reconciled values (iterated) or at the measured ones "
                        "(default %(default)s)")  # fmt: skip
    tests = parser.add_argument_group("tests")
    tests.add_argument("--alpha", type=cli_type(check_probability, "--alpha"), default=DEFAULT_ALPHA,
                       help="level of the chi-square and measurement tests, in (0, 1) (default %(default)s)")  # fmt: skip


def _add_design_options(design: argparse.ArgumentParser) -> None:
    design.add_argument("flowsheet", type=Path, help="flowsheet CSV: stream, from, to, product")
    design.add_argument("measurements", type=Path, nargs="?", default=None, metavar="SURVEY",
                        help="survey CSV (as for 'tromplab circuit'); without it, a survey simulated from the flowsheet")  # fmt: skip
    design.add_argument("-o", "--outdir", type=Path, default=Path("results/circuit-design"),
                        help="output folder (default: %(default)s)")  # fmt: skip
    design.add_argument("--quantity", action="append", default=None, metavar="RESULT",
                        help="a result whose sd matters, repeatable: 'partition at cut', 'partition', 'fine yield', "
                        "'circulating load' (every separator) or one result as worth.csv names it "
                        "(default: each separator's partition at its cut and each circulating load)")  # fmt: skip
    design.add_argument("--sampled", default=None, metavar="STREAM,...",
                        help="without SURVEY: the streams with a size analysis (default: every stream)")  # fmt: skip
    design.add_argument("--flows", default=None, metavar="STREAM,...",
                        help="without SURVEY: the streams with a measured solids flow (default: none, flows relative to a feed of 100)")  # fmt: skip
    _add_survey_options(design)
    _add_error_model_options(design)
    design.set_defaults(run=_run_design, imports=DESIGN_IMPORTS)


def _route_design(circuit: argparse.ArgumentParser, design: argparse.ArgumentParser) -> None:
    """Parse ``circuit design ...`` with the design parser and ``circuit FLOWSHEET MEASUREMENTS``
    with the circuit parser.

    argparse cannot have both a sub-command and positional files on one parser (it would read
    ``design`` as the flowsheet), so the circuit parser sends a leading ``design`` to the
    sub-parser itself; the sub-parser stays registered so that help, the generated reference
    and the option names of messages know it.
    """
    parse_circuit = circuit.parse_known_args

    def parse_known_args(args=None, namespace=None):
        args = list(sys.argv[1:] if args is None else args)
        if args[:1] == ["design"]:
            namespace, rest = design.parse_known_args(args[1:], namespace)
            namespace.circuit_command = "design"
        else:
            namespace, rest = parse_circuit(args, namespace)
        namespace.imports = _imports(namespace)
        return namespace, rest

    circuit.parse_known_args = parse_known_args


def error_model_of(args):
    """The error-model options of ``tromplab circuit`` and ``circuit design`` as one :class:`~tromplab.circuit.ErrorModel` (the page builds it too)."""
    from ..circuit import ErrorModel

    return ErrorModel(relative_error=args.relative_error, absolute_error=args.absolute_error,
                      flow_relative_error=args.flow_relative_error, pct_solids_sd=args.pct_solids_sd,
                      evaluated_at=args.error_model_at, assay_relative_error=args.assay_relative_error,
                      assay_absolute_error=args.assay_absolute_error)  # fmt: skip


def _run_circuit(args) -> int:
    from ..circuit import reconcile_circuit
    from ..circuit.commands import console_report

    check_output_folder(args.outdir, inputs=[args.flowsheet, args.measurements])  # the inputs are checked as they are read
    with stage_bars(quiet=args.quiet) as progress:
        result = reconcile_circuit(args.flowsheet, args.measurements, fit=args.fit, errors=error_model_of(args), alpha=args.alpha,
                                   size_unit=args.size_unit, exclude=args.exclude, weighting=args.weighting, progress=progress)  # fmt: skip
        written = result.save(args.outdir, figures=not args.no_figures)
    print(console_report(result, written, format_fits=format_fits))
    _print_circuit_notices(result, args)
    return EXIT_OK


def _print_circuit_notices(run, args) -> None:
    """The warnings of the separators (weights concentrated on a few classes, with ``--fit`` a cut
    their points do not bracket) on standard error once per kind, every one with ``-v``, and
    with ``--quiet`` only the one-line result; every one is in ``warnings.csv``."""
    balance = run.balance
    # a curve per separator, and one per separator and assayed component
    total = len(balance.flowsheet.separators) * (1 + len(balance.survey.components))
    notices = list(run.notices)
    print_notices(notices, total=total, quiet=args.quiet, verbose=args.verbose, noun="separators")
    if args.quiet:
        verdict = balance.chi_square_table().iloc[0].verdict if balance.dof > 0 else "no redundancy to test"
        said = f", {len(notices)} warning(s) (warnings.csv)" if notices else ""
        print_result(f"tromplab circuit: survey reconciled ({verdict}){said}; results in {args.outdir}")


def design_of_options(args, progress=None):
    """:func:`~tromplab.circuit.design_circuit` of the parsed options of ``tromplab circuit design``,
    its output folder checked first (the page runs it too)."""
    from ..circuit import design_circuit

    check_output_folder(args.outdir, inputs=[args.flowsheet] + ([args.measurements] if args.measurements is not None else []))
    return design_circuit(args.flowsheet, args.measurements, quantity=args.quantity, sampled=args.sampled, flows=args.flows,
                          errors=error_model_of(args), alpha=args.alpha, size_unit=args.size_unit, exclude=args.exclude,
                          progress=progress)  # fmt: skip


def _run_design(args) -> int:
    with stage_bars(quiet=args.quiet) as progress:
        advice = design_of_options(args, progress)
        written = advice.save(args.outdir)
    print(advice.report() + "\n\nWrote:\n" + "\n".join(f"  {path}" for path in written.values()))
    return EXIT_OK
