"""The Dask client of a batch: a local cluster sized to the machine, or an existing scheduler.

Each worker is a separate process with one thread, and its numerical libraries are limited to
one thread (``NUMBA_NUM_THREADS``, ``OMP_NUM_THREADS``, ...): the reconstruction's numba kernels
are single-threaded, so one flight per core is the whole parallelism and more threads would only
oversubscribe the cores (docs/batch.md, "Throughput").
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from typing import Any

from flightrecon.errors import MetadataError

#: environment of each local worker process: one thread per numerical library
SINGLE_THREAD_ENV: dict[str, str] = {
    "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1", "NUMEXPR_NUM_THREADS": "1",
}


def default_workers() -> int:
    """Worker count for a local cluster: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def open_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A ``dask.distributed.Client``, closed (with its local cluster) on exit.

    Parameters
    ----------
    scheduler : address of a running scheduler (``tcp://host:8786``) or a scheduler file
        (``*.json``); ``None`` starts a ``LocalCluster`` on the loopback interface with its
        dashboard off
    workers : local worker processes (default :func:`default_workers`); with ``scheduler``
        it must not be given (the cluster's owner sizes it)
    """
    from distributed import Client, LocalCluster

    if scheduler is not None:
        if workers is not None:
            raise MetadataError("--workers sizes a local cluster; with --scheduler the cluster "
                                "is sized where it runs")
        kw = ({"scheduler_file": scheduler} if scheduler.endswith(".json")
              else {"address": scheduler})
        client = Client(**kw)
        try:
            yield client
        finally:
            client.close()
        return
    n = default_workers() if workers is None else workers
    if n < 1:
        raise MetadataError(f"--workers must be at least 1, got {n}")
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None, env=SINGLE_THREAD_ENV)
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()
