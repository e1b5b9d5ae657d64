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

This module runs the steps in order and assembles the result; steps 1–2 live in
:mod:`.data` and :mod:`.diagnose`, steps 3–4 in :mod:`.leads`, step 5 in :mod:`.selection`,
and what screening found is weighed against the causes in :mod:`.artefacts`.

Steps 4–5 are written as *processes* that yield the fits they need in waves
(:mod:`.work`), so that ``discover(..., jobs=N)`` can fit them over N workers; each
(kind, soil) draws its folds in this process from a stream of its own
(:func:`.crossval.group_rng`), in one order, so the results are identical for any N and
a soil's findings do not depend on the other soils of the campaign.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .._text import plural
from ..campaign import Campaign, load_campaign
from ..errors import ConvergenceError, IdentifiabilityError, InputError
from ..models import get_model
from ..outputs import Provenance
from ..parallel import in_this_backend, one_blas_thread
from ..quality import screened
from .artefacts import quality_record, split_artefacts, with_quality_caveat
from .candidates import relation_text
from .crossval import group_folds, group_rng
from .data import build_groups
from .diagnose import diagnose_groups
from .extensions import check_own_model
from .flags import physical_flags
from .leads import discover_group, leads_of
from .power import power_records
from .result import DiscoveryResult, Finding
from .selection import CombinedModel, prepare_selection, selection_steps
from .work import Pool, run_process, warm_workers

if TYPE_CHECKING:
    from ..models.base import Model
    from .data import Group
    from .diagnose import Diagnosis

__all__ = ["discover"]


def _as_campaign(campaign: Campaign | str | Path) -> tuple[Campaign, str]:
    if isinstance(campaign, Campaign):
        return campaign, str(getattr(campaign, "source", "<campaign>"))
    return load_campaign(campaign), str(campaign)


def discover(
    campaign: Campaign | str | Path,
    *,
    alpha: float = 0.05,
    seed: int = 0,
    max_leads: int = 4,
    points_per_test: int = 60,
    progress: bool = False,
    provenance: Provenance | None = None,
    jobs: int = 1,
    model: str | Model | None = None,
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
        Seed of the cross-validation folds; each (kind, soil) draws from a stream of its
        own, seeded by ``seed`` and its name (:func:`.crossval.group_rng`).
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
        for any ``jobs``: each group's folds are drawn from its own stream in one order, and
        every fit is a deterministic function of its data and start.
    model : str or Model, optional
        A registered sinkage model (:func:`soilstats.register_model`) to use as the base of
        the sinkage groups instead of the paper's (Bekker with two or more plate sizes, else
        Bernstein); it starts from its record's starting values and its extensions are the
        generic ones (a factor on its output and an offset on its exponent n per cause, and
        the velocity law).  Shear keeps Janosi–Hanamoto.  An unknown name, or a model of
        another kind, is a :class:`~soilstats.errors.ModelError`.

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
        raise InputError(f"alpha must lie in (0, 1), got {alpha!r}; e.g. alpha=0.05")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise InputError(
            f"seed must be a non-negative integer (the folds are random and must be "
            f"reproducible), got {seed!r}; e.g. seed=0"
        )
    spec = None if model is None else get_model(model, "sinkage")
    if spec is not None:
        check_own_model(spec)
    # BLAS on one thread in this process, as in the workers: the same last bits for any
    # jobs (and faster: see .work).
    with one_blas_thread():
        return _discover(
            campaign,
            model=spec,
            alpha=alpha,
            seed=seed,
            max_leads=max_leads,
            points_per_test=points_per_test,
            progress=progress,
            provenance=provenance,
            jobs=jobs,
        )


