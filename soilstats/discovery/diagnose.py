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
trend (on ln x when x > 0 spans more than a factor four; never for time/order, a drift).
The p-values of all candidates × responses × groups form one family, adjusted by Holm's method
(:func:`soilstats.statistics.verdicts`), so the chance of any false cause stays ≤ α.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

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
    trend_on_log,
)
from .candidates import relations as find_relations
from .extensions import ModelExtension, SinkageExtension
from .ftests import (
    interaction_test,
    strata_codes,
    strata_test,
    within_blocks_test,
)
from .library import base_model, bekker_refused
from .power import minimum_detectable
from .within import (
    INTERACTION,
    RESPONSES,
    Family,
    family_row,
    interactions,
    response_range,
    trend_span,
    within_blocks,
)

if TYPE_CHECKING:
    from .data import Group
    from .extensions import FitStart, Fitted

__all__ = [
    "INTERACTION",
    "RESPONSES",
    "Diagnosis",
    "add_responses",
    "diagnose_groups",
    "training_responses",
]


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Candidates, confounding and significance tests of one (kind, soil) group."""

    group: Group  # Group with the response columns added
    base: Fitted | None  # Fitted base model (None if it failed)
    candidates: tuple[Candidate, ...]
    relations: tuple[Relation, ...]
    notes: tuple[str, ...]
    roles: tuple[ColumnRole, ...] = ()


def _sinkage_deviations(
    table: pd.DataFrame, idx: pd.Index, log_k_model: np.ndarray | float, n_model: np.ndarray | float
) -> None:
    """``level`` (ln p_test − ln p_model at z_ref, half the median depth) and ``shape``
    (n_test − n_model) of the rows ``idx``, written into ``table``."""
    z_ref = 0.5 * float(np.nanmedian(table["z_max_m"]))
    k_i, n_i = table.loc[idx, "k"].to_numpy(float), table.loc[idx, "n"].to_numpy(float)
    level = np.log(k_i) + n_i * np.log(z_ref) - log_k_model - n_model * np.log(z_ref)
    table.loc[idx, "_dev_level"] = np.where(np.isfinite(level), level, np.nan)
    table.loc[idx, "_dev_shape"] = n_i - n_model


def _shear_deviations(
    table: pd.DataFrame, idx: pd.Index, plateau: np.ndarray | float, k_model: float
) -> None:
    """``level`` (ln τ_max − ln plateau_model) and ``K`` (ln K − ln K_model) of the rows
    ``idx``, written into ``table``."""
    level = np.log(table.loc[idx, "tau_max"].to_numpy(float)) - np.log(plateau)
    dev_k = np.log(table.loc[idx, "K"].to_numpy(float) / k_model)
    table.loc[idx, "_dev_level"] = np.where(np.isfinite(level), level, np.nan)
    table.loc[idx, "_dev_K"] = np.where(np.isfinite(dev_k), dev_k, np.nan)


def add_responses(group: Group) -> tuple[Group, Fitted | None, list[str]]:
    """Fit the base model on all usable tests and add the per-test response columns.

    Returns ``(group, base, notes)``; ``base`` is None (and responses NaN) when the base model
    does not converge, which the notes state.
    """
    rows = np.unique(group.owner)
    table = group.tests.copy()
    notes: list[str] = []
    model = base_model(group, rows)
    if group.kind == "sinkage" and isinstance(model, SinkageExtension) and not model.bekker:
        why = bekker_refused(group, rows)
        if why is not None and table["b_m"].iloc[rows].nunique() > 1:
            notes.append(f"{group.label}: base model Bernstein (Eq. 8), as identify decides: {why}")
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
        _base_deviations(table, group.kind, model, base.result.values, rows, group)
    return replace(group, tests=table), base, notes


def _base_deviations(
    table: pd.DataFrame,
    kind: str,
    model: Any,  # the base model's Extension (a SinkageExtension says .bekker)
    theta: np.ndarray,
    rows: ArrayLike,
    group: Group | None = None,
) -> None:
    """The responses of the tests ``rows`` (positions) against the base model ``model``
    with parameters ``theta``, written into ``table``; every other test's are left NaN.
    A registered model's (:class:`~.extensions.ModelExtension`) curve is read as
    :func:`conditional_responses` reads an extended model's."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if isinstance(model, ModelExtension):
            assert group is not None  # a registered model's curve is read on the group
            _model_deviations(table, group, model, theta, np.asarray(rows, int))
        elif kind == "sinkage":
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
    table.loc[table.index[unused], [f"_dev_{r}" for r in RESPONSES[kind]]] = np.nan


