"""Warnings of a batch as records with stable codes, grouped by kind: what the console prints
once per kind with its count, and what ``warnings.csv`` holds, every occurrence.

A batch of 240 experiments can meet the same condition 93 times; a console that says it 93
times is not read.  Each warning of the library is a :class:`Notice` (who it concerns, which
formula or curve, its code and its full message); :func:`grouped_lines` turns many of them
into one line per kind ("93 of 240 experiments: the cut is not bracketed by the data ...")
and :func:`notice_table` into the rows of ``warnings.csv``.  :func:`regroup_warnings` does the
same for the Python warnings a loop over experiments raises, so that the API too warns once
per kind.

The codes are stable: a script may filter ``warnings.csv`` on them.  :data:`WARNING_KINDS`
lists every code with the start of the messages it covers and the words the console prints
for the kind (docs/columns.md lists them for readers, under ``warnings.csv``).
"""

from __future__ import annotations

import contextlib
import functools
import re
import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

#: Names of a kind's occurrences the console shows before "and N more".
NAMES_SHOWN = 3
#: Notices of one kind :func:`grouped_lines` looks through for the names it shows.
_NOTICES_NAMED = 4 * (NAMES_SHOWN + 1)
#: The code of a message no kind of :data:`WARNING_KINDS` covers.
OTHER = "other"


@dataclass(frozen=True)
class WarningKind:
    """One kind of warning: its stable ``code``, a ``pattern`` that the start of its messages
    match, and the ``summary`` the console prints once for all its occurrences
    (``intervals``: added only when the run makes intervals, ``--ci`` or ``--bootstrap``)."""

    code: str
    pattern: str
    summary: str
    intervals: str = ""
    detail: str = ""
    level: str = "warning"

    def named(self, notice: Notice) -> str:
        """The notice's subject, with the part of its message that ``detail`` (a pattern with
        one group) finds when there is one: a value that differs from subject to subject."""
        found = re.search(self.detail, notice.message) if self.detail else None
        return f"{notice.subject} {found.group(1)}" if found else notice.subject

    def matches(self, message: str) -> bool:
        return _compiled(self.pattern).match(message) is not None


