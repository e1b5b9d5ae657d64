"""The tests of diagnosis beyond a candidate's main effect: a drift inside blocks (a time or
order trend of its own in each block) and two-way interactions of crossed design factors,
with the rows they add to the family of tests (:mod:`soilstats.discovery.diagnose`, whose
Holm adjustment covers them too).
"""

from __future__ import annotations

from collections.abc import Collection, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .candidates import (
    WITHIN,
    Relation,
    determines,
)
from .ftests import (
    cell_codes,
    interaction_test,
    strata_codes,
    within_blocks_test,
)

if TYPE_CHECKING:
    from .candidates import Candidate
    from .data import Group

__all__ = [
    "INTERACTION",
    "RESPONSES",
    "family_row",
    "interaction_pairs",
    "interactions",
    "level_labels",
    "response_range",
    "trend_span",
    "within_blocks",
]

#: The per-test responses of each kind (soilstats.discovery.diagnose's module docstring).
RESPONSES = {"sinkage": ("level", "shape"), "shear": ("level", "K")}

#: Joins the two columns of an interaction candidate's name and of its cell labels.
INTERACTION = " × "


def interaction_pairs(
    cands: Iterable[Candidate],
    related: Mapping[str, set[str]],
    eligible: Collection[str],
    partition_of: Mapping[str, Hashable],
) -> list[tuple[str, str]]:
    """Pairs of crossed, design-like categorical candidates (design or covariate role, ≥ 3
    tests per level on median) whose interaction can be tested.  Of aliased candidates (the
    same partition: ``tool`` and ``b_m``) only the first enters, so no pair is tested twice."""
    pool, seen = [], set()
    for c in cands:
        if not (c.categorical and c.role in ("design", "covariate") and c.name in eligible):
            continue
        if partition_of[c.name] in seen:
            continue
        seen.add(partition_of[c.name])
        pool.append(c.name)
    return [(a, b) for i, a in enumerate(pool) for b in pool[i + 1 :] if b not in related[a]]


def family_row(group: Group, name: str, response: str, res: Mapping[str, Any], **kw: Any) -> dict:
    """One row of diagnosis's family of tests: (group, candidate, response) and the test's
    result ``res``; ``kw`` adds or overrides columns (``deviating``, ``within``)."""
    return dict(
        kind=group.kind,
        soil=group.soil,
        candidate=name,
        response=response,
        statistic=res["statistic"],
        df1=res["df1"],
        df2=res["df2"],
        p_value=res["p_value"],
        effect_size=res["effect_size"],
        sigma=res["sigma"],
        mde_norm2=res["mde_norm2"],
        patterns=int(res.get("patterns", 1)),
        reason=res["reason"],
        **{"deviating": "", "within": "", **kw},
    )


@dataclass(frozen=True)
class Family:
    """What the extra candidate families of one (kind, soil) are built from: its ``group``,
    the candidates, which are ``related`` (aliased or nested) to which, the ``eligible``
    block columns, each candidate's level ``codes`` and its values (``values_of``:
    :func:`candidate_values`)."""

    group: Group
    cands: Sequence[Candidate]
    related: Mapping[str, set[str]]
    eligible: Collection[str]
    codes: Mapping[str, np.ndarray]
    values_of: Mapping[str, pd.Series]

    @cached_property
    def partition_of(self) -> dict[str, tuple]:
        """Each candidate's partition of the tests (its codes in order of first level)."""
        return {n: tuple(pd.factorize(c)[0]) for n, c in self.codes.items()}


def within_blocks(family: Family, table: pd.DataFrame) -> tuple[pd.DataFrame, list[dict]]:
    """A drift inside one block of the design (:func:`.ftests.within_blocks_test`) per
    time/order candidate: its strata are those of its own trend test (one per aliased
    partition), and the candidate ``T within B`` is a column of block labels (for the folds
    and the per-block extension).  Two order columns that differ within every block by one
    scale (``repetition`` and a ``test_number`` counting on across blocks) make one test:
    only the first enters.  Returns the table with the label columns and the rows."""
    group, related, codes, values_of = family.group, family.related, family.codes, family.values_of
    rows_out: list = []
    columns: dict = {}
    seen: list = []
    partition_of = family.partition_of
    for cand in family.cands:
        if cand.categorical or cand.role != "time/order":
            continue
        blocks, partitions = [], set()
        for b in sorted(family.eligible):
            if b == cand.name or b in related[cand.name] or partition_of[b] in partitions:
                continue
            partitions.add(partition_of[b])
            blocks.append(b)
        if not blocks:
            continue
        strata = strata_codes([codes[b] for b in blocks], len(table))
        x = values_of[cand.name].to_numpy(float)
        # one test per scale-equivalent order column (centred within the blocks)
        known = np.isfinite(x)
        centred = x - pd.Series(np.where(known, x, 0)).groupby(strata).transform("mean").to_numpy()
        centred = np.where(known, centred, 0.0)
        norm = float(np.linalg.norm(centred))
        if norm == 0 or any(abs(float(centred @ v)) / norm > 1 - 1e-9 for v in seen):
            continue
        seen.append(centred / norm)
        name = f"{cand.name}{WITHIN}{', '.join(blocks)}"
        shown = [f"{b}=" + level_labels(values_of[b]) for b in blocks]
        label = shown[0]
        for more in shown[1:]:
            label = label + ", " + more
        columns[name] = label.where(known, np.nan)
        for response in RESPONSES[group.kind]:
            y_all = table[f"_dev_{response}"].to_numpy(float)
            ok = np.isfinite(y_all) & known
            res = within_blocks_test(y_all[ok], x[ok], strata=strata[ok])
            deviating = ""
            if res["block"] is not None:
                at = np.flatnonzero(strata[ok] == res["block"])[0]
                deviating = str(label[ok].to_numpy()[at])
            used = np.flatnonzero(ok)[res["used"]]
            rows_out.append(
                family_row(
                    group,
                    name,
                    response,
                    res,
                    categorical=False,
                    numeric=True,
                    role="drift within blocks",
                    n_tests=int(used.size),
                    blocks=", ".join(blocks),
                    confounded_with="",
                    singleton_levels="",
                    pair="",
                    span=trend_span(x[ok][res["used"]], False),
                    y_range=response_range(y_all[ok][res["used"]]),
                    deviating=deviating,
                    within=cand.name,
                    rows=used,
                )
            )
    return (table.assign(**columns) if columns else table), rows_out


