"""One set of range checks for options, shared by the Python API and the command line.

Each check takes the value and the option's name as the caller spells it (``alpha`` in
Python, ``--alpha`` on the command line) and returns the value converted, or raises
:class:`~tromplab.errors.OptionError` naming the option.  :func:`cli_type` turns a check
into an argparse ``type=`` callable, so the parser refuses a bad value (exit code 2)
before any work starts; :func:`state_ranges` writes each option's range into its help.

In Python a check takes numbers only: a string such as ``"0.05"`` is refused, because the
command line converts its text itself (:func:`cli_type`) and a string reaching the library
is a caller's mistake that silent conversion would hide.

Examples
--------
>>> check_probability(0.05, "alpha")
0.05
>>> check_probability(2, "alpha")
Traceback (most recent call last):
...
tromplab.errors.OptionError: alpha must lie strictly between 0 and 1, got 2
>>> check_probability("0.05", "alpha")
Traceback (most recent call last):
...
tromplab.errors.OptionError: alpha takes a number, got the text '0.05'
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import operator
from collections.abc import Callable

from .errors import OptionError
from .options import BOOTSTRAP_METHODS, DEFAULT_ALPHA, PARTITION_TO, RANK_BY

#: Largest bootstrap request accepted: 100,000 resamples of nine formulas already take
#: hours on a laptop (each resample is a full fit); more does not sharpen a 95 % interval.
MAX_BOOTSTRAP = 100_000
#: Largest number of decks of a sieve bin design (the exact distance moments sum m terms).
MAX_DECKS = 1_000
#: Largest seed: numpy's SeedSequence takes any non-negative integer; 2**63 - 1 keeps it
#: representable in every integer column and file format.
MAX_SEED = 2**63 - 1
#: Most worker processes (``--jobs``, ``jobs=``): more than any machine tromplab runs on has cores.
MAX_JOBS = 4_096
#: Sizes in any unit are refused outside this range (options and data alike), so that a cut
#: searched from size / 100 to size x 100 and the indices stay normal floating-point numbers.
SIZE_LIMITS = (1e-250, 1e250)


def _refuse_text_and_truth(value, option: str, kind: str) -> None:
    if isinstance(value, bool):
        raise OptionError(option, f"takes {kind}, got {value!r}")
    if isinstance(value, (str, bytes)):
        raise OptionError(option, f"takes {kind}, got the text {value!r}")


def _number(value, option: str) -> float:
    _refuse_text_and_truth(value, option, "a number")
    if isinstance(value, complex):
        raise OptionError(option, f"takes a real number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise OptionError(option, f"takes a number, got {value!r}") from None
    if not math.isfinite(number):
        raise OptionError(option, f"takes a finite number, got {value!r}")
    return number


def _integer(value, option: str) -> int:
    _refuse_text_and_truth(value, option, "a whole number")
    try:
        return operator.index(value)
    except TypeError:
        pass
    number = _number(value, option)
    if number != int(number):
        raise OptionError(option, f"takes a whole number, got {value!r}") from None
    return int(number)


def check_number(value, option: str) -> float:
    """Any finite real number (a shape parameter, whose range the formula states)."""
    return _number(value, option)


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


def check_range(
    value, option: str, *, low: float, high: float, low_open: bool = False, high_open: bool = False, unit: str = ""
) -> float:
    """A number from ``low`` to ``high`` (each end excluded when ``low_open``/``high_open``).

    ``unit`` is shown after the range in the message (``m/s``).
    """
    number = _number(value, option)
    above = number > low if low_open else number >= low
    below = number < high if high_open else number <= high
    if not (above and below):
        shown = f" {unit}" if unit else ""
        raise OptionError(option, f"must lie in {interval_text(low, high, low_open, high_open)}{shown}, got {value!r}")
    return number


def interval_text(low: float, high: float, low_open: bool = False, high_open: bool = False) -> str:
    """``(0, 1]``-style text of a range (``inf`` for an open end at infinity)."""
    return f"{'(' if low_open else '['}{_bound_text(low)}, {_bound_text(high)}{')' if high_open else ']'}"


def _bound_text(bound: float) -> str:
    if math.isinf(bound):
        return "inf" if bound > 0 else "-inf"
    return f"{int(bound):,}" if float(bound).is_integer() and abs(bound) < 1e6 else f"{bound:g}"


def check_size(value, option: str) -> float:
    """A size in any unit, within :data:`SIZE_LIMITS` (as the sizes of the data are)."""
    low, high = SIZE_LIMITS
    return check_range(value, option, low=low, high=high)


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


#: Heaviest relative density accepted as a cut density: above the densest media in coal and
#: mineral dense-medium practice (ferrosilicon media reach about 3.4).
MAX_CUT_DENSITY = 3.5


#: A product's yield this close to 0 or 1 leaves the other product empty to rounding (1 - 1e-308 is 1).
YIELD_MARGIN = 1e-9


def check_yield(value, option: str) -> float:
    """A product's share of the feed mass, from :data:`YIELD_MARGIN` to 1 - :data:`YIELD_MARGIN`.

    Nearer 0 or 1 the other product's share, ``1 - value``, rounds to an empty product (or
    to 1), and the balance would name the other product's yield instead of this option.
    """
    number = _number(value, option)
    if not YIELD_MARGIN <= number <= 1.0 - YIELD_MARGIN:
        raise OptionError(
            option,
            f"must lie in [{YIELD_MARGIN:g}, 1 - {YIELD_MARGIN:g}] (a share of the feed mass; nearer 0 or 1 one product "
            f"is empty to rounding), got {value!r}",
        )
    return number


def check_cut_density(value, option: str) -> float:
    """A cut (separation) relative density: above water's 1 and at most :data:`MAX_CUT_DENSITY`."""
    number = _number(value, option)
    if not 1.0 < number <= MAX_CUT_DENSITY:
        raise OptionError(option, f"must be a relative density above 1 (water) and at most {MAX_CUT_DENSITY:g}, got {value!r}")
    return number


