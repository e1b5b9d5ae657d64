"""Data-quality artefacts against causes: what screening found, as discovery reads it.

Screening (:mod:`soilstats.quality`) removes what it finds of an artefact, but what remains
(an offset it did not find, a spike's neighbours) can still follow the tests it sits in.  A
cause whose levels line up with the tests' artefact flags is reported as a residue of the
data, not as a cause (:func:`split_artefacts`), and every finding says how many of its tests
carry flags (:func:`with_quality_caveat`).
"""

from __future__ import annotations

from collections.abc import Container, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..quality import ARTEFACT_CODES, CODES, PHASE_CODES, STOP_CODES
from .candidates import candidate_values, classify_columns, level_codes, trend_on_log
from .diagnose import INTERACTION
from .ftests import strata_codes, trend_slope
from .result import Finding

if TYPE_CHECKING:
    from ..quality import ScreenedCampaign
    from .data import Group

__all__ = ["quality_record", "split_artefacts", "with_quality_caveat"]

#: Artefacts of test order (a drifting zero): they follow the order within a series, so they
#: make a residue of the causes that number the tests (role time/order), never of the
#: columns that name the series (its preparation or plate): those are where the flagged
#: tests sit, not what the artefact follows.
ORDER_CODES = frozenset({"zero-drift"})
#: ... and only when they flag at least this share of the finding's tests: one or two
#: flagged tests do not explain an effect of test order on all of them.
ORDER_SHARE = 1 / 3


# ----------------------------------------------------------------------------- the steps
def quality_record(campaign: ScreenedCampaign) -> dict:
    """What screening found in the tests discovery analyses (JSON-ready)."""
    report = campaign.report.for_tests(campaign.tests["test_id"].astype(str))
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


def _codes_by_test(
    quality: Mapping[str, Any], kind: str, keep: Container[str]
) -> dict[str, list[str]]:
    """The screening codes in ``keep`` of every flagged test of one kind (tests with none
    left out)."""
    out = {
        t["test_id"]: [c for c in t["codes"] if c in keep]
        for t in quality["tests"]
        if t["kind"] == kind
    }
    return {t: c for t, c in out.items() if c}


def _artefact_labels(group: Group, quality: Mapping[str, Any] | None) -> pd.Series | None:
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
        if code in ORDER_CODES:
            continue
        flagged = labels.str.contains(code, regex=False)
        share = flagged.groupby(values).mean()
        if share.max() >= 0.5 and share.min() == 0.0:
            out += [f"{code} in {share[lv]:.0%} of {lv}" for lv in share.index if share[lv] > 0]
    return "; ".join(out) or None


def _drifting(labels: pd.Series) -> str | None:
    """How many tests carry an artefact of test order (:data:`ORDER_CODES`), or None when
    fewer than :data:`ORDER_SHARE` of them do."""
    out = []
    for code in sorted(ORDER_CODES):
        flagged = int(labels.str.contains(code, regex=False).sum())
        if flagged and flagged >= ORDER_SHARE * len(labels):
            out.append(f"{code} in {flagged} of {len(labels)} tests: a zero drifting with order")
    return "; ".join(out) or None


def _trend_rows(table: pd.DataFrame | None, finding: Finding) -> pd.DataFrame | None:
    """The significant diagnosis rows of a finding whose cause is a trend (a continuous or
    time/order candidate), or None (a categorical cause, or no rows to read)."""
    if table is None or not len(table):
        return None
    rows = table[(table["candidate"] == finding.cause) & table["significant"]]
    if rows.empty or bool(rows.iloc[0]["categorical"]) or rows.iloc[0]["pair"]:
        return None
    return rows


#: A trend stands against the flagged tests when, without them, it keeps its sign and at
#: least this share of its slope (:func:`_flagged_trend`).
TREND_KEPT = 0.5


