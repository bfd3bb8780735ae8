"""The Dask cluster meshing runs on: a ``LocalCluster`` on this machine, or an existing scheduler anywhere.

``--workers N`` starts N worker processes with one thread each (numba's kernels then run single-threaded inside
each task, so N tasks use N cores); ``--scheduler tcp://HOST:PORT`` connects to a running ``dask-scheduler``
whose ``dask-worker`` processes can read the store at the same path. The same code path runs on either.
"""

from __future__ import annotations

import os
from contextlib import contextmanager

__all__ = ["dask_client"]


@contextmanager
def dask_client(*, workers: int | None = None, scheduler: str | None = None, memory_limit: str = "auto"):
    """A ``distributed.Client`` for the block: connected to ``scheduler``, or to a new ``LocalCluster`` of
    ``workers`` processes (default: the machine's cores), closed (and the cluster shut down) on exit.

    Raises ``ValueError`` for a worker count below 1 or both arguments, ``OSError`` (one line) when the scheduler
    cannot be reached.
    """
    from distributed import Client, LocalCluster

    if workers is not None and scheduler is not None:
        raise ValueError("give either a number of workers (a local cluster) or a scheduler address, not both")
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise OSError(f"cannot reach the Dask scheduler at {scheduler} within 10 s ({type(exc).__name__}); "
                          "start 'dask-scheduler' and 'dask-worker' there, or use --workers N") from None
        try:
            yield client
        finally:
            client.close()
        return
    workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"--workers must be at least 1, got {workers}")
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                           memory_limit=memory_limit, silence_logs=40)
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()
