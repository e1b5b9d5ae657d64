"""Out-of-sample gain of an extended model over the base model, by cross-validation.

Whole tests are held out, never single samples (samples of one test share its preparation
scatter, so leaving out samples would reward fitting that scatter).  Two schemes:

``tests``       K-fold over tests (K = 5), folds stratified by the cause's level so that every
                training set holds every level — the generic per-level extension can then
                predict every held-out test;
``conditions``  leave one condition out: each level of the cause in turn (a velocity, a
                grouser height, a bin) is predicted from the others — the stronger claim,
                made for extensions that can extrapolate (physical and linear ones).

The error of a held-out test is the mean squared prediction error of its curve weighted by
1/max of its own response (Section 2.1: every test spans 0..1), so the metric is the RMS of
the max-normalised prediction error.  The gain's uncertainty comes from the paired per-test
differences base − extended (each test is held out exactly once): mean ± standard error.  An
extension is kept when the mean difference exceeds :data:`Z_KEEP` standard errors and the
extended model's RMS is lower; the gain is called real only at 2 SE and more
(:mod:`soilstats.evidence`: one vocabulary for every command), weak below.  AIC and BIC of
the full fits are reported beside it, with the caveat that samples within a test are not
independent (they overstate the evidence).
"""

from __future__ import annotations

import zlib
from collections.abc import Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np

from .. import evidence
from ..errors import ConvergenceError, IdentifiabilityError
from .candidates import candidate_values
from .work import FitTask, Wave, per_test_error

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from ..fitting.result import FitResult
    from .data import Group
    from .extensions import Extension, FitStart
    from .work import Outcome, Process, Start

__all__ = [
    "FoldFits",
    "Gain",
    "GroupFolds",
    "HeldOutModel",
    "campaign_gain",
    "compare",
    "cross_validation",
    "fold_labels",
    "group_folds",
    "group_rng",
    "information_criteria",
    "make_folds",
    "per_test_error",
]

METRIC = "rms of max-normalised prediction error, held-out tests"
#: An extension is kept when the mean paired difference exceeds this many standard errors (its
#: gain is called real only at :data:`soilstats.evidence.REAL_SE`; below, "kept on a weak
#: gain").  It
#: judges an extension of a cause the Holm-controlled test has already named, on held-out
#: tests with that cause fixed: of 280 null leads (causes with no effect, named at a lenient
#: alpha) it kept 67 (24 %), of a 15 % bin effect named in 104 campaigns 102 (at 2 SE: 0 and
#: 55; ``benchmarks/discover_nested_null.py``, docs/discover.md "Gain").
Z_KEEP = 1.0


@dataclass(frozen=True)
class Gain:
    """Cross-validated prediction error of base and extended model.

    Attributes
    ----------
    metric : str
    scheme : {"tests", "conditions"}
    folds : int
    n_tests : int
    base, extended : float
        RMS of the max-normalised prediction error over all held-out tests [-].
    relative : float
        1 − extended/base (> 0: the extension predicts better).
    difference, stderr : float
        Mean paired per-test difference of squared errors (base − extended) and its standard
        error.
    real : bool
        The gain is real in the one vocabulary of :mod:`soilstats.evidence`: difference ≥ 2
        standard errors and ``relative > 0``.
    selected_folds : int or None
        Folds whose training tests chose the extension (the lead significant on them,
        :mod:`.nested`: the gain of the whole search); the others' held-out tests were
        predicted by the base model.  None when the cause was held fixed (the gain that
        decides what is kept; leave-one-condition-out; forward selection).
    kept : bool or None
        discover's rule for keeping the extension: ``difference > Z_KEEP·stderr`` and
        ``relative > 0`` (:data:`Z_KEEP`); None where no such decision is made.
    """

    metric: str
    scheme: str
    folds: int
    n_tests: int
    base: float
    extended: float
    relative: float
    difference: float
    stderr: float
    real: bool
    selected_folds: int | None = None
    kept: bool | None = None

    @property
    def verdict(self) -> str:
        """The word for the gain: "real", "weak" or "none" (:func:`soilstats.evidence.verdict`)."""
        return evidence.verdict(self.difference, self.stderr, self.relative)

    def text(self) -> str:
        """``"real: 0.021 ± 0.0052 (4.0 SE)"``: the word, the gain, its standard error."""
        return evidence.describe(self.difference, self.stderr, self.relative)

    @property
    def z(self) -> float:
        """The paired difference in standard errors (what :data:`Z_KEEP` is compared with)."""
        if not np.isfinite(self.stderr) or self.stderr <= 0:
            return float("inf") if self.difference > 0 else float("nan")
        return float(self.difference / self.stderr)

    def summary(self) -> str:
        """One line: the out-of-sample error before and after, and whether the gain is real."""
        chosen = (
            ""
            if self.selected_folds is None
            else f", chosen in {self.selected_folds} of {self.folds}"
        )
        return (
            f"{self.metric} {self.base:.4g} -> {self.extended:.4g} ({self.relative:+.1%}; "
            f"{self.scheme}, {self.folds} folds{chosen}): {self.text()}"
        )

    def to_dict(self) -> dict:
        return {
            "metric": self.metric,
            "base": self.base,
            "extended": self.extended,
            "relative": self.relative,
            "difference": self.difference,
            "stderr": self.stderr,
            "scheme": self.scheme,
            "folds": self.folds,
            "n_tests": self.n_tests,
            "real": self.real,
            "verdict": self.verdict,
            "kept": self.kept,
            "z": self.z,
            "selected_folds": self.selected_folds,
        }