def _discover(
    campaign: Campaign | str | Path,
    *,
    alpha: float,
    seed: int,
    max_leads: int,
    points_per_test: int,
    progress: bool,
    provenance: Provenance | None,
    jobs: int,
    model: Model | None = None,
) -> DiscoveryResult:
    """:func:`discover` after its argument checks."""
    start = time.perf_counter()
    warm_workers(jobs)  # the workers start while the campaign loads and is screened
    campaign, source = _as_campaign(campaign)
    # The provenance names the records as given, not as screening leaves them.
    provenance = provenance or Provenance.of(campaign, seed=seed)
    campaign = screened(campaign)  # once; every fit below uses the screened records
    quality = quality_record(campaign)
    groups, notes = build_groups(
        campaign, points_per_test=points_per_test, progress=progress, jobs=jobs, model=model
    )
    diags, table = diagnose_groups(groups, alpha=alpha)
    notes = list(dict.fromkeys([*notes, *(n for d in diags for n in d.notes)]))
    confounded = [rec for d in diags for rec in _confounding_records(d)]
    work = []
    if not table.empty:
        for d in diags:
            rows = table[(table["kind"] == d.group.kind) & (table["soil"] == d.group.soil)]
            work.append((d, rows, leads_of(rows, d.relations)))
    done = _extend_groups(
        work, quality, alpha=alpha, seed=seed, max_leads=max_leads, jobs=jobs, progress=progress
    )
    findings: list[Finding] = []
    explained: list[dict] = []
    models: list[CombinedModel] = []
    artefacts: list[dict] = []
    for (d, _, leads), (found, residues, why_not, combined, note) in zip(work, done, strict=True):
        findings += found
        artefacts += residues
        explained += why_not
        if note is not None:
            notes.append(note)
        if combined is not None:
            models.append(combined)
        if len(leads) > max_leads:
            notes.append(
                f"{d.group.label}: {len(leads) - max_leads} further significant cause(s) not "
                f"extended (max_leads = {max_leads}): "
                + ", ".join(lv for lv, _ in leads[max_leads:])
            )
    findings.sort(key=lambda f: (f.p_adjusted, f.p_value, -f.statistic))
    findings = [with_quality_caveat(f, quality) for f in findings]
    notes += _untestable_note(table)
    untested = _untested_groups(diags, table)
    notes += [
        f"{u['kind']} / {u['soil']}: NO CANDIDATE CAUSE COULD BE TESTED — {u['reason']}; "
        "'no finding' there is no evidence that the model is right"
        for u in untested
    ]
    return DiscoveryResult(
        findings=tuple(findings),
        flags=tuple(physical_flags(diags)),
        tests=table.drop(columns=["rows"]) if "rows" in table else table,
        confounded=tuple(confounded),
        explained=tuple(explained),
        models=tuple(models),
        artefacts=tuple(artefacts),
        power=tuple(power_records(table, alpha)),
        untested=tuple(untested),
        quality=quality,
        columns=tuple(_column_records(diags)),
        notes=tuple(notes),
        alpha=alpha,
        seed=seed,
        runtime_s=time.perf_counter() - start,
        source=source,
        provenance=provenance,
    )


def _extend_groups(
    work: list[tuple[Diagnosis, pd.DataFrame, list]],
    quality: dict,
    *,
    alpha: float,
    seed: int,
    max_leads: int,
    jobs: int,
    progress: bool,
) -> list[tuple]:
    """Extensions, cross-validated gains and the combined model of every (kind, soil):
    ``(findings, artefacts, explained, model, note)`` per entry of ``work``, in its order.

    Each group is one process of waves of fits (:func:`.work.run_process`): its leads
    (:func:`_group_leads`), then its forward selection (:func:`_group_model`).  A group
    draws its folds from a stream of its own (:func:`.crossval.group_rng`), so the groups
    do not depend on each other: with workers, every group runs in a thread of its own and
    their waves share the workers (a long fit in one group leaves the other workers to the
    others); with one job, one after the other.  The results are the same either way, and
    so is the error raised when groups fail: that of the first failing group in ``work``'s
    order.  (One thread per group: a campaign has a handful of (kind, soil) groups, and a
    thread waiting on its wave costs nothing.)
    """
    pool = Pool(jobs)
    done: list = [None] * len(work)
    bar = None
    if progress:
        from tqdm.auto import tqdm  # deferred: tqdm (a progress bar)

        bar = tqdm(total=len(work), desc="extensions", unit="group")
    failures: dict[int, BaseException] = {}
    bar_lock = threading.Lock()

    def extend(k):
        d, rows, leads = work[k]
        rng = group_rng(seed, d.group)
        try:
            process = _group_process(
                d, rows, leads, quality, alpha=alpha, rng=rng, max_leads=max_leads
            )
            done[k] = run_process(process, pool)
        except BaseException as exc:  # re-raised in the caller's thread below
            failures[k] = exc
        if bar is not None:
            with bar_lock:
                bar.update()

    if pool.parallel:
        # Each thread takes this thread's joblib backend (Dask's inside its parallel_config).
        target = in_this_backend(extend)
        threads = [
            threading.Thread(target=target, args=(k,), daemon=True) for k in range(len(work))
        ]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    else:
        for k in range(len(work)):
            extend(k)
            if failures:
                break
    if bar is not None:
        bar.close()
    if failures:
        raise failures[min(failures)]
    return done


