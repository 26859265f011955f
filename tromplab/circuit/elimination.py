r"""Gross errors that the balances can name: serial elimination with compensation, the nodal
test, and measurements left out on request.

**Serial elimination with compensation** (Serth & Heenan 1986; Narasimhan & Mah 1987): while
the global chi-square test rejects, the measurement with the largest generalised likelihood
ratio test gets a bias, estimated from all adjustments (:math:`\hat b_j`, the ``gross_error``
of the adjustments table), its raw value is corrected by it (a share of a closed analysis
moves the whole analysis, :math:`\hat b_j P e_j`), the survey is reconciled again, and the
chi-square is compared with one degree of freedom fewer (the bias is a parameter).  Each step
is a row of :func:`serial_elimination`; measurements whose tests are indistinguishable are
one group (the bias of one stands for them all: no test can tell which it is).  Nothing is
applied to the reported balance: the steps are a proposal, said in words, and
``exclude=`` (``--exclude STREAM[:WHAT]``) reconciles again without the named measurements.

**The nodal test** (Mah, Stanley & Downing 1976): the imbalance of each node and each class
balance in the raw data, :math:`e = \sum_s M_{ks} \hat F_s x_{s,i}` with the measured shares
and the reconciled flows, divided by its standard deviation from the measurements' errors.
A node whose classes are all imbalanced points at a stream missing from the flowsheet or a
sample labelled with the wrong stream.

References
----------
Mah, R. S. H., Stanley, G. M. & Downing, D. M. (1976). Reconciliation and rectification of
process flow and inventory data. *Ind. Eng. Chem. Process Des. Dev.* 15(1), 175-183.

Narasimhan, S. & Mah, R. S. H. (1987). Generalized likelihood ratio method for gross error
identification. *AIChE Journal* 33(9), 1514-1521.

Serth, R. W. & Heenan, W. A. (1986). Gross error detection and data reconciliation in
steam-metering systems. *AIChE Journal* 32(5), 733-742.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ..errors import OptionError
from ..statistics.distributions import chi2_sf, norm_isf, norm_sf
from .adjustments import ranked_by_test
from .measurements import Survey, class_name

#: Columns of the elimination table (``DIR/elimination.csv``).
ELIMINATION_COLUMNS = ["step", "stream", "kind", "size_class", "estimated_error", "estimated_error_sd", "chi_square", "dof",
                       "p_value", "measurement", "indistinguishable_from"]  # fmt: skip
#: Columns of the nodal-test table (``DIR/nodal_tests.csv``).
NODAL_COLUMNS = ["node", "balance", "size_class", "imbalance", "imbalance_sd", "nodal_test", "p_value", "suspect"]
#: What ``--exclude STREAM:WHAT`` names besides a size class.
EXCLUDE_KINDS = {"flow": "flow", "pct_solids": "pct"}
_KIND_NAMES = {"share": "share", "flow": "flow", "pct": "pct_solids"}


def serial_elimination(balance, reconcile, *, max_steps: int | None = None, progress=None) -> pd.DataFrame:
    """The steps of serial elimination with compensation, from the reconciled ``balance``.

    Row 0 is the survey as reconciled; row k names the measurement compensated at step k,
    its estimated error (measured - true) and sd, and the global test after the step.  The
    steps stop when the test passes, no redundancy is left, or no measurement is testable.

    Parameters
    ----------
    balance : CircuitBalance
    reconcile : callable
        ``reconcile(previous, survey)``: the compensated ``survey`` reconciled, ``previous`` the
        balance of the step before (its start; :class:`~tromplab.circuit.reconciliation.CircuitBalance`
        passes a warm-started reconciliation that computes what the steps read).
    max_steps : int, optional
        At most this many steps (default: as many as the redundancy allows).
    progress : callable, optional
        ``progress(step, limit, "elimination: step k")`` before each step's reconciliation.

    Returns
    -------
    pandas.DataFrame
        :data:`ELIMINATION_COLUMNS`.
    """
    rows = [_row(0, None, balance.chi_square, balance.dof)]
    current, dof = balance, balance.dof
    limit = balance.dof if max_steps is None else min(max_steps, balance.dof)
    for step in range(1, limit + 1):
        if dof <= 0 or chi2_sf(current.chi_square, dof) > current.alpha:
            break
        table = current.adjustments_table().dropna(subset=["measurement_test"])
        if table.empty:
            break
        j = ranked_by_test(table).index[0]  # the largest test; of tied ones, the first in the file
        suspect = table.loc[j]
        survey = _compensated(current, j, float(suspect["gross_error"]))
        if progress is not None:
            progress(step - 1, limit, f"elimination: step {step}")
        current = reconcile(current, survey)
        dof -= 1
        rows.append(_row(step, suspect, current.chi_square, dof))
    return pd.DataFrame(rows, columns=ELIMINATION_COLUMNS)


def _row(step: int, suspect, chi_square: float, dof: int) -> dict:
    p_value = float(chi2_sf(chi_square, dof)) if dof > 0 else float("nan")
    row = {"step": step, "chi_square": chi_square, "dof": dof, "p_value": p_value}
    if suspect is None:
        return row | {"stream": "", "kind": "", "size_class": "", "measurement": "(as reconciled)", "indistinguishable_from": ""}
    kind = "share" if suspect["class_index"] >= 0 else "flow" if suspect["class_index"] == -1 else "pct"
    component = suspect.get("component", "")
    return row | {
        "stream": suspect["stream"],
        "kind": f"assay_{component}_pct" if component else _KIND_NAMES[kind],
        "size_class": suspect["measurement"].split(" class ", 1)[1] if kind == "share" else "",
        "estimated_error": float(suspect["gross_error"]),
        "estimated_error_sd": float(suspect["gross_error_sd"]),
        "measurement": suspect["measurement"],
        "indistinguishable_from": suspect["indistinguishable_from"],
    }


def _compensated(balance, j: int, bias: float) -> Survey:
    """The survey of ``balance`` with raw measurement ``j`` corrected by ``bias``: every reported
    value it moves (its whole analysis when closed) moves back by ``bias`` times its effect."""
    problem = balance.problem
    effect = problem.effects[:, [j]].toarray().ravel() if getattr(problem, "is_sparse", False) else problem.effects[:, j]
    values = problem.y - bias * effect
    survey = balance.survey
    shares, flows, pct, assays = survey.shares.copy(), survey.flows.copy(), survey.pct_solids.copy(), survey.assays.copy()
    parts = [(shares, shares["sd"] > 0), (flows, flows["sd"] > 0), (pct, pct["sd"] > 0), (assays, assays["sd"] > 0)]
    start = 0
    for table, used in parts:
        count = int(used.sum())
        table.loc[used.to_numpy(), "value"] = values[start : start + count]
        start += count
    # said once however many measurements were compensated: the source names the file in messages
    source = survey.source if survey.source.endswith(" (compensated)") else f"{survey.source} (compensated)"
    return dataclasses.replace(survey, shares=shares, flows=flows, pct_solids=pct, assays=assays, source=source)


def proposal(table: pd.DataFrame, alpha: float) -> str:
    """The elimination steps in words, with the ``--exclude`` that would act on them; "" when
    the survey passes the global test as reconciled."""
    if len(table) <= 1:
        return ""
    steps = table.iloc[1:]
    listed = "; ".join(
        f"{r.measurement} (estimated error {r.estimated_error:+.3g} +/- {r.estimated_error_sd:.2g}"
        + (f", indistinguishable from {r.indistinguishable_from}" if r.indistinguishable_from else "")
        + ")"
        for r in steps.itertuples()
    )
    last = steps.iloc[-1]
    verdict = (
        f"after it the global test passes (chi-square {last.chi_square:.3g} on {int(last.dof)} dof, p = {last.p_value:.3g})"
        if np.isfinite(last.p_value) and last.p_value > alpha
        else "the global test still rejects after it"
    )
    names = ",".join(exclusion_name(r.stream, r.kind, r.size_class) for r in steps.itertuples())
    return (
        f"serial elimination proposes {len(steps)} gross error(s): {listed}; {verdict}. Nothing was changed: "
        f"to reconcile without them, run again with --exclude {names} (Python: exclude=[...])"
    )


def exclusion_name(stream: str, kind: str, size_class: str) -> str:
    """``STREAM:WHAT`` as ``--exclude`` reads it (``flow``, ``pct_solids``, the size class, or
    ``assay_NAME_pct:CLASS`` for an assay)."""
    if kind.startswith("assay_"):
        return f"{stream}:{kind}:{size_class}"
    return f"{stream}:{size_class if kind == 'share' else kind}"


def without(survey: Survey, exclude, stream_names, class_names) -> Survey:
    """``survey`` without the measurements named in ``exclude``: ``STREAM`` (all of the stream's),
    ``STREAM:flow``, ``STREAM:pct_solids``, ``STREAM:CLASS`` (a size class as the tables name
    it, ``-150+75``) or ``STREAM:assay_NAME_pct[:CLASS]`` (a component's assays).  A stream losing a class is no longer a closed analysis.

    Raises
    ------
    OptionError
        Naming the entry of ``exclude`` that names no measurement of the survey.
    """
    if isinstance(exclude, str):
        exclude = [part for part in exclude.split(",") if part.strip()]
    shares, flows, pct = survey.shares, survey.flows, survey.pct_solids
    closed = set(survey.closed_streams)
    assays = [str(entry).strip() for entry in exclude if ":assay_" in str(entry)]
    if assays:
        survey = _without_assays(survey, assays, class_names)
    for entry in exclude:
        text = str(entry).strip()
        if text in assays:
            continue
        stream, what = (text, "") if text in stream_names else (text.rsplit(":", 1) + [""])[:2]
        if stream not in stream_names:
            raise OptionError("exclude", f"names {text!r}: no stream {stream!r} in the flowsheet ({', '.join(stream_names)})")
        before = len(shares) + len(flows) + len(pct)
        if what in ("", "flow"):
            flows = flows[flows["stream"] != stream]
        if what in ("", "pct_solids"):
            pct = pct[pct["stream"] != stream]
        if what not in EXCLUDE_KINDS:
            if what and what not in class_names:
                raise OptionError("exclude", f"names {text!r}: no size class {what!r} (classes {', '.join(class_names)})")
            drop = (shares["stream"] == stream) & (True if not what else shares["class_index"] == class_names.index(what))
            shares = shares[~drop]
            closed.discard(stream)
        if not what:  # the whole stream: its assays too
            survey = dataclasses.replace(survey, assays=survey.assays[survey.assays["stream"] != stream])
        if len(shares) + len(flows) + len(pct) == before:
            raise OptionError("exclude", f"names {text!r}, which the survey does not measure")
    kept = tuple(s for s in survey.closed_streams if s in closed)
    return dataclasses.replace(survey, shares=shares, flows=flows, pct_solids=pct, closed_streams=kept)


def _without_assays(survey: Survey, exclude, class_names) -> Survey:
    """``survey`` without the assays named ``STREAM:assay_NAME_pct`` (every class) or
    ``STREAM:assay_NAME_pct:CLASS``."""
    assays = survey.assays
    for text in exclude:
        stream, what = text.split(":", 1)
        column, size_class = (what.split(":", 1) + [""])[:2]
        component = column[len("assay_") : -len("_pct")] if column.endswith("_pct") else ""
        if component not in survey.components:
            raise OptionError("exclude", f"names {text!r}: no assay column {column!r} in the survey")
        if size_class and size_class not in class_names:
            raise OptionError("exclude", f"names {text!r}: no size class {size_class!r} (classes {', '.join(class_names)})")
        drop = (assays["stream"] == stream) & (assays["component"] == component)
        if size_class:
            drop &= assays["class_index"] == class_names.index(size_class)
        if not drop.any():
            raise OptionError("exclude", f"names {text!r}, which the survey does not measure")
        assays = assays[~drop]
    return dataclasses.replace(survey, assays=assays)


def nodal_tests(balance) -> pd.DataFrame:
    r"""The nodal test of every class balance (separators and junctions) and every total
    balance whose streams are all measured: the imbalance of the raw data at the reconciled
    flows and its standardised value, compared with the Sidak-corrected normal quantile.

    Returns
    -------
    pandas.DataFrame
        :data:`NODAL_COLUMNS`; ``balance`` is ``class`` or ``total``.
    """
    survey, sheet = balance.survey, balance.flowsheet
    flows = balance.flows
    measured = {(r.stream, r.class_index): (r.value, r.sd) for r in survey.shares.itertuples()}
    measured_flows = {r.stream: (r.value, r.sd) for r in survey.flows.itertuples()}
    rows = []
    for node in sheet.nodes:
        streams = [*node.inputs, *node.outputs]
        signs = [1.0] * len(node.inputs) + [-1.0] * len(node.outputs)
        if node.balances_classes:
            for i in range(survey.n_classes):
                if all((s, i) in measured for s in streams):
                    terms = [(sign * flows[sheet.stream_index[s]], *measured[(s, i)]) for s, sign in zip(streams, signs)]
                    rows.append(_nodal_row(node.name, "class", class_name(survey.classes, i), terms))
        if all(s in measured_flows for s in streams):
            terms = [(sign, *measured_flows[s]) for s, sign in zip(streams, signs)]
            rows.append(_nodal_row(node.name, "total", "", terms))
    table = pd.DataFrame(rows, columns=NODAL_COLUMNS)
    if len(table):
        level = 1.0 - (1.0 - balance.alpha) ** (1.0 / len(table))
        table["suspect"] = table["nodal_test"].abs() > norm_isf(level / 2.0)
    return table


def _nodal_row(node: str, kind: str, size_class: str, terms) -> dict:
    imbalance = sum(weight * value for weight, value, _ in terms)
    sd = float(np.sqrt(sum((weight * spread) ** 2 for weight, _, spread in terms)))
    test = imbalance / sd if sd > 0 else float("nan")
    p_value = 2.0 * norm_sf(abs(test)) if np.isfinite(test) else float("nan")
    return {"node": node, "balance": kind, "size_class": size_class, "imbalance": imbalance, "imbalance_sd": sd,
            "nodal_test": test, "p_value": p_value, "suspect": False}  # fmt: skip