def training_responses(group: Group, base: FitStart, rows: np.ndarray) -> pd.DataFrame:
    """The per-test responses of the tests ``rows`` only, against a base model fitted on
    them (``base``: its extension and ``result.values``, e.g. a fold fit's
    :class:`~.work.Start`); every other test's responses are NaN.

    What diagnosis would have measured had only these tests been run — so that a
    cross-validation fold can repeat diagnosis's F-tests without its held-out tests
    (:mod:`.nested`): on all tests, the base model and so every response carry the
    held-out tests too.
    """
    table = group.tests.copy()
    for r in RESPONSES[group.kind]:
        table[f"_dev_{r}"] = np.nan
    _base_deviations(table, group.kind, base.extension, np.asarray(base.result.values), rows, group)
    return table


def _block_eligible(table: pd.DataFrame, cand: Candidate) -> bool:
    """Design-like factors only: categorical with ≥ 3 tests per level on median (a near-unique
    label such as a date would cut the tests into strata of one)."""
    if not cand.categorical:
        return False
    counts = candidate_values(table, cand.name).astype(object).fillna(MISSING).value_counts()
    return float(counts.median()) >= 3


def _diagnose_group(
    group: Group, base: Fitted | None, notes: list[str]
) -> tuple[Diagnosis, list[dict]]:
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
        strata = strata_codes([codes[b] for b in blocks], len(table))
        values = values_of[cand.name]
        recorded = values.notna().to_numpy()
        x_all = codes[cand.name] if cand.categorical else values.to_numpy(float)
        for response in RESPONSES[group.kind]:
            y_all = table[f"_dev_{response}"].to_numpy(float)
            ok = np.isfinite(y_all) & recorded
            res = strata_test(
                y_all[ok],
                x_all[ok],
                categorical=cand.categorical,
                strata=strata[ok],
                log_scale=trend_on_log(cand.role),
            )
            used = np.flatnonzero(ok)[res["used"]]
            singles = []
            if res["singletons"]:
                lv = values.to_numpy()[ok][res["used"]]
                cx = x_all[ok][res["used"]]
                singles = sorted({str(lv[cx == s][0]) for s in res["singletons"]})
            rows_out.append(
                family_row(
                    group,
                    cand.name,
                    response,
                    res,
                    categorical=cand.categorical,
                    numeric=cand.numeric,
                    role=cand.role,
                    n_tests=int(used.size),
                    blocks=", ".join(blocks),
                    confounded_with=", ".join(sorted(related[cand.name])),
                    singleton_levels=", ".join(singles),
                    pair="",
                    span=trend_span(x_all[ok][res["used"]], cand.categorical),
                    y_range=response_range(y_all[ok][res["used"]]),
                    rows=used,
                )
            )
    family = Family(group, cands, related, eligible, codes, values_of)
    table, inter_rows, inter_rels = interactions(family, table)
    rows_out += inter_rows
    table, within_rows = within_blocks(family, table)
    rows_out += within_rows
    roles = tuple(
        r for r in all_roles if r.column not in FIT_COLUMNS and sub[r.column].nunique() > 1
    )
    group = replace(group, tests=table)
    diag = Diagnosis(group, base, tuple(cands), (*rels, *inter_rels), tuple(notes), roles)
    return diag, rows_out


def diagnose_groups(
    groups: Iterable[Group], *, alpha: float = 0.05
) -> tuple[list[Diagnosis], pd.DataFrame]:
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
    # Aliased candidates (tool and b_m: the same partition) make one test, not two: one
    # hypothesis in Holm's family, its verdict shared (until issue #35 each counted).
    hypothesis = _hypotheses(table, diags)
    table["hypothesis"] = hypothesis
    first = ~pd.Series(hypothesis).duplicated().to_numpy() & testable.to_numpy()
    if first.any():
        family = table.loc[first].assign(
            soil=lambda t: t["kind"] + " / " + t["soil"],
            factor=table["candidate"],
            test="F within strata",
        )
        v = verdicts(
            family[["soil", "response", "factor", "statistic", "p_value", "effect_size", "test"]],
            alpha=alpha,
        )
        of = dict(zip(hypothesis[first], v["p_adjusted"].to_numpy(), strict=True))
        sig = dict(zip(hypothesis[first], v["significant"].to_numpy(), strict=True))
        table.loc[testable, "p_adjusted"] = [of[h] for h in hypothesis[testable.to_numpy()]]
        table.loc[testable, "significant"] = [sig[h] for h in hypothesis[testable.to_numpy()]]
    # Silence is not evidence: the effect each test would have found (80 % power) at the
    # strictest Holm level α/m, in the response's units (:mod:`.power`).
    level = alpha / max(int(first.sum()), 1)
    holm = _holm_levels(np.where(first, table["p_value"].to_numpy(float), np.nan), alpha)
    by_hypothesis = dict(zip(hypothesis[first], holm[first], strict=True))
    table["holm_level"] = [by_hypothesis.get(h, np.nan) for h in hypothesis]
    table["alpha_level"] = level
    table["mde"] = [
        minimum_detectable(r.sigma, r.mde_norm2, r.df1, r.df2, level / r.patterns) if ok else np.nan  # type: ignore[arg-type, operator]  # pandas-stubs: an itertuples field is any scalar
        for r, ok in zip(table.itertuples(), testable, strict=True)
    ]
    return diags, table


