"""The fan-out of a batch, below every command that has one: items cut into chunks, the chunks
run in process, on a process pool or on a Dask cluster, their results gathered in order
(:mod:`~tromplab.parallel.fanout`), with Python's garbage collector kept off what a batch has
made already (:mod:`~tromplab.parallel.gc_control`); and the one rule that says when a batch
streams its results to disk (:mod:`~tromplab.parallel.streaming`).
"""

from .fanout import (
    CHUNK_SIZE,
    CHUNKS_IN_FLIGHT,
    DASK_WORKER_CONFIG,
    MAX_CHUNK_SIZE,
    chunk_size,
    chunked,
    chunks_of,
    dask_client,
    map_on_workers,
    worker_count,
)
from .streaming import IN_PIECES_FROM_BYTES, STREAM_THRESHOLD, streams

__all__ = [
    "CHUNKS_IN_FLIGHT",
    "CHUNK_SIZE",
    "DASK_WORKER_CONFIG",
    "IN_PIECES_FROM_BYTES",
    "MAX_CHUNK_SIZE",
    "STREAM_THRESHOLD",
    "chunk_size",
    "chunked",
    "chunks_of",
    "dask_client",
    "map_on_workers",
    "streams",
    "worker_count",
]
