"""The fits discovery farms out, and where it starts workers (through parallel_map).

Cross-validation and forward selection (:mod:`.crossval`, :mod:`.selection`) fit the same
model many times: once without each fold, once on all tests in scope, for every extension
compared.  Given the folds, those fits are independent of each other; what depends on what
is only *which fits start from which* (an extension's fold fit starts from the base model's
fit of the same fold).  So each discovery step is written as a *process* — a generator that
yields the fits it needs next as a :class:`Wave` of :class:`FitTask` and receives their
outcomes — and :func:`run_process` has a :class:`Pool` fit each wave over ``jobs`` workers
(:func:`soilstats.parallel.parallel_map`).  Processes that do not depend on each other run
in threads of their own on one pool, their waves sharing the workers.

Why the results are the same for any number of jobs: a fit is a deterministic function of
its task (model, tests, start) and the group's data; nothing in it draws random numbers.  The
one random step of discovery, the folds (:func:`.crossval.make_folds`), stays in the calling
process: each group draws from its own ``numpy.random.Generator``
(:func:`.crossval.group_rng`) in one fixed order, before the wave that uses them is sent
out.  Outcomes come back in the order of the tasks, and a failed fit comes back as its
error, which the caller raises or records exactly where the one-at-a-time loop would have
met it (a model's later fits after a failed one are skipped, as that loop never ran them:
:class:`Pool`).

What travels to a worker is kept small.  The group (hundreds of thousands of samples) goes
once per group and worker, not once per task: the :class:`Pool` writes it to one temporary
file, which each local worker reads on its first task of the group and keeps among the
latest few groups it read (:func:`_group_of`; all groups of most campaigns, which are in
flight at once); a backend whose workers may not share this machine's files (Dask) gets the
group with every task instead.  A fit's start is only its model and parameter values
(:class:`Start`), and a fold fit comes back as such: it is read only as the start of the
fold fits after it.

One more thing decides the last bits: a multithreaded BLAS sums long dot products in
per-thread pieces, so the same fit on two threads and on one differs in its 16th digit.
Workers run their fits with BLAS on one thread (:func:`~soilstats.parallel.parallel_map`
does so for every item), and discovery runs its own process's BLAS on one thread too
(:func:`~soilstats.parallel.one_blas_thread`) — which is also
faster here: the fits' products are memory-bound, and an idle BLAS thread spinning beside
busy cores slowed a 10 000-test discovery several-fold.
"""

from __future__ import annotations

import os
import pickle
import tempfile
import threading
import uuid
import weakref
from collections.abc import Generator, Hashable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypeAlias, TypeVar

import numpy as np

from ..errors import ConvergenceError, IdentifiabilityError
from ..parallel import effective_jobs, parallel_map
from ..parallel import warm_workers as _warm_workers

if TYPE_CHECKING:
    from .data import Group
    from .extensions import Extension, FitStart, Fitted

__all__ = [
    "FIT_ERRORS",
    "FitTask",
    "Outcome",
    "Pool",
    "Process",
    "Start",
    "Wave",
    "run_process",
    "warm_workers",
]

#: What one fit may raise and discovery records (as the serial loops caught it): anything
#: else is a bug and propagates.
FIT_ERRORS = (ConvergenceError, IdentifiabilityError, np.linalg.LinAlgError, ValueError)


@dataclass(frozen=True, eq=False)
class Start:
    """What a fit reads of the fitted model it starts from: the extension, its parameter
    values (``start.result.values``, as of a :class:`~.extensions.Fitted`) and the base form
    its fit chose (``state["bekker"]``, when it differs from the extension's)."""

    extension: Extension
    values: np.ndarray
    state: dict = field(default_factory=dict)

    @property
    def result(self) -> Start:
        return self

    @classmethod
    def of(cls, fitted: FitStart | None) -> Start | None:
        """The start part of a fitted model (None stays None)."""
        if fitted is None or isinstance(fitted, Start):
            return fitted
        form = {"bekker": fitted.state["bekker"]} if "bekker" in fitted.state else {}
        return cls(fitted.extension, np.asarray(fitted.result.values), form)


@dataclass(frozen=True, eq=False)
class FitTask:
    """Fit ``extension`` on the tests ``rows`` of the group, started from ``base`` (a
    :class:`~.extensions.Fitted`, or None for the extension's own start), and — when
    ``held_out`` is given — each held-out test's prediction error under that fit
    (:func:`per_test_error`); a fold fit (with ``held_out``) gives back its
    :class:`Start` only.  Tasks with the same ``chain`` stop at the first failure
    (:class:`Pool`)."""

    extension: Extension
    rows: np.ndarray
    base: FitStart | None = None
    held_out: np.ndarray | None = None
    chain: Hashable = None


