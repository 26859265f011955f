"""The fan-out of a batch: items (experiments, tests) cut into chunks (:func:`chunked`), the
chunks run in process, on a process pool or on a Dask cluster (:func:`dask_client`,
:func:`map_on_workers`), and their results gathered in order.  It knows nothing of what a chunk
holds: the batch of fits (:mod:`tromplab.workbench.chunks`) and of density tests use it alike.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import importlib.util
import itertools
import math
import os
import pickle
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor

from ..errors import OptionError
from .gc_control import results_kept_out_of_collections, with_older_objects_frozen

#: Experiments per unit of work: at least ``CHUNK_SIZE`` (progress, and balance over the
#: workers), at most ``MAX_CHUNK_SIZE`` (memory), in between two units per worker (one
#: worker: as few units as ``MAX_CHUNK_SIZE`` allows, as there is nothing to balance).  The
#: numbers do not depend on the cut: every chunk is padded to the widest experiment of the
#: batch (:class:`~tromplab.curves.batched.PaddedPoints`), and the fits of one experiment
#: use its own rows only.  Large units matter: the engine's cost per call is mostly
#: interpreter overhead that a larger batch shares (1,024 experiments on one worker, chunks
#: of 64 against 512: 7.5 s against 4.3 s; 10,000 experiments on two workers, at most 1,024
#: against at most 512: the workers' CPU 47.1-49.0 s against 49.7-55.0 s in six alternating
#: runs, 20 MiB more at the peak; docs/performance.md).
CHUNK_SIZE = 64
MAX_CHUNK_SIZE = 1024


def chunked(items: Sequence, *, workers: int) -> list:
    """``items`` cut into consecutive units of work for ``workers`` (see :data:`CHUNK_SIZE`):
    at least two per worker where there are several, as many for each worker (units of at
    most :data:`MAX_CHUNK_SIZE` of equal size, so that no worker is left with a short last
    unit while another works on a full one: 10,000 experiments on 2 workers are 10 units of
    1,000, not 9 of 1,024 and one of 784)."""
    size = chunk_size(len(items), workers=workers)
    return [items[i : i + size] for i in range(0, len(items), size)]


def chunk_size(count: int, *, workers: int) -> int:
    """The experiments per unit of work of :func:`chunked` for ``count`` experiments."""
    workers = max(workers, 1)
    units = max(math.ceil(count / MAX_CHUNK_SIZE), 2 * workers if workers > 1 else 1)  # one worker: nothing to balance
    units = math.ceil(units / workers) * workers
    return min(MAX_CHUNK_SIZE, max(CHUNK_SIZE, math.ceil(count / units)))


def chunks_of(items: Iterable, size: int) -> Iterator[list]:
    """Consecutive lists of ``size`` items of ``items`` (the last shorter), taken as they come."""
    items = iter(items)
    while chunk := list(itertools.islice(items, size)):
        yield chunk


def worker_count(jobs, client) -> int:
    """Workers the chunks will run on: the Dask cluster's threads, else ``jobs`` (None or 0: all cores)."""
    if client is not None:
        return max(1, sum(client.nthreads().values()))
    return jobs or os.cpu_count() or 1


#: Dask settings of the local cluster (``dask="local"``), and the ones docs/performance.md
#: recommends for the workers of a cluster that runs tromplab's chunks:
#:
#: - no ``MALLOC_TRIM_THRESHOLD_=65536`` from the nanny, which makes glibc map and unmap every
#:   numpy array above 64 KiB: the fits ran 1.5 x slower;
#: - no statistical profiler (a sample of the task thread's stack every 10 ms, for the
#:   dashboard's profile page), and the event loop's health check and the system monitor every
#:   1 s and 2 s instead of 20 ms and 0.5 s: a scheduler and two idle workers used 1.1 s of CPU
#:   in 20 s with Dask's defaults, 0.3 s with these, and the two workers' CPU for 4,000
#:   experiments fell from about 19 s to 17.7 s, what two local worker processes use (18 s).
#:
#: The memory monitor, which keeps a worker within its memory limit, is left as it is.
DASK_WORKER_CONFIG = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
}


@contextlib.contextmanager
def dask_client(*, scheduler: str | None = None, dask: str | None = None, client=None):
    """The Dask client to run on: ``client`` as given, one connected to ``scheduler``, or
    one on a local cluster of two workers (``dask="local"``); None when none is asked for.
    A client made here is closed afterwards."""
    if client is not None or (scheduler is None and dask is None):
        yield client
        return
    if dask not in (None, "local"):
        raise OptionError("dask", f"must be 'local', got {dask!r}")
    if importlib.util.find_spec("distributed") is None:
        raise OptionError(
            "scheduler" if scheduler is not None else "dask", "needs the package distributed: pip install 'tromplab[dask]'"
        )
    from dask import config as dask_config
    from dask.distributed import Client, LocalCluster

    with contextlib.ExitStack() as stack:
        if scheduler is not None:
            made = stack.enter_context(Client(scheduler))
        else:
            with dask_config.set(DASK_WORKER_CONFIG):
                cluster = stack.enter_context(LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None))
            made = stack.enter_context(Client(cluster))
        yield made


def map_on_workers(function, chunks, argument, *, jobs, client, count: int | None = None):
    """Yield ``function(argument, chunk)`` for each chunk, in order: in process, in a
    process pool of ``jobs`` workers (None: all cores), or on a Dask client.  ``chunks`` may
    be an iterator (``count``: how many it yields): a chunk is taken from it when a worker
    can soon start on it, at most :data:`CHUNKS_IN_FLIGHT` per worker ahead of the results."""
    work = functools.partial(with_older_objects_frozen, function, argument)
    count = len(chunks) if count is None else count
    with results_kept_out_of_collections() as keep:
        if client is not None:
            pickled_work = pickle.dumps(work, protocol=pickle.HIGHEST_PROTOCOL)

            def submit(chunk):
                chunk = pickle.dumps(chunk, protocol=pickle.HIGHEST_PROTOCOL)
                return client.submit(_call_pickled, pickled_work, chunk, pure=False)

            ahead = CHUNKS_IN_FLIGHT * worker_count(jobs, client)
        else:
            workers = min(jobs or os.cpu_count() or 1, count)
            if workers <= 1:
                for result in map(work, chunks):
                    yield result
                    keep()
                return
            pool = ProcessPoolExecutor(max_workers=workers)
            submit, ahead = functools.partial(pool.submit, work), CHUNKS_IN_FLIGHT * workers
        with contextlib.nullcontext() if client is not None else pool:
            for result in _in_order(submit, chunks, ahead):
                yield result
                keep()


def _call_pickled(work: bytes, chunk: bytes):
    """``work(chunk)``, both pickled by the client.  A Dask scheduler unpickles every task it
    is given and pickles it again for its worker: a chunk of 1,000 experiments' points is about
    1 MB of small objects, about 0.1 s of the scheduler's CPU, taken from the workers when they
    share its cores; bytes it only copies."""
    return pickle.loads(work)(pickle.loads(chunk))


#: Chunks submitted per worker ahead of the result awaited: one at work, one queued.
CHUNKS_IN_FLIGHT = 2


def _in_order(submit, chunks, ahead: int):
    """The results of ``submit(chunk)`` for each chunk in order, with at most ``ahead``
    chunks submitted and not yet returned; each future is released once its result is
    taken (a Dask worker forgets it then, not at the end)."""
    pending: collections.deque = collections.deque()
    for chunk in chunks:
        pending.append(submit(chunk))
        if len(pending) >= ahead:
            yield pending.popleft().result()
    while pending:
        yield pending.popleft().result()