#: Every kind of warning the fit, report and reading of lab tables give, in the order the
#: console lists them.
WARNING_KINDS = (
    WarningKind(
        "cut-not-bracketed",
        r"the cut is not bracketed by the data",
        "the cut is not bracketed by the data: the cut size, and the d50, d25, d75 and Ep that rest on it, are read "
        "off the formula's shape, not off measurements",
        intervals="no interval is given for them",
    ),
    WarningKind(
        "cut-ambiguous",
        r"the measured cut is ambiguous",
        "the measured cut is ambiguous: partitions near 1/2 put it far apart, and formula (11) may change with the "
        "data's last digits",
    ),
    WarningKind(
        "partition-rises-with-size",
        r"the partition to fines rises with size",
        "the partition to fines rises with size: is the column the partition to the coarse product? (use partition_coarse)",
    ),
    WarningKind(
        "yield-estimated",
        r"fine yield estimated by least squares",
        "the fine yield was estimated by least squares from the three streams (value +/- standard error)",
        detail=r": (\S+ \+/- \S+)",
        level="note",
    ),
    WarningKind(
        "yield-from-masses",
        r"fine yield \S+ taken from the product masses",
        "the fine yield was taken from the product masses",
        level="note",
    ),
    WarningKind(
        "yield-contradicts-masses",
        r"the stated fine yield .* contradicts the product masses",
        "the stated fine yield contradicts the product masses; the stated yield is used",
    ),
    WarningKind(
        "yield-contradicts-sizes",
        r"the stated fine yield .* contradicts the size data",
        "the stated fine yield contradicts the size data; the stated yield is used (estimate_yield uses the estimate)",
    ),
    WarningKind("blank-cells", r"column '.*': blank cell\(s\)", "blank cells of a stream column were read as no material"),
    WarningKind(
        "cut-classes-left-out",
        r"every class around the cut",
        "every class around the cut was left out by the feed-share filter, so the points do not measure the cut "
        "(a smaller min_feed_share keeps them)",
    ),
    WarningKind(
        "weight-concentrated",
        r"\d+ of \d+ classes \(.*\) carry \d+ % of the weight",
        "a few classes carry most of the weight of the fit: the fitted curve follows them more than the others",
    ),
    WarningKind(
        "parameter-at-bound",
        r"\S+ = \S+ at its bound",
        "a parameter lies at its bound: the unconstrained optimum lies beyond it and its standard error is unreliable",
    ),
    WarningKind(
        "parameter-undetermined",
        r"\S+ = \S+ is not determined by the data",
        "a parameter is not determined by the data: quite different values fit as well",
    ),
    WarningKind(
        "no-break-point",
        r"formula \(11\): no break point",
        "formula (11) has no break point for its fitted kr: the curve falls back to the nearer limit",
    ),
    WarningKind("curve-exceeds-1", r"the fitted curve exceeds 1", "the fitted curve exceeds 1: not a physical partition"),
    WarningKind(
        "residuals-systematic",
        r"adequate by F but the residuals are systematic",
        "adequate by F but the residuals are systematic (runs test)",
    ),
    WarningKind(
        "residuals-not-normal",
        r"adequate by F but the residuals are not normal",
        "adequate by F but the residuals are not normal (Shapiro-Wilk), as the F test assumes",
    ),
    # the density face (tromplab density fit): notes on the tests and on the fitted curves
    WarningKind("tracers-lost", r"\d+ of \d+ tracers lost", "some tracers were lost and are not counted", level="note"),
    WarningKind(
        "overdispersed",
        r"overdispersed \(Pearson",
        "the counts are overdispersed (Pearson chi2/df > 1): intervals use the quasi-binomial scale",
    ),
    WarningKind(
        "quasi-binomial-intervals",
        r"intervals on the quasi-binomial scale \S+ \(Pearson",
        "the intervals use the fit's own quasi-binomial scale (Pearson chi2/df, above 1): the profile deviance is "
        "divided by it and compared with F(1, residual df)",
        level="note",
    ),
    WarningKind(
        "quasi-binomial-intervals-pooled",
        r"intervals on the quasi-binomial scale \S+ of the file",
        "the intervals use the quasi-binomial scale of the file (Pearson chi2/df of the curve pooled over the "
        "file's tests, above the fit's own): the profile deviance is divided by it and compared with F(1, pooled "
        "residual df)",
        level="note",
    ),
    WarningKind(
        "floats-yield-estimated",
        r"floats yield .*estimated by least squares",
        "the floats yield was estimated by least squares from the three analyses (value +/- standard error)",
        detail=r"floats yield (\S+ \+/- \S+)",
        level="note",
    ),
    WarningKind(
        "floats-yield-contradicts",
        r"the stated floats yield .* contradicts the float-sink analyses",
        "the stated floats yield contradicts the float-sink analyses; the stated yield is used",
    ),
    WarningKind(
        "open-fraction-placed",
        r"the (float below|sink above) \S+ is placed as the fraction",
        "an open density fraction was placed as a closed one",
        level="note",
    ),
    WarningKind(
        "no-interval",
        r"(no intervals: |\S+ has no interval: |Ep and the imperfection have no interval: )",
        "a quantity has no interval: the data do not bound it",
    ),
    WarningKind(
        "no-cut-density",
        r"no cut density between",
        "no cut density gives floats of the ash sought with this curve (the reachable ash range is in the message)",
    ),
    WarningKind(
        "classes-left-out", r"\d+ class\(es\) left out", "size classes were left out of the fit (left_out.csv)", level="note"
    ),
)

_KINDS = {kind.code: kind for kind in WARNING_KINDS}


@functools.cache
def _compiled(pattern: str) -> re.Pattern:
    return re.compile(pattern)


