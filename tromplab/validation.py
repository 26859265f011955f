"""One set of range checks for options, shared by the Python API and the command line.

Each check takes the value and the option's name as the caller spells it (``alpha`` in
Python, ``--alpha`` on the command line) and returns the value converted, or raises
:class:`~tromplab.errors.OptionError` naming the option.  :func:`cli_type` turns a check
into an argparse ``type=`` callable, so the parser refuses a bad value (exit code 2)
before any work starts.

Examples
--------
>>> check_probability(0.05, "alpha")
0.05
>>> check_probability(2, "alpha")
Traceback (most recent call last):
...
tromplab.errors.OptionError: alpha must lie strictly between 0 and 1, got 2
"""

from __future__ import annotations

import argparse
import math
import operator
from collections.abc import Callable

from .errors import OptionError

#: Largest bootstrap request accepted: 100,000 resamples of nine formulas already take
#: hours on a laptop (each resample is a full fit); more does not sharpen a 95 % interval.
MAX_BOOTSTRAP = 100_000
#: Largest number of decks of a sieve bin design (the exact distance moments sum m terms).
MAX_DECKS = 1_000
#: Largest seed: numpy's SeedSequence takes any non-negative integer; 2**63 - 1 keeps it
#: representable in every integer column and file format.
MAX_SEED = 2**63 - 1


def _number(value, option: str) -> float:
    if isinstance(value, bool):
        raise OptionError(option, f"takes a number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise OptionError(option, f"takes a number, got {value!r}") from None
    if not math.isfinite(number):
        raise OptionError(option, f"takes a finite number, got {value!r}")
    return number


def _integer(value, option: str) -> int:
    if isinstance(value, bool):
        raise OptionError(option, f"takes a whole number, got {value!r}")
    try:
        return operator.index(value)
    except TypeError:
        pass
    text = str(value).strip()
    try:
        return int(text)
    except ValueError:
        number = _number(value, option)
        if number != int(number):
            raise OptionError(option, f"takes a whole number, got {value!r}") from None
        return int(number)


def check_probability(value, option: str) -> float:
    """A level, share or significance strictly between 0 and 1."""
    number = _number(value, option)
    if not 0.0 < number < 1.0:
        raise OptionError(option, f"must lie strictly between 0 and 1, got {value!r}")
    return number


def check_share(value, option: str) -> float:
    """A share from 0 to 1 inclusive (a threshold such as the smallest feed share)."""
    number = _number(value, option)
    if not 0.0 <= number <= 1.0:
        raise OptionError(option, f"must lie between 0 and 1, got {value!r}")
    return number


def check_water_recovery(value, option: str) -> float:
    """The share of the feed water reporting to the underflow (coarse product), in [0, 1).

    1 is refused: with all the water in the underflow the Kelsall correction divides by zero.
    """
    number = _number(value, option)
    if not 0.0 <= number < 1.0:
        raise OptionError(option, f"must lie in [0, 1) (the share of the feed water reporting to the underflow), got {value!r}")
    return number


def check_positive(value, option: str) -> float:
    """A size or length: finite and above zero."""
    number = _number(value, option)
    if number <= 0.0:
        raise OptionError(option, f"must be a positive finite number, got {value!r}")
    return number


def check_non_negative(value, option: str) -> float:
    """A tolerance or lower bound: finite and not below zero."""
    number = _number(value, option)
    if number < 0.0:
        raise OptionError(option, f"must be a finite number >= 0, got {value!r}")
    return number


def check_count(value, option: str, *, maximum: int, minimum: int = 1) -> int:
    """A whole number of things from ``minimum`` to ``maximum``."""
    number = _integer(value, option)
    if number < minimum:
        raise OptionError(option, f"must be a whole number >= {minimum}, got {value!r}")
    if number > maximum:
        raise OptionError(option, f"is capped at {maximum:,}, got {number:,}")
    return number


def check_bootstrap(value, option: str) -> int:
    """Number of bootstrap resamples: 0 (none) up to :data:`MAX_BOOTSTRAP`."""
    number = check_count(value, option, minimum=0, maximum=10**18)
    if number > MAX_BOOTSTRAP:
        raise OptionError(
            option,
            f"is capped at {MAX_BOOTSTRAP:,} resamples (each one refits every formula; "
            f"{number:,} would run for days), got {number:,}",
        )
    return number


def check_seed(value, option: str) -> int:
    """A random seed: a whole number from 0 to 2**63 - 1."""
    return check_count(value, option, minimum=0, maximum=MAX_SEED)


def check_optional(check: Callable, value, option: str, **kwargs):
    """``check`` unless ``value`` is None (an option left at its default)."""
    return None if value is None else check(value, option, **kwargs)


def cli_type(check: Callable, option: str, **kwargs) -> Callable[[str], object]:
    """An argparse ``type=`` callable running ``check``; argparse then names the option."""

    def parse(text: str):
        try:
            return check(text, option, **kwargs)
        except OptionError as error:
            raise argparse.ArgumentTypeError(error.reason) from None

    parse.__name__ = check.__name__.removeprefix("check_")  # argparse names the type in some messages
    return parse


# --- circuit surveys: ranges of the error model of tromplab.circuit ----------------------
#: Largest relative error of a measurement (1 = 100 % of the measured value): beyond it the
#: measurement says nothing about its value, and the weights of the reconciliation span more
#: than floating point resolves (a relative error of 1e6 made every flow look unobservable).
MAX_RELATIVE_ERROR = 1.0
#: Largest standard deviation of a share (fraction of the stream): a share lies in 0..1.
MAX_SHARE_SD = 0.5
#: Largest standard deviation of a per cent solids (percentage points): it lies in 0..100.
MAX_PCT_SOLIDS_SD = 50.0


def _at_most(number: float, value, option: str, maximum: float, what: str) -> float:
    if number > maximum:
        raise OptionError(option, f"is at most {maximum:g} ({what}), got {value!r}")
    return number


def check_relative_error(value, option: str) -> float:
    """A relative error of a measurement, 0 to :data:`MAX_RELATIVE_ERROR` (0.05 = 5 %)."""
    number = check_non_negative(value, option)
    return _at_most(number, value, option, MAX_RELATIVE_ERROR, "a relative error of 100 % of the measured value")


def check_positive_relative_error(value, option: str) -> float:
    """A relative error above 0 (a measurement that is not exact) up to :data:`MAX_RELATIVE_ERROR`."""
    number = check_positive(value, option)
    return _at_most(number, value, option, MAX_RELATIVE_ERROR, "a relative error of 100 % of the measured value")


def check_share_sd(value, option: str) -> float:
    """A standard deviation of a share (fraction of the stream), 0 to :data:`MAX_SHARE_SD`."""
    number = check_non_negative(value, option)
    return _at_most(number, value, option, MAX_SHARE_SD, "a share lies in 0..1")


def check_pct_solids_sd(value, option: str) -> float:
    """A standard deviation of a per cent solids above 0, up to :data:`MAX_PCT_SOLIDS_SD` percentage points."""
    number = check_positive(value, option)
    return _at_most(number, value, option, MAX_PCT_SOLIDS_SD, "a per cent solids lies in 0..100")
