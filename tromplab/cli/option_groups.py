"""Option groups declared once and shared by several commands: the lab-table options, the
options of ``fit`` and ``report``, ``--water-recovery``, ``--partition-to``, the scale and
uncertainty options, and the lab options turned into :class:`~tromplab.loading.lab.LabOptions`."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import OptionError
from ..options import (
    BOOTSTRAP_METHODS,
    DEFAULT_ALPHA,
    DEFAULT_MIN_FEED_SHARE,
    DEFAULT_SUM_TOLERANCE_PCT,
    KINDS,
    PARTITION_METHODS,
    PARTITION_TO,
    RANK_BY,
    WEIGHTINGS,
)
from ..validation import (
    MAX_BOOTSTRAP,
    MAX_JOBS,
    SIZE_LIMITS,
    check_bootstrap,
    check_count,
    check_probability,
    check_range,
    check_seed,
    check_share,
    check_size,
    check_water_recovery,
    cli_type,
)

if TYPE_CHECKING:
    from ..loading.lab import LabOptions

#: The modules each command imports when it runs (its functions' own imports), imported by
#: main() before the command starts; the readers of lab tables estimate a yield with numpy
#: alone (they imported statsmodels, and with it scipy.stats, before).
READERS = ("tromplab.loading.lab", "tromplab.loading.tables")


def shared_groups() -> dict[str, argparse.ArgumentParser]:
    """The parent parsers of the commands: ``lab`` options, ``shared`` options of fit and report, ``water``."""
    return {"lab": lab_options_parser(), "shared": fit_options_parser(), "water": water_recovery_parser()}


def fit_options_parser() -> argparse.ArgumentParser:
    """Options shared by ``fit`` and ``report``, declared once."""
    shared = argparse.ArgumentParser(add_help=False)
    shared.add_argument("input", type=Path, help="Tromp points or a lab table (CSV or .xlsx), told apart by their columns")
    shared.add_argument(
        "--alpha",
        type=cli_type(check_probability, "--alpha"),
        default=DEFAULT_ALPHA,
        help="significance level of the Fisher screen, in (0, 1) (default %(default)s)",
    )
    shared.add_argument(
        "--delta-max",
        type=cli_type(check_size, "--delta-max"),
        default=None,
        help="largest feed particle size for the misplacement eps, at most 1e9 times the smallest size of "
        "an experiment (default: largest size of the data)",
    )
    shared.add_argument(
        "--formulas",
        default=None,
        help="comma-separated ids or equation numbers; 'paper' = the nine, 'extended' = the bypass and "
        "fish-hook curves (default: the nine)",
    )
    shared.add_argument("--rank-by", choices=sorted(RANK_BY), default="F", help="criterion within an experiment")
    shared.add_argument("--size-unit", default="", help="unit of the sizes, for the figure labels")
    shared.add_argument(
        "--extended",
        action="store_true",
        help="also fit the curves with bypass and fish-hook (reported, kept out of the ranking)",
    )
    shared.add_argument("--rank-extended", action="store_true", help="rank the extended curves with the nine")
    return shared


def water_recovery_parser() -> argparse.ArgumentParser:
    """``--water-recovery`` of ``fit``, ``report`` and ``points``, declared once."""
    water = argparse.ArgumentParser(add_help=False)
    water.add_argument(
        "--water-recovery",
        type=cli_type(check_water_recovery, "--water-recovery"),
        default=None,
        metavar="RF",
        help="hydrocyclones: share of the feed water reporting to the underflow, in [0, 1); gives the "
        "Kelsall-corrected partition (points) and compares the fitted bypass with it (fit, report)",
    )
    return water


def add_partition_to(parser) -> None:
    parser.add_argument(
        "--partition-to",
        choices=PARTITION_TO,
        default="fine",
        help="report the partition to the fine product (default) or to the coarse product (underflow, oversize)",
    )


def add_jobs_option(group) -> None:
    group.add_argument(
        "--jobs",
        type=cli_type(check_count, "--jobs", minimum=0, maximum=MAX_JOBS),
        default=0,
        metavar="N",
        help="worker processes (default 0: all cores)",
    )


def add_dask_options(group) -> None:
    """``--scheduler`` and ``--dask``: the batch on a Dask cluster (:func:`tromplab.parallel.dask_client`)."""
    group.add_argument("--scheduler", default=None, metavar="ADDRESS", help="run on this Dask scheduler (tcp://host:8786)")
    group.add_argument("--dask", choices=("local",), default=None, help="run on a local Dask cluster")


def add_scale_options(scale) -> None:
    add_jobs_option(scale)
    add_dask_options(scale)
    scale.add_argument(
        "--single-fits",
        action="store_true",
        help="fit one experiment and formula at a time with lmfit instead of the batched engine",
    )


def add_uncertainty_options(uncertainty) -> None:
    uncertainty.add_argument(
        "--ci",
        type=cli_type(check_probability, "--ci"),
        default=None,
        metavar="LEVEL",
        help="add interval columns at this level (profile likelihood for parameters, delta method for indices)",
    )
    uncertainty.add_argument(
        "--bootstrap",
        type=cli_type(check_bootstrap, "--bootstrap"),
        default=0,
        metavar="N",
        help=f"add bootstrap percentile intervals from N resamples (at most {MAX_BOOTSTRAP:,})",
    )
    uncertainty.add_argument(
        "--bootstrap-method",
        choices=BOOTSTRAP_METHODS,
        default="residuals",
        help="resample the residuals of the fit or whole points (default: residuals)",
    )
    uncertainty.add_argument(
        "--seed",
        type=cli_type(check_seed, "--seed"),
        default=0,
        help="seed of the bootstrap, a whole number >= 0: the same seed gives the same intervals (default %(default)s)",
    )


def lab_options_parser() -> argparse.ArgumentParser:
    """The options of a lab table (``fit``, ``report``, ``compare``, ``trend``, ``points``, ``balance``)."""
    lab = argparse.ArgumentParser(add_help=False)
    group = lab.add_argument_group("lab data (schema: docs/lab_tables.md)")
    _add_balance_options(group)
    _add_reading_options(group)
    return lab


def _add_balance_options(group) -> None:
    """What the streams hold and how the balance is closed: kind, yields, left-out classes, open classes."""
    group.add_argument(
        "--kind",
        choices=KINDS,
        default=None,
        help="what plain feed/fine/coarse columns hold (not needed with suffixed column names)",
    )
    group.add_argument(
        "--fine-yield",
        type=cli_type(check_probability, "--fine-yield"),
        default=None,
        help="fine-product yield, fraction of the feed",
    )
    group.add_argument(
        "--coarse-yield",
        type=cli_type(check_probability, "--coarse-yield"),
        default=None,
        help="coarse-product yield, fraction of the feed",
    )
    group.add_argument("--estimate-yield", action="store_true", help="estimate the yield from three streams even if one is given")
    group.add_argument("--reconcile", action="store_true", help="adjust the three streams minimally so every class balances")
    group.add_argument(
        "--min-feed-share",
        type=cli_type(check_share, "--min-feed-share"),
        default=DEFAULT_MIN_FEED_SHARE,
        help="leave out classes with a smaller feed share (fraction; default %(default)s)",
    )
    group.add_argument(
        "--sum-tolerance",
        type=cli_type(check_range, "--sum-tolerance", low=0.0, high=100.0),
        default=DEFAULT_SUM_TOLERANCE_PCT,
        help="allowed deviation of per-class percentages from 100 (percentage points; default %(default)s)",
    )
    group.add_argument(
        "--top-size", type=cli_type(check_size, "--top-size"), default=None, help="upper bound of the open top class"
    )
    group.add_argument(
        "--pan-lower-size",
        type=cli_type(check_range, "--pan-lower-size", low=0.0, high=SIZE_LIMITS[1]),
        default=None,
        help="lower bound of the pan",
    )


def _add_reading_options(group) -> None:
    """How the table is read and its points weighted: renames, sheet, weights, partition method, CSV dialect."""
    group.add_argument("--rename", default="", help="column renames OLD=NEW,OLD=NEW applied before reading")
    group.add_argument("--sheet", default=None, help="Excel sheet name (default: the first sheet)")
    group.add_argument(
        "--weight-by-feed-share",
        action="store_true",
        help="weight each point by its class's feed share (variance inversely proportional to it)",
    )
    group.add_argument(
        "--weighting",
        choices=WEIGHTINGS,
        default="none",
        help="how the points are weighted in the fit: every class alike (default), by its feed share (as "
        "--weight-by-feed-share), or by the inverse variance of its partition under the error model of the size "
        "analyses with a floor relative to the feed share (as tromplab circuit --fit weights them)",
    )
    group.add_argument(
        "--partition-from",
        choices=PARTITION_METHODS,
        default="products",
        help="with three streams: partition from both products y b/(y b + (1-y) c) (default; swapping fine "
        "and coarse gives 1 - partition) or from the fine stream over the measured feed y b/a",
    )
    group.add_argument("--sep", default=None, help="CSV field separator, e.g. ';' (default: detected from the header)")
    group.add_argument("--decimal", default=None, help="CSV decimal mark, e.g. ',' (default: '.', or ',' when detected)")


def lab_options(args) -> LabOptions:
    from ..loading.lab import LabOptions

    rename = {}
    for pair in filter(None, (p.strip() for p in args.rename.split(","))):
        old, sep, new = pair.partition("=")
        if not sep or not old.strip() or not new.strip():
            raise OptionError("--rename", f"takes OLD=NEW pairs separated by commas, got {pair!r}")
        rename[old.strip()] = new.strip()
    return LabOptions(
        kind=args.kind,
        fine_yield=args.fine_yield,
        coarse_yield=args.coarse_yield,
        estimate_yield=args.estimate_yield,
        reconcile=args.reconcile,
        min_feed_share=args.min_feed_share,
        sum_tolerance_pct=args.sum_tolerance,
        top_size=args.top_size,
        pan_lower_size=args.pan_lower_size,
        rename=rename,
        sheet=args.sheet,
        weight_by_feed_share=args.weight_by_feed_share,
        partition_from=args.partition_from,
        size_unit=getattr(args, "size_unit", None) or None,
        sep=args.sep,
        decimal=args.decimal,
        water_recovery=getattr(args, "water_recovery", None),
        weighting=args.weighting,
    )