def _hypotheses(table: pd.DataFrame, diags: list[Diagnosis]) -> np.ndarray:
    """One id per row of the diagnosis table: rows of aliased candidates (the same partition
    of the tests, :class:`~.candidates.Relation` ``aliased``) of one (kind, soil) and
    response whose tests came out identical (the same F and degrees of freedom) share it:
    one hypothesis, however many names the design gives it.  So do two trends tested in the
    same strata with the same F: within the strata their regressors are the same (CMU's
    ``repetition`` and ``test_number``, which counts on across the plate blocks)."""
    root: dict[tuple, str] = {}

    def find(key):
        while root.get(key, key) != key:
            key = root[key]
        return key

    for d in diags:
        g = d.group
        for rel in d.relations:
            if rel.kind == "aliased":
                a, b = find((g.kind, g.soil, rel.finer)), find((g.kind, g.soil, rel.coarser))
                if a != b:
                    root[max(a, b)] = min(a, b)
    ids: dict[tuple, int] = {}
    out = np.empty(len(table), int)
    columns = ["kind", "soil", "candidate", "response", "statistic", "df1", "df2"]
    columns += ["categorical", "role", "blocks"]
    for i, r in enumerate(table[columns].itertuples(index=False)):
        stat = float(r.statistic)  # type: ignore[arg-type]  # pandas-stubs: an itertuples field is any scalar
        trend = not r.categorical and r.role not in ("interaction", "drift within blocks")
        key = (
            ("trend", r.kind, r.soil, r.blocks) if trend else find((r.kind, r.soil, r.candidate)),
            r.response,
            round(stat, 9 - int(np.floor(np.log10(abs(stat)))))
            if np.isfinite(stat) and stat
            else stat,
            r.df1,
            r.df2,
        )
        if not np.isfinite(stat):
            key = (r.kind, r.soil, r.candidate, r.response, "untested")  # type: ignore[assignment]  # pandas-stubs: an itertuples field is any scalar
        out[i] = ids.setdefault(key, len(ids))
    return out


def _holm_levels(p: np.ndarray, alpha: float) -> np.ndarray:
    """The level Holm's step-down compares each p-value with, α/(m − i) for the i-th
    smallest (0-based) of the m finite ones; NaN for an untestable row.  A cross-validation
    fold repeats a lead's test at this level on its training tests (:mod:`.nested`)."""
    out = np.full(p.size, np.nan)
    finite = np.flatnonzero(np.isfinite(p))
    order = finite[np.argsort(p[finite], kind="stable")]
    out[order] = alpha / (finite.size - np.arange(finite.size))
    return out


#: Noiseless points per sinkage test on which a model's curve is read.
_SYNTHETIC_POINTS = 24


def _synthetic(group, rows):
    """Two to twenty-four noiseless sample points per test, for reading a model's curve."""
    t = group.tests.iloc[rows]
    if group.kind == "sinkage":
        grid = np.linspace(0.05, 1.0, _SYNTHETIC_POINTS)
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


def _model_deviations(
    table: pd.DataFrame, group: Group, model: ModelExtension, theta: np.ndarray, rows: np.ndarray
) -> None:
    """``level`` and ``shape`` of the tests ``rows`` against a registered sinkage model with
    parameters ``theta``: its curve of each test, read on noiseless points as a Bernstein
    (k̂, n̂) by a p-weighted log–log line (:func:`conditional_responses`)."""
    synth, x = _synthetic(replace(group, tests=table), rows)
    fitted = SimpleNamespace(result=SimpleNamespace(values=np.asarray(theta, float)), state={})
    y_hat = np.asarray(model.predict(fitted, synth, rows), float)  # type: ignore[arg-type, type-var]  # a stand-in with the .result.values and .state that predict reads
    m = _SYNTHETIC_POINTS
    lz, lp = np.log(x["z"]).reshape(-1, m), np.log(y_hat).reshape(-1, m)
    n_hat, lk_hat = _weighted_lines(lz, lp, np.nan_to_num(y_hat).reshape(-1, m))
    _sinkage_deviations(table, table.index[rows], lk_hat, n_hat)


