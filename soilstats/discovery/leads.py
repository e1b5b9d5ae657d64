"""A group's leads, strongest first, each to a finding (steps 3–4 of :mod:`.pipeline`).

The significant candidates of one (kind, soil) are grouped where the design confounds them,
and each group is led by its designed factor (:func:`leads_of`).  Each lead is then examined
(:func:`discover_group`): the library's extensions are cross-validated on the tests in scope
and one is kept only where its out-of-sample gain is real and its parameters plausible; a
later lead that the kept extension already explains is no finding.  The examination is a
*process* (:mod:`.work`): it yields the fits it needs in waves and receives their outcomes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pandas as pd

from ..errors import ConvergenceError, IdentifiabilityError
from .candidates import candidate_values, trend_on_log
from .crossval import (
    SAME,
    FoldFits,
    compare,
    cross_validation,
    information_criteria,
    make_folds,
)
from .diagnose import conditional_responses, retest
from .library import base_model, library
from .nested import fold_choices, fold_extensions
from .plausibility import implausible
from .result import Finding
from .testlevel import scatter_caveat, test_level
from .work import FIT_ERRORS, FitTask, Wave

if TYPE_CHECKING:
    from ..fitting.result import FitResult
    from .candidates import Relation
    from .crossval import Gain, GroupFolds
    from .data import Group
    from .diagnose import Diagnosis
    from .extensions import Extension, Fitted
    from .work import Process, Start

__all__ = ["discover_group", "leads_of"]


def leads_of(rows: pd.DataFrame, relations: Iterable[Relation]) -> list[tuple[str, list[str]]]:
    """(lead, confounded members) per connected group of significant, confounded candidates."""
    sig = rows[rows["significant"]]
    if sig.empty:
        return []
    best = sig.sort_values(["p_adjusted", "p_value", "statistic"], ascending=[True, True, False])
    order = list(dict.fromkeys(best["candidate"]))
    role = dict(zip(best["candidate"], best["role"], strict=True))
    members = set(order)
    adj: dict[str, set[str]] = {m: set() for m in members}
    finer: set[str] = set()
    aliased: dict[str, set[str]] = {m: set() for m in members}
    for r in relations:
        if r.finer in members and r.coarser in members:
            adj[r.finer].add(r.coarser)
            adj[r.coarser].add(r.finer)
            if r.kind == "nested":
                finer.add(r.finer)
        if r.kind == "aliased":
            for a, b in ((r.finer, r.coarser), (r.coarser, r.finer)):
                if a in aliased:
                    aliased[a].add(b)
    seen: set[str] = set()
    out = []
    for name in order:
        if name in seen:
            continue
        comp, stack = set(), [name]
        while stack:
            m = stack.pop()
            if m not in comp:
                comp.add(m)
                stack.extend(adj[m] - comp)
        seen |= comp
        # The designed factor leads a confounded group (the experimenter set it; a covariate
        # or the test day merely travelled with it), then the coarsest member, then p.
        in_comp = [m for m in order if m in comp]
        design = [m for m in in_comp if role.get(m) == "design"]
        pool = design or in_comp
        eligible = [m for m in pool if m not in finer] or pool
        lead = eligible[0]
        others = [m for m in order if m in comp and m != lead]
        others += sorted(aliased[lead] - set(others) - {lead})
        out.append((lead, others))
    return out


def _caveats(lead_rows: pd.DataFrame, lead: str, confounded: list[str]) -> list[str]:
    out = []
    if confounded:
        out.append(
            f"{lead} cannot be separated from {', '.join(confounded)} in this design; the named "
            "cause is the coarsest of them with the smallest p, not a proven mechanism"
        )
    top = lead_rows.sort_values(["p_adjusted", "p_value"]).iloc[0]
    if top.get("deviating"):
        what = "block that drifts" if top["role"] == "drift within blocks" else "cell that deviates"
        out.append(
            f"the {what} most: {top['deviating']} (the largest of "
            f"{int(top['patterns'])} one-degree-of-freedom tests, Bonferroni-adjusted)"
        )
    singles = [s for s in lead_rows["singleton_levels"] if s]
    if singles:
        out.append(
            f"level(s) {singles[0]} of {lead} rest on a single test each: their part of the "
            "effect is one test's scatter as much as the level's"
        )
    return out


# The candidate a physical extension is written in; among *aliased* candidates (identical
# partitions, which no data can tell apart) the finding is named after it.
_PHYSICS_NAME = {
    "softening": "aspect_ratio",
    "velocity": "velocity_m_s",
    "side-walls": "grouser_height_m",
    "reece": "b_m",
}


def _physical_name(lead: str, extension: str, relations: Sequence[Relation]) -> str:
    want = _PHYSICS_NAME.get(extension)
    for r in relations:
        if want is not None and r.kind == "aliased" and {r.finer, r.coarser} == {lead, want}:
            return want
    return lead


def _search_plan(ext, choices, library_args):
    """fold → what the whole search fits there for ``ext`` (:mod:`.nested`): None where the
    fold's training tests do not choose the lead (the base model predicts), :data:`SAME`
    where they choose the very extension the cause-fixed plan fits on that fold (its fold
    fit is shared), else the fold's own extension."""
    out = {}
    for fold, chosen in fold_extensions(ext, choices, **library_args).items():
        out[fold] = SAME if chosen == ext else chosen
    return out


