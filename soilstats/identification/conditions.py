"""Per soil and condition identification: the paper's Tables 5–7 as one library call.

A *condition* is one value of a test-log column (``by``: velocity, preparation, ring size …).
Each (soil, condition) is fitted on its own with the paper's weighted LM (Section 2.1 pooling
within it, never across conditions).  Campaigns with a ``series`` column keep their series
apart too: tests of different series are different experiments and are never pooled.

Used by ``soilstats identify`` and by every study's parameter table.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pandas as pd

from ..errors import CampaignError, ConvergenceError, IdentifiabilityError
from ..models import get_model
from ..parallel import effective_jobs, parallel_map
from ..quality import screened
from .result import CampaignFit

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..quality import ScreenedCampaign
from .shear import fit_shear
from .sinkage import fit_sinkage
from .table import format_parameter_table, parameter_table

__all__ = [
    "ConditionFit",
    "ConditionFits",
    "ConditionPlan",
    "ConditionTask",
    "condition_label",
    "default_condition",
    "fit_conditions",
    "fit_planned",
    "plan_conditions",
]

#: Test-log columns that define conditions when the caller names none, in order of preference.
DEFAULT_CONDITION_COLUMNS = {
    "sinkage": ("velocity_m_s", "preparation"),
    "shear": ("tool", "r_inner_m"),
}


def condition_label(value: object) -> str:
    """A condition value as text: numbers in short general format (4.8e-3 → '0.0048')."""
    if isinstance(value, float | np.floating):
        return f"{value:g}"
    return str(value)


def default_condition(
    tests: pd.DataFrame, kind: str, requested: str | None = None, file: str = "tests.csv"
) -> str | None:
    """The column whose values are the conditions: ``requested`` (checked), else the first of
    :data:`DEFAULT_CONDITION_COLUMNS` that varies among ``tests``, else None (one condition).
    ``file``: the test log's name, for messages."""
    if requested:
        if requested not in tests.columns:
            raise CampaignError(
                f"condition column {requested!r} is not a test-log column; "
                f"columns: {list(tests.columns)}",
                file=file,
                column=requested,
            )
        return requested
    for column in DEFAULT_CONDITION_COLUMNS[kind]:
        if column in tests.columns and tests[column].dropna().nunique() > 1:
            return column
    return None


@dataclass(frozen=True)
class ConditionFit:
    """One (soil, series, condition) and its pooled fit."""

    kind: str
    soil: str
    series: str | None
    column: str | None
    condition: str
    model: str
    fit: CampaignFit = field(repr=False)

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "soil": self.soil,
            "series": self.series,
            "condition": {"column": self.column, "value": self.condition} if self.column else None,
            "model": self.model,
        } | {k: v for k, v in self.fit.to_dict().items() if k != "model"}


@dataclass(frozen=True)
class ConditionFits:
    """Every (soil, condition) fit of one call, the conditions that failed, and why."""

    fits: tuple[ConditionFit, ...]
    failures: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def blocks(self) -> dict[tuple, dict[str, CampaignFit]]:
        """Fits grouped for Table-5 display: (kind, series, soil, model, column) → {label: fit}."""
        out: dict[tuple, dict[str, CampaignFit]] = {}
        for f in self.fits:
            key = (f.kind, f.series, f.soil, f.model, f.column)
            out.setdefault(key, {})[f.condition] = f.fit
        return out

    def table(self) -> pd.DataFrame:
        """Tidy: one row per soil, condition and parameter (see :func:`parameter_table`)."""
        frames = [
            parameter_table(fits).assign(kind=k, series=s, soil=soil, model=m)
            for (k, s, soil, m, _), fits in self.blocks().items()
        ]
        return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()

    def summary(self) -> str:
        """Table 5-style blocks, then the conditions not identified and the notes."""
        lines = []
        for (kind, series, soil, model, column), fits in self.blocks().items():
            where = f" · series {series}" if series else ""
            title = f"{kind}{where} · {soil} · {model} · conditions by {column or '(all tests)'}"
            lines += ["", format_parameter_table(fits, title=title)]
        windows = sorted({f.fit.window for f in self.fits if f.fit.window != "none"})
        lines += [f"  window: {w}" for w in windows]
        lines += [f"  ! not identified: {failure}" for failure in self.failures]
        lines += [f"  note: {note}" for note in self.notes]
        return "\n".join(lines).lstrip("\n")

    def to_dict(self) -> dict:
        return {
            "fits": [f.to_dict() for f in self.fits],
            "failures": list(self.failures),
            "notes": list(self.notes),
        }


#: Bekker-type models need plates whose sizes differ at least this much (largest / smallest
#: b): kc/b + kphi separates kc from kphi only through the spread of 1/b. At 1.5 the kc
#: term changes by a third across the plates; plates of 20 and 22.5 mm (1.125) change it by
#: 11 %, which no real scatter lets a fit resolve.
MIN_SIZE_RATIO = 1.5


