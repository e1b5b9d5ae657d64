"""Run one study on a campaign: select tests, per-test responses, statistics, tables.

Data flow (one way): campaign → per-test fits (:mod:`.responses`) → statistics
(:mod:`.effects`, :mod:`.shear`, :mod:`.preparation`, :mod:`.verdict`) → :class:`StudyResult`;
outputs and the PDF only read the result.
"""

from __future__ import annotations

import time
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from ..campaign import load_campaign
from ..identification.conditions import fit_conditions
from ..identification.per_test import not_converged_message
from ..identification.result import ONSET_TOLERANCE
from ..outputs import Provenance, source_date
from ..quality import ScreenedCampaign
from .data import StudyDataError, check_reference, select_tests, soils_with_levels
from .defaults import RESPONSE, moved_verdicts, warn_moved, with_best_method
from .effects import factor_effects
from .preparation import evaluate_criteria
from .responses import PerTestCache
from .result import StudyResult
from .shear import shear_effects
from .spec import load_spec
from .verdict import classify

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from .spec import StudySpec

__all__ = ["run_study"]


def _pooled_fits(
    campaign: Campaign, tests: pd.DataFrame, spec: StudySpec, soil: str, notes: list
) -> pd.DataFrame:
    """Per-condition identification of one soil (the paper's Tables 5–7), tidy."""
    result = fit_conditions(
        campaign,
        spec.kind,
        by=spec.factor,
        model=spec.model,
        fallback_model=spec.fallback_model,
        soils=[soil],
        test_ids=tests["test_id"].astype(str).tolist(),
    )
    notes += list(result.notes) + [f"pooled fit failed: {f}" for f in result.failures]
    table = result.table()
    if table.empty:
        return table
    return table.drop(columns=["kind", "series"]).pipe(
        lambda t: t[["soil", *[c for c in t.columns if c != "soil"]]]
    )


def _failed_in_bearing(campaign: Campaign, per_test: pd.DataFrame) -> set[str]:
    """Tests flagged ``bearing-failure`` whose fitted curve still reaches the onset (a window
    that cuts the failure off resolves it, as for the identification's health flags); none
    where ``campaign`` was not screened (a :class:`ScreenedCampaign` carries the report)."""
    if not isinstance(campaign, ScreenedCampaign) or "z_max_m" not in per_test:
        return set()
    report = campaign.report
    z_max = dict(zip(per_test["test_id"].astype(str), per_test["z_max_m"], strict=True))
    return {
        f.test_id
        for f in report.flags_of(z_max)
        if f.code == "bearing-failure"
        and not z_max[f.test_id] <= (f.value or 0.0) * (1 + ONSET_TOLERANCE)
    }