@dataclass(frozen=True, eq=False)
class Outcome:
    """What a :class:`FitTask` gave: the fitted model and held-out errors, or its error."""

    fitted: Fitted | Start | None = None
    errors: np.ndarray | None = None
    error: Exception | None = None
    skipped: bool = False  # not run: an earlier task of its chain failed

    def raise_error(self) -> None:
        """Raise the fit's error, if it failed."""
        if self.error is not None:
            raise self.error


def per_test_error(group: Group, rows: np.ndarray, y_hat: np.ndarray) -> np.ndarray:
    """Each test's mean squared weighted prediction error (:mod:`.crossval`) over its
    samples, for the tests ``rows`` predicted as ``y_hat`` (their samples, in order); here,
    beside the fold fits that compute it, so that :mod:`.crossval` imports this module and
    not the other way round."""
    mask = group.samples_of(rows)
    owner = group.owner[mask]
    e2 = (group.w[mask] * (group.y[mask] - y_hat)) ** 2
    sums = np.bincount(owner, weights=e2, minlength=len(group.tests))
    counts = np.bincount(owner, minlength=len(group.tests))
    return sums[rows] / np.maximum(counts[rows], 1)


def _run(item: tuple[Group, FitTask]) -> tuple:
    """One task: (fitted, errors, None) or, for a failed fit, (None, None, (exception class,
    message)) — the class and message are all callers use, and they cross a process
    boundary where the exception object might not."""
    group, task = item
    try:
        fitted = task.extension.fit(group, task.rows, base=task.base)
        errors = None
        if task.held_out is not None:
            y_hat = task.extension.predict(fitted, group, task.held_out)
            errors = per_test_error(group, task.held_out, y_hat)
            # read only as the start of later fold fits
            return Start.of(fitted), errors, None
    except FIT_ERRORS as exc:
        return None, None, (type(exc), str(exc))
    return fitted, errors, None


# The groups this worker has read (key → group), the latest few: a Pool's tasks name their
# group by key and file, and a worker reads each file once while it is among them.  Every
# (kind, soil) group is in flight at once (pipeline._extend_groups), so a few more than a
# campaign's usual kinds × soils; a group of a 10,000-test campaign is ~15 MB.
_GROUPS: dict = {}
_KEEP_GROUPS = 8


def _group_of(shipped):
    """The group a task names: ``(key, path)`` of a Pool's file, or the group itself."""
    if not isinstance(shipped, tuple):
        return shipped
    key, path = shipped
    group = _GROUPS.pop(key, None)
    if group is None:
        with open(path, "rb") as fh:
            group = pickle.load(fh)
    _GROUPS[key] = group  # most recent last
    while len(_GROUPS) > _KEEP_GROUPS:
        _GROUPS.pop(next(iter(_GROUPS)))
    return group


def _run_in_worker(item: tuple[Group | tuple[str, str], FitTask]) -> tuple:
    """:func:`_run` in a worker: the group read from its file or kept from an earlier task
    (:func:`_group_of`).  (BLAS is on one thread there already: parallel_map runs every
    item so, as this process runs its own fits; module docstring.)"""
    shipped, task = item
    return _run((_group_of(shipped), task))


def _outcome(raw: tuple) -> Outcome:
    fitted, errors, failure = raw
    return Outcome(fitted, errors, None if failure is None else failure[0](failure[1]))


_SKIPPED = Outcome(skipped=True)