def _group_process(d, rows, leads, quality, *, alpha, rng, max_leads):
    """Process of one group: its leads (:func:`_group_leads`), then its forward selection
    (:func:`_group_model`); ``(findings, artefacts, explained, model, note)``."""
    found, residues, why_not, prepared, note = yield from _group_leads(
        d, rows, leads, quality, alpha=alpha, rng=rng, max_leads=max_leads
    )
    model = None
    if prepared is not None:
        model, model_note = yield from _group_model(d.group, prepared)
        note = note or model_note
    return found, residues, why_not, model, note


def _group_leads(d, rows, leads, quality, *, alpha, rng, max_leads):
    """Process of one group's leads (:func:`discover_group`), then the folds of its
    forward selection drawn (:func:`.selection.prepare_selection`).  Returns ``(findings,
    artefacts, explained, prepared selection or None, note or None)``."""
    # One set of folds for the group: every finding and forward selection share it.
    folds = group_folds(d.group, [lead for lead, _ in leads[:max_leads]], rng)
    found, why_not = yield from discover_group(
        d, rows, leads, alpha=alpha, folds=folds, max_leads=max_leads
    )
    found, residues = split_artefacts(d.group, found, quality, rows)
    # Every named cause's best plausible extension is offered, kept alone or not: measured
    # alone, each gain had the other effects in its noise (two causes in one soil); forward
    # selection adds each only where it really gains over the model so far.
    kept = [(f.cause, f.fitted.extension) for f in found if f.fitted is not None and _offered(f)]
    try:
        prepared, note = prepare_selection(d.group, kept, folds, base=d.base), None
    except (ConvergenceError, IdentifiabilityError) as exc:
        prepared, note = None, _no_model_note(d.group, exc)
    return found, residues, why_not, prepared, note


def _group_model(group, prepared):
    """Process of one group's forward selection: ``(CombinedModel or None, note or None)``."""
    try:
        return (yield from selection_steps(group, prepared)), None
    except (ConvergenceError, IdentifiabilityError) as exc:
        return None, _no_model_note(group, exc)


def _no_model_note(group: Group, exc: Exception) -> str:
    return f"{group.label}: no combined model — the base model fails on all tests: {exc}"


def _offered(finding: Finding) -> bool:
    """Whether a finding's best extension may enter the combined model: fitted and plausible
    (its gain alone need not be real; forward selection measures it with the others in:
    soil02 of ``simulated-paper``, whose operator × loosening-pattern cells gain +2.4 %
    alone and add to the model once its velocity extension carries the velocity)."""
    if finding.fitted is None:
        return False
    name = finding.fitted.extension.name
    return not any(t.get("implausible") for t in finding.tried if t["extension"] == name)


def _column_records(diags: Sequence[Diagnosis]) -> list[dict]:
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


def _confounding_records(diag: Diagnosis) -> list[dict]:
    """What the design cannot tell apart in one (kind, soil), as JSON-ready records."""
    g = diag.group
    out = []
    for r in diag.relations:
        text = relation_text(r, g.tests)
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


def _untested_groups(diags: Sequence[Diagnosis], table: pd.DataFrame) -> list[dict]:
    """The (kind, soil) groups in which not one candidate cause got a p-value, and why:
    discovery compares tests that differ in a set-up column, so one test, or tests that
    differ in nothing, leave it nothing to test."""
    out = []
    for d in diags:
        g = d.group
        rows = table[(table["kind"] == g.kind) & (table["soil"] == g.soil)] if len(table) else table
        if len(rows) and rows["p_value"].notna().any():
            continue
        n = len(g.tests)
        if n < 2:
            reason = (
                f"{plural(n, 'test')}: nothing to compare with; discovery needs two or more "
                "tests that differ in a set-up column (and more for any power)"
            )
        elif not d.candidates:
            reason = f"no set-up column varies among its {n} tests: no candidate cause to test"
        else:
            reason = (
                f"none of its {plural(len(d.candidates), 'candidate')} could be tested with "
                f"{n} tests (no degrees of freedom left once the strata are taken out)"
            )
        out.append({"kind": g.kind, "soil": g.soil, "n_tests": n, "reason": reason})
    return out


def _untestable_note(table: pd.DataFrame) -> list[str]:
    """One note naming the candidates that could not be tested, if any."""
    untestable = table[table["p_value"].isna()] if not table.empty else table
    if not len(untestable):
        return []
    names = sorted({f"{r.kind}/{r.soil}:{r.candidate}" for r in untestable.itertuples()})
    more = ", …" if len(names) > 12 else ""
    return [
        f"{len(names)} candidate(s) could not be tested (no variation within strata, nothing "
        "left once the strata and main effects are taken out, or no degrees of freedom): "
        f"{', '.join(names[:12])}{more}"
    ]
