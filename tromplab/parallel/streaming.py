"""When a batch streams its results to disk: one rule, for every command that streams.

A streamed batch writes its tables chunk by chunk as the workers finish them, so the main
process holds no fit and its memory does not grow with the batch; the files are the same as
those of a batch held in memory.  :func:`streams` is the only place that decides it:
``tromplab fit`` asks it twice, once before reading its input (whether to read a large CSV
file in pieces, from its size) and once with the experiments counted (whether to stream);
``tromplab density fit`` once, with the tests (and size fractions) counted
(:func:`tromplab.density.streamed.fit_density_to_folder`).
"""

from __future__ import annotations

from ..options import AUTO_FIGURE_LIMIT

#: Items (experiments, density tests) from which a batch streams when the caller does not say: below it the
#: results stay in memory, where every method of the result is at hand without refitting.
STREAM_THRESHOLD = 1000

#: Size of a CSV input that stands for a batch of :data:`STREAM_THRESHOLD` items or more before
#: they are counted: a points file of 1 MiB holds about 2,000 experiments of 20 sizes.  Below it
#: a file is read whole (reading it in pieces costs a second reading).
IN_PIECES_FROM_BYTES = 1 << 20


def streams(
    count: int | None,
    *,
    tables_only: bool,
    figures: str,
    stream: bool | None = None,
    input_bytes: int | None = None,
) -> bool:
    """Whether a batch of ``count`` items streams its results to disk.

    It streams when its outputs can be written chunk by chunk and it is large (or ``stream`` is
    True).  The outputs can stream when they are CSV tables only (``tables_only``: no workbook,
    no parquet, no reloadable pickle) and the figures need no fit kept: ``figures`` ``"none"``,
    or ``"auto"`` above :data:`~tromplab.options.AUTO_FIGURE_LIMIT` items, which draws one
    overview from the top-ranked rows.  It is large from :data:`STREAM_THRESHOLD` items; before
    the items are counted (``count`` None), from an input of :data:`IN_PIECES_FROM_BYTES`
    (``input_bytes``).  ``stream`` False keeps the results in memory.

    Parameters
    ----------
    count : int or None
        The items of the batch (None: not counted yet).
    tables_only : bool
        Whether the outputs are CSV tables only.
    figures : str
        The figures asked for (:data:`~tromplab.options.FIGURE_CHOICES`).
    stream : bool, optional
        Stream (True) or not (False) where the outputs allow; default: by the size.
    input_bytes : int, optional
        The size of the input, where ``count`` is None.

    Returns
    -------
    bool

    Examples
    --------
    >>> streams(5000, tables_only=True, figures="auto")
    True
    >>> streams(5000, tables_only=True, figures="all"), streams(10, tables_only=True, figures="none")
    (False, False)
    >>> streams(None, tables_only=True, figures="auto", input_bytes=2 << 20)
    True
    """
    if count == 0 or stream is False:
        return False
    drawn_alone = figures == "none" or (figures == "auto" and (count is None or count > AUTO_FIGURE_LIMIT))
    if not (tables_only and drawn_alone):
        return False
    if stream:
        return True
    if count is not None:
        return count >= STREAM_THRESHOLD
    return input_bytes is not None and input_bytes >= IN_PIECES_FROM_BYTES