def run_study(
    spec: StudySpec | str | Path,
    campaign: Campaign | str | Path,
    *,
    cache: PerTestCache | None = None,
    progress: bool = False,
    seed: int | None = None,
    provenance: Provenance | None = None,
) -> StudyResult:
    """Run ``spec`` on ``campaign`` and return its :class:`StudyResult`.

    Parameters
    ----------
    spec : StudySpec, str or Path
        A shipped study's name (``"velocity"``, as ``soilstats study velocity``), the path of
        a specification file (.toml), or a spec from :func:`soilstats.study.load_spec`.
    campaign : Campaign, str or Path
        A campaign, or what :func:`soilstats.load_campaign` takes (a folder or a bundled name).
    cache : PerTestCache, optional
        Shared per-test fits (for several studies on one campaign).
    progress : bool
        tqdm progress bars for the per-test fits.
    seed : int, optional
        Recorded in the result; seeds the parametric bootstrap of the Welch-type test of a
        factor with a random block (the preparation study), one stream per soil and response.
    provenance : Provenance, optional
        Recorded in every output (default: a library call on ``campaign``, as given, with
        ``seed``).

    Raises
    ------
    StudyDataError
        The campaign lacks what the study needs (also: no soil has a repeated factor level).
    """
    start = time.perf_counter()
    if isinstance(spec, str | Path):
        spec = load_spec(spec)
    if isinstance(campaign, str | Path):
        campaign = load_campaign(campaign)
    # The provenance names the campaign as given, before this study's window.
    provenance = provenance or Provenance.of(campaign, seed=seed)
    window_notes = []
    if spec.window:  # the spec's own window: every per-test and pooled fit sees it
        campaign = campaign.windowed(spec.window)
        cache = PerTestCache(campaign, progress=progress)
        window_notes.append(f"Fitting window of this study: {spec.window.describe()}")
    cache = cache or PerTestCache(campaign, progress=progress)
    tests = select_tests(campaign, spec)
    soils, notes = soils_with_levels(tests, spec)
    tests = tests[tests["soil"].astype(str).isin(soils)]
    notes = window_notes + notes + check_reference(tests, spec)
    per_test = _per_test(cache, tests, spec, notes)
    failed = not_converged_message(per_test, spec.kind)
    if failed:
        notes.append(failed)
    effect_rows, anovas, pairs, lines, params, untested = [], [], [], [], [], []
    for soil in soils:
        out = _soil_effects(per_test, spec, soil, seed)
        if spec.kind == "shear":
            lines.append(out["lines"])
        else:
            pairs.append(out["pairs"])
        effect_rows += out["effects"]
        untested += out.get("untested", [])
        anovas.append(out["anova"])
        notes += out["notes"]
        params.append(_pooled_fits(campaign, tests, spec, soil, notes))
    if untested and not effect_rows:  # nothing tested: an error, not an empty verdict
        raise StudyDataError("\n".join(untested))
    effects = classify(effect_rows, alpha=spec.alpha, family=spec.family)
    parameters = pd.concat(params, ignore_index=True) if params else pd.DataFrame()
    criteria = best = None
    if spec.type == "preparation":
        criteria, best = _preparation(campaign, per_test, parameters, spec, notes)

    defaults = spec_defaults(spec)
    moved = moved_verdicts(
        spec,
        defaults,
        effects if best is None else with_best_method(effects, best),
        lambda alt: _verdicts_at(
            alt, cache, per_test, effect_rows, soils, seed, campaign, parameters, best
        ),
    )
    warn_moved(moved)
    return StudyResult(
        spec=spec,
        source=str(campaign.source),
        date=source_date(),
        soils=soils,
        effects=effects,
        anova=pd.concat(anovas, ignore_index=True) if anovas else pd.DataFrame(),
        pairs=pd.concat(pairs, ignore_index=True) if pairs else pd.DataFrame(),
        parameters=parameters,
        lines=pd.concat(lines, ignore_index=True) if lines else pd.DataFrame(),
        per_test=per_test,
        criteria=criteria,
        best=best,
        notes=tuple(dict.fromkeys(notes)),
        runtime_s=time.perf_counter() - start,
        seed=seed,
        provenance=provenance,
        defaults=defaults,
        default_warnings=moved,
    )


#: Spec keys with a default that the result rests on -> (default as written, kinds it applies
#: to): what a spec leaving them out is told on page 1 and in the JSON's "defaults".
_SPEC_DEFAULTS = {
    "alpha": ("0.05", ("sinkage", "shear")),
    "z_ref_m": ("0.025", ("sinkage",)),
    "z_window_m": ("0.001", ("sinkage",)),
    "fallback_model": ("none (a failed fit is a failure)", ("sinkage",)),
}


def spec_defaults(spec: StudySpec) -> dict[str, str]:
    """``{"spec: KEY": default}`` for every key of :data:`_SPEC_DEFAULTS` the specification
    file of ``spec`` leaves out (a spec built in memory, without a file: none known)."""
    if spec.path is None or not Path(spec.path).is_file():
        return {}
    raw = tomllib.loads(Path(spec.path).read_text(encoding="utf-8"))
    return {
        f"spec: {key}": value
        for key, (value, kinds) in _SPEC_DEFAULTS.items()
        if key not in raw and spec.kind in kinds
    }


def _soil_effects(
    per_test: pd.DataFrame, spec: StudySpec, soil: str, seed: int | None, *, pair_p: bool = True
) -> dict:
    """The effects of ``spec``'s factor in ``soil`` (:func:`.shear.shear_effects` or
    :func:`.effects.factor_effects`; ``pair_p``: the Tukey pairs' p-values too)."""
    data = per_test[per_test["soil"].astype(str) == soil]
    if spec.kind == "shear":
        return shear_effects(data, spec, soil)
    return factor_effects(data, spec, soil, spec.alpha, seed=seed or 0, p_values=pair_p)


