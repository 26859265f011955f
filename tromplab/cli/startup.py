"""The shared start-up of every command: exit codes, signals, verbosity, progress bars, the
parser classes and the command line's wording of errors.

Nothing here imports the numerical stack, so building the parser and checking a command's
input paths stay fast (``tromplab fit nosuch.csv`` answers before numpy is loaded).
"""

from __future__ import annotations

import argparse
import contextlib
import contextvars
import errno
import functools
import gc
import logging
import os
import re
import signal
import sys
import textwrap
import warnings
from collections.abc import Callable
from pathlib import Path

from ..errors import InputError, InputNote, OptionError
from ..notices import NUMBER_IN_WORDS
from ..output.outputs import written_outputs

#: Exit codes (documented in the README and docs/reliability.md).
EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_PARTIAL, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 1, 2, 3, 70, 130
EXIT_TERMINATED = 143  # 128 + SIGTERM, as shells report a process ended by SIGTERM


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread so the same clean-up runs as for Ctrl-C."""


def raise_terminated(signum, frame):
    """Signal handler: SIGTERM becomes :class:`Terminated`."""
    raise Terminated


@contextlib.contextmanager
def sigterm_as_interrupt():
    """Turn SIGTERM into :class:`Terminated` while the command runs (main thread only)."""
    try:
        previous = signal.signal(signal.SIGTERM, raise_terminated)
    except ValueError:  # not the main thread (main() called from a worker thread): leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupted(interruption=None) -> int:
    """Print the one-line message for an interrupted run; return 130 (SIGINT) or 143 (SIGTERM).

    The message says what is on disk: the previous outputs, or the new ones when the run was
    interrupted after it had put them in place (they are complete: a swap is one step)."""
    what = "terminated (SIGTERM)" if isinstance(interruption, Terminated) else "interrupted"
    written = written_outputs()
    if written:
        places = ", ".join(dict.fromkeys(str(path) for path in written))
        print(f"tromplab: {what} after the new results were written, complete, to {places}", file=sys.stderr)
    else:
        print(f"tromplab: {what}; the output folder was left as it was", file=sys.stderr)
    return EXIT_TERMINATED if isinstance(interruption, Terminated) else EXIT_INTERRUPTED


@contextlib.contextmanager
def collector_paused():
    """A command's imports with Python's cyclic garbage collector paused, their objects then
    handed to its oldest generation (``gc.freeze`` and ``gc.unfreeze``).

    The numerical stack makes hundreds of thousands of objects (modules, functions, classes)
    that live as long as the process: collected young, each collection of the young
    generations scanned them again, several times over (about 0.1 s of CPU of a command's
    start-up).  The collector is left as it was where it is off or where objects are frozen
    already (by the process's owner)."""
    if not gc.isenabled() or gc.get_freeze_count():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.unfreeze()
        gc.enable()


@contextlib.contextmanager
def verbosity(args):
    """``--quiet`` silences the tables, warnings and progress on standard output and error
    (errors stay, and a command prints a one-line result); ``-v`` adds the library's
    informational log lines."""
    handler = None
    library = logging.getLogger("tromplab")
    previous_level = library.level
    if args.verbose:  # a handler for this command only: main() may run many times in one process
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(name)s: %(message)s"))
        library.addHandler(handler)
        library.setLevel(logging.INFO if args.verbose == 1 else logging.DEBUG)
    token = _RESULT_OUTPUT.set(sys.stdout)  # the one-line result of --quiet goes here, not to the sink
    try:
        if args.quiet:
            with open(os.devnull, "w") as sink, contextlib.redirect_stdout(sink):
                yield
        else:
            yield
    finally:
        _RESULT_OUTPUT.reset(token)
        if handler is not None:
            library.removeHandler(handler)
            library.setLevel(previous_level)


_RESULT_OUTPUT: contextvars.ContextVar = contextvars.ContextVar("result_output", default=None)


def print_usage(parser: argparse.ArgumentParser) -> int:
    """Print ``parser``'s help and return the usage exit code: a command group given no sub-command."""
    parser.print_help()
    return EXIT_USAGE


def print_result(line: str) -> None:
    """Print the one-line result of a command run with ``--quiet`` on standard output (which
    :func:`verbosity` otherwise silences)."""
    print(line, file=_RESULT_OUTPUT.get() or sys.stdout)


@contextlib.contextmanager
def python_warnings(*, quiet: bool, verbose: int):
    """Python warnings raised while a command runs, as a person reads them: a note on the
    input (a detected CSV dialect) as one line (none with ``--quiet``); any other warning held
    and printed when the command ends, once per kind (same category, same words but for the
    numbers) with how many more there were; with ``-v`` every one as it comes.  The caller
    resets ``warnings.showwarning`` (``warnings.catch_warnings``)."""
    show = warnings.showwarning
    held: dict[tuple[str, str], list] = {}  # (category, words without numbers) -> [count, first message]

    def showwarning(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, InputNote):
            if not quiet:
                print(textwrap.fill(f"note: {message}", width=98, break_on_hyphens=False), file=sys.stderr)
        elif verbose:
            show(message, category, filename, lineno, file, line)
        else:
            key = (category.__name__, NUMBER_IN_WORDS.sub("...", str(message)))
            held.setdefault(key, [0, str(message)])[0] += 1

    warnings.showwarning = showwarning
    try:
        yield
    finally:
        for (category, _), (count, first) in held.items():
            more = f" (and {count - 1} more like it)" if count > 1 else ""
            print(textwrap.fill(f"warning ({category}): {first}{more}", width=98, break_on_hyphens=False), file=sys.stderr)


def global_options(*, in_subcommand: bool) -> argparse.ArgumentParser:
    """--quiet, -v and --debug, accepted before or after the command."""
    options = argparse.ArgumentParser(add_help=False)
    default = argparse.SUPPRESS if in_subcommand else None
    group = options.add_argument_group("general")
    group.add_argument(
        "-q", "--quiet", action="store_true", default=default or False, help="print only errors and a one-line result"
    )
    group.add_argument("-v", "--verbose", action="count", default=default or 0, help="more detail (repeat for more)")
    group.add_argument("--debug", action="store_true", default=default or False, help="show the Python traceback of an error")
    return options


class CommandParser(argparse.ArgumentParser):
    """A usage error prints the error and where to look, not the whole usage block."""

    def error(self, message):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n  see '{self.prog} -h' for the options\n")


class SubcommandParser(CommandParser):
    """Every command accepts the global options after its name too (``tromplab fit -q ...``)."""

    def __init__(self, *args, **kwargs):
        kwargs["parents"] = [*kwargs.get("parents", []), _global_options_after_the_command()]
        super().__init__(*args, **kwargs)


@functools.cache
def _global_options_after_the_command() -> argparse.ArgumentParser:
    # one parent for the thirty-odd commands (argparse copies a parent's actions and never
    # changes them): a parser each was a third of the time the whole parser takes to build
    return global_options(in_subcommand=True)


def cli_message(error: InputError, parser: argparse.ArgumentParser) -> str:
    """The error in the command line's words: an option error of the library (``formulas``,
    ``bootstrap``) names the option as typed (``--formulas``), other Python names too."""
    if isinstance(error, OptionError) and not error.option.startswith("-"):
        flags = {action.dest: flag for action in _all_actions(parser) for flag in action.option_strings if flag.startswith("--")}
        flag = flags.get(error.option) or flags.get({"n_bootstrap": "bootstrap"}.get(error.option, ""))
        if flag:
            return f"{flag} {cli_words(error.reason, parser)}"
    return cli_words(str(error), parser)


#: The whole ``tromplab`` parser (or the function that builds it) while a command runs (see :func:`words_of`).
_RUNNING_PARSER: contextvars.ContextVar[argparse.ArgumentParser | Callable[[], argparse.ArgumentParser] | None] = (
    contextvars.ContextVar("parser", default=None)
)


@contextlib.contextmanager
def words_of(parser):
    """While the command runs, messages worded without a command's parser (the balance notes of
    lab tables) take the options of ``parser``, the whole command line's.  A context variable, not
    an argument: the command modules sit below the module that builds the parser.  ``parser`` may
    be a function that returns it, called when a message first needs its words."""
    token = _RUNNING_PARSER.set(parser)
    try:
        yield
    finally:
        _RUNNING_PARSER.reset(token)


def cli_words(message: str, parser: argparse.ArgumentParser | None = None) -> str:
    """Replace Python argument names (``fine_yield``) by the CLI's options (``--fine-yield``);
    without ``parser``, those of the running command line (:func:`words_of`)."""
    parser = parser or _RUNNING_PARSER.get()
    if parser is None:
        raise RuntimeError("cli_words needs a parser outside a running command (tromplab.cli.main)")
    if not ("_" in message or "=" in message):  # every Python name replaced has a "_", every keyword a "="
        return message
    if callable(parser):  # the whole parser, built on first need (tromplab.cli.main)
        parser = parser()
    for name, flag in _python_names_of_options(parser).items():
        if name in message:  # not inside quoted column names
            message = re.sub(rf"(?<![-\w'\"]){name}(?![\w'\"])", flag, message)
    for name, flag in _keywords_of_options(parser).items():  # kind='pct' -> --kind pct
        if f"{name}=" in message:
            message = re.sub(rf"(?<![-\w'\"]){name}=(['\"]?)([\w.,-]+)\1", rf"{flag} \2", message)
    return message


def _keywords_of_options(parser: argparse.ArgumentParser) -> dict[str, str]:
    """Every option's Python keyword (``kind``) and its flag (``--kind``)."""
    return {
        action.dest: flag
        for action in _all_actions(parser)
        for flag in action.option_strings
        if flag.startswith("--") and flag[2:].replace("-", "_") == action.dest
    }


def _python_names_of_options(parser: argparse.ArgumentParser) -> dict[str, str]:
    options = {"sum_tolerance_pct": "--sum-tolerance", "n_bootstrap": "--bootstrap"}  # Python names unlike the option
    for action in _all_actions(parser):
        for flag in action.option_strings:
            if flag.startswith("--") and "_" in action.dest:
                options[action.dest] = flag
    return options


def _all_actions(parser: argparse.ArgumentParser):
    for action in parser._actions:
        yield action
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _all_actions(sub)


#: Errors of the file system that are the place, not tromplab: a full disk, a quota, a folder
#: that cannot be written.  Every writer stages its files and swaps them in at the end, so the
#: previous results are whole when one of these stops a run.
_PLACE_ERRNOS = frozenset(
    getattr(errno, name)
    for name in ("ENOSPC", "EDQUOT", "EROFS", "EACCES", "EPERM", "EFBIG", "EMFILE", "ENFILE")
    if hasattr(errno, name)
)


def write_failure(error: OSError, args) -> str | None:
    """The message of a run stopped by the file system (disk full, no permission), naming the
    folder and saying the old results are intact; None for another ``OSError`` (a bug)."""
    if error.errno not in _PLACE_ERRNOS:
        return None
    target = next((getattr(args, name) for name in ("outdir", "output") if getattr(args, name, None) is not None), None)
    folder = Path(target).absolute().parent if target is not None and Path(target).suffix else target
    if folder is None and error.filename:
        folder = Path(error.filename).parent
    where = f" in {folder}" if folder is not None else ""
    return (
        f"could not write{where}: {error.strerror or error}; the previous results there are intact (nothing was "
        "replaced): free some space or choose a folder you may write (-o)"
    )


def broken_installation(error: ImportError) -> str | None:
    """The message of a module of tromplab (or a dependency) that cannot be imported: the
    installation is broken, say how to reinstall; None when the import is not of those."""
    name = error.name or ""
    if not name:
        return None
    own = name == "tromplab" or name.startswith("tromplab.")
    what = f"tromplab's module {name}" if own else f"the package {name.split('.')[0]}, which tromplab needs,"
    return (
        f"the installation is broken: {what} cannot be imported ({error}); reinstall with "
        "'python -m pip install --force-reinstall tromplab' (from a source checkout: 'python -m pip install -e .')"
    )


def unexpected_error(command: str, error: Exception, args) -> int:
    """Print an error no check of the command foresaw and return its exit code: a full disk or
    a folder that cannot be written is the place (exit 1, the old results intact), a module that
    cannot be imported a broken installation, anything else a bug in tromplab (exit 70)."""
    place = write_failure(error, args) if isinstance(error, OSError) else None
    if place is not None:
        print(f"{command}: error: {place}", file=sys.stderr)
        return EXIT_INPUT
    broken = broken_installation(error) if isinstance(error, ImportError) else None
    if broken is not None:
        print(f"{command}: error: {broken}", file=sys.stderr)
        return EXIT_INTERNAL
    print(
        f"{command}: internal error (a bug in tromplab, please report it): {type(error).__name__}: {error}\n"
        f"  run again with --debug for the traceback",
        file=sys.stderr,
    )
    return EXIT_INTERNAL


def require(module: str, option: str, install: str) -> None:
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise InputError(f"{option} needs the package {module}: {install}")


class progress_bars:
    """tqdm bars on standard error with rate and ETA, as one ``progress(done, total, label)``
    callback: a bar for the fits, then one for each later stage (labels ``"<stage>: ..."``,
    ``stages`` naming them: by default the intervals, counted in fits); ``unit`` is what the
    fitting stage counts, ``units`` what a later stage counts where it is not ``unit`` (the
    intervals: fits).  Silent when standard error is not a terminal, with --quiet, or
    without tqdm."""

    def __init__(self, *, quiet: bool = False, unit: str = "exp", stages: tuple[str, ...] = ("intervals",), units=None):
        self.enabled = not quiet and sys.stderr.isatty()
        self.bar, self.stage = None, None
        self.unit, self.stages = unit, stages
        self.units = {"intervals": "fit", **(units or {})}

    def __enter__(self):
        if not self.enabled:
            return None
        try:
            from tqdm import tqdm
        except ImportError:
            from ..workbench import print_progress

            return print_progress

        def update(done, total, label):
            stage = next((stage for stage in self.stages if label.startswith(f"{stage}: ")), "fitting")
            if total <= 1:
                return
            if stage != self.stage:
                self._close()
                unit = self.units.get(stage, self.unit)
                self.bar = tqdm(total=total, desc=stage, unit=unit, file=sys.stderr, dynamic_ncols=True)
                self.stage = stage
            self.bar.update(done - self.bar.n)

        return update

    def _close(self):
        if self.bar is not None:
            self.bar.close()

    def __exit__(self, *exc):
        self._close()
        return False


class stage_bars:
    """The progress of a command that works in stages (``tromplab circuit``): one tqdm bar per
    stage on standard error, the stage being the label up to ``": "`` and the rest the step shown
    beside the bar (``"reconciliation: round 2"``, ``"elimination: step 1"``, ``"design:
    candidate 4 of 30"``), as one ``progress(done, total, label)`` callback; silent when standard
    error is not a terminal, with --quiet, or without tqdm."""

    def __init__(self, *, quiet: bool = False):
        self.enabled = not quiet and sys.stderr.isatty()
        self.bar, self.stage = None, None

    def __enter__(self):
        if not self.enabled:
            return None
        try:
            from tqdm import tqdm
        except ImportError:
            return None

        def update(done, total, label):
            stage, _, step = label.partition(": ")
            if stage != self.stage:
                self._close()
                counted = {} if total > 1 else {"bar_format": "{desc} [{elapsed}]"}  # a stage of unknown length: its step
                self.bar = tqdm(total=total if total > 1 else None, desc=stage, unit="step", file=sys.stderr,
                                dynamic_ncols=True, leave=False, **counted)  # fmt: skip
                self.stage = stage
            if step and total > 1:
                self.bar.set_postfix_str(step, refresh=False)
            elif step:
                self.bar.set_description_str(label, refresh=False)
            self.bar.update(max(done - self.bar.n, 0))
            self.bar.refresh()

        return update

    def _close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __exit__(self, *exc):
        self._close()
        return False
