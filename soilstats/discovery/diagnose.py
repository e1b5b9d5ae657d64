"""Diagnosis: fit the base model, then look for structure in what it leaves, per candidate.

**Responses.**  Each test is fitted on its own (:func:`soilstats.fit_per_test`) and compared
with the base model fitted to all tests of its (kind, soil):

* sinkage — ``level``: ln of the test's own Bernstein pressure (Eq. 8) over the base model's
  (Eq. 7 with the test's b, or Eq. 8) at a reference sinkage z_ref (half the median depth
  reached), i.e. the relative stiffness misfit; ``shape``: the test's n minus the base n (a
  narrow plate that softens, or a velocity that changes the curve's shape, shows here);
* shear — ``level``: ln of the test's plateau τ_max (Eq. 13 at its σ) over the base
  c + σ·tan φ (Eqs. 13, 15); ``K``: ln of its K over the base K.

**Tests.**  For every candidate cause X and response y, X is tested *within strata* of the
other categorical candidates that are not confounded with it: y = stratum + X + ε, the
F-test of X after the strata (absorbed by within-stratum centring, Frisch–Waugh–Lovell), on
the strata in which X varies.  A categorical X enters as levels, a continuous one as a linear
trend (on ln x when x > 0 spans more than a factor four).  The p-values of all candidates ×
responses × groups form one family, adjusted by Holm's method
(:func:`soilstats.statistics.verdicts`), so the chance of any false cause stays ≤ α.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy import stats

from ..errors import ConvergenceError
from ..statistics import verdicts
from .candidates import (
    FIT_COLUMNS,
    MISSING,
    Candidate,
    ColumnRole,
    Relation,
    candidate_values,
    classify_columns,
    enumerate_candidates,
    level_codes,
    spans_log,
)
from .candidates import relations as find_relations
from .extensions import SinkageExtension, base_model

__all__ = ["RESPONSES", "Diagnosis", "add_responses", "diagnose_groups", "strata_test"]

RESPONSES = {"sinkage": ("level", "shape"), "shear": ("level", "K")}


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Candidates, confounding and significance tests of one (kind, soil) group."""

    group: object  # Group with the response columns added
    base: object  # Fitted base model (None if it failed)
    candidates: tuple[Candidate, ...]
    relations: tuple[Relation, ...]
    notes: tuple[str, ...]
    roles: tuple[ColumnRole, ...] = ()


def _sinkage_deviations(table: pd.DataFrame, idx, log_k_model, n_model) -> None:
    """``level`` (ln p_test − ln p_model at z_ref, half the median depth) and ``shape``
    (n_test − n_model) of the rows ``idx``, written into ``table``."""
    z_ref = 0.5 * float(np.nanmedian(table["z_max_m"]))
    k_i, n_i = table.loc[idx, "k"].to_numpy(float), table.loc[idx, "n"].to_numpy(float)
    level = np.log(k_i) + n_i * np.log(z_ref) - log_k_model - n_model * np.log(z_ref)
    table.loc[idx, "_dev_level"] = np.where(np.isfinite(level), level, np.nan)
    table.loc[idx, "_dev_shape"] = n_i - n_model


def _shear_deviations(table: pd.DataFrame, idx, plateau, k_model) -> None:
    """``level`` (ln τ_max − ln plateau_model) and ``K`` (ln K − ln K_model) of the rows
    ``idx``, written into ``table``."""
    level = np.log(table.loc[idx, "tau_max"].to_numpy(float)) - np.log(plateau)
    dev_k = np.log(table.loc[idx, "K"].to_numpy(float) / k_model)
    table.loc[idx, "_dev_level"] = np.where(np.isfinite(level), level, np.nan)
    table.loc[idx, "_dev_K"] = np.where(np.isfinite(dev_k), dev_k, np.nan)


