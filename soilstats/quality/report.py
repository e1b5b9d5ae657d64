"""The findings of a screening: :class:`QualityFlag` per finding, :class:`QualityReport` for
a campaign, the fitting windows ``bearing-failure`` proposes (:meth:`QualityReport
.proposed_windows`), and the :class:`ScreenedCampaign` that analyses take (the campaign as
screening leaves it, with its report). :func:`soilstats.quality.screen` builds them.
"""

from __future__ import annotations

import warnings
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, fields, replace
from decimal import ROUND_CEILING, Decimal
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pandas as pd

from .._text import plural
from ..campaign.campaign import Campaign
from ..campaign.window import FitWindow
from ..errors import RENAMED_GO_IN
from ..outputs.files import json_safe
from ..outputs.text import notes_block
from .codes import CODES

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.window import FitWindow

__all__ = ["PLATE_WINDOW_SHARE", "QualityFlag", "QualityReport", "ScreenedCampaign"]

#: ``bearing-failure`` proposes one window for a whole plate (soil and plate size b) only
#: when more than this share of its sinkage tests failed; otherwise a window per failed
#: test (Cullinan sand: 1 of 13 fails at 10.8 mm; the others run to ~80 mm intact).
PLATE_WINDOW_SHARE = 0.5


@dataclass(frozen=True)
class QualityFlag:
    """One finding of one rule in one test.

    ``rows`` are 1-based data rows of the test's sample file (empty: the whole test);
    ``excluded`` says whether they are left out of fits in the screening's mode; ``value``
    is the contact point (``pre-contact``), the failure onset (``bearing-failure``) or the
    z at which a loading branch at z <= 0 starts (``late-zero``) in m.
    """

    test_id: str
    kind: str
    code: str
    rows: tuple[int, ...]
    message: str
    excluded: bool = False
    value: float | None = None

    def to_dict(self) -> dict:
        out: dict[str, object] = {
            "code": self.code,
            "rows": list(self.rows),
            "message": self.message,
        }
        out["excluded"] = self.excluded
        if self.value is not None:
            out["value_m"] = self.value
        return out


