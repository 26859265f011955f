"""``tromplab density predict`` as a Python function: :func:`predict_density` returns a
:class:`DensityPrediction` whose ``save(output, table=...)`` writes the command's files, byte for
byte what the command line writes (it calls them).

The products a density separator with a given partition curve makes of a feed of known
washability: yield and ash of floats and sinks, the theoretical yield at the same ash and the
organic efficiency (:func:`tromplab.density.washability.predict`), one row per feed and cut
density; with ``target_ash_pct`` the cut density giving floats of that ash.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from ..errors import OptionError
from ..options import DEFAULT_SUM_TOLERANCE_PCT
from ..output.outputs import check_output_file, write_files
from ..results_contract import ResultContract


@dataclass(frozen=True)
class DensityPrediction(ResultContract):
    """What ``tromplab density predict`` makes of a washability table.

    Attributes
    ----------
    predictions : pandas.DataFrame
        One row per feed and cut density (columns
        :data:`~tromplab.density.washability.PREDICTION_COLUMNS`): the ``-o`` file.
    washability : pandas.DataFrame
        The feeds' washability tables (cumulative floats and sinks, near-gravity material;
        :meth:`~tromplab.density.washability.Washability.cumulative_table`): the ``--table`` file.
    source : path or None
        The washability file read (no output may overwrite it).
    """

    predictions: pd.DataFrame = field(repr=False)
    washability: pd.DataFrame = field(repr=False)
    source: object = None

    def summary(self) -> pd.DataFrame:
        """The predictions, one row per feed and cut density."""
        return self.predictions

    def _result_context(self) -> str:
        return f"Density separation predicted for the washability of {self.source}"

    def save(self, output, *, table=None) -> dict:
        """Write the predictions to the CSV file ``output`` (the command's ``-o``) and, with
        ``table``, the washability tables to that CSV file (``--table``); each file is replaced
        in one step.  Returns ``{file name: path}``."""
        output, table = check_prediction_files(output, table, source=self.source)
        written = _write_csv(self.predictions, output)
        if table is not None:
            written.update(_write_csv(self.washability, table))
        return written


def check_prediction_files(output, table=None, *, source=None) -> tuple[Path, Path | None]:
    """``output`` and ``table`` as paths, refused (:class:`~tromplab.errors.OutputError`,
    :class:`~tromplab.errors.OptionError`) before any work when they cannot be written, name the
    input ``source`` or the same file."""
    inputs = [] if source is None else [source]
    output = check_output_file(output, inputs=inputs, option="output")
    if table is not None:
        table = check_output_file(table, inputs=inputs, option="table")
        if Path(table).resolve() == Path(output).resolve():
            raise OptionError("table", "names the same file as output")
    return output, table


def predict_density(
    washability,
    *,
    curve: str = "normal",
    rho50=None,
    ep: float | None = None,
    light_limit: float | None = None,
    heavy_limit: float | None = None,
    target_ash_pct=None,
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT,
    float_lower_density: float | None = None,
    sink_upper_density: float | None = None,
) -> DensityPrediction:
    """Predict the products of every feed in ``washability``: what ``tromplab density predict``
    does, its options as keywords of the same names.

    Parameters
    ----------
    washability : path
        The washability table(s) (:func:`tromplab.density.washability.read_washability`).
    curve, rho50, ep, light_limit, heavy_limit, target_ash_pct
        As for :func:`tromplab.density.washability.predict` (``--curve``, ``--rho50``,
        ``--ep``, ``--light-limit``, ``--heavy-limit``, ``--target-ash``).
    sum_tolerance_pct, float_lower_density, sink_upper_density
        As for :func:`~tromplab.density.washability.read_washability` (``--sum-tolerance``,
        ``--float-lower-density``, ``--sink-upper-density``).

    Returns
    -------
    DensityPrediction
        Its ``save(output, table=...)`` writes the command's files.

    Notes
    -----
    Bad input ends in an :class:`~tromplab.errors.InputError` before anything is written.
    """
    from ..loading.tables import check_input_file
    from .washability import predict, read_washability

    check_input_file(washability)
    tables = read_washability(
        washability, sum_tolerance_pct=sum_tolerance_pct, float_lower_density=float_lower_density,
        sink_upper_density=sink_upper_density,
    )  # fmt: skip
    predictions = predict(tables, curve=curve, rho50=rho50, ep=ep, light_limit=light_limit, heavy_limit=heavy_limit,
                          target_ash_pct=target_ash_pct)  # fmt: skip
    cumulative = pd.concat([table.cumulative_table() for table in tables], ignore_index=True)
    return DensityPrediction(predictions, cumulative, washability)


def _write_csv(table, path: Path) -> dict:
    from ..output.csv_parts import write_csv

    path.absolute().parent.mkdir(parents=True, exist_ok=True)
    written = write_files({path.name: lambda target: write_csv(table, target)}, path.absolute().parent)
    return {name: path.parent / name for name in written}  # as given (relative), as the other commands print it