def add_responses(group):
    """Fit the base model on all usable tests and add the per-test response columns.

    Returns ``(group, base, notes)``; ``base`` is None (and responses NaN) when the base model
    does not converge, which the notes state.
    """
    rows = np.unique(group.owner)
    table = group.tests.copy()
    notes: list[str] = []
    model = base_model(group, rows)
    try:
        base = model.fit(group, rows)
    except ConvergenceError as exc:
        base = None
        if group.kind == "sinkage" and getattr(model, "bekker", False):
            model = SinkageExtension("bernstein (base)", False, "Eq. 8", bekker=False)
            try:
                base = model.fit(group, rows)
                notes.append(f"{group.label}: Bekker did not converge ({exc}); Bernstein used")
            except ConvergenceError as exc2:
                exc = exc2
        if base is None:
            notes.append(f"{group.label}: the base model did not converge — {exc}; not diagnosed")
    for r in RESPONSES[group.kind]:
        table[f"_dev_{r}"] = np.nan
    if base is not None:
        theta = base.result.values
        with np.errstate(divide="ignore", invalid="ignore"):
            if group.kind == "sinkage":
                if model.bekker:
                    k_base = theta[0] / table["b_m"].to_numpy(float) + theta[1]
                else:
                    k_base = np.full(len(table), theta[0])
                _sinkage_deviations(table, table.index, np.log(k_base), theta[-1])
            else:
                c, phi, k = theta[:3]
                plateau = c + table["sigma_mean_Pa"].to_numpy(float) * np.tan(np.radians(phi))
                _shear_deviations(table, table.index, plateau, k)
        unused = np.setdiff1d(np.arange(len(table)), rows)
        table.loc[table.index[unused], [f"_dev_{r}" for r in RESPONSES[group.kind]]] = np.nan
    return replace(group, tests=table), base, notes


def _trend(x: np.ndarray) -> np.ndarray:
    """A continuous candidate as a regressor: ln x when x > 0 spans more than a factor four."""
    return np.log(x) if spans_log(x) else x


def _strata(columns: list[np.ndarray], n: int) -> np.ndarray:
    """Stratum code of each of ``n`` rows: one per combination of the block codes given."""
    if not columns:
        return np.zeros(n, int)
    return np.unique(np.column_stack(columns), axis=0, return_inverse=True)[1].ravel()


def strata_test(y, x, *, categorical: bool, strata) -> dict:
    """F-test of X after stratum effects, on the strata in which X varies.

    Parameters
    ----------
    y : array (n,)
        Response, finite.
    x : array (n,)
        Candidate values: integer level codes (categorical) or numbers (continuous).
    categorical : bool
    strata : array (n,) of int
        Stratum code of each row (a single stratum when there is no block).

    Returns
    -------
    dict
        ``statistic`` (F), ``df1``, ``df2``, ``p_value``, ``effect_size`` (partial η²),
        ``used`` (boolean mask of the rows tested), ``singletons`` (levels with one test), or
        ``reason`` when the test cannot be made (then ``p_value`` is NaN).
    """
    y = np.asarray(y, float)
    x = np.asarray(x)
    strata = np.asarray(strata)
    varies = pd.Series(x).groupby(strata).transform("nunique").to_numpy() >= 2
    out = {"used": varies, "singletons": [], "p_value": np.nan, "statistic": np.nan}
    out.update(df1=0, df2=0, effect_size=np.nan, reason="")
    n = int(varies.sum())
    if n < 4:
        out["reason"] = "the candidate varies within no stratum of the other candidates"
        return out
    y, x, s = y[varies], x[varies], pd.factorize(strata[varies])[0]
    if categorical:
        levels, counts = np.unique(x, return_counts=True)
        out["singletons"] = levels[counts == 1].tolist()
        design = (x[:, None] == levels[None, :]).astype(float)
    else:
        design = _trend(x.astype(float))[:, None]
    n_strata = s.max() + 1

    def centre(a):
        sums = np.zeros((n_strata, *a.shape[1:]))
        np.add.at(sums, s, a)
        return a - (sums / np.bincount(s, minlength=n_strata).reshape(-1, *[1] * (a.ndim - 1)))[s]

    yc, dc = centre(y), centre(design)
    sv = np.linalg.svd(dc, compute_uv=False)
    rank = int(np.sum(sv > sv[0] * 1e-9)) if sv.size and sv[0] > 0 else 0
    df2 = n - n_strata - rank
    if rank < 1 or df2 < 2:
        out["reason"] = f"no degrees of freedom left (n = {n}, strata = {n_strata}, rank = {rank})"
        return out
    beta = np.linalg.lstsq(dc, yc, rcond=1e-9)[0]
    rss1 = float(np.sum((yc - dc @ beta) ** 2))
    rss0 = float(np.sum(yc**2))
    if rss1 <= 0:
        f_stat, p = (np.inf, 0.0) if rss0 > 0 else (np.nan, np.nan)
    else:
        f_stat = ((rss0 - rss1) / rank) / (rss1 / df2)
        p = float(stats.f.sf(f_stat, rank, df2))
    out.update(
        statistic=float(f_stat),
        df1=rank,
        df2=int(df2),
        p_value=p,
        effect_size=(rss0 - rss1) / rss0 if rss0 > 0 else np.nan,
    )
    return out


