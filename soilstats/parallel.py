"""Parallel work over independent pieces (soils, conditions, folds, resamples) with joblib.

One function, :func:`parallel_map`, is the only place soilstats starts workers.  It keeps
three promises:

* **Identical results for any number of jobs.**  Results come back in the order of the
  inputs, and no task draws from a random stream another task shares: every random step
  takes its own seed from its inputs (see the callers), so ``jobs=1`` and ``jobs=8`` give
  the same numbers, bit for bit.
* **No surprise processes.**  ``jobs=1`` (the default everywhere) runs in this process with
  no joblib machinery at all; ``jobs=-1`` uses every core; ``jobs=N`` at most N workers.
* **Any joblib backend.**  The workers come from joblib's active backend: ``loky``
  processes by default, or — on a cluster — Dask's, when the call runs inside
  ``joblib.parallel_config(backend="dask")`` with a ``dask.distributed.Client`` open
  (docs/performance.md shows how).

Progress, when asked for, is a tqdm bar over completed tasks on stderr.
"""

from __future__ import annotations

import contextlib
import copy
import importlib
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future
from typing import TypeVar

from threadpoolctl import threadpool_limits

from .errors import InputError

__all__ = [
    "effective_jobs",
    "in_one_worker",
    "in_this_backend",
    "one_blas_thread",
    "parallel_map",
    "stop_one_worker",
    "warm_one_worker",
    "warm_workers",
]

T = TypeVar("T")
R = TypeVar("R")