def _verdicts_at(
    alt: StudySpec,
    cache: PerTestCache,
    per_test: pd.DataFrame,
    effect_rows: list[dict],
    soils: list[str],
    seed: int | None,
    campaign: Campaign,
    parameters: pd.DataFrame,
    best: dict | None,
) -> pd.DataFrame | None:
    """The classified effects at ``alt`` (:func:`_effects_at`) and, for a preparation study
    (``best`` given), its best method chosen again there (:func:`.defaults.with_best_method`);
    None where ``alt``'s depth is not reached by every test."""
    at = _effects_at(cache, per_test, effect_rows, soils, alt, seed)
    if at is None:
        return None
    effects, per_test_alt = at
    if best is None:
        return effects
    _, best_alt = _preparation(campaign, per_test_alt, parameters, alt, [])
    return with_best_method(effects, best_alt)


def _effects_at(
    cache: PerTestCache,
    per_test: pd.DataFrame,
    effect_rows: list[dict],
    soils: list[str],
    alt: StudySpec,
    seed: int | None,
) -> tuple[pd.DataFrame, pd.DataFrame] | None:
    """The classified effects with the :data:`~.defaults.RESPONSE` rows re-tested at
    ``alt``'s z_ref_m and z_window_m (the per-test fits reused from ``cache``, the other
    responses' rows kept), and the per-test table there; None when a test with a pressure at
    the default has none there."""
    ids = per_test["test_id"].astype(str).tolist()
    at = cache.sinkage(ids, alt.z_ref_m, alt.z_window_m)
    if (at["p_ref_Pa"].isna() & per_test["p_ref_Pa"].notna().to_numpy()).any():
        return None
    one = replace(alt, responses=tuple(r for r in alt.responses if r.name == RESPONSE))
    new = per_test.assign(
        p_ref_Pa=at["p_ref_Pa"].to_numpy(), log10_p_ref=at["log10_p_ref"].to_numpy()
    )
    rows = [r for r in effect_rows if r["response"] != RESPONSE]
    for soil in soils:
        # the verdicts read the pairs' intervals, not their p-values (the costly part)
        rows += _soil_effects(new, one, soil, seed, pair_p=False)["effects"]
    return classify(rows, alpha=alt.alpha, family=alt.family), new


def _per_test(
    cache: PerTestCache, tests: pd.DataFrame, spec: StudySpec, notes: list
) -> pd.DataFrame:
    """The per-test responses of the selected ``tests`` (p_ref at z_ref for sinkage; a note
    for tests too shallow, an error when none reaches it)."""
    ids = tests["test_id"].astype(str).tolist()
    if spec.kind != "sinkage":
        return cache.shear(ids)
    per_test = cache.sinkage(ids, spec.z_ref_m, spec.z_window_m)
    short = per_test["p_ref_Pa"].isna().sum()
    if short == len(per_test):
        raise StudyDataError(
            f"{spec.name} study needs sinkage tests reaching z_ref_m = {spec.z_ref_m:g} m; "
            f"none of the {len(per_test)} selected tests does"
        )
    if short:
        notes.append(f"{short} test(s) do not reach z_ref = {spec.z_ref_m * 1e3:g} mm: no p_ref")
    return per_test


def _preparation(
    campaign: Campaign,
    per_test: pd.DataFrame,
    parameters: pd.DataFrame,
    spec: StudySpec,
    notes: list,
) -> tuple[pd.DataFrame, dict]:
    """The preparation study's Table 3 criteria and best method; a note per single test."""
    eps = parameters.groupby(["soil", "condition"], as_index=False)["epsilon"].first()
    criteria, best = evaluate_criteria(
        per_test,
        eps.rename(columns={"condition": "level"}),  # type: ignore[call-overload]  # pandas-stubs: groupby(as_index=False)[col].first() is a DataFrame
        spec,
        spec.alpha,
        failed=_failed_in_bearing(campaign, per_test),
    )
    single = per_test.groupby(["soil", spec.factor]).size()
    single = single[single == 1]
    if len(single):
        notes.append(
            "single test (no repetition, scatter unknown): "
            + ", ".join(f"{s} {spec.factor} {m}" for s, m in single.index)
        )
    return criteria, best