def _block_eligible(table: pd.DataFrame, cand: Candidate) -> bool:
    """Design-like factors only: categorical with ≥ 3 tests per level on median (a near-unique
    label such as a date would cut the tests into strata of one)."""
    if not cand.categorical:
        return False
    counts = candidate_values(table, cand.name).astype(object).fillna(MISSING).value_counts()
    return float(counts.median()) >= 3


def _diagnose_group(group, base, notes) -> tuple[Diagnosis, list[dict]]:
    table = group.tests
    have = table[[f"_dev_{r}" for r in RESPONSES[group.kind]]].notna().any(axis=1).to_numpy()
    sub = table.loc[have]
    all_roles = classify_columns(sub, group.kind, group.time_columns)
    cands, cand_notes = enumerate_candidates(sub, group.kind, roles=all_roles)
    notes = [*notes, *(f"{group.soil}: {n}" for n in cand_notes)]
    rels = find_relations(sub, cands)
    related: dict[str, set[str]] = {c.name: set() for c in cands}
    for r in rels:
        related[r.finer].add(r.coarser)
        related[r.coarser].add(r.finer)
    eligible = {c.name for c in cands if _block_eligible(sub, c)}
    values_of = {c.name: candidate_values(table, c.name) for c in cands}
    codes = {c.name: level_codes(values_of[c.name]) for c in cands if c.categorical}
    rows_out: list[dict] = []
    for cand in cands:
        blocks = [b for b in sorted(eligible) if b != cand.name and b not in related[cand.name]]
        strata = _strata([codes[b] for b in blocks], len(table))
        values = values_of[cand.name]
        recorded = values.notna().to_numpy()
        x_all = codes[cand.name] if cand.categorical else values.to_numpy(float)
        for response in RESPONSES[group.kind]:
            y_all = table[f"_dev_{response}"].to_numpy(float)
            ok = np.isfinite(y_all) & recorded
            res = strata_test(y_all[ok], x_all[ok], categorical=cand.categorical, strata=strata[ok])
            used = np.flatnonzero(ok)[res["used"]]
            singles = []
            if res["singletons"]:
                lv = values.to_numpy()[ok][res["used"]]
                cx = x_all[ok][res["used"]]
                singles = sorted({str(lv[cx == s][0]) for s in res["singletons"]})
            rows_out.append(
                dict(
                    kind=group.kind,
                    soil=group.soil,
                    candidate=cand.name,
                    response=response,
                    statistic=res["statistic"],
                    df1=res["df1"],
                    df2=res["df2"],
                    p_value=res["p_value"],
                    effect_size=res["effect_size"],
                    categorical=cand.categorical,
                    numeric=cand.numeric,
                    role=cand.role,
                    n_tests=int(used.size),
                    blocks=", ".join(blocks),
                    confounded_with=", ".join(sorted(related[cand.name])),
                    singleton_levels=", ".join(singles),
                    reason=res["reason"],
                    rows=used,
                )
            )
    roles = tuple(
        r for r in all_roles if r.column not in FIT_COLUMNS and sub[r.column].nunique() > 1
    )
    diag = Diagnosis(group, base, tuple(cands), tuple(rels), tuple(notes), roles)
    return diag, rows_out


def diagnose_groups(groups, *, alpha: float = 0.05) -> tuple[list[Diagnosis], pd.DataFrame]:
    """Diagnose every group; one Holm family over all testable candidate × response rows.

    Returns the per-group diagnoses and a table with one row per (kind, soil, candidate,
    response): F, degrees of freedom, raw and Holm-adjusted p, partial η², the blocks used,
    the confounded candidates, single-test levels, and the reason a row was not testable.
    """
    diags, rows = [], []
    for group in groups:
        group, base, notes = add_responses(group)
        d, r = _diagnose_group(group, base, notes)
        diags.append(d)
        rows.extend(r)
    table = pd.DataFrame(rows)
    if table.empty:
        return diags, table
    testable = table["p_value"].notna()
    table["p_adjusted"] = np.nan
    table["significant"] = False
    if testable.any():
        family = table.loc[testable].assign(
            soil=lambda t: t["kind"] + " / " + t["soil"],
            factor=table["candidate"],
            test="F within strata",
        )
        v = verdicts(
            family[["soil", "response", "factor", "statistic", "p_value", "effect_size", "test"]],
            alpha=alpha,
        )
        table.loc[testable, "p_adjusted"] = v["p_adjusted"].to_numpy()
        table.loc[testable, "significant"] = v["significant"].to_numpy()
    return diags, table


