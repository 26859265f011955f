"""Command-line interface: the ``tromplab`` parser built from one module per command, and the
dispatch that runs a command with the shared start-up.

Commands (``tromplab COMMAND -h`` for each; the command-line reference of the docs is generated
from :func:`build_parser`), each in its own module of this package:

- ``formulas`` (the formula catalogue): :mod:`~tromplab.cli.formulas`;
- ``fit`` (fit, screen and rank on points or lab tables): :mod:`~tromplab.cli.fit`;
- ``report`` (HTML and Markdown report), ``compare`` (did the sharpness or the cut change) and
  ``export`` (parameters in a simulator's convention): :mod:`~tromplab.cli.report`;
- ``trend`` (control charts over surveys): :mod:`~tromplab.cli.trend`;
- ``points`` and ``balance`` (lab table to Tromp points, mass balance): :mod:`~tromplab.cli.points`;
- ``sieve identify | pg | bin``: :mod:`~tromplab.cli.sieve`;
- ``rank`` (F table to ranks): :mod:`~tromplab.cli.rank`;
- ``layer simulate | fit``, ``pulp optimum | fit`` and ``optimize`` (the process models):
  :mod:`~tromplab.cli.models`;
- ``circuit`` and ``circuit design`` (plant survey reconciled, what to measure next):
  :mod:`~tromplab.cli.circuit`;
- ``density fit | predict`` (density partition of gravity separators):
  :mod:`~tromplab.cli.density` and :mod:`~tromplab.cli.density_predict`;
- ``plant predict`` (a coal-washing plant's products from washability and partition curves):
  :mod:`~tromplab.cli.plant`.
- ``app`` (the local web workbench, :mod:`tromplab.app`): :mod:`~tromplab.cli.app`.

Shared by the commands: :mod:`~tromplab.cli.startup` (exit codes, signals, verbosity, progress
bars, the parser classes, errors in the command line's words), :mod:`~tromplab.cli.option_groups`
(options declared once) and :mod:`~tromplab.cli.printing` (console tables).  The console script
enters through :mod:`tromplab._launch`, which handles SIGINT and SIGTERM before numpy is imported.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import os
import re
import sys
import traceback
import warnings

from .._version import __version__
from ..errors import InputError, OptionError, ResultError, YieldWarning
from ..output.outputs import forget_written
from ..validation import state_ranges
from .option_groups import shared_groups
from .startup import (
    EXIT_INPUT,
    EXIT_OK,
    EXIT_PARTIAL,
    EXIT_USAGE,
    CommandParser,
    SubcommandParser,
    Terminated,
    cli_message,
    cli_words,
    collector_paused,
    global_options,
    interrupted,
    print_usage,
    python_warnings,
    raise_terminated,
    sigterm_as_interrupt,
    unexpected_error,
    verbosity,
    words_of,
)

# Each command module imports the library modules it needs when the command runs: building the
# parser takes only the light modules, so --version, -h and a command that needs little (export)
# do not pay for scipy.stats, lmfit, matplotlib and statsmodels at start-up (nothing below
# imports the CLI, so the imports inside the functions hide no cycle).  A command run by its
# name builds only its own parser and imports only its own module (COMMANDS): the modules and
# the thirty-odd parsers of the others were about 20 ms of every command's start-up.

#: The commands in the order ``tromplab -h`` lists them: the names each entry registers, the
#: module of this package that registers them (None: this one), its function that does, and
#: whether that function takes the option groups shared by the commands on tables
#: (:func:`~tromplab.cli.option_groups.shared_groups`).
COMMANDS = (
    (("formulas",), "formulas", "add_formulas", True),
    (("fit",), "fit", "add_fit", True),
    (("report",), "report", "add_report", True),
    (("compare",), "report", "add_compare", True),
    (("export",), "report", "add_export", True),
    (("trend",), "trend", "add_trend", True),
    (("points",), "points", "add_points", True),
    (("balance",), "points", "add_balance", True),
    (("sieve",), "sieve", "add_sieve", False),
    (("rank",), "rank", "add_rank", False),
    (("layer", "pulp", "optimize"), "models", "add_model_commands", False),
    (("circuit",), "circuit", "add_circuit_command", False),
    (("density",), None, "_add_density", False),  # fit in cli.density, predict in cli.density_predict
    (("plant",), "plant", "add_plant_command", False),
    (("app",), "app", "add_app", False),  # the local web workbench (tromplab.app)
)
#: Words before the command that leave the parser of every other command unread: -q, -v (and
#: -qv, -vv ...), --quiet, --verbose, --debug.  Anything else (-h lists every command) builds them all.
_QUIET_WORDS = re.compile(r"-[qv]+|--quiet|--verbose|--debug")

__all__ = ["Terminated", "build_parser", "interrupted", "main", "raise_terminated"]


def main(argv=None, *, on_start=None) -> int:
    """Run the command line; returns the exit code (0 done, 1 bad input, 2 usage,
    3 partial, 70 internal error, 130 interrupted by SIGINT, 143 terminated by SIGTERM).

    ``on_start`` (from :mod:`tromplab._launch`) is called when the command has imported its
    modules and starts its work: until then an interrupt ends the start-up at once.
    """
    command_named = _command_named(sys.argv[1:] if argv is None else argv)
    parser = build_parser(command_named)
    # the whole parser's option words for messages worded without a command's parser (the
    # notes printed as the command ends), built only if such a message names a Python word
    whole = parser if command_named is None else functools.cache(build_parser)
    forget_written()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # argparse stops on a usage error (2) or after --help/--version (0)
        return stop.code if isinstance(stop.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        return interrupted()
    if not hasattr(args, "run"):  # no command: the whole parser was built
        return print_usage(parser)
    path = [
        name
        for name in (
            args.command,
            *(getattr(args, f"{n}_command", None) for n in ("sieve", "layer", "pulp", "density", "circuit", "plant")),
        )
        if name
    ]
    command = " ".join(("tromplab", *path))
    own = _command_parser(parser, path)  # its options, not another command's, name the Python words
    try:
        _check_input_paths(args, own)  # before the imports: a missing file answers at once
        # a command imports its modules before it starts: an interrupt inside an import can stop
        # a module half-initialised (an ImportError, or Python's exit by SIGINT instead of 130)
        with collector_paused():
            for module in getattr(args, "imports", ()):
                importlib.import_module(module)
        if on_start is not None:
            on_start()
        with sigterm_as_interrupt(), warnings.catch_warnings(), verbosity(args), words_of(whole):
            warnings.simplefilter("ignore", YieldWarning)  # printed from the balance notes instead
            with python_warnings(quiet=args.quiet, verbose=args.verbose):
                return args.run(args)
    except BrokenPipeError:  # output piped into head or less and closed early
        sys.stderr.close()
        return EXIT_OK
    except KeyboardInterrupt as interruption:
        return interrupted(interruption)
    except InputError as error:  # the project's own input, option and output errors
        if args.debug:
            traceback.print_exc()
        print(f"{command}: error: {cli_message(error, own)}", file=sys.stderr)
        return EXIT_USAGE if isinstance(error, OptionError) else EXIT_INPUT
    except ResultError as error:  # a result outside its range is a failure, not a result
        print(f"{command}: failed: {cli_words(str(error), own)}", file=sys.stderr)
        return EXIT_PARTIAL
    except Exception as error:  # anything else is a bug in tromplab (or the place it writes to): say which
        if args.debug:
            raise
        return unexpected_error(command, error, args)


#: Positional arguments that name an input file, checked before a command imports its modules.
INPUT_FILE_ARGUMENTS = ("input", "data", "table", "flowsheet", "measurements")


def _check_input_paths(args, command_parser: argparse.ArgumentParser) -> None:
    """Every input file of the command exists and can be read (the loaders check it again).
    Only positional arguments are input files (an option such as ``--table`` may name an output)."""
    from ..loading.paths import check_input_file

    positional = {action.dest for action in command_parser._actions if not action.option_strings}
    for name in INPUT_FILE_ARGUMENTS:
        path = getattr(args, name, None) if name in positional else None
        if isinstance(path, (str, os.PathLike)):
            check_input_file(path, option=name)


def _command_parser(parser: argparse.ArgumentParser, path) -> argparse.ArgumentParser:
    """The parser of the (sub)command ``path`` (``["sieve", "identify"]``) under ``parser``."""
    for name in path:
        actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction) and name in a.choices]
        if not actions:
            break
        parser = actions[0].choices[name]
    return parser


def _command_named(argv) -> str | None:
    """The command ``argv`` runs, when no other command's parser can be needed to answer it: its
    first word, after only -q, -v and --debug, if it names a command; None otherwise (the whole
    parser: ``-h`` before the command lists every command, and an unknown one is told the choices)."""
    for word in argv:
        if not _QUIET_WORDS.fullmatch(word):
            return word if any(word in names for names, *_ in COMMANDS) else None
    return None


def _add_density(commands) -> None:
    """``tromplab density`` with ``fit`` (:mod:`~tromplab.cli.density`, which holds the sub-commands)
    and ``predict`` (:mod:`~tromplab.cli.density_predict`)."""
    from .density import add_density_command
    from .density_predict import add_predict_parser

    add_predict_parser(add_density_command(commands).density_commands)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``tromplab`` parser: one builder per command, from the option groups declared once.

    With ``command`` (a name of :data:`COMMANDS`), only that command and its sub-commands are
    registered, and only its module is imported (what :func:`main` parses a command line with);
    their help and messages are those of the whole parser.
    """
    parser = CommandParser(
        prog="tromplab",
        description="Fit, screen and rank separation (Tromp) curves.",
        parents=[global_options(in_subcommand=False)],
        epilog="Exit codes: 0 done, 1 bad input (nothing written), 2 usage, 3 partial "
        "(failures listed in failures.csv), 70 internal error, 130 interrupted, 143 terminated.",
    )
    parser.add_argument("--version", action="version", version=f"tromplab {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=SubcommandParser)
    groups = functools.cache(shared_groups)  # made for the first command on tables built, then shared
    for names, module, function, shared in COMMANDS:
        if command is None or command in names:
            add_command = getattr(importlib.import_module(f"{__name__}.{module}" if module else __name__), function)
            add_command(commands, groups()) if shared else add_command(commands)
    state_ranges(parser)
    return parser