def check_percent(value, option: str) -> float:
    """A per cent strictly between 0 and 100 (an ash per cent sought, say)."""
    number = _number(value, option)
    if not 0.0 < number < 100.0:
        raise OptionError(option, f"must lie strictly between 0 and 100 (per cent), got {value!r}")
    return number


def check_choice(value, option: str, *, choices: tuple[str, ...]) -> str:
    """One of ``choices`` (a string), else an :class:`~tromplab.errors.OptionError` listing them."""
    if not isinstance(value, str) or value not in choices:
        raise OptionError(option, f"takes one of {', '.join(repr(c) for c in choices)}, got {value!r}")
    return value


def check_optional(check: Callable, value, option: str, **kwargs):
    """``check`` unless ``value`` is None (an option left at its default)."""
    return None if value is None else check(value, option, **kwargs)


def range_text(check: Callable, **kwargs) -> str:
    """The range ``check`` accepts with ``kwargs``, in the words of the help texts."""
    if check is check_range:
        return interval_text(kwargs["low"], kwargs["high"], kwargs.get("low_open", False), kwargs.get("high_open", False)) + (
            f" {kwargs['unit']}" if kwargs.get("unit") else ""
        )
    if check is check_count:
        return f"{kwargs.get('minimum', 1):,} to {kwargs['maximum']:,}"
    fixed = {
        check_probability: "(0, 1)",
        check_share: "[0, 1]",
        check_water_recovery: "[0, 1)",
        check_positive: "(0, inf)",
        check_non_negative: "[0, inf)",
        check_number: "(-inf, inf)",
        check_size: interval_text(*SIZE_LIMITS),
        check_bootstrap: f"0 to {MAX_BOOTSTRAP:,}",
        check_seed: "0 to 2**63 - 1",
        check_cut_density: f"(1, {MAX_CUT_DENSITY:g}]",
        check_yield: f"[{YIELD_MARGIN:g}, 1 - {YIELD_MARGIN:g}]",
        check_percent: "(0, 100)",
        check_relative_error: f"[0, {MAX_RELATIVE_ERROR:g}]",
        check_positive_relative_error: f"(0, {MAX_RELATIVE_ERROR:g}]",
        check_share_sd: f"[0, {MAX_SHARE_SD:g}]",
        check_assay_sd: f"[0, {MAX_ASSAY_SD:g}]",
        check_pct_solids_sd: f"(0, {MAX_PCT_SOLIDS_SD:g}]",
    }
    return fixed[check]