def _extension_plans(
    extensions: list,
    rows: np.ndarray,
    folds: np.ndarray,
    starts: dict,
    e_base: np.ndarray | None,
    base_fitted: Fitted | None,
    choices: Any,
    library_args: dict,
) -> tuple[list[tuple[FoldFits, FoldFits]], list[FitTask]]:
    """Per extension its cause-fixed and whole-search fold plans (:class:`.work.FoldFits`),
    and the tasks of the second wave: chain i holds extension i's folds, then its fit on all
    tests (started from the base fit), then its search folds."""
    plans, tasks = [], []
    for i, ext in enumerate(extensions):  # chain i: the folds, then all tests
        fixed = FoldFits(rows, ext, folds, scheme="tests", starts=starts, chain=i)
        search = FoldFits(
            rows,
            _search_plan(ext, choices, library_args),
            folds,
            scheme="tests",
            starts=starts,
            chain=(i, "search"),
            base_errors=e_base,
        )
        plans.append((fixed, search))
        tasks += [*fixed.tasks, FitTask(ext, rows, base_fitted, chain=i), *search.tasks]
    return plans, tasks


def _tried_entry(
    entry: dict, gain: Gain, search_gain: Gain | None, reasons: list[str]
) -> dict:
    """``entry`` (a tried extension's record) with its gains, cause fixed and whole search,
    and the reasons its parameters are implausible."""
    entry.update(
        relative=gain.relative,
        real=gain.real,
        verdict=gain.verdict,
        kept=gain.kept,
        difference=gain.difference,
        stderr=gain.stderr,
        z=gain.z,
        base=gain.base,
        extended=gain.extended,
        relative_search=None if search_gain is None else search_gain.relative,
        selected_folds=None if search_gain is None else search_gain.selected_folds,
        implausible=reasons,
    )
    return entry


