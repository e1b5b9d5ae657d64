"""``discover``: diagnosis → cause → extension → cross-validated gain, for a whole campaign.

1. Split the campaign by kind and soil; fit every test on its own and the base model on all.
2. Test every candidate cause on every per-test response (Holm over the whole campaign).
3. Group significant candidates that the design confounds; the lead of a group is its
   coarsest member with the smallest p (``aspect_ratio`` rather than the plate ``tool`` that
   determines it), the rest are named as confounded.
4. For each lead, strongest first: try the library's extensions (physical first, then the
   generic one), keep one only where its cross-validated gain is real, then re-test the
   remaining leads against the kept extension — a pattern it explains is no finding.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..campaign import Campaign, load_campaign
from ..errors import ConvergenceError, IdentifiabilityError
from ..report import Provenance
from .candidates import candidate_values
from .crossval import cross_validate, information_criteria, make_folds
from .data import build_groups
from .diagnose import conditional_responses, diagnose_groups, retest
from .extensions import base_model, library
from .flags import physical_flags
from .result import DiscoveryResult, Finding

__all__ = ["discover"]


def _leads(rows: pd.DataFrame, relations) -> list[tuple[str, list[str]]]:
    """(lead, confounded members) per connected group of significant, confounded candidates."""
    sig = rows[rows["significant"]]
    if sig.empty:
        return []
    best = sig.sort_values(["p_adjusted", "p_value", "statistic"], ascending=[True, True, False])
    order = list(dict.fromkeys(best["candidate"]))
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
        eligible = [m for m in order if m in comp and m not in finer] or [
            m for m in order if m in comp
        ]
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


def _implausible(fit, base_fit) -> list[str]:
    """Out-of-range values of the parameters an extension adds (K0 > 1, f outside 0..1);
    the base parameters' own red flags (a negative kc) are reported among the flags."""
    own = set(fit.param_names) - set(base_fit.param_names)
    return [
        f.message
        for f in fit.flags
        if f.code == "outside-bounds" and f.message.split(" ", 1)[0] in own
    ]