def _flagged_trend(
    group: Group, rows: pd.DataFrame, labels: pd.Series
) -> tuple[str | None, str | None]:
    """``(residue reason, caveat)`` of a trend cause against the tests' artefact flags.

    A trend has no levels to line up with flags (each start time is a "level" of its own,
    so any flag would line up 100 %, as it did until issue #35): instead the trend's slope
    is compared with and without the flagged tests, in its strongest response, within the
    strata it was tested in.  Where the tests without a flag keep its sign and at least
    :data:`TREND_KEPT` of its slope, the flagged tests do not make it, and it stands (the
    caveat says so); otherwise what screening left of the artefacts may make it, and it is
    a residue."""
    present = [
        c
        for c in ARTEFACT_CODES
        if c not in ORDER_CODES and labels.str.contains(c, regex=False).any()
    ]
    if not present:
        return None, None
    flagged = np.zeros(len(labels), bool)
    for c in present:
        flagged |= labels.str.contains(c, regex=False).to_numpy()
    counts = ", ".join(f"{c} in {int(labels.str.contains(c, regex=False).sum())}" for c in present)
    row = rows.sort_values(["p_value"]).iloc[0]
    column, response = row["candidate"], row["response"]
    table = group.tests
    blocks = [b for b in row["blocks"].split(", ") if b]
    strata = strata_codes([level_codes(candidate_values(table, b)) for b in blocks], len(table))
    y = table[f"_dev_{response}"].to_numpy(float)
    if row.get("within"):
        # a drift inside one block: its slope there, with and without the flagged tests
        x = candidate_values(table, row["within"]).to_numpy(float)
        inside = (candidate_values(table, column).astype(str) == row["deviating"]).to_numpy()
        y = np.where(inside, y, np.nan)
    else:
        x = candidate_values(table, column).to_numpy(float)
    ok = np.isfinite(y) & np.isfinite(x)
    log_scale = False if row.get("within") else trend_on_log(row["role"])
    slope = trend_slope(y[ok], x[ok], strata=strata[ok], log_scale=log_scale)
    rest = ok & ~flagged
    without = trend_slope(y[rest], x[rest], strata=strata[rest], log_scale=log_scale)
    ratio = without / slope if np.isfinite(without) and slope != 0 else np.nan
    compared = (
        f"its {response} slope is {slope:.3g} on all tests and {without:.3g} without the "
        f"{int((ok & flagged).sum())} flagged ones ({counts})"
    )
    if np.isfinite(ratio) and ratio >= TREND_KEPT:
        return None, f"the trend in {column} stands without the flagged tests: {compared}"
    return (
        f"the trend in {column} rests on the flagged tests: {compared}; the pattern may be "
        "what is left of the artefacts after screening, not a cause; inspect the flagged "
        "records (soilstats check) and re-test",
        None,
    )


def split_artefacts(
    group: Group,
    found: list[Finding],
    quality: dict | None,
    table: pd.DataFrame | None = None,
) -> tuple[list[Finding], list[dict]]:
    """Findings whose cause lines up with the data-quality artefacts of the tests are data
    problems, not causes: screening removes what it finds of an artefact, but what remains
    (an offset it did not find, a spike's neighbours) can still follow the tests it sits in.

    A categorical cause lines up when a code flags at least half the tests of one of its
    levels and none of another's (:func:`_aligned`); a trend (continuous or time/order
    cause, read from its rows of the diagnosis ``table``) when the flagged tests carry it
    (:func:`_flagged_trend`); a time/order cause also when a third of its tests drift
    (:func:`_drifting`)."""
    labels = _artefact_labels(group, quality)
    if labels is None:
        return found, []
    order = {
        r.column
        for r in classify_columns(group.tests, group.kind, group.time_columns)
        if r.role == "time/order"
    }
    kept, residues = [], []
    for f in found:
        rows = f.scope_rows if f.scope_rows is not None else np.arange(len(labels))
        why, caveat = None, None
        trend = _trend_rows(table, f)
        if trend is not None:
            why, caveat = _flagged_trend(group, trend, labels)
            if why is None and (f.cause in order or trend.iloc[0].get("within") in order):
                pattern = _drifting(labels.iloc[rows])
                if pattern is not None:
                    why = (
                        f"{f.cause} follows the test order, and so do the data-quality flags "
                        f"({pattern}): the pattern may be what is left of the artefacts after "
                        "screening, not a cause; inspect the flagged records (soilstats "
                        "check) and re-test"
                    )
        for column in [] if trend is not None else f.cause.split(INTERACTION):
            values = candidate_values(group.tests, column).astype(str).iloc[rows]
            pattern = _aligned(values, labels.iloc[rows])
            if pattern is None and column in order:
                pattern = _drifting(labels.iloc[rows])
            if pattern is not None:
                why = (
                    f"the levels of {column} line up with data-quality flags ({pattern}): the "
                    "pattern may be what is left of the artefacts after screening, not a "
                    "cause; inspect the flagged records (soilstats check) and re-test"
                )
                break
        if why is None:
            kept.append(f if caveat is None else replace(f, caveats=(*f.caveats, caveat)))
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


def with_quality_caveat(finding: Finding, quality: dict | None) -> Finding:
    """A finding whose tests carry data-quality flags says how many and which codes: a
    reader judges whether the data problem, not the cause, drives it."""
    if not quality or not quality["tests"] or finding.group is None:
        return finding
    # A load-capped test is sound (its depth is an outcome, never a cause: .candidates), and
    # a record's hold or release is no fault of it (its samples are left out of the fits).
    flagged = _codes_by_test(quality, finding.kind, set(CODES) - STOP_CODES - PHASE_CODES)
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