#: A number in a warning's words: not one that is part of a name (``x50``, ``plitt2``, ``deck_2``,
#: ``run-3``, ``chi2``), which keeps the warning's kind; a unit may follow it (``0.4mm``).
NUMBER_IN_WORDS = re.compile(r"(?<![\w.\-])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\d.])")


def code_of(message: str) -> str:
    """The code of the kind of warning ``message`` is (:data:`OTHER` when none covers it).

    Examples
    --------
    >>> code_of("the cut is not bracketed by the data (every measured partition lies below 1/2)")
    'cut-not-bracketed'
    >>> code_of("something new")
    'other'
    """
    return next((kind.code for kind in WARNING_KINDS if kind.matches(message)), OTHER)


@dataclass(frozen=True)
class Notice:
    """One occurrence of a warning: the experiment (test, survey, stream) it concerns, the
    formula or curve (empty when it concerns the data), its code and its whole message.
    The code is found from the message when not given (:func:`code_of`)."""

    subject: str
    message: str
    curve: str = ""
    code: str = field(default="")

    def __post_init__(self):
        if not self.code:
            object.__setattr__(self, "code", code_of(self.message))


def _kind_key(notice: Notice) -> str:
    """What makes two notices one kind: the code, or for a message of no known kind its words
    with the numbers left out."""
    return notice.code if notice.code != OTHER else f"{OTHER}:{NUMBER_IN_WORDS.sub('...', notice.message)}"


def level_of(code: str) -> str:
    """``"warning"``, or ``"note"`` for a kind that only says what was done (a yield estimated)."""
    kind = _KINDS.get(code)
    return kind.level if kind else "warning"


def occurrence_line(notice: Notice) -> str:
    """One occurrence as the console prints it with ``-v``: ``warning (name, formula): message``."""
    where = f"{notice.subject}, {notice.curve}" if notice.curve else notice.subject
    return f"{level_of(notice.code)} ({where}): {notice.message}"


def grouped_lines(
    notices: Iterable[Notice],
    *,
    total: int,
    noun: str = "experiments",
    intervals: bool = False,
    listed_in: str = "warnings.csv",
    labelled: bool = False,
) -> list[str]:
    """One line per kind of warning among ``notices``, in the order the kinds first occur.

    A kind met once keeps its own words: ``(name): message``.  A kind met more often is said
    once with its count out of ``total`` ``noun``, the first :data:`NAMES_SHOWN` names and
    where every occurrence is (``listed_in``; empty: no file holds them all, ``-v`` prints
    them).  The words of a known kind mention intervals only when ``intervals`` (the run
    makes them).  ``labelled``: each line begins with ``warning`` or ``note``
    (:func:`level_of`), as the console prints it.

    Examples
    --------
    >>> notices = [Notice(f"e{i}", "the cut is not bracketed by the data (a gap)") for i in range(5)]
    >>> grouped_lines(notices, total=12)  # doctest: +NORMALIZE_WHITESPACE
    ["5 of 12 experiments: the cut is not bracketed by the data: the cut size, and the d50, d25, d75 and Ep that
      rest on it, are read off the formula's shape, not off measurements (e0, e1, e2 and 2 more; every one in
      warnings.csv)"]
    """
    # per kind: its first notices (those the line can name), how many in all, and its subjects:
    # a stream of notices (a streamed batch's warnings.csv read back) is never held whole
    kinds: dict[str, tuple[list[Notice], list[int], set]] = {}
    for notice in notices:
        head, counter, subjects = kinds.setdefault(_kind_key(notice), ([], [0], set()))
        if len(head) < _NOTICES_NAMED:
            head.append(notice)
        counter[0] += 1
        subjects.add(notice.subject)
    lines = []
    for head, counter, subjects in kinds.values():
        first, count = head[0], counter[0]
        if count == 1:
            line = occurrence_line(first)
            lines.append(line if labelled else line.split(" ", 1)[1])
            continue
        kind = _KINDS.get(first.code)
        limit = NAMES_SHOWN + (len(subjects) == NAMES_SHOWN + 1)  # "and 1 more" would take the place of its name
        shown = list(dict.fromkeys(kind.named(n) if kind else n.subject for n in head[: 4 * limit]))[:limit]
        named = ", ".join(shown) + (f" and {len(subjects) - len(shown)} more" if len(subjects) > len(shown) else "")
        words = NUMBER_IN_WORDS.sub("...", first.message) if kind is None else kind.summary
        if kind is not None and intervals and kind.intervals:
            words += f"; {kind.intervals}"
        counted = f"{len(subjects)} of {total} {noun}" + (f" ({count} times)" if count > len(subjects) else "")
        label = f"{level_of(first.code)}: " if labelled else ""
        where = f"every one in {listed_in}" if listed_in else "-v prints every one"
        lines.append(f"{label}{counted}: {words} ({named}; {where})")
    return lines


