"""Errors raised for bad input: each names the file, row and column at fault; the warnings about
input; and the warning about a result unpickled from another tromplab version."""

from __future__ import annotations


class InputError(ValueError):
    """Bad input data.

    The message names the file, the row (as a spreadsheet user counts it: the header is
    row 1 of the data table, so the first data row is row 2) and the column, then says
    what is wrong.
    """

    def __init__(self, message: str, *, source: str | None = None, row: int | None = None, column: str | None = None):
        self.source = source
        self.row = row
        self.column = column
        self.reason = message
        where = []
        if source:
            where.append(str(source))
        if row is not None:
            where.append(f"row {row}")
        if column:
            where.append(f"column '{column}'")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)


class OptionError(InputError):
    """An option (command-line flag or keyword argument) has a value outside its range.

    ``option`` is the name the caller used (``--fine-yield`` on the command line,
    ``fine_yield`` in Python) and ``reason`` says what is wrong without the name, so the
    command line can report it in argparse's own words.
    """

    def __init__(self, option: str, reason: str):
        self.option = option
        super().__init__(f"{option} {reason}")
        self.reason = reason


class ResultError(ArithmeticError):
    """A computed result is not finite or lies outside its range (an overflow at extreme
    inputs, a root the numbers cannot reach): it is reported as a failure, never as a result.

    The command line prints the message and exits 3, as for failed fits, and writes nothing
    for the command that failed.
    """


class OutputError(InputError):
    """An output path cannot be used (a file where a folder is needed, not writable, ...)."""


# The warnings about input live here, beside the errors, so the command line can set its
# filters for them without importing the loaders (tromplab.loading offers them too).
class InputNote(UserWarning):
    """Something about an input was inferred rather than declared (e.g. a detected CSV dialect)."""


class YieldWarning(UserWarning):
    """A stated yield contradicts the size distributions."""


class InconsistentVersionWarning(UserWarning):
    """A result was unpickled from a pickle written by another tromplab version.

    The result loads (its data are plain records), but numbers derived on first use (the
    indices, intervals and tables computed from the stored fit) may differ from what the
    version that wrote it reported, and a record whose layout changed may fail later.
    Refit with this version, or load with the version named in ``saved_version``.  A
    warning rather than an error, as scikit-learn does for its estimators: it keeps a saved
    result readable across a patch release (:func:`tromplab.load` refuses a batch saved by
    another major version outright).
    """

    def __init__(self, *, result_class: str, saved_version: str, current_version: str):
        self.result_class = result_class
        self.saved_version = saved_version
        self.current_version = current_version
        super().__init__(
            f"{result_class} unpickled from tromplab {saved_version}, this is tromplab {current_version}: "
            "numbers derived on first use may differ from those the other version reported; refit to be sure"
        )


def expect_kind(value, kinds, argument: str, accepted: str):
    """``value`` when it is an instance of ``kinds``; else a :class:`TypeError` that names the
    argument, says what it accepts and what it got (never an ``AttributeError`` later on).

    Examples
    --------
    >>> expect_kind([1], dict, "table", "a pandas DataFrame")
    Traceback (most recent call last):
    ...
    TypeError: table must be a pandas DataFrame, got list
    """
    if not isinstance(value, kinds):
        raise TypeError(f"{argument} must be {accepted}, got {type(value).__name__}")
    return value


def expect_like(value, attributes, argument: str, accepted: str):
    """``value`` when it has every one of ``attributes`` (for a kind a lower layer cannot
    import); else the :class:`TypeError` of :func:`expect_kind`."""
    if not all(hasattr(value, name) for name in attributes):
        raise TypeError(f"{argument} must be {accepted}, got {type(value).__name__}")
    return value
