"""``discover``: diagnosis → cause → extension → cross-validated gain, for a whole campaign.

1. Split the campaign by kind and soil; fit every test on its own and the base model on all.
2. Test every candidate cause on every per-test response (Holm over the whole campaign).
3. Group significant candidates that the design confounds; the lead of a group is its
   designed factor (role ``design``: the preparation rather than the test day that travelled
   with it), among those the coarsest member with the smallest p (``aspect_ratio`` rather than
   the plate ``tool`` that determines it); the rest are named as confounded.  Outcomes (the
   depth a test reached, its sample count) never enter (:mod:`.candidates`).
4. For each lead, strongest first: try the library's extensions (physical first, then the
   generic one), keep one only where its cross-validated gain is real, then re-test the
   remaining leads against the kept extension — a pattern it explains is no finding.
5. Per (kind, soil), forward selection of one model that carries every kept extension.

Steps 4–5 are written as *processes* that yield the fits they need in waves
(:mod:`.work`), so that ``discover(..., jobs=N)`` can fit them over N workers; the folds
are drawn in this process in the order of the one-at-a-time loop, so the results are
identical for any N.
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import numpy as np
import pandas as pd

from ..campaign import Campaign, load_campaign
from ..errors import ConvergenceError, IdentifiabilityError
from ..quality import ARTEFACT_CODES, CODES, STOP_CODES, screened
from ..report import Provenance
from .candidates import candidate_values
from .crossval import FoldFits, compare, cross_validation, information_criteria, make_folds
from .data import build_groups
from .diagnose import INTERACTION, conditional_responses, diagnose_groups, retest
from .extensions import base_model, library
from .flags import physical_flags
from .plausibility import implausible
from .power import power_records
from .result import DiscoveryResult, Finding
from .selection import CombinedModel, prepare_selection, selection_steps
from .work import FitTask, Pool, Wave, one_blas_thread, run_process, warm_workers

__all__ = ["discover"]


def _leads(rows: pd.DataFrame, relations) -> list[tuple[str, list[str]]]:
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


def _physical_name(lead: str, extension: str, relations) -> str:
    want = _PHYSICS_NAME.get(extension)
    for r in relations:
        if r.kind == "aliased" and {r.finer, r.coarser} == {lead, want}:
            return want
    return lead


def _try_extensions(group, rows, lead, confounded, numeric, responses, levels, rng):
    """Cross-validate every applicable extension on the same folds and fit it on all tests
    in scope.

    Preference: a physical extension with a real gain and physically plausible parameters
    (no value outside its range, e.g. K0 > 1), else the generic one with a real gain, else the
    best gain (not kept).  Returns ``(base, base fitted, chosen, tried)``, chosen being
    ``(extension, gain, fitted, implausible)`` (the reasons it is not physical, empty when it
    is) or None.

    A process (:mod:`.work`): the fits go out in two waves, the base model on all tests and
    without each fold, then every extension without each fold (started from the base
    model's fit of that fold) and on all tests (started from the base fit).  Errors are
    recorded where the one-at-a-time loop met them: a base fit that fails raises, a failed
    fold or full fit of an extension is that extension's ``error``.
    """
    base_ext = base_model(group, rows)
    folds = make_folds(levels, "tests", rng)
    extensions = library(group, rows, lead, confounded, numeric=numeric, responses=responses)
    # One chain, in the order the base model is read: its fit on all tests, then the folds.
    base_plan = FoldFits(rows, base_ext, folds, scheme="tests", chain="base")
    first = yield Wave(group, [FitTask(base_ext, rows, chain="base"), *base_plan.tasks])
    first[0].raise_error()
    base_fitted = first[0].fitted
    base_failure = None
    try:
        starts, e_base = base_plan.collect(first[1:])
    except (ConvergenceError, np.linalg.LinAlgError, ValueError) as exc:
        base_failure = exc  # every extension's cross-validation fails with it
    plans, tasks = [], []
    if base_failure is None:
        for i, ext in enumerate(extensions):  # chain i: the folds, then all tests
            plan = FoldFits(rows, ext, folds, scheme="tests", starts=starts, chain=i)
            plans.append(plan)
            tasks += [*plan.tasks, FitTask(ext, rows, base_fitted, chain=i)]
    outcomes = iter((yield Wave(group, tasks, probe=True)))
    tried, options = [], []
    for i, ext in enumerate(extensions):
        entry = {"extension": ext.name, "physical": ext.physical, "description": ext.description}
        try:
            if base_failure is not None:
                raise base_failure
            plan = plans[i]
            folds_out = [next(outcomes) for _ in plan.tasks]
            full = next(outcomes)
            gain = compare(e_base, plan.collect(folds_out)[1], scheme="tests", folds=folds)
            full.raise_error()
            fitted = full.fitted
        except (ConvergenceError, np.linalg.LinAlgError, ValueError) as exc:
            entry["error"] = str(exc)[:400]
            tried.append(entry)
            continue
        reasons = implausible(fitted, base_fitted, group, rows)
        entry.update(
            relative=gain.relative,
            real=gain.real,
            base=gain.base,
            extended=gain.extended,
            implausible=reasons,
        )
        tried.append(entry)
        # An implausible extension is never kept, however much it gains.
        plausible = gain.real and not reasons
        rank = (plausible, plausible and ext.physical, gain.relative)
        options.append((rank, ext, gain, fitted, reasons))
    if not options:
        return base_ext, base_fitted, None, tried
    return base_ext, base_fitted, max(options, key=lambda o: o[0])[1:], tried


def _as_campaign(campaign) -> tuple[Campaign, str]:
    if isinstance(campaign, Campaign):
        return campaign, str(getattr(campaign, "source", "<campaign>"))
    return load_campaign(campaign), str(campaign)


def discover(
    campaign,
    *,
    alpha: float = 0.05,
    seed: int = 0,
    max_leads: int = 4,
    points_per_test: int = 60,
    progress: bool = False,
    provenance: Provenance | None = None,
    jobs: int = 1,
) -> DiscoveryResult:
    """Find what the soil model gets wrong in a campaign, extend it, and measure the gain.

    Parameters
    ----------
    campaign : Campaign, str or path
        A loaded campaign, a campaign folder or a bundled name (``"simulated-paper"``).
    alpha : float, default 0.05
        Family-wise error rate of the causes named (Holm over every candidate × response ×
        (kind, soil)); on a campaign without any effect, the chance of any finding is ≤ alpha.
    seed : int, default 0
        Seed of the cross-validation folds (``numpy.random.default_rng``).
    max_leads : int, default 4
        Leading causes extended per (kind, soil), strongest first.
    points_per_test : int, default 60
        Samples per test, nearest to equally spaced sinkages / deformations (Section 2.1).
    progress : bool
        tqdm progress bars for the per-test fits and the extensions.
    provenance : Provenance, optional
        Recorded in the outputs (default: a library call on the campaign with ``seed``).
    jobs : int, default 1
        Worker processes (joblib; −1 every core) for the per-test fits and for the fits of
        cross-validation and forward selection (:mod:`.work`).  The results are identical
        for any ``jobs``: the folds are drawn here, in one order, and every fit is a
        deterministic function of its data and start.

    Returns
    -------
    DiscoveryResult
        ``findings`` strongest first, ``flags``, ``summary()``, ``to_json()``.

    Examples
    --------
    >>> import soilstats
    >>> result = soilstats.discover("simulated-paper")        # doctest: +SKIP
    >>> print(result.summary())                                # doctest: +SKIP
    """
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha!r}; e.g. alpha=0.05")
    # BLAS on one thread in this process, as in the workers: the same last bits for any
    # jobs (and faster: see .work).
    with one_blas_thread():
        return _discover(
            campaign,
            alpha=alpha,
            seed=seed,
            max_leads=max_leads,
            points_per_test=points_per_test,
            progress=progress,
            provenance=provenance,
            jobs=jobs,
        )


def _discover(
    campaign, *, alpha, seed, max_leads, points_per_test, progress, provenance, jobs
) -> DiscoveryResult:
    """:func:`discover` after its argument checks."""
    start = time.perf_counter()
    warm_workers(jobs)  # the workers start while the campaign loads and is screened
    campaign, source = _as_campaign(campaign)
    campaign = screened(campaign)  # once; every fit below uses the screened records
    quality = _quality_record(campaign)
    rng = np.random.default_rng(seed)
    groups, notes = build_groups(
        campaign, points_per_test=points_per_test, progress=progress, jobs=jobs
    )
    diags, table = diagnose_groups(groups, alpha=alpha)
    notes = list(dict.fromkeys([*notes, *(n for d in diags for n in d.notes)]))
    confounded = [rec for d in diags for rec in _confounding_records(d)]
    work = []
    if not table.empty:
        for d in diags:
            rows = table[(table["kind"] == d.group.kind) & (table["soil"] == d.group.soil)]
            work.append((d, rows, _leads(rows, d.relations)))
    done = _extend_groups(
        work, quality, alpha=alpha, rng=rng, max_leads=max_leads, jobs=jobs, progress=progress
    )
    findings: list[Finding] = []
    explained: list[dict] = []
    models: list[CombinedModel] = []
    artefacts: list[dict] = []
    for (d, _, leads), (found, residues, why_not, model, note) in zip(work, done, strict=True):
        findings += found
        artefacts += residues
        explained += why_not
        if note is not None:
            notes.append(note)
        if model is not None:
            models.append(model)
        if len(leads) > max_leads:
            notes.append(
                f"{d.group.label}: {len(leads) - max_leads} further significant cause(s) not "
                f"extended (max_leads = {max_leads}): "
                + ", ".join(lv for lv, _ in leads[max_leads:])
            )
    findings.sort(key=lambda f: (f.p_adjusted, f.p_value, -f.statistic))
    findings = [_with_quality_caveat(f, quality) for f in findings]
    notes += _untestable_note(table)
    return DiscoveryResult(
        findings=tuple(findings),
        flags=tuple(physical_flags(diags)),
        tests=table.drop(columns=["rows"]) if "rows" in table else table,
        confounded=tuple(confounded),
        explained=tuple(explained),
        models=tuple(models),
        artefacts=tuple(artefacts),
        power=tuple(power_records(table, alpha)),
        quality=quality,
        columns=tuple(_column_records(diags)),
        notes=tuple(notes),
        alpha=alpha,
        seed=seed,
        runtime_s=time.perf_counter() - start,
        source=source,
        provenance=provenance or Provenance.of(campaign, seed=seed),
    )


def _extend_groups(work, quality, *, alpha, rng, max_leads, jobs, progress) -> list[tuple]:
    """Extensions, cross-validated gains and the combined model of every (kind, soil):
    ``(findings, artefacts, explained, model, note)`` per entry of ``work``, in its order.

    Each group is two processes of waves of fits (:func:`.work.run_process`): its leads
    (:func:`_group_leads`), then its forward selection (:func:`_group_model`).  The leads
    run one group after the other, as they draw the folds from ``rng`` in the order the
    one-at-a-time loop did (a group's leads, its selection's folds, then the next group's
    leads); with workers, a group's forward selection — its folds drawn — runs in a thread
    of its own beside the next groups' leads, so that the workers stay busy through a long
    fit one process waits for.  The results are those of the loop, whatever ran together.
    """
    pool = Pool(jobs)
    done: list = [None] * len(work)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(work), desc="extensions", unit="group")
    failures: list[BaseException] = []

    def model(k, prepared):
        try:
            done[k][3], note = run_process(_group_model(work[k][0].group, prepared), pool)
            done[k][4] = done[k][4] or note
        except BaseException as exc:  # re-raised in the caller's thread below
            failures.append(exc)
        if bar is not None:
            bar.update()

    threads = []
    for k, (d, rows, leads) in enumerate(work):
        process = _group_leads(d, rows, leads, quality, alpha=alpha, rng=rng, max_leads=max_leads)
        found, residues, why_not, prepared, note = run_process(process, pool)
        done[k] = [found, residues, why_not, None, note]
        if prepared is None:
            if bar is not None:
                bar.update()
        elif not pool.parallel:
            model(k, prepared)
        else:
            threads.append(threading.Thread(target=model, args=(k, prepared), daemon=True))
            threads[-1].start()
        if failures:
            break
    for thread in threads:
        thread.join()
    if bar is not None:
        bar.close()
    if failures:
        raise failures[0]
    return [tuple(entry) for entry in done]


def _group_leads(d, rows, leads, quality, *, alpha, rng, max_leads):
    """Process of one group's leads (:func:`_discover_group`), then the folds of its
    forward selection drawn (:func:`.selection.prepare_selection`).  Returns ``(findings,
    artefacts, explained, prepared selection or None, note or None)``."""
    found, why_not = yield from _discover_group(
        d, rows, leads, alpha=alpha, rng=rng, max_leads=max_leads
    )
    found, residues = _split_artefacts(d.group, found, quality)
    # Every finding's best plausible extension is offered, kept alone or not: measured
    # alone, each gain had the other effects in its noise (two causes in one soil).
    kept = [(f.cause, f.fitted.extension) for f in found if _offered(f)]
    try:
        prepared, note = prepare_selection(d.group, kept, rng, base=d.base), None
    except (ConvergenceError, IdentifiabilityError) as exc:
        prepared, note = None, _no_model_note(d.group, exc)
    return found, residues, why_not, prepared, note


def _group_model(group, prepared):
    """Process of one group's forward selection: ``(CombinedModel or None, note or None)``."""
    try:
        return (yield from selection_steps(group, prepared)), None
    except (ConvergenceError, IdentifiabilityError) as exc:
        return None, _no_model_note(group, exc)


def _no_model_note(group, exc) -> str:
    return f"{group.label}: no combined model — the base model fails on all tests: {exc}"


# ----------------------------------------------------------------------------- the steps
def _quality_record(campaign) -> dict | None:
    """What screening found in the tests discovery analyses (JSON-ready), or None."""
    report = getattr(campaign, "quality", None)
    if report is None:
        return None
    report = report.for_tests(campaign.tests["test_id"].astype(str))
    codes: dict[str, list[str]] = {}
    for f in report.flags:
        codes.setdefault(f.test_id, [])
        if f.code not in codes[f.test_id]:
            codes[f.test_id].append(f.code)
    kinds = dict(zip(report.tests["test_id"].astype(str), report.tests["kind"], strict=True))
    return {
        "mode": report.mode,
        "counts": dict(report.counts),
        "excluded_samples": len(report.excluded),
        "tests": [{"test_id": t, "kind": kinds.get(t), "codes": c} for t, c in codes.items()],
    }


def _offered(finding: Finding) -> bool:
    """Whether a finding's best extension may enter the combined model: fitted and plausible
    (its gain alone need not be real; forward selection measures it with the others in)."""
    if finding.fitted is None:
        return False
    name = finding.fitted.extension.name
    return not any(t.get("implausible") for t in finding.tried if t["extension"] == name)


def _codes_by_test(quality, kind: str, keep) -> dict[str, list[str]]:
    """The screening codes in ``keep`` of every flagged test of one kind (tests with none
    left out)."""
    out = {
        t["test_id"]: [c for c in t["codes"] if c in keep]
        for t in quality["tests"]
        if t["kind"] == kind
    }
    return {t: c for t, c in out.items() if c}


def _artefact_labels(group, quality) -> pd.Series | None:
    """Per test of the group, its artefact codes ("clean" when none), or None if no test of
    the group has any."""
    if not quality:
        return None
    codes = _codes_by_test(quality, group.kind, ARTEFACT_CODES)
    ids = group.tests["test_id"].astype(str)
    labels = pd.Series(["+".join(codes.get(t, ["clean"])) for t in ids], index=group.tests.index)
    return None if (labels == "clean").all() else labels


def _aligned(values: pd.Series, labels: pd.Series) -> str | None:
    """How the levels of a candidate line up with artefact codes, or None: a code flags at
    least half the tests of one level and none of another's."""
    out = []
    for code in ARTEFACT_CODES:
        flagged = labels.str.contains(code, regex=False)
        share = flagged.groupby(values).mean()
        if share.max() >= 0.5 and share.min() == 0.0:
            out += [f"{code} in {share[lv]:.0%} of {lv}" for lv in share.index if share[lv] > 0]
    return "; ".join(out) or None


def _split_artefacts(group, found, quality) -> tuple[list, list[dict]]:
    """Findings whose cause lines up with the data-quality artefacts of the tests
    (:func:`_aligned`) are data problems, not causes: screening removes what it finds of an
    artefact, but what remains (an offset it did not find, a spike's neighbours) can still
    follow the tests it sits in."""
    labels = _artefact_labels(group, quality)
    if labels is None:
        return found, []
    kept, residues = [], []
    for f in found:
        rows = f.scope_rows if f.scope_rows is not None else np.arange(len(labels))
        why = None
        for column in f.cause.split(INTERACTION):
            values = candidate_values(group.tests, column).astype(str).iloc[rows]
            pattern = _aligned(values, labels.iloc[rows])
            if pattern is not None:
                why = (
                    f"the levels of {column} line up with data-quality flags ({pattern}): the "
                    "pattern may be what is left of the artefacts after screening, not a "
                    "cause; inspect the flagged records (soilstats check) and re-test"
                )
                break
        if why is None:
            kept.append(f)
            continue
        residues.append(
            {
                "kind": f.kind,
                "soil": f.soil,
                "candidate": f.cause,
                "p_adjusted": f.p_adjusted,
                "p_value": f.p_value,
                "reason": why,
            }
        )
    return kept, residues


def _with_quality_caveat(finding: Finding, quality: dict | None) -> Finding:
    """A finding whose tests carry data-quality flags says how many and which codes: a
    reader judges whether the data problem, not the cause, drives it."""
    if not quality or not quality["tests"] or finding.group is None:
        return finding
    # A load-capped test is sound (its depth is an outcome, never a cause: .candidates).
    flagged = _codes_by_test(quality, finding.kind, set(CODES) - STOP_CODES)
    scope = finding.group.tests["test_id"].astype(str).to_numpy()[finding.scope_rows]
    hit = [t for t in scope if t in flagged]
    if not hit:
        return finding
    codes = sorted({c for t in hit for c in flagged[t]})
    text = (
        f"{len(hit)} of {len(scope)} tests in scope carry data-quality flags "
        f"({', '.join(codes)}; soilstats check); flagged samples were left out where the "
        "screening excludes them, the rest fitted as recorded"
    )
    return replace(finding, caveats=(*finding.caveats, text))


def _column_records(diags) -> list[dict]:
    """The role of every varying column per (kind, soil), and whether it was tested."""
    out = []
    for d in diags:
        tested = {c.name for c in d.candidates}
        for r in d.roles:
            out.append(
                {
                    "kind": d.group.kind,
                    "soil": d.group.soil,
                    "column": r.column,
                    "role": r.role,
                    "reason": r.reason,
                    "tested": r.column in tested,
                }
            )
    return out


def _confounding_records(diag) -> list[dict]:
    """What the design cannot tell apart in one (kind, soil), as JSON-ready records."""
    g = diag.group
    out = []
    for r in diag.relations:
        text = (
            f"{r.finer} and {r.coarser} are aliased (the same partition of the tests)"
            if r.kind == "aliased"
            else f"{r.finer} determines {r.coarser} (each {r.finer} has one {r.coarser})"
        )
        out.append(
            {
                "kind": g.kind,
                "soil": g.soil,
                "relation": r.kind,
                "columns": [r.finer, r.coarser],
                "text": text,
            }
        )
    return out


def _discover_group(diag, rows, leads, *, alpha, rng, max_leads):
    """Process (:mod:`.work`) of the findings of one (kind, soil), leads strongest first, and
    the leads that an extension kept before them already explains: ``(findings,
    explained)``."""
    g = diag.group
    findings, explained = [], []
    accepted = None  # (name, fitted) of the latest kept extension in this group
    for lead, confounded_with in leads[:max_leads]:
        lead_rows = rows[(rows["candidate"] == lead) & rows["significant"]]
        top = lead_rows.sort_values(["p_adjusted", "p_value"]).iloc[0]
        if accepted is not None:
            why = _explained_by(g, accepted, lead, top, n_leads=len(leads), alpha=alpha)
            if why is not None:
                explained.append(why)
                continue
        finding = yield from _examine_lead(
            g, diag.relations, lead_rows, top, lead, confounded_with, rng
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


def _explained_by(g, accepted, lead, top, *, n_leads, alpha) -> dict | None:
    """The record of ``lead`` explained by the accepted extension (no response stays
    significant, Bonferroni over the leads), or None when it still shows."""
    cond_table = conditional_responses(g, accepted[1])
    p_after = retest(g, cond_table, top)
    if any(p * n_leads < alpha for p in p_after.values() if np.isfinite(p)):
        return None
    return {
        "kind": g.kind,
        "soil": g.soil,
        "candidate": lead,
        "by": accepted[0],
        "p_after": float(np.nanmin([*p_after.values(), 1.0])),
    }


def _examine_lead(g, relations, lead_rows, top, lead, confounded_with, rng):
    """Process (:mod:`.work`) of one finding: try the library's extensions on the tests in
    scope, keep one only where its cross-validated gain is real, and state every caveat."""
    scope = np.asarray(top["rows"], int)
    levels = candidate_values(g.tests, lead).astype(str).to_numpy()[scope]
    responses = tuple(lead_rows["response"])
    caveats = _caveats(lead_rows, lead, confounded_with)
    base_ext = base_fitted = chosen = None
    tried: list = []
    if scope.size >= 6:
        numeric = bool(top["numeric"])
        try:
            base_ext, base_fitted, chosen, tried = yield from _try_extensions(
                g, scope, lead, confounded_with, numeric, set(responses), levels, rng
            )
        except (ConvergenceError, IdentifiabilityError) as exc:
            caveats.append(f"cross-validation on the tests in scope failed: {exc}")
    else:
        caveats.append(f"only {scope.size} tests in scope: too few to cross-validate")
    kept = chosen is not None and chosen[1].real and not chosen[3]
    if kept and chosen[0].physical:
        lead = _physical_name(lead, chosen[0].name, relations)
        confounded_with = [m for m in [top["candidate"], *confounded_with] if m != lead]
    fitted = chosen[2] if chosen is not None else None
    fit = fitted.result if fitted is not None else None
    base_fit = base_fitted.result if chosen is not None else None
    info, gain_cond = {}, None
    if chosen is not None:
        info = _information(base_fit, fit)
        if chosen[3]:  # the reasons decided in _try_extensions, not recomputed
            caveats.append(f"{chosen[0].name}: physically implausible: " + "; ".join(chosen[3]))
        if kept:
            gain_cond = yield from _condition_gain(
                g, scope, base_ext, chosen[0], levels, rng, caveats
            )
        elif chosen[1].real:
            caveats.append(
                "no plausible extension gives a real out-of-sample gain; the base model is kept"
            )
        else:
            caveats.append("no extension gives a real out-of-sample gain; the base model is kept")
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
        gain_conditions=gain_cond,
        information=info,
        tried=tuple(tried),
        caveats=tuple(caveats),
        scope_rows=scope,
        group=g,
        fitted=fitted,
        base_fitted=base_fitted,
    )


def _information(base_fit, fit) -> dict:
    """AIC and BIC of the base and the extended fit, side by side."""
    ib, ie = information_criteria(base_fit), information_criteria(fit)
    return {
        "aic_base": ib["aic"],
        "aic_extended": ie["aic"],
        "bic_base": ib["bic"],
        "bic_extended": ie["bic"],
    }


def _condition_gain(g, scope, base_ext, ext, levels, rng, caveats: list):
    """Leave-one-condition-out gain: does the extension predict a condition it never saw?

    Only for trends a formula can carry to a new level (physical or linear extensions, three
    or more levels); softening has no such level.  A failure becomes a caveat.
    """
    if np.unique(levels).size < 3 or ext.name == "softening":
        return None
    if not (ext.physical or "linear" in ext.name):
        return None
    try:
        folds = make_folds(levels, "conditions", rng)
        return (yield from cross_validation(g, scope, base_ext, ext, folds, scheme="conditions"))
    except (ConvergenceError, IdentifiabilityError) as exc:
        caveats.append(f"leave-one-condition-out failed: {exc}")
        return None


def _untestable_note(table: pd.DataFrame) -> list[str]:
    """One note naming the candidates that could not be tested, if any."""
    untestable = table[table["p_value"].isna()] if not table.empty else table
    if not len(untestable):
        return []
    names = sorted({f"{r.kind}/{r.soil}:{r.candidate}" for r in untestable.itertuples()})
    more = ", …" if len(names) > 12 else ""
    return [
        f"{len(names)} candidate(s) could not be tested (no variation within strata, or no "
        f"degrees of freedom): {', '.join(names[:12])}{more}"
    ]