def notice_table(notices: Iterable[Notice], *, subject: str = "experiment", curve: str = "formula"):
    """The rows of ``warnings.csv``: one per notice, columns ``subject, curve, code, message``
    named ``subject`` and ``curve`` for the face (``experiment, formula`` by default)."""
    import pandas as pd

    rows = [(n.subject, n.curve, n.code, n.message) for n in notices]
    return pd.DataFrame(rows, columns=[subject, curve, "code", "message"]).astype(object)


class _Subjects:
    """The subjects of a :func:`regroup_warnings` block, each with the number of warnings
    caught before it began, so that a warning is taken as the subject's during which it came."""

    def __init__(self, caught: list):
        self._caught = caught
        self.starts: list[tuple[int, str]] = []

    def begin(self, subject: str) -> None:
        """The warnings from now on concern ``subject``."""
        self.starts.append((len(self._caught), subject))

    def of(self, index: int) -> str:
        """The subject of the ``index``-th warning caught ("" before the first subject)."""
        return next((subject for start, subject in reversed(self.starts) if start <= index), "")


@contextlib.contextmanager
def regroup_warnings(category: type[Warning], *, noun: str = "experiments", stacklevel: int = 2) -> Iterator[_Subjects]:
    """Collect the warnings of ``category`` raised inside the block and warn once per kind
    when it ends (:func:`grouped_lines`); other warnings are warned again unchanged.

    The block calls ``begin(name)`` on what it gets before the work of each subject (an
    experiment), so that each warning is counted as that subject's.  A message is expected as
    ``"<source>: <note>"``; a kind met once is warned again in its own words.  ``stacklevel``
    is that of the function holding the block, as :func:`warnings.warn` takes it.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", category)
        subjects = _Subjects(caught)
        yield subjects  # an error raised here ends the block unwarned: the error is what the caller must see
    _warn_again(caught, subjects, category, noun=noun, stacklevel=stacklevel + 3)


def _warn_again(caught, subjects: _Subjects, category, *, noun: str, stacklevel: int) -> None:
    """The warnings ``caught`` inside :func:`regroup_warnings`, warned again outside it."""
    by_source: dict[str, list[Notice]] = {}
    for index, message in enumerate(caught):
        if not issubclass(message.category, category):
            warnings.warn_explicit(message.message, message.category, message.filename, message.lineno)
            continue
        source, _, note = str(message.message).partition(": ")
        by_source.setdefault(source, []).append(Notice(subjects.of(index), note))
    total = len({subject for _, subject in subjects.starts})
    for source, notices in by_source.items():
        kinds: dict[str, list[Notice]] = {}
        for notice in notices:
            kinds.setdefault(_kind_key(notice), []).append(notice)
        for members in kinds.values():
            if len(members) == 1:
                warnings.warn(f"{source}: {members[0].message}", category, stacklevel=stacklevel)
                continue
            (line,) = grouped_lines(members, total=total, noun=noun, listed_in="warnings.csv of a results folder")
            warnings.warn(
                f"{source}: {line}; each experiment's note is in its mass balance's notes", category, stacklevel=stacklevel
            )