def effective_jobs(jobs: int | None) -> int:
    """The number of workers ``jobs`` asks for: N ≥ 1 as given, −1 every core, −2 all but
    one (joblib's convention), None or 0 one.  Raises ValueError below −cores."""
    if jobs is None or jobs == 0:
        return 1
    cores = os.cpu_count() or 1
    if jobs < 0:
        if cores + 1 + jobs < 1:
            raise InputError(f"jobs={jobs} asks for fewer than one worker on {cores} cores")
        return cores + 1 + jobs
    return int(jobs)


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with BLAS on one thread, then restore the previous setting.

    OpenBLAS sums a long dot product in per-thread pieces, so a product's last bit depends
    on its thread count; worker processes and this one must therefore use the same count for
    ``--jobs`` to change nothing. One thread is also what N workers on N cores want.
    (threadpoolctl, the joblib/scikit-learn project's library for exactly this.)
    """
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _on_one_blas_thread(function, item):
    """``function(item)`` in a worker, with BLAS on one thread (see :func:`one_blas_thread`)."""
    with one_blas_thread():
        return function(item)


def parallel_map(
    function: Callable[[T], R],
    items: Iterable[T],
    *,
    jobs: int | None = 1,
    progress: bool = False,
    desc: str | None = None,
    single_in_process: bool = True,
) -> list[R]:
    """``[function(item) for item in items]``, spread over ``jobs`` workers.

    Parameters
    ----------
    function : callable
        A module-level function (workers receive it pickled); it must not depend on state
        another task changes, and must take any seed it needs from its item.
    items : iterable
        The independent pieces of work; materialised once.
    jobs : int, default 1
        See :func:`effective_jobs`.  With one job, or one item, no worker is started.
    progress : bool
        Show a tqdm bar of completed items on stderr.
    desc : str, optional
        The bar's label.
    single_in_process : bool, default True
        Run a lone item in this process (no worker round trip).  False sends it to a
        worker too: for callers that run several ``parallel_map`` at once from threads,
        where in-process work would contend for this process's interpreter lock.

    Returns
    -------
    list
        The results in the order of ``items``, whatever order the workers finished in.
    """
    items = list(items) if not isinstance(items, Sequence) else items
    n_jobs = effective_jobs(jobs)
    if n_jobs == 1 or len(items) == 0 or (len(items) == 1 and single_in_process):
        if progress:
            from tqdm.auto import tqdm  # deferred: tqdm, 0.3 s (only with a progress bar)

            items = tqdm(items, desc=desc, leave=False)
        with one_blas_thread():
            return [function(item) for item in items]

    from joblib import Parallel, delayed  # deferred: joblib, 0.4 s (only when workers start)

    # return_as="generator" streams results in input order, so the bar advances as they land.
    # A negative jobs goes to joblib as given: on Dask it means every cluster worker.  The
    # worker count is the same whatever the number of items: loky keeps one pool of workers
    # and resizes it when a call asks for another count, which restarts the workers between
    # calls and deadlocks when calls from several threads (discovery's groups) overlap.
    n_jobs = jobs if jobs is not None and jobs < 0 else n_jobs
    runner = Parallel(n_jobs=n_jobs, return_as="generator")
    results = runner(delayed(_on_one_blas_thread)(function, item) for item in items)
    if progress:
        from tqdm.auto import tqdm  # deferred: tqdm, 0.3 s (only with a progress bar)

        results = tqdm(results, total=len(items), desc=desc, leave=False)
    return list(results)


def in_this_backend(target: Callable[..., R]) -> Callable[..., R]:
    """``target`` wrapped to run under the joblib configuration of the calling thread.

    joblib's ``parallel_config`` is per thread: a thread started inside
    ``parallel_config(backend="dask")`` would otherwise send its :func:`parallel_map` work
    to local loky workers while the cluster idles. Wrap every thread's target with this
    when the thread is started (discovery's group threads do).

    Each thread gets its own copy of the backend object: joblib configures and terminates
    the instance it is given, so threads sharing one (a loky backend shared by discovery's
    group threads) pull its pool from under each other (``'NoneType' object has no attribute
    'submit'``, or a hang). Where the caller set nothing, the thread keeps joblib's default,
    a fresh backend for every call.
    """
    if "joblib" not in sys.modules:  # nothing configured: no joblib import on the serial path
        return target

    from joblib import parallel_config  # deferred: joblib (only once it is loaded)
    from joblib.parallel import _backend, default_parallel_config  # deferred: joblib

    config = getattr(_backend, "config", default_parallel_config)
    chosen = {
        key: value
        for key, value in config.items()
        if key in default_parallel_config and value is not default_parallel_config[key]
    }
    if not chosen:
        return target

    def run(*args, **kwargs):
        mine = dict(chosen)
        if "backend" in mine:
            mine["backend"] = copy.copy(mine["backend"])
        with parallel_config(**mine):
            return target(*args, **kwargs)

    return run


def in_one_worker(function: Callable[[T], R], item: T) -> Future[R]:
    """Start ``function(item)`` in a worker process and return its future, for a caller that
    does its own share of the work meanwhile (``soilstats posterior --jobs 2`` samples one
    model here and the other there).  The worker is loky's, the processes of
    :func:`parallel_map`'s default backend, one at a time (always local: a Dask backend's
    workers are reached through :func:`parallel_map`); submitting again reuses it, so a
    first call that only imports (:func:`warm_one_worker`) takes its start-up off the clock."""
    from joblib.externals.loky import get_reusable_executor  # deferred: joblib (workers only)

    executor = get_reusable_executor(max_workers=1)
    if executor not in _ONE_WORKER:  # loky hands out one executor while it lives
        _ONE_WORKER.append(executor)
    return executor.submit(_on_one_blas_thread, function, item)


#: The executors :func:`in_one_worker` submitted to (for :func:`stop_one_worker`).
_ONE_WORKER: list = []


def warm_one_worker(modules: Sequence[str]) -> Future[int]:
    """Start :func:`in_one_worker`'s process now, importing ``modules`` in it."""
    return in_one_worker(_import, tuple(modules))


def stop_one_worker(*, at_once: bool = False) -> None:
    """Stop :func:`in_one_worker`'s process: when its work is done, or ``at_once`` whatever
    it is doing (a command that ends early, by a refusal or an error, must not wait at exit
    for its worker's warm-up)."""
    while _ONE_WORKER:
        _ONE_WORKER.pop().shutdown(wait=not at_once, kill_workers=at_once)


def _import(modules: tuple[str, ...]) -> int:
    """Import ``modules`` in a worker (its first real task need not wait for them)."""
    for name in modules:
        importlib.import_module(name)
    time.sleep(0.05)  # long enough that every worker gets one
    return os.getpid()


def warm_workers(jobs: int | None, modules: Sequence[str] = ()) -> threading.Thread | None:
    """Start the ``jobs`` workers of :func:`parallel_map` in the background, each importing
    ``modules``, while this process does its serial part (loading and screening the
    campaign): starting processes and importing numpy, pandas and soilstats in them takes
    about a second, which would otherwise come before the first parallel task.  Returns
    the thread (None with one job); a failed warm-up only costs the time it would save."""
    n = effective_jobs(jobs)
    if n <= 1:
        return None

    def start():
        try:
            parallel_map(_import, [tuple(modules)] * n, jobs=jobs)
        except Exception:  # the real tasks will meet (and report) whatever went wrong
            pass

    thread = threading.Thread(target=in_this_backend(start), daemon=True)
    thread.start()
    return thread
