"""The page's options, generated from the command line's own declarations.

The form of a command is read off its argparse parser (the one ``tromplab COMMAND -h``
prints), so the page offers the same options, with the same names, choices, defaults and help
(ranges included: :func:`tromplab.validation.state_ranges` writes them into the help). The
values the page sends back are turned into the command's arguments and parsed by that same
parser, whose ``type=`` checks are :mod:`tromplab.validation`'s: a bad value gets the command
line's own message.
"""

from __future__ import annotations

import argparse
import contextlib
import io
from dataclasses import dataclass

#: Options of the commands the page does not offer, and why: the server chooses where the
#: results go and writes the workbook and the report beside the tables (all are downloads); the number of
#: worker processes and the scheduler belong to the machine, not to the data; ``--sheet`` is
#: offered as a choice of the uploaded workbook's sheets, not as free text; the global options
#: (``-q``, ``-v``, ``--debug``) are about the console.
SERVER_CHOSEN = frozenset({"help", "input", "file", "outdir", "excel", "report", "format", "jobs", "scheduler", "dask", "sheet",
                           "quiet", "verbose", "debug", "version"})  # fmt: skip


@dataclass(frozen=True)
class FormOption:
    """One option of a command as the page shows it.

    Attributes
    ----------
    dest : str
        The option's name in the parsed arguments (``size_unit``).
    flag : str
        The long flag typed on the command line (``--size-unit``).
    widget : str
        ``"flag"`` (on or off), ``"choice"`` (one of ``choices``) or ``"text"``.
    choices : tuple of str
        The allowed values of a choice.
    default : str or bool or None
        The command's default, as the page shows it.
    help : str
        The command line's help text, with its default and range filled in.
    group : str
        The title of the argparse group the option belongs to (``"options"`` when none).
    """

    dest: str
    flag: str
    widget: str
    choices: tuple[str, ...]
    default: str | bool | None
    help: str
    group: str

    def as_dict(self) -> dict:
        return {"dest": self.dest, "flag": self.flag, "widget": self.widget, "choices": list(self.choices),
                "default": self.default, "help": self.help, "group": self.group}  # fmt: skip


class OptionsRefused(Exception):
    """The command's parser refused the options; ``str()`` is the command line's own message."""


def command_parser(*path: str) -> argparse.ArgumentParser:
    """The parser of ``tromplab PATH...`` (``command_parser("fit")``), from the command line's builder."""
    from ..cli import build_parser

    parser = build_parser()
    for name in path:
        commands = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
        parser = commands[0].choices[name]
    return parser


def form_options(parser: argparse.ArgumentParser) -> list[FormOption]:
    """The options of ``parser`` that the page offers, in the order ``-h`` lists them."""
    formatter = parser._get_formatter()
    groups = {id(action): group.title for group in parser._action_groups for action in group._group_actions}
    shown, seen = [], set()
    for action in parser._actions:
        if action.dest in SERVER_CHOSEN or action.dest in seen or not action.option_strings:
            continue
        if isinstance(action, argparse._StoreConstAction) and not isinstance(action, argparse._StoreTrueAction):
            continue  # an alias of another option's value (--no-figures is --figures none)
        seen.add(action.dest)
        long_flags = [flag for flag in action.option_strings if flag.startswith("--")]
        if isinstance(action, argparse._StoreTrueAction):
            widget, default = "flag", False
        elif action.choices is not None:
            widget, default = "choice", None if action.default is None else str(action.default)
        else:
            widget, default = "text", None if action.default is None else str(action.default)
        help_text = formatter._expand_help(action) if action.help else ""
        group = groups.get(id(action)) or "options"
        shown.append(FormOption(action.dest, (long_flags or action.option_strings)[0], widget,
                                tuple(str(c) for c in action.choices or ()), default, help_text, group))  # fmt: skip
    return shown


def arguments_from_form(options: list[FormOption], values: dict) -> list[str]:
    """The command-line arguments the page's ``values`` (``{dest: value}``) stand for.

    An option left at its default is not typed, as on the command line; a value is passed as
    text, for the parser to check. Names the form does not know are refused.
    """
    known = {option.dest: option for option in options}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise OptionsRefused(f"unknown option(s): {', '.join(unknown)}")
    arguments = []
    for dest, value in values.items():
        option = known[dest]
        if option.widget == "flag":
            if value is True:
                arguments.append(option.flag)
            elif value not in (False, None):
                raise OptionsRefused(f"{option.flag} is on or off, not {value!r}")
            continue
        if value is None or not isinstance(value, str | int | float) or str(value) == (option.default or ""):
            if value is not None and not isinstance(value, str | int | float):
                raise OptionsRefused(f"{option.flag} takes one value, not {type(value).__name__}")
            continue
        arguments.append(f"{option.flag}={value}")  # '=' keeps a value that starts with '-' a value
    return arguments


def parse_arguments(parser: argparse.ArgumentParser, arguments: list[str]) -> argparse.Namespace:
    """``parser.parse_args(arguments)``, its usage error raised as :class:`OptionsRefused`
    with the command line's message (what ``tromplab COMMAND`` prints on standard error)."""
    said = io.StringIO()
    try:
        with contextlib.redirect_stderr(said):
            return parser.parse_args(arguments)
    except SystemExit:
        raise OptionsRefused(said.getvalue().strip()) from None