class Pool:
    """Fits tasks of any groups over ``jobs`` workers (1: in this process).

    :meth:`execute` takes ``(group, task, probe)`` triples and returns one :class:`Outcome`
    per task, in their order.  Tasks of one ``chain`` (the fold fits and the full fit of one
    model, in the order the caller reads them; chains are told apart by group too) stop at
    the first that fails: the caller raises or records that error, so the rest is never
    needed.  In this process the rest is skipped, as the one-at-a-time loops did; over
    workers, the first task of every chain marked ``probe`` runs first and only the chains
    that passed it go on (a model that fails usually fails on every fold — and a fit that
    runs to its iteration limit costs seconds).  Skipping changes which fits run, never a
    result read.
    """

    def __init__(self, jobs: int | None = 1) -> None:
        self.jobs = jobs
        self.parallel = effective_jobs(jobs) > 1
        self._shipped: dict[int, tuple] = {}  # id(group) → (group, what tasks carry)
        self._lock = threading.Lock()  # processes in several threads share the pool

    def _ship(self, group):
        """What tasks carry to name ``group``: ``(key, path)`` of a file written once, for
        workers on this machine; the group itself for other backends."""
        with self._lock:
            return self._ship_locked(group)

    def _ship_locked(self, group):
        entry = self._shipped.get(id(group))
        if entry is None:
            shipped = group
            if _local_workers():
                fd, path = tempfile.mkstemp(prefix="soilstats-discover-", suffix=".pkl")
                with os.fdopen(fd, "wb") as fh:
                    pickle.dump(group, fh, protocol=pickle.HIGHEST_PROTOCOL)
                weakref.finalize(self, _remove, path)
                shipped = (uuid.uuid4().hex, path)
            entry = self._shipped[id(group)] = (group, shipped)  # the group kept: its id stays
        return entry[1]

    def execute(self, items: list[tuple]) -> list[Outcome]:
        """Outcomes of ``(group, task, probe)`` items, in their order."""

        def chain_of(i):
            group, task, _ = items[i]
            return (id(group), i) if task.chain is None else (id(group), task.chain)

        out: list  # Outcomes (the parallel branch fills a list of None in place)
        if not self.parallel:
            failed, out = set(), []
            for i, (group, task, _) in enumerate(items):
                if chain_of(i) in failed:
                    out.append(_SKIPPED)
                    continue
                outcome = _outcome(_run((group, task)))
                if outcome.error is not None:
                    failed.add(chain_of(i))
                out.append(outcome)
            return out
        first: dict = {}
        for i, (_, _, probe) in enumerate(items):
            first.setdefault(chain_of(i) if probe else ("all", i), i)
        # (No filling of idle workers with later tasks of a probed chain: another process's
        # wave may be waiting for them, and a chain that fails would waste them.)
        probes = sorted(first.values())
        out = [None] * len(items)
        for i, outcome in zip(probes, self._parallel([items[i] for i in probes]), strict=True):
            out[i] = outcome
        failed = {chain_of(i) for i in probes if out[i].error is not None}
        rest = [i for i, o in enumerate(out) if o is None and chain_of(i) not in failed]
        for i, outcome in zip(rest, self._parallel([items[i] for i in rest]), strict=True):
            out[i] = outcome
        return [_SKIPPED if o is None else o for o in out]

    def _parallel(self, items: list[tuple]) -> list[Outcome]:
        if not items:
            return []
        sent = [
            (
                self._ship(group),
                FitTask(t.extension, t.rows, Start.of(t.base), t.held_out, t.chain),
            )
            for group, t, _ in items
        ]
        # Even a lone fit goes to a worker: the waves of several groups are in flight at
        # once, and fits run here would queue on this process's interpreter lock.
        done = parallel_map(_run_in_worker, sent, jobs=self.jobs, single_in_process=False)
        return [_outcome(r) for r in done]


@dataclass(frozen=True, eq=False)
class Wave:
    """The fits a discovery step needs next, yielded by a process (:func:`run_process`)."""

    group: Group
    tasks: list[FitTask]
    probe: bool = False


T = TypeVar("T")
#: A discovery step written as the fits it needs (:func:`run_process`): a generator that
#: yields :class:`Wave` objects, receives each wave's outcomes and returns its result.
Process: TypeAlias = Generator[Wave, list[Outcome], T]


def run_process(process: Process[T], pool: Pool) -> T:
    """Run a *process* to its end on ``pool``; its value.

    A process is a generator that yields :class:`Wave` objects and receives each wave's
    outcomes (``outcomes = yield wave``), returning its result at the end: a discovery
    step written as the fits it needs, so that the caller decides where they run.  Several
    processes may run at once, each in its own thread on one pool: their waves then share
    the workers, so that a worker idle in one process's wave (a long fit it waits for)
    takes up another's.  A process's outcomes depend on its own tasks only, so the results
    do not depend on which processes ran together.
    """
    try:
        wave = next(process)
        while True:
            items = [(wave.group, t, wave.probe) for t in wave.tasks]
            wave = process.send(pool.execute(items))
    except StopIteration as stop:
        return stop.value


def warm_workers(jobs: int | None) -> threading.Thread | None:
    """Start the workers and the imports discovery's tasks need, in the background
    (:func:`soilstats.parallel.warm_workers`)."""
    return _warm_workers(
        jobs, ("soilstats.discovery.pipeline", "soilstats.identification.per_test")
    )


def _local_workers() -> bool:
    """Whether joblib's active backend runs its workers on this machine (loky, processes,
    threads), so that they can read a file written here."""
    from joblib.parallel import get_active_backend  # deferred: joblib (workers only)

    backend = type(get_active_backend()[0]).__name__
    return backend in ("LokyBackend", "MultiprocessingBackend", "ThreadingBackend")


def _remove(path: str) -> None:
    try:
        os.remove(path)
    except OSError:
        pass