def conditional_responses(group: Group, fitted: Fitted) -> pd.DataFrame:
    """The per-test responses measured against a fitted (extended) model instead of the base.

    The model's curve of each test is read on noiseless points: for sinkage its Bernstein
    (k̂, n̂) by a p-weighted log–log line (exact where the curve is a power law), compared with
    the test's own (k, n) as in :func:`add_responses`; for shear its plateau and K̂ from two
    points j₁, 2j₁ of Eq. 13 (exact for the family).  Rows the model cannot describe are NaN.
    """
    table = group.tests.copy()
    rows = np.flatnonzero(table[[c for c in table if c.startswith("_dev_")]].notna().any(axis=1))  # type: ignore[attr-defined]  # pandas-stubs: a label is Hashable (ours are str)
    synth, x = _synthetic(group, rows)
    y_hat = fitted.extension.predict(fitted, synth, rows)
    for c in [c for c in table if c.startswith("_dev_")]:  # type: ignore[attr-defined]  # pandas-stubs: a label is Hashable (ours are str)
        table[c] = np.nan
    idx = table.index[rows]
    with np.errstate(divide="ignore", invalid="ignore"):
        if group.kind == "sinkage":
            m = 24
            lz = np.log(x["z"]).reshape(-1, m)
            lp = np.log(y_hat).reshape(-1, m)
            wt = np.nan_to_num(y_hat.reshape(-1, m))
            n_hat, lk_hat = _weighted_lines(lz, lp, wt)
            _sinkage_deviations(table, idx, lk_hat, n_hat)
        else:
            t1, t2 = y_hat[0::2], y_hat[1::2]
            r = t2 / t1 - 1.0  # = exp(−j₁/K̂)
            k_hat = -x["j"][0] / np.log(r)
            _shear_deviations(table, idx, t1 / (1.0 - r), k_hat)
    return table


def _weighted_lines(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(slope, intercept) of the line through each row of ``y`` against ``x`` minimising
    Σ (w·(y − a·x − b))² over the points with finite y and w > 0, as ``np.polyfit(x, y, 1,
    w=w)`` per row, for all rows at once (centred normal equations); NaN for a row with
    fewer than three such points."""
    ok = np.isfinite(y) & (w > 0)
    w2 = np.where(ok, w, 0.0) ** 2
    x, y = np.where(ok, x, 0.0), np.where(ok, y, 0.0)
    total = w2.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        mx = (w2 * x).sum(axis=1) / total
        my = (w2 * y).sum(axis=1) / total
        dx = np.where(ok, x - mx[:, None], 0.0)
        slope = (w2 * dx * (y - my[:, None])).sum(axis=1) / (w2 * dx * dx).sum(axis=1)
    enough = ok.sum(axis=1) >= 3
    slope = np.where(enough, slope, np.nan)
    return slope, np.where(enough, my - slope * mx, np.nan)


def retest(group: Group, table: pd.DataFrame, row: pd.Series) -> dict[str, float]:
    """Raw p-value per response of one candidate (a row of the diagnosis table, main effect
    or interaction) against the responses in ``table``."""
    blocks_list = [b for b in row["blocks"].split(", ") if b]
    strata = strata_codes(
        [level_codes(candidate_values(table, b)) for b in blocks_list], len(table)
    )
    out = {}
    if row["pair"]:
        a, b = row["pair"].split("|")
        va, vb = candidate_values(table, a), candidate_values(table, b)
        recorded = (va.notna() & vb.notna()).to_numpy()
        ca, cb = level_codes(va), level_codes(vb)
        for response in RESPONSES[group.kind]:
            y_all = table[f"_dev_{response}"].to_numpy(float)
            ok = np.isfinite(y_all) & recorded
            res = interaction_test(y_all[ok], ca[ok], cb[ok], strata=strata[ok])
            out[response] = res["p_value"]
        return out
    if row.get("within"):
        x_all = candidate_values(table, row["within"]).to_numpy(float)
        for response in RESPONSES[group.kind]:
            y_all = table[f"_dev_{response}"].to_numpy(float)
            ok = np.isfinite(y_all) & np.isfinite(x_all)
            res = within_blocks_test(y_all[ok], x_all[ok], strata=strata[ok])
            out[response] = res["p_value"]
        return out
    categorical = bool(row["categorical"])
    log_scale = trend_on_log(row["role"])
    values = candidate_values(table, row["candidate"])
    x_all = level_codes(values) if categorical else values.to_numpy(float)
    for response in RESPONSES[group.kind]:
        y_all = table[f"_dev_{response}"].to_numpy(float)
        ok = np.isfinite(y_all) & values.notna().to_numpy()
        res = strata_test(
            y_all[ok], x_all[ok], categorical=categorical, strata=strata[ok], log_scale=log_scale
        )
        out[response] = res["p_value"]
    return out