def _try_extensions(
    group, rows, lead, confounded, numeric, responses, folds, log_scale, lead_table
):
    """Cross-validate every applicable extension on the same folds and fit it on all tests
    in scope.

    Two gains per extension, on the same folds (:mod:`.crossval`, whole tests left out):

    * **cause fixed** — the named cause and the responses it showed in (both established by
      the Holm-controlled test on all tests) stay fixed; every fold fits the extension on
      its training tests and predicts its held-out tests.  This is the gain of the named
      cause's extension, and it decides what is kept (:func:`.crossval.compare`'s rule,
      whose false-keep rate on null leads docs/discover.md states);
    * **whole search** — each fold repeats the choice of the lead on its training tests
      (:mod:`.nested`, from ``lead_table``, the lead's diagnosis rows): a fold where the lead
      is not significant predicts with the base model.  The gain of the whole search,
      reported beside the other, never deciding.  Folds that choose what the cause-fixed
      plan fits share its fold fit.

    Preference: a physical extension with a real gain and physically plausible parameters
    (no value outside its range, e.g. K0 > 1), else the generic one with a real gain, else
    the best gain (not kept).  Returns ``(base, base fitted, chosen, tried)``, chosen being
    ``(extension, gain, fitted, implausible, search gain)`` (the reasons it is not
    physical, empty when it is; the search gain None when a fold of its own failed) or None.

    A process (:mod:`.work`): the fits go out in two waves, the base model on all tests and
    without each fold, then every extension without each fold (started from the base
    model's fit of that fold) and on all tests (started from the base fit).  Errors are
    recorded where the one-at-a-time loop met them: a base fit that fails raises, a failed
    fold or full fit of an extension is that extension's ``error``.
    """
    base_ext = base_model(group, rows)
    library_args = dict(
        group=group,
        rows=rows,
        cause=lead,
        related=confounded,
        numeric=numeric,
        log_scale=log_scale,
    )
    extensions = library(**library_args, responses=responses)
    # One chain, in the order the base model is read: its fit on all tests, then the folds.
    base_plan = FoldFits(rows, base_ext, folds, scheme="tests", chain="base")
    first = yield Wave(group, [FitTask(base_ext, rows, chain="base"), *base_plan.tasks])
    first[0].raise_error()
    base_fitted = first[0].fitted
    base_failure = None
    try:
        starts, e_base = base_plan.collect(first[1:])
    except FIT_ERRORS as exc:
        base_failure = exc  # every extension's cross-validation fails with it
    plans: list[tuple[FoldFits, FoldFits]] = []
    tasks: list[FitTask] = []
    if base_failure is None:
        # The base model's fold fits: one per fold, none skipped.
        choices = fold_choices(group, lead_table, rows, folds, cast("dict[int, Start]", starts))
        plans, tasks = _extension_plans(
            extensions, rows, folds, starts, e_base, base_fitted, choices, library_args
        )
    outcomes = iter((yield Wave(group, tasks, probe=True)))
    tried, options = [], []
    for i, ext in enumerate(extensions):
        entry = {"extension": ext.name, "physical": ext.physical, "description": ext.description}
        search_gain = None
        try:
            if base_failure is not None:
                raise base_failure
            fixed, search = plans[i]
            folds_out = [next(outcomes) for _ in fixed.tasks]
            full = next(outcomes)
            search_out = [next(outcomes) for _ in search.tasks]
            e_ext = fixed.collect(folds_out)[1]
            gain = compare(e_base, e_ext, scheme="tests", folds=folds)
            full.raise_error()
            fitted = full.fitted
            try:
                e_search = search.collect(search_out, same_errors=e_ext)[1]
                search_gain = compare(
                    e_base, e_search, scheme="tests", folds=folds, selected_folds=search.extended
                )
            except FIT_ERRORS as exc:
                entry["search_error"] = str(exc)[:400]
        except FIT_ERRORS as exc:
            entry["error"] = str(exc)[:400]
            tried.append(entry)
            continue
        reasons = implausible(fitted, base_fitted, group, rows)
        tried.append(_tried_entry(entry, gain, search_gain, reasons))
        # An implausible extension is never kept, however much it gains.
        plausible = bool(gain.kept) and not reasons
        rank = (plausible, plausible and ext.physical, gain.relative)
        options.append((rank, ext, gain, fitted, reasons, search_gain))
    if not options:
        return base_ext, base_fitted, None, tried
    return base_ext, base_fitted, max(options, key=lambda o: o[0])[1:], tried


