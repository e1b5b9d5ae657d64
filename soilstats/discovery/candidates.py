"""Candidate causes: every test-log column and derived quantity that could explain a misfit.

A *candidate* is one column of the per-test table of one (kind, soil): a named log column
(``velocity_m_s``, ``operator``, ``grouser_height_m`` …), any extra covariate a lab adds
(``bin``, ``moisture_pct``, ``date`` …) or a derived quantity (plate size ``b_m``, ``area_m2``,
``aspect_ratio``; the sinkage depth range ``z_max_m``; the mean normal pressure
``sigma_mean_Pa`` of a shear test).

Each candidate is **categorical** (text, or numbers with a few replicated levels such as three
velocities) or **continuous** (numbers with many distinct values, e.g. a moisture reading per
test).  Two candidates are **confounded** in a campaign when their effects cannot be told
apart from its design: *aliased* (the same partition of the tests, e.g. ``tool`` and ``b_m``)
or *nested* (one determines the other, e.g. ``preparation`` determines ``session`` in the
Cullinan campaign).  Confounding is reported, never resolved by a guess.

**Roles** (:func:`classify_columns`; every column of the table gets one, with its reason):

* ``design`` — a setup the experimenter chose (plate, velocity, preparation, ring, grousers,
  operator …: the campaign format's test-log columns and the geometry derived from them);
* ``covariate`` — anything else recorded before or beside the test (a lab's extra columns:
  ``bin``, ``moisture_pct`` …);
* ``time/order`` — when the test ran: ``repetition``, a sequence number (``sequence``,
  ``order``, ``run``, ``test_order``, ``test_number``) or a column whose values parse as dates
  or times (converted to hours since the first test).  Always tested as a linear *trend*: a
  drift over the day or over the series;
* ``outcome`` — a quantity the test's own result determines: the depth reached ``z_max_m``, the
  maximum pressure ``p_max_Pa``, the number of samples ``n_samples`` / ``nobs``, the fitted
  parameters.  A load-terminated test stops deeper in softer soil, so its depth *is* its
  stiffness: "explaining" the curve by it predicts a test from its own result.  **Outcomes
  never enter**;
* ``bookkeeping`` — identifiers (``test_id``, ``kind``, ``soil``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..campaign import times

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = [
    "FIT_COLUMNS",
    "ROLES",
    "WITHIN",
    "Candidate",
    "ColumnRole",
    "Relation",
    "candidate_values",
    "classify_columns",
    "determines",
    "enumerate_candidates",
    "level_codes",
    "relation_text",
    "relations",
    "spans_log",
    "trend_on_log",
    "with_time_hours",
]

#: The roles a column can play (module docstring).
ROLES = ("design", "covariate", "time/order", "outcome", "bookkeeping")
_BOOKKEEPING = frozenset({"test_id", "kind", "soil"})
# Quantities the test's own result determines (module docstring: outcomes never enter).
_OUTCOMES = {
    "z_max_m": "the depth the test reached: a load-terminated test stops deeper in softer soil",
    "p_max_Pa": "the largest pressure the test reached: set by where the test stopped",
    "n_samples": "the number of samples: set by how long the test ran, i.e. by its result",
    "nobs": "the number of samples used: set by the record's length",
}
#: Columns the per-test fit adds (its results: outcomes, not shown among a table's columns).
FIT_COLUMNS = frozenset(
    {"k", "k_stderr", "n", "n_stderr", "epsilon", "converged", "message"}
    | {"tau_max", "tau_max_stderr", "K", "K_stderr", "tau_ss_Pa", "steady"}
)
#: Column names read as test order (besides ``repetition`` and date/time columns).
ORDER_NAMES = frozenset({"sequence", "seq", "order", "run", "test_order", "test_number"})
# Test-log columns of the campaign format that describe the setup (design factors).
_DESIGN = frozenset(
    {"preparation", "operator", "shape", "radius_m", "width_m", "length_m", "velocity_m_s"}
    | {"r_inner_m", "r_outer_m", "grousers", "grouser_height_m", "omega_rpm", "series", "tool"}
    | {"loosening_tool", "levelling_tool", "loosening_pattern", "loosening_movement"}
    | {"loosening_depth_cm", "b_m", "area_m2", "aspect_ratio", "ring_area_m2", "sigma_mean_Pa"}
)
# Raw geometry summarised by the derived b, area and aspect ratio (Eq. 7's b): keeping both
# would only add aliased pairs.
_SUMMARISED = {"sinkage": frozenset({"radius_m", "width_m", "length_m"}), "shear": frozenset()}
# Columns of the other kind's set-up (empty for this kind's tests).
_OTHER_KIND = {
    "sinkage": frozenset(
        {"r_inner_m", "r_outer_m", "grousers", "grouser_height_m", "omega_rpm", "ring_area_m2"}
    ),
    "shear": frozenset(
        {"shape", "radius_m", "width_m", "length_m", "velocity_m_s", "b_m", "area_m2"}
        | {"aspect_ratio"}
    ),
}
_DERIVED = {
    "sinkage": ("b_m", "area_m2", "aspect_ratio"),
    "shear": ("ring_area_m2", "sigma_mean_Pa"),
}
#: Numeric columns with at most this many distinct, replicated values are tested as levels.
MAX_LEVELS = 8
#: A categorical candidate whose levels carry at least this share of a continuous one's
#: variance is confounded with it (:func:`relations`).
EXPLAINED_SHARE = 0.95
MISSING = "<not recorded>"
#: Joins a time/order candidate and the blocks a drift inside one of them is tested in
#: (``repetition within b_m``): the name of the candidate and of its block-label column
#: (:func:`soilstats.discovery.diagnose._within_blocks`).
WITHIN = " within "


@dataclass(frozen=True)
class Candidate:
    """One candidate cause of one (kind, soil).

    Attributes
    ----------
    name : str
        Column of the per-test table.
    categorical : bool
        Tested as levels (one-way layout within strata) rather than as a linear trend.
    numeric : bool
        Holds numbers (then physical and linear extensions can use its values).
    derived : bool
        Computed by soilstats (b, area, aspect ratio, depth range, normal pressure).
    n_recorded : int
        Tests in which it is recorded (not NaN).
    levels : int
        Distinct recorded values.
    role : str
        ``design``, ``covariate`` or ``time/order`` (:data:`ROLES`; outcomes never become
        candidates).
    """

    name: str
    categorical: bool
    numeric: bool
    derived: bool
    n_recorded: int
    levels: int
    role: str = "design"


@dataclass(frozen=True)
class ColumnRole:
    """The role of one column of a per-test table and why (shown in every report)."""

    column: str
    role: str
    reason: str


@dataclass(frozen=True)
class Relation:
    """Confounding between two candidates (:func:`relations`), as the data show it:

    * ``aliased`` — the same partition of the tests (each determines the other);
    * ``nested`` — ``finer`` determines ``coarser`` (each level of it holds one of the other);
    * ``explains`` — the levels of the categorical ``finer`` carry ``share`` (≥ 95 %) of the
      variance of the continuous ``coarser``: it varies little within them, but it does vary
      (a start time within each test day), so neither determines the other;
    * ``correlated`` — two continuous candidates with |r| = ``share`` ≥ 0.98;
    * ``time-blocks`` — the categorical ``finer`` changed only between blocks of the test
      order ``coarser`` (a time/order column): each level's tests run one after another, so
      its effect cannot be told apart from a drift over the test order.

    :func:`relation_text` says which in words, checked against the data.
    """

    kind: str
    finer: str
    coarser: str
    share: float | None = None


def _rounded(values: pd.Series) -> pd.Series:
    """Numbers to 9 significant digits, so CSV round-off does not split a level."""
    x = pd.to_numeric(values, errors="coerce").astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        mag = np.where(x != 0, np.floor(np.log10(np.abs(x))), 0.0)
    scale = 10.0 ** (8 - np.nan_to_num(mag))
    return pd.Series(np.round(x * scale) / scale, index=values.index)


def with_time_hours(table: pd.DataFrame) -> tuple[pd.DataFrame, tuple[str, ...]]:
    """``table`` with every date/time column replaced by hours since its earliest value
    (:func:`~soilstats.campaign.times.time_columns`), and the names of those columns.  Done
    once per per-test table, so that nothing downstream parses times again."""
    hours = times.time_columns(table)
    return (table.assign(**hours) if hours else table), tuple(hours)


def candidate_values(table: pd.DataFrame, name: str) -> pd.Series:
    """The column as the tests use it: numbers rounded to 9 digits, text unchanged."""
    col = table[name]
    if pd.api.types.is_numeric_dtype(col) and not pd.api.types.is_bool_dtype(col):
        return _rounded(col)
    return col.astype(object).where(col.notna(), np.nan)


def classify_columns(
    table: pd.DataFrame, kind: str, time_columns: tuple[str, ...] = ()
) -> list[ColumnRole]:
    """The role of every column of a per-test table (module docstring), with its reason.

    ``time_columns``: the columns :func:`with_time_hours` converted from dates/times.
    """
    out = []
    for name in table.columns:
        name = str(name)
        if name.startswith("_"):
            continue
        if name in _BOOKKEEPING:
            out.append(ColumnRole(name, "bookkeeping", "an identifier, not a property of the test"))
        elif name in _OUTCOMES:
            out.append(ColumnRole(name, "outcome", _OUTCOMES[name] + "; never a cause"))
        elif name in FIT_COLUMNS:
            out.append(ColumnRole(name, "outcome", "a result of the per-test fit; never a cause"))
        elif name == "repetition" or name.lower() in ORDER_NAMES:
            out.append(
                ColumnRole(name, "time/order", "numbers the tests in order: tested as a trend")
            )
        elif name in time_columns:
            out.append(
                ColumnRole(
                    name,
                    "time/order",
                    "dates/times: tested as a trend in hours since the first test",
                )
            )
        elif name in _DESIGN:
            out.append(ColumnRole(name, "design", "a setup of the test chosen by the experimenter"))
        else:
            out.append(ColumnRole(name, "covariate", "recorded beside the test (not a set-up)"))
    return out


def enumerate_candidates(
    table: pd.DataFrame,
    kind: str,
    *,
    min_recorded: int = 4,
    roles: list[ColumnRole] | None = None,
) -> tuple[list[Candidate], list[str]]:
    """Candidates of one (kind, soil) per-test table, and notes on the columns left out.

    Parameters
    ----------
    table : pandas.DataFrame
        One row per test: test log, derived columns and the per-test fit columns.
    kind : {"sinkage", "shear"}
    min_recorded : int
        A column recorded in fewer tests is not tested (and a note says so).
    roles : list of ColumnRole, optional
        The table's :func:`classify_columns`, when the caller has it already.

    Returns
    -------
    (list of Candidate, list of str)
        Outcomes and bookkeeping never become candidates (:func:`classify_columns` says why).
    """
    role_of = {r.column: r.role for r in (roles or classify_columns(table, kind))}
    skip = _SUMMARISED[kind] | _OTHER_KIND[kind]
    names = [
        c for c, role in role_of.items() if role not in ("outcome", "bookkeeping") and c not in skip
    ]
    out: list[Candidate] = []
    notes: list[str] = []
    for name in names:
        values = candidate_values(table, name)
        recorded = values.notna()
        n_rec = int(recorded.sum())
        if n_rec == 0:
            continue
        distinct = values[recorded].nunique()
        if distinct < 2:
            continue  # constant: nothing to compare
        if n_rec < min_recorded:
            notes.append(
                f"{kind}: {name!r} is recorded for {n_rec} of {len(table)} tests only; too few "
                "to test, not analysed"
            )
            continue
        numeric = pd.api.types.is_numeric_dtype(values.dtype)
        counts = values[recorded].value_counts()
        replicated = bool((counts >= 2).mean() >= 0.5)
        trend = role_of[name] == "time/order" and numeric
        categorical = not trend and ((not numeric) or (distinct <= MAX_LEVELS and replicated))
        if not numeric and not (counts >= 2).any():
            notes.append(
                f"{kind}: {name!r} has a different value in every test ({distinct} values); "
                "a one-test-per-level column cannot be tested, not analysed"
            )
            continue
        out.append(
            Candidate(
                name=name,
                categorical=categorical,
                numeric=numeric,
                derived=name in _DERIVED[kind],
                n_recorded=n_rec,
                levels=int(distinct),
                role=role_of[name],
            )
        )
    return out, notes


def spans_log(x: np.ndarray) -> bool:
    """Whether a continuous candidate enters on ln x: all x > 0, spanning more than a factor 4."""
    return bool(np.all(x > 0) and x.max() / x.min() > 4.0)


def trend_on_log(role: str) -> bool:
    """Whether a trend in a candidate of ``role`` may enter on ln x (:func:`spans_log`
    decides then): never for time/order — a drift is linear in time or order, and ln of a test
    number would put most of it on the first few tests."""
    return role != "time/order"


def level_codes(values: pd.Series) -> np.ndarray:
    """Integer level codes of a column (unrecorded values form a level of their own)."""
    return pd.factorize(values.astype(object).where(values.notna(), MISSING))[0]


def _as_codes(values: ArrayLike) -> np.ndarray:
    """Non-negative integer codes of an array (unchanged when it already is one)."""
    values = np.asarray(values)
    if values.dtype.kind in "iu" and (values.size == 0 or values.min() >= 0):
        return values
    return pd.factorize(values, use_na_sentinel=False)[0]


def determines(a: np.ndarray, b: np.ndarray) -> bool:
    """True when every level of ``a`` holds a single level of ``b`` (b is a function of a).

    ``a`` and ``b`` are best given as level codes (:func:`level_codes`): then the test is one
    scatter and one comparison, O(n) without sorting — discovery asks it for every pair of
    candidates and of interaction cells, thousands of times in a large campaign.  Each level
    of ``a`` records one ``b`` it holds (whichever write lands last); b is a function of a
    exactly when every row's ``b`` equals the one recorded for its level.
    """
    a, b = _as_codes(a), _as_codes(b)
    if a.size == 0:
        return True
    held = np.empty(int(a.max()) + 1, dtype=b.dtype)
    held[a] = b
    return bool(np.array_equal(held[a], b))


def relations(table: pd.DataFrame, candidates: list[Candidate]) -> list[Relation]:
    """Aliased and nested pairs among the candidates, over the rows of ``table``.

    Categorical pairs: aliased when each determines the other, nested when one determines the
    other.  A continuous candidate is confounded with a categorical one when the latter
    explains ≥ 95 % of its variance (``explains``: it hardly varies within the levels;
    ``nested`` only when it does not vary within them at all); two continuous ones when
    |r| ≥ 0.98 (``correlated``).
    """
    out: list[Relation] = []
    cols = {c.name: candidate_values(table, c.name) for c in candidates}
    codes = {c.name: level_codes(cols[c.name]) for c in candidates if c.categorical}
    for i, a in enumerate(candidates):
        for b in candidates[i + 1 :]:
            if a.categorical and b.categorical:
                ab = determines(codes[a.name], codes[b.name])
                ba = determines(codes[b.name], codes[a.name])
                if ab and ba:
                    out.append(Relation("aliased", a.name, b.name))
                elif ab:
                    out.append(Relation("nested", a.name, b.name))
                elif ba:
                    out.append(Relation("nested", b.name, a.name))
            elif a.categorical != b.categorical:
                cat, con = (a, b) if a.categorical else (b, a)
                x = cols[con.name].astype(float)
                ok = x.notna().to_numpy()
                if ok.sum() < 3:
                    continue
                xs = x[ok].to_numpy()
                groups = pd.Series(xs).groupby(codes[cat.name][ok])
                ss_tot = float(((xs - xs.mean()) ** 2).sum())
                ss_within = float(groups.transform(lambda g: (g - g.mean()) ** 2).sum())
                if ss_tot > 0 and 1.0 - ss_within / ss_tot >= EXPLAINED_SHARE:
                    share = 1.0 - ss_within / ss_tot
                    # Determined only when it does not vary within any level at all.
                    kind = "nested" if ss_within <= 1e-12 * ss_tot else "explains"
                    out.append(Relation(kind, cat.name, con.name, float(share)))
                elif con.role == "time/order" and _in_time_blocks(xs, codes[cat.name][ok]):
                    share = 1.0 - ss_within / ss_tot if ss_tot > 0 else 1.0
                    out.append(Relation("time-blocks", cat.name, con.name, float(share)))
            else:
                x = cols[a.name].astype(float)
                y = cols[b.name].astype(float)
                ok = (x.notna() & y.notna()).to_numpy()
                if ok.sum() >= 3 and np.std(x[ok]) > 0 and np.std(y[ok]) > 0:
                    r = abs(float(np.corrcoef(x[ok], y[ok])[0, 1]))
                    if r >= 0.98:
                        out.append(Relation("correlated", a.name, b.name, r))
    return out


def _in_time_blocks(order: np.ndarray, levels: np.ndarray) -> bool:
    """Whether the levels (codes) occupy one contiguous run each along ``order`` (at least
    two levels of two tests each, their order ranges disjoint)."""
    counts = np.bincount(levels)
    counts = counts[counts > 0]
    if counts.size < 2 or counts.min() < 2:
        return False
    ranked = levels[np.argsort(order, kind="stable")]
    return int((np.diff(ranked) != 0).sum()) == counts.size - 1


def relation_text(relation: Relation, table: pd.DataFrame | None = None) -> str:
    """A confounding relation in words.  A claim that one column determines another is
    checked against ``table`` (the tests it was found in) before it is made: where the
    finer column's levels do not each hold one value of the other, the text says how much
    of the other's variance they carry instead (until issue #35 a box that explained 99.9 %
    of the start times was printed as "box determines start_time (each box has one
    start_time)", which was false)."""
    a, b = relation.finer, relation.coarser
    if relation.kind == "aliased":
        return f"{a} and {b} are aliased (the same partition of the tests)"
    if relation.kind == "time-blocks":
        return (
            f"{a} changed only between time blocks of {b} (each {a} ran as one block): its "
            "effect cannot be told apart from test order (a drifting zero, a changing bed)"
        )
    if relation.kind == "correlated":
        return (
            f"{a} and {b} are correlated (|r| = {relation.share:.3f}): their trends cannot be "
            "told apart in this design"
        )
    if relation.kind == "nested" and table is not None and a in table and b in table:
        if not determines(
            level_codes(candidate_values(table, a)), level_codes(candidate_values(table, b))
        ):
            relation = Relation("explains", a, b, relation.share)
    if relation.kind == "nested":
        return f"{a} determines {b} (each {a} has one {b})"
    share = ""
    if relation.share is not None:
        share = "more than 99.9 % of " if relation.share > 0.999 else f"{relation.share:.1%} of "
    return (
        f"{a} explains {share}the variance of {b} ({b} varies little within each {a}, but "
        f"{a} does not determine it)"
    )