@dataclass(frozen=True, eq=False)
class QualityReport:
    """Every finding of :func:`screen`, and the cleaned campaign.

    Attributes
    ----------
    mode : {"off", "flag", "clean"}
    flags : tuple of QualityFlag
    tests : DataFrame
        ``test_id``, ``kind``, ``soil``, ``b_m`` of every screened test.
    campaign : ScreenedCampaign
        The campaign analyses use: in mode ``clean`` without the excluded samples and with
        re-zeroed sinkage; otherwise the input.  Its ``report`` is this report (without its
        ``campaign``).
    phases : dict
        Test id → :class:`~soilstats.quality.staging.TestPhases` of every sinkage record
        (empty in mode ``off``).
    unseated : callable, optional
        In mode ``clean`` with re-zeroed tests: returns the campaign cleaned as ``campaign``
        but with every seating toe kept and z as recorded, for the fits that state how much
        the re-zeroing moved them (``rezero-sensitive``).
    """

    mode: str
    flags: tuple[QualityFlag, ...]
    tests: pd.DataFrame
    campaign: ScreenedCampaign | None = field(repr=False, default=None)
    phases: dict = field(repr=False, default_factory=dict)
    unseated: Callable[[], ScreenedCampaign] | None = field(repr=False, default=None, compare=False)

    @property
    def rezeroed(self) -> frozenset[str]:
        """Tests whose z was re-zeroed at a seating contact (``pre-contact`` in mode clean)."""
        return frozenset(f.test_id for f in self.flags if f.code == "pre-contact" and f.excluded)

    def for_tests(self, test_ids: Iterable[str]) -> QualityReport:
        """The findings of these tests only."""
        keep = set(map(str, test_ids))
        return replace(
            self,
            flags=self.flags_of(keep),
            tests=self.tests[self.tests["test_id"].astype(str).isin(keep)],
            phases={t: p for t, p in self.phases.items() if t in keep},
        )

    def flags_of(self, test_ids: Iterable[str]) -> tuple[QualityFlag, ...]:
        """The findings of these tests, in report order: :meth:`for_tests`'s ``flags``
        without its table of tests (a fit asks this on every call)."""
        keep = set(map(str, test_ids))
        return tuple(f for f in self.flags if f.test_id in keep)

    @property
    def excluded(self) -> pd.DataFrame:
        """One row per sample left out of fits: ``test_id``, ``kind``, ``code``, ``row``."""
        rows = [(f.test_id, f.kind, f.code, r) for f in self.flags if f.excluded for r in f.rows]
        return pd.DataFrame(rows, columns=["test_id", "kind", "code", "row"])

    @property
    def counts(self) -> Counter:
        """Tests flagged, by code."""
        return Counter(f.code for f in {(f.test_id, f.code): f for f in self.flags}.values())

    def flagged(self, *, excluded: bool | None = None) -> list[QualityFlag]:
        """The findings, optionally only those whose samples are (not) excluded."""
        return [f for f in self.flags if excluded is None or f.excluded == excluded]

    def phase_table(self, *, all_tests: bool = False) -> pd.DataFrame:
        """One row per sinkage test whose record holds more than approach, contact and
        loading (every test with ``all_tests``): ``test_id`` and ``phases``, each phase with
        the 1-based data rows of its first and last sample (``loading 178-274``)."""
        plain = {"approach", "contact", "loading"}
        rows = [
            {
                "test_id": t,
                "phases": " · ".join(f"{s.phase} {s.rows[0]}-{s.rows[1]}" for s in found.spans),
            }
            for t, found in self.phases.items()
            if all_tests or not set(found.names) <= plain
        ]
        return pd.DataFrame(rows, columns=["test_id", "phases"])

    def proposed_windows(self) -> pd.DataFrame:
        """The sinkage windows ``bearing-failure`` proposes, one row per window.

        A plate (soil and plate size b) most of whose sinkage tests failed (more than
        :data:`PLATE_WINDOW_SHARE`) gets one window for all its tests: the smallest onset
        among them (``scope`` "plate", ``test_id`` None).  Otherwise each failed test gets
        its own, at its onset (``scope`` "test"): one failed test says nothing about the
        depth its plate's other tests reached intact.  Columns: ``soil``, ``b_m``,
        ``z_max_m`` (the onset, m), ``tests`` (failed tests the window covers),
        ``scope``, ``test_id``, ``plate_tests`` (sinkage tests of the plate that fits use)
        and ``z_max_item`` (the ``--z-max`` item that sets it, the onset rounded up to 4
        significant digits).  Tests left out as copies (``duplicate``) are not counted.
        """
        columns = ["soil", "b_m", "z_max_m", "tests", "scope", "test_id", "plate_tests"]
        columns.append("z_max_item")
        gone = {f.test_id for f in self.flags if f.code == "duplicate" and f.excluded}
        onsets: dict[str, float] = {
            f.test_id: cast(float, f.value)  # a bearing failure has its onset
            for f in self.flags
            if f.code == "bearing-failure" and f.test_id not in gone
        }
        if not onsets:
            return pd.DataFrame(columns=columns)
        tests = self.tests.assign(test_id=self.tests["test_id"].astype(str))
        sink = tests[(tests["kind"] == "sinkage") & ~tests["test_id"].isin(gone)]
        rows = []
        for (soil, b), plate in sink.groupby(["soil", "b_m"], sort=True, dropna=False):
            ids = [t for t in plate["test_id"] if t in onsets]
            if not ids:
                continue
            if len(ids) > PLATE_WINDOW_SHARE * len(plate):
                z = min(onsets[t] for t in ids)
                others = sink[sink["soil"] != soil]["b_m"].to_numpy(float)
                if np.isfinite(b) and not np.isclose(others, b, rtol=1e-9, atol=0).any():  # type: ignore[call-overload]  # pandas-stubs: a groupby key is any scalar (here a plate size)
                    items = [f"b_m={float(b)!r}:{_ceil4(z)}"]  # type: ignore[arg-type]  # pandas-stubs: a groupby key is any scalar (here a plate size)
                else:  # b unknown or shared with another soil: the plate's tests by name
                    items = [f"test_id={t}:{_ceil4(z)}" for t in plate["test_id"]]
                rows.append((soil, b, z, len(ids), "plate", None, len(plate), " ".join(items)))
                continue
            for t in ids:
                item = f"test_id={t}:{_ceil4(onsets[t])}"
                rows.append((soil, b, onsets[t], 1, "test", t, len(plate), item))
        return pd.DataFrame(rows, columns=columns)

    def proposed_window(self) -> FitWindow:
        """:meth:`proposed_windows` as one :class:`~soilstats.campaign.window.FitWindow`
        (``fit_sinkage(..., window=...)``; empty when nothing failed)."""
        items = " ".join(self.proposed_windows()["z_max_item"]).split()
        return FitWindow.parse(z_max=items)

    def summary(self) -> str:
        """The findings, test by test, then what was excluded and proposed."""
        n = len(self.tests)
        head = [
            f"Data quality ({self.mode} mode): {n} tests screened, "
            f"{len({f.test_id for f in self.flags})} with findings.",
        ]
        if self.mode == "off":
            return "\n".join([*head, "Screening is off: nothing was checked."])
        counts = self.counts
        head.append(
            "Codes: "
            + (", ".join(f"{code} {counts[code]}" for code in CODES if code in counts) or "none")
        )
        lines = []
        for f in self.flags:
            what = f"{len(f.rows)} rows" if f.rows else "whole test"
            act = "excluded" if f.excluded else "flagged"
            lines.append(f"  {f.test_id:<16} {f.code:<16} {what:>10}  {act}: {f.message}")
        table = self.phase_table()
        if self.phases:
            lines.append(
                "Phases (rows of the sample file; approach, contact and loading only in the "
                f"other {len(self.phases) - len(table)} sinkage tests):"
                if len(table)
                else f"Phases: approach, contact and loading only, in all {len(self.phases)} "
                "sinkage tests."
            )
            lines += [f"  {r.test_id:<16} {r.phases}" for r in table.itertuples()]
        excluded = self.excluded
        notes = []
        if len(excluded):
            notes.append(
                f"{plural(len(excluded), 'sample')} in "
                f"{plural(excluded['test_id'].nunique(), 'test')} "
                f"{'is' if len(excluded) == 1 else 'are'} left out of every fit "
                "(rows listed in the JSON output; --quality flag keeps them)."
            )
        windows = self.proposed_windows()
        for w in windows.itertuples():
            if w.scope == "plate":
                notes.append(
                    f"bearing-failure proposes z_max = {_ceil4(w.z_max_m)} m for all "  # type: ignore[arg-type]  # pandas-stubs: an itertuples field is any scalar
                    f"{w.plate_tests} tests of {w.soil}, b = {w.b_m:g} m ({w.tests} of "
                    f"{w.plate_tests} failed): --z-max {w.z_max_item}"
                )
            else:
                notes.append(
                    f"bearing-failure proposes z_max = {_ceil4(w.z_max_m)} m for {w.test_id} only "  # type: ignore[arg-type]  # pandas-stubs: an itertuples field is any scalar
                    f"({w.soil}, b = {w.b_m:g} m: {_failed(windows, w)} of {w.plate_tests} "
                    f"failed; the others keep their depth): --z-max {w.z_max_item}"
                )
        return "\n".join(head + lines + notes_block(notes))

    def to_dict(self) -> dict:
        """``{"mode", "tests": [{"test_id", "kind", "flags": [...]}], "excluded", ...}``;
        every screened test is listed, with an empty ``flags`` list when clean."""
        by_test: dict[str, list[dict]] = {str(t): [] for t in self.tests["test_id"]}
        for f in self.flags:
            by_test.setdefault(f.test_id, []).append(f.to_dict())
        kinds = dict(zip(self.tests["test_id"].astype(str), self.tests["kind"], strict=True))
        return json_safe(
            {
                "mode": self.mode,
                "tests": [
                    {"test_id": t, "kind": kinds.get(t), "flags": flags}
                    | ({"phases": self.phases[t].to_list()} if t in self.phases else {})
                    for t, flags in by_test.items()
                ],
                "counts": dict(self.counts),
                "excluded_samples": len(self.excluded),
                "proposed_windows": self.proposed_windows().to_dict("records"),
                "proposed_z_max": " ".join(self.proposed_windows()["z_max_item"]).split(),
                # The codes found, with what each means and what to do; every rule, its
                # thresholds and measured rates: docs/quality.md.
                "codes": {
                    c.code: {"what": c.what, "action": c.action}
                    for c in CODES.values()
                    if c.code in self.counts
                },
                "documentation": "docs/quality.md",
            }
        )


