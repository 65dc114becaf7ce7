"""Executors: in-process, a pool of local processes, or a ``dask.distributed`` cluster."""

from __future__ import annotations

import concurrent.futures
import logging
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from cwproc.batch.records import DaskNotInstalledError
from cwproc.errors import CwprocError


def run_tasks(
    fn: Callable[..., Any],
    items: Sequence[Any],
    *args: Any,
    client: Any = None,
    retries: int = 0,
) -> Iterator[tuple[Any, Any]]:
    """Run ``fn(item, *args)`` for every item; yield ``(item, result)`` as they finish.

    Without ``client`` the calls run here, one after the other. With a
    :class:`concurrent.futures.Executor` (:func:`local_pool`) or a
    ``dask.distributed.Client`` they are submitted to its processes and yielded in order
    of completion; a task that could not run (worker killed, function not importable
    there, an exception out of ``fn``) is submitted again, up to ``retries`` more times,
    and then yields the exception as its result. (The functions of a batch return their
    failures as records and never raise for anything the data cause, so an exception is
    a failure of the machinery, which a second attempt on another worker may not meet;
    Dask also reschedules by itself the tasks of a worker that died, up to
    ``distributed.scheduler.allowed-failures`` times.)
    """
    if client is None:
        for item in items:
            yield item, fn(item, *args)
        return
    if isinstance(client, concurrent.futures.Executor):
        yield from _run_on_executor(client, fn, items, args, retries)
        return
    yield from _run_on_dask(client, fn, items, args, retries)


def _run_on_executor(
    pool: concurrent.futures.Executor,
    fn: Callable[..., Any],
    items: Sequence[Any],
    args: tuple,
    retries: int,
) -> Iterator[tuple[Any, Any]]:
    """:func:`run_tasks` on a local process pool (a broken pool cannot take a retry:
    the exception is the result)."""
    pending = {pool.submit(fn, item, *args): (item, 0) for item in items}
    while pending:
        done, _ = concurrent.futures.wait(pending, return_when=concurrent.futures.FIRST_COMPLETED)
        for future in done:
            item, attempt = pending.pop(future)
            try:
                yield item, future.result()
                continue
            except Exception as exc:  # a worker died or the call failed
                result: Any = exc
            if attempt < retries:
                try:
                    pending[pool.submit(fn, item, *args)] = (item, attempt + 1)
                    continue
                except Exception as exc:  # the pool is broken: no second attempt
                    result = exc
            yield item, result


def _run_on_dask(
    client: Any,
    fn: Callable[..., Any],
    items: Sequence[Any],
    args: tuple,
    retries: int,
) -> Iterator[tuple[Any, Any]]:
    """:func:`run_tasks` on a ``dask.distributed`` client."""
    from dask.distributed import as_completed

    futures = {client.submit(fn, item, *args, pure=False): (item, 0) for item in items}
    completed = as_completed(futures)
    for future in completed:
        item, attempt = futures.pop(future)
        try:
            result = future.result()
        except Exception as exc:
            result = exc
        finally:
            future.release()
        if isinstance(result, Exception) and attempt < retries:
            again = client.submit(fn, item, *args, pure=False)
            futures[again] = (item, attempt + 1)
            completed.add(again)
            continue
        yield item, result


def dask_client(
    workers: int | None = None, scheduler: str | None = None, timeout_s: float = 10.0
) -> Any:
    """A ``dask.distributed.Client``: a new ``LocalCluster`` or an existing scheduler.

    Parameters
    ----------
    workers : int, optional
        Start a LocalCluster of this many worker processes, one thread each.
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``).
    timeout_s : float
        How long to try to reach the scheduler (s).

    Raises
    ------
    DaskNotInstalledError
        dask.distributed is not installed.
    CwprocError
        The scheduler cannot be reached.
    """
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise DaskNotInstalledError() from None
    if scheduler:
        try:
            return Client(scheduler, timeout=f"{timeout_s}s")
        except (OSError, TimeoutError) as exc:
            raise CwprocError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
    cluster = LocalCluster(
        n_workers=int(workers or 1),
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    return Client(cluster)


def local_pool(workers: int) -> concurrent.futures.ProcessPoolExecutor:
    """A pool of ``workers`` processes on this machine (``--workers N``).

    A process pool rather than a Dask ``LocalCluster``: units take a tenth of a second
    to a few seconds, and a LocalCluster's start (about 2 s) and its cost per task
    (scheduler round trips, about 10 ms) made two workers slower than one on 30 days
    of scans. Workers are forked where the platform allows it (no second import of
    cwproc), else spawned. Dask remains the executor of a cluster (``--scheduler``).
    """
    import multiprocessing

    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    return concurrent.futures.ProcessPoolExecutor(
        max_workers=int(workers), mp_context=multiprocessing.get_context(method)
    )


def close_client(client: Any) -> None:
    """Close a client and, when it owns one, its LocalCluster (or shut a local pool)."""
    if isinstance(client, concurrent.futures.Executor):
        client.shutdown(wait=True, cancel_futures=True)
        return
    cluster = getattr(client, "cluster", None)
    client.close()
    if cluster is not None:
        cluster.close()