def discover_group(
    diag: Diagnosis,
    rows: pd.DataFrame,
    leads: Sequence[tuple[str, list[str]]],
    *,
    alpha: float,
    folds: GroupFolds,
    max_leads: int,
) -> Process[tuple[list[Finding], list[dict]]]:
    """Process (:mod:`.work`) of the findings of one (kind, soil), leads strongest first, and
    the leads that an extension kept before them already explains: ``(findings,
    explained)``.  ``folds``: the group's folds (:class:`.crossval.GroupFolds`)."""
    g = diag.group
    findings, explained = [], []
    accepted = None  # (name, fitted) of the latest kept extension in this group
    for lead, confounded_with in leads[:max_leads]:
        lead_rows = rows[(rows["candidate"] == lead) & rows["significant"]]
        top = lead_rows.sort_values(["p_adjusted", "p_value"]).iloc[0]
        if accepted is not None:
            why = _explained_by(
                g, accepted, lead, top, set(lead_rows["response"]), n_leads=len(leads), alpha=alpha
            )
            if why is not None:
                explained.append(why)
                continue
        finding = yield from _examine_lead(
            g, diag.relations, lead_rows, top, lead, confounded_with, folds, rows
        )
        findings.append(finding)
        if finding.extension is not None:
            # Re-test later leads against this extension fitted on the whole group.
            ext = finding.fitted.extension
            whole = (yield Wave(g, [FitTask(ext, np.unique(g.owner))]))[0]
            if isinstance(whole.error, ConvergenceError | IdentifiabilityError):
                accepted = (ext.name, finding.fitted)
            else:
                whole.raise_error()
                accepted = (ext.name, whole.fitted)
    return findings, explained


def _explained_by(
    g: Group,
    accepted: tuple[str, Fitted],
    lead: str,
    top: pd.Series,
    responses: set[str],
    *,
    n_leads: int,
    alpha: float,
) -> dict | None:
    """The record of ``lead`` explained by the accepted extension (every response in which it
    was significant, ``responses``, re-tested, and none significant any more, Bonferroni over
    the leads), or None when it still shows — or when a response it showed in cannot be
    re-tested against the extension: a lead is never called explained for want of a test."""
    cond_table = conditional_responses(g, accepted[1])
    p_after = retest(g, cond_table, top)
    if not all(np.isfinite(p_after.get(r, np.nan)) for r in responses):
        return None
    if any(p * n_leads < alpha for p in p_after.values() if np.isfinite(p)):
        return None
    return {
        "kind": g.kind,
        "soil": g.soil,
        "candidate": lead,
        "by": accepted[0],
        "p_after": float(np.nanmin([*p_after.values(), 1.0])),
    }


def _examine_lead(g, relations, lead_rows, top, lead, confounded_with, folds, rows):
    """Process (:mod:`.work`) of one finding: try the library's extensions on the tests in
    scope, keep one only where its cross-validated gain is real, and state every caveat.
    ``rows``: the group's diagnosis rows (each fold repeats the lead's test, :mod:`.nested`)."""
    scope = np.asarray(top["rows"], int)
    lead_table = rows[rows["candidate"] == top["candidate"]]
    levels = candidate_values(g.tests, lead).astype(str).to_numpy()[scope]
    responses = tuple(lead_rows["response"])
    caveats = _caveats(lead_rows, lead, confounded_with)
    base_ext, base_fitted, chosen, tried = yield from _search_extensions(
        g, top, lead, confounded_with, folds, scope, responses, lead_table, caveats
    )
    kept = chosen is not None and bool(chosen[1].kept) and not chosen[3]
    if kept and chosen[0].physical:
        lead = _physical_name(lead, chosen[0].name, relations)
        confounded_with = [m for m in [top["candidate"], *confounded_with] if m != lead]
    fitted = chosen[2] if chosen is not None else None
    fit = fitted.result if fitted is not None else None
    # The printed ± of the kept fit is Eq. 4's, which treats samples as independent: its
    # test-level counterpart (one Jacobian, no refit) says when the tests scatter more.
    # kept: an extension was chosen, so ``fitted`` and ``fit`` are set.
    level = test_level(cast("Fitted", fitted), g, scope) if kept else None
    if (scatter := scatter_caveat(cast("FitResult", fit), level)) is not None:
        caveats.append(scatter)
    base_fit = base_fitted.result if chosen is not None else None
    info, gain_cond = {}, None
    if chosen is not None:
        info = _information(base_fit, fit)
        if chosen[3]:  # the reasons decided in _try_extensions, not recomputed
            caveats.append(f"{chosen[0].name}: physically implausible: " + "; ".join(chosen[3]))
        if kept:
            gain_cond = yield from _condition_gain(g, scope, base_ext, chosen[0], levels, caveats)
        else:
            caveats.append(_not_kept_caveat(chosen[1]))
    return Finding(
        kind=g.kind,
        soil=g.soil,
        cause=lead,
        confounded_with=tuple(confounded_with),
        p_adjusted=float(top["p_adjusted"]),
        p_value=float(top["p_value"]),
        responses=responses,
        statistic=float(top["statistic"]),
        effect_size=float(top["effect_size"]),
        n_tests=int(scope.size),
        extension=chosen[0].name if kept else None,
        fit=fit if kept else None,
        base_fit=base_fit,
        gain=chosen[1] if chosen is not None else None,
        gain_search=chosen[4] if chosen is not None else None,
        gain_conditions=gain_cond,
        information=info,
        tried=tuple(tried),
        caveats=tuple(caveats),
        scope_rows=scope,
        group=g,
        fitted=fitted,
        base_fitted=base_fitted,
        test_level=level,
    )