def model_for(
    kind: str, model: str, fallback: str | None, tests: pd.DataFrame
) -> tuple[str | None, str | None]:
    """(model to fit or None, note): a model whose record needs several plate sizes
    (``Model.min_plate_sizes``: Bekker, Reece) falls back where the condition has fewer."""
    if kind == "shear":
        return model, None
    if model == "auto":
        model, fallback = "bekker", fallback or "bernstein"
    sizes = tests["b_m"].dropna()
    needed = get_model(model).min_plate_sizes
    if needed < 2:
        return model, None
    if sizes.nunique() < needed:
        why = f"one plate size: {model}'s kc and kphi cannot be separated (Section 2.1)"
        return (fallback, why) if fallback else (None, why)
    if sizes.max() / sizes.min() < MIN_SIZE_RATIO:
        why = (
            f"plate sizes b = {sizes.min():g}-{sizes.max():g} m differ by less than "
            f"{MIN_SIZE_RATIO:g}x: kc/b and kphi cannot be told apart by this design"
        )
        return (fallback, why) if fallback else (None, why)
    return model, None


class ConditionTask(NamedTuple):
    """One (soil, series, condition) to fit: where it is (for messages), the table keys, the
    model and its tests."""

    where: str
    soil: str
    series: str | None
    column: str | None
    label: str
    model: str
    test_ids: list[str]


@dataclass(frozen=True)
class ConditionPlan:
    """The conditions one :func:`fit_conditions` call fits, before any fitting: the
    screened (and windowed) campaign, the fit of every (soil, series, condition) as a task,
    and the notes of the planning (:func:`plan_conditions`; run by :func:`fit_planned`)."""

    campaign: ScreenedCampaign = field(repr=False)
    kind: str
    tasks: tuple[ConditionTask, ...]  # in table order
    options: dict
    notes: tuple[str, ...] = ()


def plan_conditions(
    campaign: Campaign,
    kind: str,
    *,
    by: str | None = None,
    model: str = "auto",
    fallback_model: str | None = None,
    soils: Sequence[str] | None = None,
    test_ids: Sequence[str] | None = None,
    **options: Any,  # fit_sinkage's or fit_shear's keywords, each of its own type
) -> ConditionPlan:
    """The conditions :func:`fit_conditions` would fit (same arguments, no ``jobs``)."""
    prepared = screened(campaign, options.pop("quality", "clean"))
    prepared = prepared.windowed(options.pop("window", None))
    tests = prepared.tests[prepared.tests["kind"] == kind]
    if test_ids is not None:
        tests = tests[tests["test_id"].astype(str).isin(set(map(str, test_ids)))]
    if soils is not None:
        tests = tests[tests["soil"].astype(str).isin(set(map(str, soils)))]
    if kind == "shear" and model == "auto":
        model = "mohr-coulomb"
    for name in (model, fallback_model):  # an unknown name or kind: an error, before any fit
        if name is not None and name != "auto":
            get_model(name, kind)
    fallbacks: dict[tuple, list[str]] = {}
    tasks = []
    by_series: list[tuple[str | None, pd.DataFrame]]
    if "series" in tests.columns:
        by_series = [(str(k), g) for k, g in tests.groupby("series", sort=True, dropna=False)]
    else:
        by_series = [(None, tests)]
    for series, series_tests in by_series:
        column = default_condition(series_tests, kind, by, prepared.file_name("tests"))
        keys = ["soil", column] if column else ["soil"]
        for key, group in series_tests.groupby(keys, sort=True, dropna=False):
            soil = str(key[0])
            label = condition_label(key[1]) if column else "all"
            where = soil + (f", series {series}" if series else "")
            where += f", {column} {label}" if column else ""
            chosen, why = model_for(kind, model, fallback_model, group)
            if why:
                fallbacks.setdefault((why, chosen), []).append(where)
            if chosen is not None:
                ids = list(group["test_id"].astype(str))
                tasks.append(ConditionTask(where, soil, series, column, label, chosen, ids))
    notes = tuple(
        f"{why}; {chosen + ' used' if chosen else 'not identified'}: {'; '.join(where)}"
        for (why, chosen), where in fallbacks.items()
    )
    return ConditionPlan(prepared, kind, tuple(tasks), options, notes)


def fit_conditions(
    campaign: Campaign,
    kind: str,
    *,
    by: str | None = None,
    model: str = "auto",
    fallback_model: str | None = None,
    soils: Sequence[str] | None = None,
    test_ids: Sequence[str] | None = None,
    jobs: int | None = 1,
    progress: bool = False,
    **options: Any,  # as plan_conditions'
) -> ConditionFits:
    """Fit every soil × series × condition of ``kind`` in ``campaign`` separately.

    Parameters
    ----------
    campaign : Campaign
    kind : ``"sinkage"`` or ``"shear"``
    by : str, optional
        Test-log column whose values are the conditions (default: :func:`default_condition`).
    model : str
        A registered model of ``kind`` (:func:`soilstats.models.models_of_kind`): sinkage
        ``auto`` (Bekker, Bernstein where one plate size), ``bekker``, ``bernstein``,
        ``reece``; shear ``mohr-coulomb`` or ``janosi`` (``auto`` means Mohr–Coulomb); or
        one's own (:func:`soilstats.register_model`).
    fallback_model : str, optional
        Model for a condition with one plate size when ``model`` needs several (else the
        condition is reported as not identified).
    soils, test_ids : sequence of str, optional
        Restrict to these soils / tests.
    jobs : int, default 1
        Worker processes over the conditions (:func:`soilstats.parallel.parallel_map`;
        −1: every core).  The result is the same for any number: each condition's fit,
        bootstrap seed included, depends on its own tests only.
    progress : bool
        A tqdm bar over the conditions.
    **options
        Passed to :func:`fit_sinkage` or :func:`fit_shear` (``method``, ``points_per_test`` …).
    """
    plan = plan_conditions(
        campaign,
        kind,
        by=by,
        model=model,
        fallback_model=fallback_model,
        soils=soils,
        test_ids=test_ids,
        **options,
    )
    return fit_planned([plan], jobs=jobs, progress=progress)[0]


