"""The batch layer: every formula fitted to many experiments, on processes or Dask, and the
:class:`Workbench` that holds the results.

Modules, top first (each imports only from those below it): ``stream``
(:func:`fit_to_folder`: fit and write the results folder, a large batch streamed to disk),
``batch`` (:func:`fit_experiments`), ``result`` (:class:`Workbench`, :func:`load`,
:func:`model_averages`), ``store`` (where a workbench reads its fits: :class:`FitStore`, in
memory or read back from a streamed folder), ``chunks`` (the fits chunk by chunk on the fan-out
of :mod:`tromplab.parallel`: a process pool or a Dask cluster) and ``spool`` (the chunks' rows
written to disk by the workers), ``worker`` (what a worker does with one chunk), then
``averages``, ``tables`` (the fits table) and ``inputs`` (the experiments a batch accepts).  Import the names below from
``tromplab.workbench`` (or :mod:`tromplab`): the modules may change.
"""

from ..parallel import CHUNK_SIZE, DASK_WORKER_CONFIG, MAX_CHUNK_SIZE, STREAM_THRESHOLD, chunked, dask_client
from .averages import averages_level
from .batch import check_formula_selection, fit_experiments, fit_with_settings, formula_keys, print_progress
from .chunks import ChunkResults
from .inputs import ACCEPTED_EXPERIMENTS, ExperimentsInPieces, data_notes
from .result import Workbench, load, model_averages
from .store import FitsInMemory, FitsOnDisk, FitStore
from .stream import fit_to_folder
from .tables import by_experiment, completed_fit_rows, fit_row_settings, fit_rows_frame, output_view, ranked_among
from .worker import ChunkOptions, FittedChunk, derive, fit_chunk, work_on_chunk

# pickles name the class by its public path, which stays when the modules inside move
Workbench.__module__ = __name__

__all__ = [
    "ACCEPTED_EXPERIMENTS",
    "CHUNK_SIZE",
    "MAX_CHUNK_SIZE",
    "STREAM_THRESHOLD",
    "ChunkOptions",
    "ChunkResults",
    "ExperimentsInPieces",
    "FitsInMemory",
    "FitsOnDisk",
    "FitStore",
    "FittedChunk",
    "Workbench",
    "averages_level",
    "by_experiment",
    "check_formula_selection",
    "chunked",
    "completed_fit_rows",
    "dask_client",
    "DASK_WORKER_CONFIG",
    "data_notes",
    "derive",
    "fit_chunk",
    "fit_experiments",
    "fit_row_settings",
    "fit_rows_frame",
    "fit_to_folder",
    "fit_with_settings",
    "formula_keys",
    "load",
    "model_averages",
    "output_view",
    "print_progress",
    "ranked_among",
    "work_on_chunk",
]
