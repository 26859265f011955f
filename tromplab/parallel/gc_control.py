"""Python's cyclic garbage collector kept off the objects a batch has made already, in the
main process and in each worker (``gc.freeze``/``gc.unfreeze``).
"""

from __future__ import annotations

import contextlib
import gc


def with_older_objects_frozen(function, argument, chunk):
    """``function(argument, chunk)`` with the objects alive before it (the imported modules, in
    process the earlier chunks' results) left out of the cyclic garbage collections it
    triggers; the chunk's own garbage is collected as usual.  Where objects are frozen
    already (in process by the batch itself, or by the process's owner), nothing is changed."""
    if gc.get_freeze_count():
        return function(argument, chunk)
    gc.freeze()
    try:
        return function(argument, chunk)
    finally:
        gc.unfreeze()


@contextlib.contextmanager
def results_kept_out_of_collections():
    """The chunks' results left out of Python's cyclic garbage collections while more arrive:
    yields the function to call after each chunk.

    Each chunk's results are tens of thousands of objects (fits, their dicts and arrays);
    every collection triggered while later chunks are unpickled or built traversed all of
    them again: at 10,000 experiments on two workers, about 3 s of the main process's CPU.
    ``gc.freeze`` after each chunk moves the objects alive to a generation collections
    skip (reference counting still frees them); ``gc.unfreeze`` at the end returns them to
    the collector, so no garbage outlives the batch.  A process with objects frozen before
    the batch (a server that froze them before forking its workers) is left as it is: its
    freezing is its own to undo.
    """
    if gc.get_freeze_count():
        yield lambda: None
        return
    try:
        yield gc.freeze
    finally:
        gc.unfreeze()