def fit_planned(
    plans: Sequence[ConditionPlan], *, jobs: int | None = 1, progress: bool = False
) -> list[ConditionFits]:
    """The :class:`ConditionFits` of each plan, their conditions fitted over ``jobs``
    workers as one queue (``soilstats identify`` plans sinkage and shear, then fits both
    at once: no worker waits for the other kind to finish)."""
    # Workers get only their condition's tests (a small pickle, each plan's campaign cut
    # in one pass); in-process the campaign is used as it is. Both fit the same samples:
    # fit_* selects test_id=ids either way. The largest conditions go out first, so that no
    # worker starts a long fit while the other has nothing left to do.
    items = [(plan, task) for plan in plans for task in plan.tasks]
    one_process = effective_jobs(jobs) == 1 or len(items) < 2
    if one_process:
        pieces = [plan.campaign for plan, _ in items]
        order = list(range(len(items)))
    else:
        pieces = [
            _for_worker(piece, task.test_ids)
            for plan in plans
            for piece, task in zip(
                plan.campaign.partition([t.test_ids for t in plan.tasks]) if plan.tasks else [],
                plan.tasks,
                strict=True,
            )
        ]
        order = sorted(range(len(items)), key=lambda i: -_size(pieces[i], items[i][0].kind))
    kinds = "+".join(dict.fromkeys(plan.kind for plan in plans))
    sent = []
    for i in order:
        plan, task = items[i]
        # The record itself, not its name: a model registered in this process only
        # reaches a worker process that way.
        spec = get_model(task.model)
        sent.append((pieces[i], plan.kind, spec, task.test_ids, plan.options))
    done = parallel_map(
        _fit_condition,
        sent,
        jobs=jobs,
        progress=progress,
        desc=f"{kinds} conditions",
    )
    outcomes: list = [None] * len(items)
    for i, outcome in zip(order, done, strict=True):
        outcomes[i] = outcome
    results, start = [], 0
    for plan in plans:
        fits, failures = [], []
        for task, outcome in zip(
            plan.tasks, outcomes[start : start + len(plan.tasks)], strict=True
        ):
            if isinstance(outcome, str):
                failures.append(f"{task.where}: {task.model} — {outcome}")
            else:
                fits.append(
                    ConditionFit(
                        plan.kind,
                        task.soil,
                        task.series,
                        task.column,
                        task.label,
                        task.model,
                        outcome,
                    )
                )
        start += len(plan.tasks)
        results.append(ConditionFits(tuple(fits), tuple(failures), plan.notes))
    return results


def _for_worker(piece: ScreenedCampaign, ids: Sequence[str]) -> ScreenedCampaign:
    """A condition's campaign with its screening report and window cut to its tests: the
    fit reads only theirs, and the whole campaign's, sent with every condition, would grow
    as conditions × tests."""
    window = piece.window
    if window is not None:
        kept = window.per_test["test_id"].astype(str).isin(set(ids))
        window = replace(window, per_test=window.per_test[kept])
    return replace(piece, report=piece.report.for_tests(ids), window=window)


#: Time per sample of a condition's fit, relative to a sinkage sample (measured on the
#: 10,000-test benchmark campaign: a shear condition adds its Mohr–Coulomb line and a
#: bootstrap of two fits).  Only the order conditions go to workers depends on it.
_COST_PER_SAMPLE = {"sinkage": 1.0, "shear": 4.0}


def _size(piece: ScreenedCampaign, kind: str) -> float:
    """A condition's expected fitting time, in sinkage samples (the dispatch order)."""
    return _COST_PER_SAMPLE[kind] * len(piece.sinkage if kind == "sinkage" else piece.shear)


def _fit_condition(task: tuple[Any, str, Any, Sequence[str], dict[str, Any]]) -> CampaignFit | str:
    """One condition's pooled fit, or the reason it failed (a task of :func:`parallel_map`)."""
    campaign, kind, model, ids, options = task
    fitter = fit_sinkage if kind == "sinkage" else fit_shear
    try:
        return fitter(campaign, model, test_id=ids, **options)
    except (ConvergenceError, IdentifiabilityError, CampaignError) as err:
        return str(err)