def _parsed_text(text: str) -> int | float | str:
    """The number a command-line text spells (an integer where it is one), else the text."""
    for convert in (int, float):
        try:
            return convert(text.strip())
        except ValueError:
            continue
    return text


def cli_type(check: Callable, option: str, **kwargs) -> Callable[[str], object]:
    """An argparse ``type=`` callable running ``check`` on the number the text spells;
    argparse then names the option.  Its ``range`` attribute is :func:`range_text`."""

    def parse(text: str):
        value = _parsed_text(text)
        if isinstance(value, str):
            raise argparse.ArgumentTypeError(f"takes a number, got {text!r}")
        try:
            return check(value, option, **kwargs)
        except OptionError as error:
            raise argparse.ArgumentTypeError(error.reason) from None

    parse.__name__ = check.__name__.removeprefix("check_")  # argparse names the type in some messages
    parse.range = range_text(check, **kwargs)  # type: ignore[attr-defined]  # read by state_ranges
    return parse


def state_ranges(parser: argparse.ArgumentParser) -> None:
    """Add ``(range ...)`` to the help of every option of ``parser`` and its sub-commands
    whose type comes from :func:`cli_type`, so ``--help`` and the CLI reference state it."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                state_ranges(sub)
        elif action.help and (stated := getattr(action.type, "range", None)) and stated not in action.help:
            action.help = f"{action.help} (range {stated.replace('%', '%%')})"  # argparse formats help with %


# --- circuit surveys: ranges of the error model of tromplab.circuit ----------------------
#: Largest relative error of a measurement (1 = 100 % of the measured value): beyond it the
#: measurement says nothing about its value, and the weights of the reconciliation span more
#: than floating point resolves (a relative error of 1e6 made every flow look unobservable).
MAX_RELATIVE_ERROR = 1.0
#: Largest standard deviation of a share (fraction of the stream): a share lies in 0..1.
MAX_SHARE_SD = 0.5
#: Largest standard deviation of a per cent solids (percentage points): it lies in 0..100.
MAX_PCT_SOLIDS_SD = 50.0
#: Largest standard deviation of an assay (fraction of the class's solids): an assay lies in 0..1.
MAX_ASSAY_SD = 0.5


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


def check_assay_sd(value, option: str) -> float:
    """A standard deviation of an assay (fraction of the class's solids), 0 to :data:`MAX_ASSAY_SD`."""
    number = check_non_negative(value, option)
    return _at_most(number, value, option, MAX_ASSAY_SD, "an assay lies in 0..1 of the class's solids")


def check_pct_solids_sd(value, option: str) -> float:
    """A standard deviation of a per cent solids above 0, up to :data:`MAX_PCT_SOLIDS_SD` percentage points."""
    number = check_positive(value, option)
    return _at_most(number, value, option, MAX_PCT_SOLIDS_SD, "a per cent solids lies in 0..100")


# --- the settings of a batch fit -----------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class FitSettings:
    """The settings of a batch fit (``tromplab fit``, :func:`tromplab.fit_experiments`), checked
    once, here, and handed unchanged to the workers and the writers.

    Built from the API's keywords (``FitSettings(alpha=0.1, ...)``) or from the command line's
    parsed options (:meth:`from_options`); a field is the option of the same name (``rank_by``
    is ``--rank-by``) with the same default.  A wrong value is an
    :class:`~tromplab.errors.OptionError` naming the option.  What can only be checked against
    the data (``delta_max`` against the sizes, the bootstrap's work against the number of fits,
    ``formulas`` against the registry) is checked by the batch before any fit.

    Attributes
    ----------
    formulas : str, iterable of ids or equation numbers, or None
        The formulas to fit (None: the nine); a list is kept as a tuple.
    extended, rank_extended : bool
        Also fit the extended curves; rank them with the nine.
    alpha : float
        Significance level of the Fisher screen, in (0, 1).
    delta_max : float or None
        Largest feed size for the misplacement index (None: per experiment).
    rank_by : str
        ``"F"`` or ``"aicc"``: the criterion within an experiment.
    size_unit : str
        Unit of the sizes as given ("" when not given; the batch takes the loader's unit when
        every experiment has the same one).
    water_recovery : float or None
        Share of the feed water to the underflow, in [0, 1), compared with the fitted bypass.
    partition_to : str
        ``"fine"`` or ``"coarse"``: the product whose partition the tables and figures show.
    ci : float or None
        Level of the interval columns, in (0, 1) (None: none).
    bootstrap : int
        Bootstrap resamples per fit (0: none), drawn by ``bootstrap_method`` from ``seed``.
    bootstrap_method : str
        ``"residuals"`` or ``"cases"``.
    seed : int
        Seed of the bootstrap, a whole number >= 0.
    jobs : int or None
        Worker processes (None or 0: all cores).  The command line's default is 0 (all cores),
        the API's 1 (one process, as a library call should be unless asked): the field's
        metadata ``cli_default`` says so.
    scheduler : str or None
        Address of a Dask scheduler to run the chunks on.
    dask : str or None
        ``"local"``: a local Dask cluster of two workers.
    single_fits : bool
        Fit one experiment and formula at a time with lmfit instead of the batched engine.
    """

    formulas: str | tuple | frozenset | None = None
    extended: bool = False
    alpha: float = DEFAULT_ALPHA
    delta_max: float | None = None
    rank_by: str = "F"
    rank_extended: bool = False
    size_unit: str = ""
    water_recovery: float | None = None
    partition_to: str = "fine"
    ci: float | None = None
    bootstrap: int = 0
    bootstrap_method: str = "residuals"
    seed: int = 0
    jobs: int | None = dataclasses.field(default=1, metadata={"cli_default": 0})
    scheduler: str | None = None
    dask: str | None = None
    single_fits: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.formulas, list):
            object.__setattr__(self, "formulas", tuple(self.formulas))
        check_probability(self.alpha, "alpha")
        check_optional(check_count, self.jobs, "jobs", minimum=0, maximum=MAX_JOBS)
        if self.partition_to not in PARTITION_TO:
            raise OptionError("partition_to", f"must be 'fine' or 'coarse', got {self.partition_to!r}")
        check_optional(check_probability, self.ci, "ci")
        check_seed(self.seed, "seed")
        if self.rank_by not in RANK_BY:
            raise OptionError("rank_by", f"must be one of {', '.join(sorted(RANK_BY))}, got {self.rank_by!r}")
        if self.bootstrap_method not in BOOTSTRAP_METHODS:
            raise OptionError("bootstrap_method", f"must be one of {', '.join(BOOTSTRAP_METHODS)}, got {self.bootstrap_method!r}")
        check_bootstrap(self.bootstrap, "bootstrap")
        object.__setattr__(self, "water_recovery", check_optional(check_water_recovery, self.water_recovery, "water_recovery"))

    @property
    def engine(self) -> bool:
        """Whether the batched engine fits (else one lmfit fit per experiment and formula)."""
        return not self.single_fits

    @classmethod
    def from_options(cls, options, **overrides) -> FitSettings:
        """The settings of the command line's parsed ``options`` (an ``argparse.Namespace``):
        each field from the option of its name, a field the command has no option for at its
        default; ``overrides`` replace fields (``ci=None`` where a command's ``--ci`` means
        something else)."""
        given = {field.name: getattr(options, field.name, field.default) for field in dataclasses.fields(cls)}
        return cls(**{**given, **overrides})