def group_rng(seed: int, group: Group) -> np.random.Generator:
    """The stream one (kind, soil) group draws its folds from: seeded by ``seed`` and the
    group's name, so that a group's folds — and so its findings — depend neither on which
    other soils the campaign holds nor on the order the groups run in (they may run side by
    side: :func:`.pipeline.discover` with ``jobs``)."""
    name = zlib.crc32(f"{group.kind}\x00{group.soil}".encode())
    return np.random.default_rng([seed, name])


def make_folds(
    levels: np.ndarray, scheme: str, rng: np.random.Generator | None, k: int = 5
) -> np.ndarray:
    """Fold number of each test: stratified K-fold (``tests``) or one fold per level.

    Stratified: each level's tests, shuffled, are dealt to the folds in turn, continuing
    from where the previous level stopped, so every fold holds its share of every level.
    The levels are taken in a random order too: when each level is a single test (a trend
    in time, say) the folds are then random, not the order of the levels as text.
    """
    levels = np.asarray(levels)
    codes = np.unique(levels, return_inverse=True)[1].ravel()
    if scheme == "conditions":
        return codes
    assert rng is not None, "stratified folds are drawn: they need a generator"
    folds = np.empty(codes.size, int)
    k = int(min(k, codes.size))
    offset = 0
    for lv in rng.permutation(codes.max() + 1):
        idx = np.flatnonzero(codes == lv)
        idx = idx[rng.permutation(idx.size)]
        folds[idx] = (np.arange(idx.size) + offset) % k
        offset += idx.size
    return folds