def _try_extensions(group, rows, lead, confounded, numeric, responses, levels, rng):
    """Cross-validate every applicable extension on the same folds and fit it on all tests
    in scope.

    Preference: a physical extension with a real gain and physically plausible parameters
    (no value outside its range, e.g. K0 > 1), else the generic one with a real gain, else the
    best gain (not kept).  Returns ``(base, base fitted, chosen, tried)``, chosen being
    ``(extension, gain, fitted)`` or None.
    """
    base_ext = base_model(group, rows)
    folds = make_folds(levels, "tests", rng)
    cache: dict = {}
    base_fitted = base_ext.fit(group, rows)
    tried, options = [], []
    for ext in library(group, rows, lead, confounded, numeric=numeric, responses=responses):
        entry = {"extension": ext.name, "physical": ext.physical, "description": ext.description}
        try:
            gain = cross_validate(group, rows, base_ext, ext, folds, scheme="tests", cache=cache)
            fitted = ext.fit(group, rows, base=base_fitted)
        except (ConvergenceError, np.linalg.LinAlgError, ValueError) as exc:
            entry["error"] = str(exc)[:400]
            tried.append(entry)
            continue
        implausible = _implausible(fitted.result, base_fitted.result)
        entry.update(
            relative=gain.relative,
            real=gain.real,
            base=gain.base,
            extended=gain.extended,
            implausible=implausible,
        )
        tried.append(entry)
        rank = (gain.real, gain.real and ext.physical and not implausible, gain.relative)
        options.append((rank, ext, gain, fitted))
    if not options:
        return base_ext, base_fitted, None, tried
    _, ext, gain, fitted = max(options, key=lambda o: o[0])
    return base_ext, base_fitted, (ext, gain, fitted), tried


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
    start = time.perf_counter()
    campaign, source = _as_campaign(campaign)
    rng = np.random.default_rng(seed)
    groups, notes = build_groups(campaign, points_per_test=points_per_test, progress=progress)
    diags, table = diagnose_groups(groups, alpha=alpha)
    notes = list(notes)
    for d in diags:
        notes.extend(n for n in d.notes if n not in notes)
    findings: list[Finding] = []
    explained: list[dict] = []
    confounded: list[dict] = []
    work = []
    for d in diags:
        g = d.group
        for r in d.relations:
            text = (
                f"{r.finer} and {r.coarser} are aliased (the same partition of the tests)"
                if r.kind == "aliased"
                else f"{r.finer} determines {r.coarser} (each {r.finer} has one {r.coarser})"
            )
            confounded.append(
                {
                    "kind": g.kind,
                    "soil": g.soil,
                    "relation": r.kind,
                    "columns": [r.finer, r.coarser],
                    "text": text,
                }
            )
        if table.empty:
            continue
        rows = table[(table["kind"] == g.kind) & (table["soil"] == g.soil)]
        leads = _leads(rows, d.relations)
        work.append((d, rows, leads))
    iterator = work
    if progress:
        from tqdm.auto import tqdm

        iterator = tqdm(work, desc="extensions", unit="group")
    for d, rows, leads in iterator:
        g = d.group
        accepted = None  # (name, fitted) of the latest kept extension in this group
        for lead, confounded_with in leads[:max_leads]:
            lead_rows = rows[(rows["candidate"] == lead) & rows["significant"]]
            top = lead_rows.sort_values(["p_adjusted", "p_value"]).iloc[0]
            if accepted is not None:
                cond_table = conditional_responses(g, accepted[1])
                p_after = retest(g, cond_table, lead, bool(top["categorical"]), top["blocks"])
                m = len(leads)
                if all(not (p * m < alpha) for p in p_after.values() if np.isfinite(p)):
                    explained.append(
                        {
                            "kind": g.kind,
                            "soil": g.soil,
                            "candidate": lead,
                            "by": accepted[0],
                            "p_after": float(np.nanmin([*p_after.values(), 1.0])),
                        }
                    )
                    continue
            scope = np.asarray(top["rows"], int)
            levels = candidate_values(g.tests, lead).astype(str).to_numpy()[scope]
            responses = tuple(lead_rows["response"])
            caveats = _caveats(lead_rows, lead, confounded_with)
            base_ext, base_fitted, chosen, tried = None, None, None, []
            if scope.size >= 6:
                try:
                    base_ext, base_fitted, chosen, tried = _try_extensions(
                        g,
                        scope,
                        lead,
                        confounded_with,
                        bool(top["numeric"]),
                        set(responses),
                        levels,
                        rng,
                    )
                except (ConvergenceError, IdentifiabilityError) as exc:
                    caveats.append(f"cross-validation on the tests in scope failed: {exc}")
            else:
                caveats.append(f"only {scope.size} tests in scope: too few to cross-validate")
            kept = chosen is not None and chosen[1].real
            if kept and chosen[0].physical:
                lead = _physical_name(lead, chosen[0].name, d.relations)
                confounded_with = [m for m in [top["candidate"], *confounded_with] if m != lead]
            fit = base_fit = fitted = None
            info, gain_cond = {}, None
            if chosen is not None:
                fitted = chosen[2]
                fit, base_fit = fitted.result, base_fitted.result
                ib, ie = information_criteria(base_fit), information_criteria(fit)
                info = {
                    "aic_base": ib["aic"],
                    "aic_extended": ie["aic"],
                    "bic_base": ib["bic"],
                    "bic_extended": ie["bic"],
                }
                implausible = _implausible(fit, base_fit)
                if implausible:
                    caveats.append(
                        f"{chosen[0].name}: physically implausible parameter(s): "
                        + "; ".join(implausible)
                    )
                n_levels = np.unique(levels).size
                if (
                    kept
                    and n_levels >= 3
                    and (chosen[0].physical or "linear" in chosen[0].name)
                    and chosen[0].name != "softening"
                ):
                    try:
                        gain_cond = cross_validate(
                            g,
                            scope,
                            base_ext,
                            chosen[0],
                            make_folds(levels, "conditions", rng),
                            scheme="conditions",
                        )
                    except (ConvergenceError, IdentifiabilityError) as exc:
                        caveats.append(f"leave-one-condition-out failed: {exc}")
            if chosen is not None and not chosen[1].real:
                caveats.append(
                    "no extension gives a real out-of-sample gain; the base model is kept"
                )
            findings.append(
                Finding(
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
            )
            if kept and fitted is not None:
                # Re-test later leads against this extension fitted on the whole group.
                try:
                    accepted = (chosen[0].name, chosen[0].fit(g, np.unique(g.owner)))
                except (ConvergenceError, IdentifiabilityError):
                    accepted = (chosen[0].name, fitted)
        if len(leads) > max_leads:
            notes.append(
                f"{g.label}: {len(leads) - max_leads} further significant cause(s) not extended "
                f"(max_leads = {max_leads}): {', '.join(lv for lv, _ in leads[max_leads:])}"
            )
    findings.sort(key=lambda f: (f.p_adjusted, f.p_value, -f.statistic))
    untestable = table[table["p_value"].isna()] if not table.empty else table
    if len(untestable):
        names = sorted({f"{r.kind}/{r.soil}:{r.candidate}" for r in untestable.itertuples()})
        notes.append(
            f"{len(names)} candidate(s) could not be tested (no variation within strata, or no "
            f"degrees of freedom): {', '.join(names[:12])}{', …' if len(names) > 12 else ''}"
        )
    return DiscoveryResult(
        findings=tuple(findings),
        flags=tuple(physical_flags(diags)),
        tests=table.drop(columns=["rows"]) if "rows" in table else table,
        confounded=tuple(confounded),
        explained=tuple(explained),
        notes=tuple(notes),
        alpha=alpha,
        seed=seed,
        runtime_s=time.perf_counter() - start,
        source=source,
        provenance=provenance or Provenance.of(campaign, seed=seed),
    )
