"""Data-quality artefacts against causes: what screening found, as discovery reads it.

Screening (:mod:`soilstats.quality`) removes what it finds of an artefact, but what remains
(an offset it did not find, a spike's neighbours) can still follow the tests it sits in.  A
cause whose levels line up with the tests' artefact flags is reported as a residue of the
data, not as a cause (:func:`split_artefacts`), and every finding says how many of its tests
carry flags (:func:`with_quality_caveat`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from ..quality import ARTEFACT_CODES, CODES, PHASE_CODES, STOP_CODES
from .candidates import candidate_values, classify_columns
from .diagnose import INTERACTION
from .result import Finding

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
def quality_record(campaign) -> dict | None:
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


def split_artefacts(group, found, quality) -> tuple[list, list[dict]]:
    """Findings whose cause lines up with the data-quality artefacts of the tests
    (:func:`_aligned`) are data problems, not causes: screening removes what it finds of an
    artefact, but what remains (an offset it did not find, a spike's neighbours) can still
    follow the tests it sits in."""
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
        why = None
        for column in f.cause.split(INTERACTION):
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
