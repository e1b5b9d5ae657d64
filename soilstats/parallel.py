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
import os
from collections.abc import Callable, Iterable, Sequence
from typing import TypeVar

__all__ = ["effective_jobs", "parallel_map"]

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
            raise ValueError(f"jobs={jobs} asks for fewer than one worker on {cores} cores")
        return cores + 1 + jobs
    return int(jobs)


def _blas_threads() -> int:
    """The BLAS thread count of this process: OpenBLAS's default (every usable core) unless
    the environment sets one."""
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        value = os.environ.get(name, "").strip()
        if value.isdigit() and int(value) > 0:
            return int(value)
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def parallel_map(
    function: Callable[[T], R],
    items: Iterable[T],
    *,
    jobs: int | None = 1,
    progress: bool = False,
    desc: str | None = None,
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

    Returns
    -------
    list
        The results in the order of ``items``, whatever order the workers finished in.
    """
    items = list(items) if not isinstance(items, Sequence) else items
    n_jobs = min(effective_jobs(jobs), max(len(items), 1))
    if n_jobs == 1:
        if not progress:
            return [function(item) for item in items]
        from tqdm.auto import tqdm

        return [function(item) for item in tqdm(items, desc=desc, leave=False)]

    # Imported only when workers start: joblib takes a while to import.
    from joblib import Parallel, delayed, parallel_config
    from joblib.parallel import get_active_backend

    # return_as="generator" streams results in input order, so the bar advances as they land.
    # loky caps each worker's BLAS at cores/jobs threads; but OpenBLAS sums a long dot
    # product in per-thread pieces, so its last bit depends on the thread count. Workers get
    # this process's count instead: the same answer for any --jobs, at the price of some
    # oversubscription in the (small) matrix products.
    # (Only for loky, joblib's default: another backend, e.g. Dask's, keeps its own settings.)
    backend, _ = get_active_backend()
    same_threads = (
        parallel_config(backend="loky", inner_max_num_threads=_blas_threads())
        if type(backend).__name__ == "LokyBackend"
        else contextlib.nullcontext()
    )
    with same_threads:
        # A negative jobs goes to joblib as given: on Dask it means every cluster worker.
        runner = Parallel(n_jobs=jobs if jobs < 0 else n_jobs, return_as="generator")
        results = runner(delayed(function)(item) for item in items)
    if progress:
        from tqdm.auto import tqdm

        results = tqdm(results, total=len(items), desc=desc, leave=False)
    return list(results)