def _search_extensions(g, top, lead, confounded_with, folds, scope, responses, lead_table, caveats):
    """Process step of :func:`_examine_lead`: the library's extensions tried on the tests in
    scope (:func:`_try_extensions`) when there are enough of them to cross-validate; too few
    tests, or a failed cross-validation, become a caveat (appended to ``caveats``).

    Returns (base extension, base Fitted, chosen, tried): chosen is (Extension, Gain, Fitted,
    implausible reasons, search Gain) or None, tried a list (empty when nothing was tried).
    """
    base_ext = None
    base_fitted: Any = None  # Fitted
    chosen: Any = None  # (Extension, Gain, Fitted, implausible reasons, search Gain)
    tried: list = []
    if scope.size >= 6:
        numeric = bool(top["numeric"])
        try:
            base_ext, base_fitted, chosen, tried = yield from _try_extensions(
                g,
                scope,
                lead,
                confounded_with,
                numeric,
                set(responses),
                folds.of(scope),
                log_scale=trend_on_log(top["role"]),
                lead_table=lead_table,
            )
        except (ConvergenceError, IdentifiabilityError) as exc:
            caveats.append(f"cross-validation on the tests in scope failed: {exc}")
    else:
        caveats.append(f"only {scope.size} tests in scope: too few to cross-validate")
    return base_ext, base_fitted, chosen, tried


def _not_kept_caveat(gain: Gain) -> str:
    """Why the base model is kept although an extension was chosen: its gain was enough but
    it is physically implausible, or no extension gains enough (the best one's gain said)."""
    if gain.kept:
        return (
            "no plausible extension gains enough out of sample to be kept; the base model is kept"
        )
    return (
        f"no extension gains enough out of sample to be kept (best: "
        f"{gain.text()}); the base model is kept"
    )


def _information(base_fit: FitResult | None, fit: FitResult | None) -> dict:
    """AIC and BIC of the base and the extended fit, side by side."""
    assert base_fit is not None and fit is not None  # an extension was chosen: both fitted
    ib, ie = information_criteria(base_fit), information_criteria(fit)
    return {
        "aic_base": ib["aic"],
        "aic_extended": ie["aic"],
        "bic_base": ib["bic"],
        "bic_extended": ie["bic"],
    }


def _condition_gain(
    g: Group,
    scope: np.ndarray,
    base_ext: Extension,
    ext: Extension,
    levels: np.ndarray,
    caveats: list,
) -> Process[Gain | None]:
    """Leave-one-condition-out gain: does the extension predict a condition it never saw?

    Only for trends a formula can carry to a new level (physical or linear extensions, three
    or more levels); softening has no such level.  A failure becomes a caveat.  Not nested
    (:mod:`.nested`): it asks whether the extension carries to an unseen condition, not
    whether the other conditions alone would have shown the lead (without one of three
    velocities the rest often do not), and it never decides what is kept.
    """
    if np.unique(levels).size < 3 or ext.name == "softening" or "per block" in ext.name:
        return None  # softening has no level, an unseen block no drift of its own
    if not (ext.physical or "linear" in ext.name):
        return None
    try:
        folds = make_folds(levels, "conditions", None)
        return (yield from cross_validation(g, scope, base_ext, ext, folds, scheme="conditions"))
    except (ConvergenceError, IdentifiabilityError) as exc:
        caveats.append(f"leave-one-condition-out failed: {exc}")
        return None