def fold_labels(group: Group, rows: np.ndarray, causes: Iterable[str]) -> np.ndarray:
    """Labels to stratify folds by: the joint level of the categorical ``causes`` on the
    tests ``rows`` (a trend, with a value per test, stratifies nothing)."""
    labels = np.full(rows.size, "", dtype=object)
    for cause in causes:
        values = candidate_values(group.tests, cause).iloc[rows]
        if values.nunique() <= max(8, rows.size // 4):
            labels = labels + "|" + np.array([str(v) for v in values], dtype=object)
    return labels.astype(str)


@dataclass(frozen=True, eq=False)
class GroupFolds:
    """One set of folds for every cross-validation of a (kind, soil) over its tests:
    each finding's (cause fixed, whole search) on the tests in its scope, and forward
    selection's on all of them.  With the same folds a finding's gain and the first step of
    forward selection are the same measurement where the scope is every test (until issue
    #35 each drew its own folds, and an extension kept by its finding at 1.2 SE could miss
    the combined model at 0.9 SE on other folds of the same tests)."""

    rows: np.ndarray  # the usable tests (rows of the group's table), sorted
    folds: np.ndarray  # the fold of each

    def of(self, rows: ArrayLike) -> np.ndarray:
        """The folds of the tests ``rows`` (a subset of :attr:`rows`)."""
        return self.folds[np.searchsorted(self.rows, np.asarray(rows, int))]


def group_folds(group: Group, causes: Iterable[str], rng: np.random.Generator) -> GroupFolds:
    """The folds of a group's usable tests, stratified by the joint level of its leading
    ``causes`` (:func:`fold_labels`), drawn from ``rng``."""
    rows = np.unique(group.owner)
    return GroupFolds(rows, make_folds(fold_labels(group, rows, causes), "tests", rng))


class HeldOutModel(Protocol):
    """What :func:`campaign_gain` reads of a combined model (:class:`.selection
    .CombinedModel`; that module imports this one, so an import back would close a loop)."""

    @property
    def held_out(self) -> tuple | None: ...

    @property
    def gain(self) -> Gain | None: ...


#: A fold whose training tests did not choose the extension (:mod:`.nested`): its held-out
#: tests are predicted by the base model.
_BASE = object()
#: A fold whose training tests chose the very extension another plan fits on the same fold
#: (the whole search re-selecting the named cause, :mod:`.nested`): its held-out errors are
#: that plan's (``same_errors`` of :meth:`FoldFits.collect`), not fitted twice.
SAME = object()


class FoldFits:
    """The fold fits of one model, as :class:`~.work.FitTask` to run (``tasks``), then
    :meth:`collect`-ed into the fits and each test's held-out error.

    ``ext`` is fitted without each fold (started from ``starts[fold]`` when given: the base
    model's fit of that fold) and predicts the fold's tests.  ``ext`` may also be a mapping
    fold → extension (the one each fold's training tests chose, :mod:`.nested`), None (that
    fold chose no extension: its held-out errors are ``base_errors``, the base model's, same
    rows) or :data:`SAME` (the fold's extension is one another plan fits on the same fold:
    its errors are given to :meth:`collect`).  Planning and collecting are apart so that the
    fold fits of several models can run in one wave (:mod:`.work`); the tasks form one
    ``chain``: after a fold that fails, the rest need not run.
    """

    def __init__(
        self,
        rows: ArrayLike,
        ext: Extension | dict[int, Extension | object | None],  # object: SAME
        folds: ArrayLike,
        *,
        scheme: str,
        starts: Mapping[int, FitStart | None] | None = None,
        chain: Hashable = 0,
        base_errors: ArrayLike | None = None,
    ) -> None:
        self.rows = np.asarray(rows, int)
        self.folds = np.asarray(folds)
        self.scheme = scheme
        self.base_errors = base_errors
        self.plan: list[tuple[int, object]] = []
        for fold in np.unique(self.folds):
            train = self.rows[self.folds != fold]
            test = self.rows[self.folds == fold]
            start = None if starts is None else starts[int(fold)]
            model = ext.get(int(fold)) if isinstance(ext, dict) else ext
            if model is None:
                task = _BASE
            elif model is SAME:
                task = SAME
            else:
                # Neither None nor SAME: an extension.
                fit = cast("Extension", model)
                task = FitTask(fit, train, start, test, chain) if train.size >= 2 else None
            self.plan.append((int(fold), task))
        self.tasks = [task for _, task in self.plan if isinstance(task, FitTask)]
        #: Folds whose training tests chose the extension (not predicted by the base model).
        self.extended = sum(task is not _BASE for _, task in self.plan)

    def collect(
        self, outcomes: Iterable[Outcome], same_errors: ArrayLike | None = None
    ) -> tuple[dict[int, Start | None], np.ndarray]:
        """(fits by fold, each test's held-out error) from the outcomes of ``tasks``;
        ``same_errors``: the held-out errors (same rows) of the plan whose fold fits the
        :data:`SAME` folds share.

        Raises :class:`ConvergenceError` or :class:`IdentifiabilityError` naming the first
        fold (in fold order) whose fit failed or had fewer than two training tests: an error
        is never computed from a failed fit.
        """
        outcomes = iter(outcomes)
        fits: dict[int, Start | None] = {}
        errors = np.empty(self.rows.size)
        for fold, task in self.plan:
            if task is _BASE or task is SAME:
                fits[fold] = None
                known = self.base_errors if task is _BASE else same_errors
                errors[self.folds == fold] = np.asarray(known)[self.folds == fold]
                continue
            if task is None:
                raise IdentifiabilityError(
                    f"cross-validation fold {fold} ({self.scheme}): fewer than two training tests"
                )
            outcome = next(outcomes)
            exc = outcome.error
            if isinstance(exc, ConvergenceError | IdentifiabilityError):
                raise type(exc)(f"cross-validation fold {fold} ({self.scheme}): {exc}") from exc
            outcome.raise_error()
            fits[fold] = cast("Start", outcome.fitted)  # a fold fit comes back as its Start
            errors[self.folds == fold] = outcome.errors
        return fits, errors


def compare(
    e_base: np.ndarray,
    e_ext: np.ndarray,
    *,
    scheme: str,
    folds: ArrayLike,
    selected_folds: int | None = None,
) -> Gain:
    """The gain of the per-test errors ``e_ext`` over ``e_base`` (the same held-out tests);
    ``selected_folds``: see :class:`Gain`."""
    d = np.asarray(e_base) - np.asarray(e_ext)
    stderr = float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else np.inf
    base, extended = float(np.sqrt(np.mean(e_base))), float(np.sqrt(np.mean(e_ext)))
    relative = 1.0 - extended / base if base > 0 else np.nan
    return Gain(
        metric=METRIC,
        scheme=scheme,
        folds=int(np.unique(folds).size),
        n_tests=int(d.size),
        base=base,
        extended=extended,
        relative=float(relative),
        difference=float(d.mean()),
        stderr=stderr,
        real=evidence.is_real(float(d.mean()), stderr, float(relative)),
        selected_folds=selected_folds,
        kept=bool(d.mean() > Z_KEEP * stderr and relative > 0 and d.mean() > 0),
    )


def cross_validation(
    group: Group,
    rows: np.ndarray,
    base_ext: Extension,
    ext: Extension | dict[int, Extension | object | None],
    folds: np.ndarray,
    *,
    scheme: str,
) -> Process[Gain]:
    """Process (:mod:`.work`) of the held-out prediction error of ``base_ext`` and ``ext``
    on the tests ``rows``: the base model's fold fits, then the extension's (each started
    from the base model's fit of its fold), each one wave; returns the :class:`Gain`.

    ``folds`` (one fold number per row, from :func:`make_folds`) is shared by every
    extension compared for one finding, so their gains differ by the model only.  Raises
    :class:`ConvergenceError` when a fold's fit does not converge and
    :class:`IdentifiabilityError` when a fold leaves too little to fit (the fold, the model
    and the reason are in the message): a gain is never computed from a failed fit."""
    base_plan = FoldFits(rows, base_ext, folds, scheme=scheme, chain="base")
    starts, e_base = base_plan.collect((yield Wave(group, base_plan.tasks)))
    plan = FoldFits(rows, ext, folds, scheme=scheme, starts=starts, chain="extension")
    e_ext = plan.collect((yield Wave(group, plan.tasks)))[1]
    return compare(e_base, e_ext, scheme=scheme, folds=folds)


def information_criteria(result: FitResult) -> dict:
    """AIC and BIC of a weighted least-squares fit: N ln(RSS/N) + 2p (or p ln N)."""
    n, p = result.nobs, len(result.param_names)
    ll = n * np.log(result.rss / n)
    return {"aic": float(ll + 2 * p), "bic": float(ll + p * np.log(n)), "nobs": n, "params": p}


def campaign_gain(models: Sequence[HeldOutModel]) -> Gain | None:
    """The gain of the combined models over the base models, every extended (kind, soil)
    together: the same paired per-test comparison over all their held-out tests."""
    pairs = [m.held_out for m in models if m.held_out is not None]
    if not pairs:
        return None
    e_base = np.concatenate([p[0] for p in pairs])
    e_ext = np.concatenate([p[1] for p in pairs])
    folds = max(m.gain.folds for m in models if m.gain is not None)
    return compare(e_base, e_ext, scheme="tests", folds=np.arange(folds))