def trend_span(x: np.ndarray, categorical: bool) -> str:
    """The observed range of a trend candidate, for the power statement ("" for levels)."""
    if categorical or x.size == 0:
        return ""
    x = np.asarray(x, float)
    return f"{np.nanmin(x):.4g} to {np.nanmax(x):.4g}"


def response_range(y: np.ndarray) -> float:
    """The observed range (max − min) of a response over the tests a candidate is tested on:
    no effect larger than it shows in these data (:mod:`.power` caps its statements)."""
    y = np.asarray(y, float)
    y = y[np.isfinite(y)]
    return float(np.ptp(y)) if y.size else float("nan")


def level_labels(values: pd.Series) -> pd.Series:
    """Level labels as a reader writes them (0.00196 rather than 0.00196349541)."""
    if pd.api.types.is_numeric_dtype(values):
        return values.map(lambda v: f"{v:.4g}")
    return values.astype(str)


def interactions(
    family: Family, table: pd.DataFrame
) -> tuple[pd.DataFrame, list[dict], list[Relation]]:
    """Two-way interactions of crossed design-like factors (:func:`interaction_test`): the
    per-test rows of the family, the table with one cell-label column per pair (``A × B``,
    for the per-cell extension), and the main candidates each pair is aliased with.

    ``values_of`` holds :func:`candidate_values` of every candidate; labels, their codes and
    the strata of a block set are computed once per candidate or set, not once per pair.
    """
    group, related, codes, values_of = family.group, family.related, family.codes, family.values_of
    eligible, partition_of = family.eligible, family.partition_of
    pairs = interaction_pairs(family.cands, related, eligible, partition_of)
    rows_out, rels, columns, cells = [], [], {}, {}
    labels: dict[str, pd.Series] = {}
    label_codes: dict[str, np.ndarray] = {}
    strata_of: dict[tuple, np.ndarray] = {}
    for name in dict.fromkeys(x for pair in pairs for x in pair):
        labels[name] = level_labels(values_of[name])
        label_codes[name] = pd.factorize(labels[name])[0]
    for a, b in pairs:
        name = f"{a}{INTERACTION}{b}"
        va, vb = values_of[a], values_of[b]
        recorded = (va.notna() & vb.notna()).to_numpy()
        label = labels[a] + INTERACTION + labels[b]
        columns[name] = label.where(recorded, np.nan)
        # The cells' partition as codes in order of first appearance (tests without both
        # values form one cell): the numbering of factorising the label column, from the
        # labels' codes.
        la, lb = label_codes[a], label_codes[b]
        combined = np.where(recorded, la.astype(np.int64) * (int(lb.max()) + 1) + lb, -1)
        cells[name] = pd.factorize(combined)[0]
        cell = tuple(cells[name])
        aliased = sorted(n for n, part in partition_of.items() if part == cell)
        rels += [Relation("aliased", name, n) for n in aliased]
        blocks = [
            k for k in sorted(eligible) if k not in (a, b) and not ({k} & (related[a] | related[b]))
        ]
        key = tuple(blocks)
        if key not in strata_of:
            strata_of[key] = strata_codes([codes[k] for k in blocks], len(table))
        strata = strata_of[key]
        for response in RESPONSES[group.kind]:
            y_all = table[f"_dev_{response}"].to_numpy(float)
            ok = np.isfinite(y_all) & recorded
            res = interaction_test(y_all[ok], codes[a][ok], codes[b][ok], strata=strata[ok])
            deviating = ""
            if res["cell"] is not None:
                cell_of = cell_codes(codes[a][ok], codes[b][ok])
                shown = label[ok].to_numpy()
                deviating = " or ".join(
                    str(shown[np.flatnonzero(cell_of == c)[0]]) for c in res["cells"]
                )
            rows_out.append(
                family_row(
                    group,
                    name,
                    response,
                    res,
                    categorical=True,
                    numeric=False,
                    role="interaction",
                    n_tests=int(ok.sum()),
                    blocks=", ".join(blocks),
                    confounded_with=", ".join(aliased),
                    singleton_levels="",
                    pair=f"{a}|{b}",
                    span="",
                    y_range=response_range(y_all[ok]),
                    deviating=deviating,
                    rows=np.flatnonzero(ok),
                )
            )
    rels += _related_interactions(cells)
    return (table.assign(**columns) if columns else table), rows_out, rels


def _related_interactions(cells: Mapping[str, np.ndarray]) -> list[Relation]:
    """Interactions of nested factors nest in turn (velocity × tool determines velocity ×
    area when tool determines area): related, so that one leads and the other is named."""
    rels = []
    names = list(cells)
    for i, m in enumerate(names):
        for n in names[i + 1 :]:
            mn, nm = determines(cells[m], cells[n]), determines(cells[n], cells[m])
            if mn and nm:
                rels.append(Relation("aliased", m, n))
            elif mn or nm:
                rels.append(Relation("nested", *((m, n) if mn else (n, m))))
    return rels