def _synthetic(group, rows):
    """Two to twenty-four noiseless sample points per test, for reading a model's curve."""
    t = group.tests.iloc[rows]
    if group.kind == "sinkage":
        grid = np.linspace(0.05, 1.0, 24)
        z = (t["z_max_m"].to_numpy(float)[:, None] * grid[None, :]).ravel()
        b = np.repeat(t["b_m"].to_numpy(float), grid.size)
        x = {"z": z, "b": b}
        owner = np.repeat(rows, grid.size)
    else:
        j1 = float(np.nanmedian(group.tests["K"])) if group.tests["K"].notna().any() else 0.01
        j = np.tile([j1, 2 * j1], rows.size)
        x = {"j": j, "sigma": np.repeat(t["sigma_mean_Pa"].to_numpy(float), 2)}
        owner = np.repeat(rows, 2)
    ones = np.ones(owner.size)
    return replace(group, x=x, y=ones, w=ones, owner=owner), x


def conditional_responses(group, fitted) -> pd.DataFrame:
    """The per-test responses measured against a fitted (extended) model instead of the base.

    The model's curve of each test is read on noiseless points: for sinkage its Bernstein
    (k̂, n̂) by a p-weighted log–log line (exact where the curve is a power law), compared with
    the test's own (k, n) as in :func:`add_responses`; for shear its plateau and K̂ from two
    points j₁, 2j₁ of Eq. 13 (exact for the family).  Rows the model cannot describe are NaN.
    """
    table = group.tests.copy()
    rows = np.flatnonzero(table[[c for c in table if c.startswith("_dev_")]].notna().any(axis=1))
    synth, x = _synthetic(group, rows)
    y_hat = fitted.extension.predict(fitted, synth, rows)
    for c in [c for c in table if c.startswith("_dev_")]:
        table[c] = np.nan
    idx = table.index[rows]
    with np.errstate(divide="ignore", invalid="ignore"):
        if group.kind == "sinkage":
            m = 24
            lz = np.log(x["z"]).reshape(-1, m)
            lp = np.log(y_hat).reshape(-1, m)
            wt = np.nan_to_num(y_hat.reshape(-1, m))
            n_hat = np.full(rows.size, np.nan)
            lk_hat = np.full(rows.size, np.nan)
            for i in range(rows.size):
                ok = np.isfinite(lp[i]) & (wt[i] > 0)
                if ok.sum() >= 3:
                    n_hat[i], lk_hat[i] = np.polyfit(lz[i, ok], lp[i, ok], 1, w=wt[i, ok])
            _sinkage_deviations(table, idx, lk_hat, n_hat)
        else:
            t1, t2 = y_hat[0::2], y_hat[1::2]
            r = t2 / t1 - 1.0  # = exp(−j₁/K̂)
            k_hat = -x["j"][0] / np.log(r)
            _shear_deviations(table, idx, t1 / (1.0 - r), k_hat)
    return table


def retest(group, table, candidate: str, categorical: bool, blocks: str) -> dict[str, float]:
    """Raw p-value per response of one candidate against the responses in ``table``."""
    blocks_list = [b for b in blocks.split(", ") if b]
    strata = _strata([level_codes(candidate_values(table, b)) for b in blocks_list], len(table))
    values = candidate_values(table, candidate)
    x_all = level_codes(values) if categorical else values.to_numpy(float)
    out = {}
    for response in RESPONSES[group.kind]:
        y_all = table[f"_dev_{response}"].to_numpy(float)
        ok = np.isfinite(y_all) & values.notna().to_numpy()
        res = strata_test(y_all[ok], x_all[ok], categorical=categorical, strata=strata[ok])
        out[response] = res["p_value"]
    return out