@dataclass(frozen=True, eq=False, repr=False)
class ScreenedCampaign(Campaign):
    """A campaign as :func:`~soilstats.quality.screen` leaves it, with the screening's report.

    ``screen(campaign).campaign`` is one. It is a :class:`~soilstats.campaign.Campaign` in
    every respect (the cleaned tables; ``select``, ``partition`` and ``windowed`` return
    screened campaigns with the same report), and analyses given one do not screen again
    (:func:`~soilstats.quality.screened`). The report stays here, on the screening's floor:
    a plain campaign holds no screening state (docs/conventions.md, "Layers").

    Attributes
    ----------
    report : QualityReport
        The findings behind these samples, of every test screened (a selection keeps the
        whole report: :meth:`QualityReport.for_tests` cuts it).
    """

    report: QualityReport = field(kw_only=True)

    @classmethod
    def of(cls, campaign: Campaign, report: QualityReport) -> ScreenedCampaign:
        """``campaign``'s tables, source, window and files, with ``report``."""
        kept = {f.name: getattr(campaign, f.name) for f in fields(Campaign)}
        return cls(**kept, report=report)

    @property
    def quality(self) -> QualityReport:
        """Deprecated (removed in soilstats 0.3.0): :attr:`report`."""
        warnings.warn(
            f"campaign.quality is deprecated and will be removed in soilstats {RENAMED_GO_IN}: a "
            "campaign holds no screening state; the screened campaign screen() returns "
            "(a ScreenedCampaign) carries the report as .report",
            FutureWarning,
            stacklevel=2,
        )
        return self.report


def _ceil4(z: float) -> str:
    """``z`` rounded up to 4 significant digits: a window at the onset as printed keeps
    the onset sample and cuts everything beyond it by at most 0.1 % (see
    :data:`soilstats.identification.result.ONSET_TOLERANCE`)."""
    exact = Decimal(repr(float(z)))
    step = Decimal(1).scaleb(exact.adjusted() - 3)
    return f"{float(exact.quantize(step, rounding=ROUND_CEILING)):.4g}"


def _failed(windows: pd.DataFrame, w: Any) -> int:  # w: a row of itertuples() (untyped)
    """Failed tests of ``w``'s plate (per-test rows)."""
    same = (windows["soil"] == w.soil) & (
        (windows["b_m"] == w.b_m) | (windows["b_m"].isna() & pd.isna(w.b_m))
    )
    return int(windows.loc[same, "tests"].sum())
