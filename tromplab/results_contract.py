"""The contract every public result class follows, and the mixin that gives the shared part of it.

A result (:class:`~tromplab.CurveFit`, :class:`~tromplab.Workbench`,
:class:`~tromplab.circuit.CircuitBalance`, :class:`~tromplab.density.DensityResult`, ...)
documents its attributes in one numpydoc ``Attributes`` block and offers these verbs, each
with one meaning (as lmfit's ``ModelResult`` and scikit-learn's estimators do):

``summary()``
    A :class:`pandas.DataFrame`: one row per fit, experiment, curve, stream or survey (as
    suits the class), the numbers a reader looks at first.
``report()``
    Human-readable text: what was fitted or computed, its numbers and what the reader must
    know about them.
``_repr_html_()``
    HTML for notebooks: a line of context and the summary as a table (names escaped).
``to_frame()``
    The main table of the result (the one its command writes as its main file, where there
    is a command).
``save(directory)``
    Only where a command writes a folder: the files that command writes, all or nothing.

Pickles carry the tromplab version that wrote them; unpickling one written by another
version warns with :class:`~tromplab.errors.InconsistentVersionWarning` (a warning, not an
error: the records are plain data and usually load fine, but what is derived from them on
first use may differ).  A pickle without a stamp (written before results were stamped) loads
without a warning: there is no version to compare.

This module sits in the foundation layer, so every layer's result classes can use it; it
imports neither numpy nor pandas at module level.
"""

from __future__ import annotations

import warnings

from ._version import __version__
from .errors import InconsistentVersionWarning

#: Key of the tromplab version in the pickled state of a result.
VERSION_KEY = "_tromplab_version"

#: Rows of the summary shown by the notebook view before it is cut (pandas' ``max_rows``).
HTML_MAX_ROWS = 30


def summary_html(table, context: str) -> str:
    """HTML for a notebook: ``context`` as a line above ``table`` (every name escaped).

    Parameters
    ----------
    table : pandas.DataFrame
        The table shown (at most :data:`HTML_MAX_ROWS` rows, then cut by pandas).
    context : str
        One line saying what the table is.

    Returns
    -------
    str
    """
    import html  # a notebook's display only

    shown = table.to_html(index=False, escape=True, na_rep="", max_rows=HTML_MAX_ROWS, border=0)
    return f'<div class="tromplab-result">\n<p><b>{html.escape(context)}</b></p>\n{shown}\n</div>'


def parameters_frame(fit):
    """One row per fitted parameter of ``fit`` (a :class:`~tromplab.curves.fitting.ParameterFit`):
    ``parameter, value, stderr``, then ``ssr`` and ``success`` of the fit on every row."""
    import pandas as pd

    rows = [
        {"parameter": name, "value": value, "stderr": fit.stderr.get(name, float("nan")), "ssr": fit.ssr, "success": fit.success}
        for name, value in fit.values.items()
    ]
    return pd.DataFrame(rows, columns=["parameter", "value", "stderr", "ssr", "success"])


def check_version(result_class: str, saved_version: str | None) -> None:
    """Warn with :class:`~tromplab.errors.InconsistentVersionWarning` when ``saved_version``
    (the stamp of a pickle; None: no stamp) is not this tromplab's version."""
    if saved_version is not None and saved_version != __version__:
        warnings.warn(
            InconsistentVersionWarning(result_class=result_class, saved_version=str(saved_version), current_version=__version__),
            stacklevel=3,
        )


class ResultContract:
    """The shared verbs of a result class (mixin); see the module docstring for the contract.

    A subclass defines :meth:`summary` and ``_result_context()`` (one line saying what the result is); the notebook view, the default
    :meth:`report` and :meth:`to_frame` and the version-stamped pickling come from here.
    A subclass with a richer text or table overrides :meth:`report` or :meth:`to_frame`.
    """

    __slots__ = ()

    def summary(self):
        """One row per fit, experiment, curve or stream: a :class:`pandas.DataFrame`."""
        raise NotImplementedError(f"{type(self).__name__} defines summary()")

    def _result_context(self) -> str:
        """One line saying what the result is (the heading of :meth:`report` and of the notebook view)."""
        return type(self).__name__

    def report(self) -> str:
        """The line of context and the :meth:`summary` as text."""
        table = self.summary().to_string(index=False, float_format=lambda value: f"{value:.4g}", na_rep="-")
        return f"{self._result_context()}\n{table}"

    def to_frame(self):
        """The main table of the result (here: the :meth:`summary`)."""
        return self.summary()

    def _repr_html_(self) -> str:
        return summary_html(self.summary(), self._result_context())

    # --- pickling: the version stamped into the state, checked on load ----------------------------
    def __getstate__(self):
        state = super().__getstate__()
        if not isinstance(state, dict):  # results keep their fields in __dict__
            raise TypeError(f"{type(self).__name__} keeps no __dict__ to stamp the version into")
        return {**state, VERSION_KEY: __version__}

    def __setstate__(self, state: dict) -> None:
        state = dict(state)
        check_version(type(self).__name__, state.pop(VERSION_KEY, None))
        self.__dict__.update(state)  # as the default unpickling does (frozen dataclasses too)
