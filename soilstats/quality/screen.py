"""``screen``: run every data-quality rule over a campaign; the cleaned campaign analyses use.

One place, used by every analysis: the command-line tools screen a campaign right after
loading it, and the fitting functions screen what they are given unless it was screened
already (:func:`screened`).  In the default mode ``"clean"`` the samples of ``spike`` and
``pre-contact`` findings are left out of the cleaned campaign and z is re-zeroed at the
contact point found, and a ``duplicate`` test (a copied record) leaves it; every other
finding only flags.  Every finding names its test, its
code and the 1-based data rows of the sample file it concerns; nothing is left out silently.
"""

from __future__ import annotations

import hashlib
import weakref
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, cast

import numpy as np
import pandas as pd

from ..campaign.units import implausible_units
from ..errors import CampaignError, InputError
from . import samples
from .codes import CODES, MODES
from .copies import RECORDS, find_copies
from .drift import find_drift
from .report import QualityFlag, QualityReport, ScreenedCampaign
from .samples import Records, spike_findings
from .sinkage_rules import seating_per_soil, sinkage_findings

# Read from here by tests/test_quality_blocks.py (seating) and benchmarks/drift_rates.py.
_Records = Records

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion

__all__ = [
    "QualityFlag",
    "QualityReport",
    "ScreenedCampaign",
    "screen",
    "screened",
    "seating_per_soil",
]

#: Load-capped: the spread (max/min − 1) of the end force or pressure that counts as "the
#: same load" ...
LOAD_CAP_SPREAD = 0.10
#: ... and the spread of the depth reached that shows the depth was not the stop criterion
#: (at least this, and five times the load's spread).
LOAD_CAP_DEPTH_SPREAD = 0.25
LOAD_CAP_MIN_TESTS = 3


def _shear_findings(shear: pd.DataFrame, mode: str) -> tuple[list[QualityFlag], list]:
    """Spike findings of every shear record, and the labels they drop."""
    rec = Records.of(shear, ("torque_Nm", "normal_force_N"))
    per_test, drop, _ = spike_findings(
        rec, "shear", ("torque_Nm", "normal_force_N"), mode == "clean"
    )
    return [f for found in per_test for f in found], drop


def _load_capped(tests: pd.DataFrame, ends: pd.DataFrame) -> list[QualityFlag]:
    """Tests of one soil that all stop at one load while reaching different depths."""
    out = []
    frame = ends.merge(tests[["test_id", "soil", "area_m2"]], on="test_id")
    frame["pressure_end"] = frame["force_end"] / frame["area_m2"]

    def spread(values: pd.Series) -> float:
        return float(values.max() / values.min() - 1) if values.min() > 0 else np.inf

    for soil, group in frame.groupby("soil", sort=True):
        if len(group) < LOAD_CAP_MIN_TESTS:
            continue
        depth = spread(group["z_end"])
        load, column, unit = min(
            (spread(group["force_end"]), "force_end", "N"),
            (spread(group["pressure_end"]), "pressure_end", "Pa"),
        )
        if load > LOAD_CAP_SPREAD or depth <= max(LOAD_CAP_DEPTH_SPREAD, 5 * load):
            continue
        message = (
            f"all {len(group)} sinkage tests of {soil} end at {group[column].median():.4g} "
            f"{unit} (spread {load:.1%}) while their depth ranges {group['z_end'].min():.3g}"
            f"-{group['z_end'].max():.3g} m: stopped at a load, so depth is an outcome"
        )
        out += [
            QualityFlag(str(t), "sinkage", "load-capped", (), message) for t in group["test_id"]
        ]
    return out


def _zero_drift(log: pd.DataFrame, ends: pd.DataFrame) -> list[QualityFlag]:
    """Sinkage tests whose start force trends with test order within their series
    (:mod:`.drift`)."""
    if not {"force_start", "force_end"} <= set(ends.columns):
        return []
    return [
        QualityFlag(
            d.test_id,
            "sinkage",
            "zero-drift",
            (),
            f"the start force of its series ({d.series_size} tests of {d.soil}, in "
            f"{d.order}) trends by {d.slope_N:+.3g} N per test (p = {d.p_value:.2g}); this "
            f"test's zero is off by about {d.offset_N:+.3g} N since the series' first test "
            f"({abs(d.offset_N) / d.peak_N:.1%} of the peak force)",
        )
        for d in find_drift(log, ends)
    ]


def _findings(campaign: Campaign, tests: pd.DataFrame, mode: str, progress: bool) -> tuple:
    """(flags, sample labels to drop by table, z offsets by test) of every rule on
    ``campaign``."""
    log = campaign.tests
    flags: list[QualityFlag] = []
    for finding in implausible_units(log, campaign.sinkage, campaign.shear):
        for tid, value in zip(finding.test_ids, finding.values, strict=True):
            kind = "shear" if finding.file == "shear.csv" else "sinkage"
            if finding.file == "tests.csv":
                kind = str(log.loc[log["test_id"].astype(str) == tid, "kind"].iloc[0])
            flags.append(
                QualityFlag(
                    tid,
                    kind,
                    "units",
                    (),
                    f"{finding.file} {finding.column} = {value:.4g}: {finding.what}",
                )
            )
    sink = campaign.sinkage
    # Labels to drop per table: both tables label their samples by file row from 0, so the
    # same label names different samples in each.
    drop: dict[str, list[np.ndarray]] = {"sinkage": [], "shear": []}
    offsets: dict[str, float] = {}
    if len(sink):
        b_of = dict(
            zip(tests["test_id"], pd.to_numeric(tests["b_m"], errors="coerce"), strict=True)
        )
        # A seating toe is decided once per soil and preparation (one bed, one procedure).
        group = tests["soil"].astype(str)
        if "preparation" in tests.columns:
            group = group + "\x00" + tests["preparation"].astype(str)
        soil_of = dict(zip(tests["test_id"], group, strict=True))
        per_test, drop["sinkage"], offsets, ends, phases = sinkage_findings(
            sink, mode, progress, b_of, soil_of
        )
        flags += [f for found in per_test for f in found]
    else:
        ends = pd.DataFrame([], columns=["test_id", "force_end", "z_end"])
        phases = {}
    flags += _load_capped(tests, ends)
    flags += _zero_drift(log, ends)
    if len(campaign.shear):
        found, drop["shear"] = _shear_findings(campaign.shear, mode)
        flags += found
    found, copies = _duplicates(campaign, clean=mode == "clean")
    flags += found
    for table, labels in copies.items():
        drop[table] += labels
    return flags, drop, offsets, phases


def _duplicates(
    campaign: Campaign, *, clean: bool
) -> tuple[list[QualityFlag], dict[str, list[np.ndarray]]]:
    """``duplicate`` flags of the copied records (:mod:`.copies`) and, when ``clean``, the
    sample labels of the copies to leave out, by table."""
    flags: list[QualityFlag] = []
    drop: dict[str, list[np.ndarray]] = {"sinkage": [], "shear": []}
    for kind, (columns, response) in RECORDS.items():
        table = getattr(campaign, kind)
        if not len(table) or not set(columns) <= set(table.columns):
            continue
        for copy, original, rows in find_copies(table, columns, response):
            labels = table.index.to_numpy()[rows]
            message = (
                f"its {rows.size} samples repeat test {original!r}'s value for value: a copy "
                "of one record, not a second preparation"
            )
            flags.append(
                QualityFlag(copy, kind, "duplicate", samples.rows(labels), message, excluded=clean)
            )
            if clean:
                drop[kind].append(labels)
    return flags, drop


#: Findings by (mode, content of the records): screening is a pure function of the data, and
#: one campaign is often loaded afresh by every call of a session.
_FINDINGS: dict[tuple, tuple] = {}


def _fingerprint(campaign: Campaign) -> str:
    """A digest of everything the rules read: the log's identity columns and the samples."""
    digest = hashlib.blake2b(digest_size=16)
    for frame, columns in (
        # The whole log: zero-drift reads every setup column and the test order.
        (campaign.tests, list(campaign.tests.columns)),
        (campaign.sinkage, ["test_id", "z_m", "force_N", "pressure_Pa"]),
        (campaign.shear, ["test_id", "torque_Nm", "normal_force_N", "tau_Pa", "angle_rad"]),
    ):
        present = [c for c in columns if c in frame.columns]
        digest.update(pd.util.hash_pandas_object(frame[present], index=True).to_numpy().tobytes())
    return digest.hexdigest()


def screen(campaign: Campaign, mode: str = "clean", *, progress: bool = False) -> QualityReport:
    """Screen every test of ``campaign`` (rules and thresholds: :mod:`soilstats.quality`).

    Parameters
    ----------
    campaign : Campaign
    mode : {"off", "flag", "clean"}
        ``off``: check nothing; ``flag``: report, exclude nothing; ``clean`` (default):
        also leave spike and pre-contact samples out and re-zero z at the contact found.
    progress : bool
        A tqdm bar over the tests.

    Returns
    -------
    QualityReport
        With ``campaign``, the campaign to analyse: a :class:`ScreenedCampaign`, whose
        ``report`` is this report.
    """
    if mode not in MODES:
        raise InputError(f"quality mode must be one of {MODES}, got {mode!r}")
    log = campaign.tests
    tests = log[["test_id", "kind", "soil", "b_m", "area_m2"]].copy()
    tests["test_id"] = tests["test_id"].astype(str)
    if mode == "off":
        report = QualityReport(mode, (), tests)
        return replace(report, campaign=ScreenedCampaign.of(campaign, report))
    key = (mode, _fingerprint(campaign))
    if key not in _FINDINGS:
        if len(_FINDINGS) >= 16:
            _FINDINGS.pop(next(iter(_FINDINGS)))
        _FINDINGS[key] = _findings(campaign, tests, mode, progress)
    flags, drop, offsets, phases = _FINDINGS[key]
    flags = list(flags)
    order = {t: i for i, t in enumerate(tests["test_id"])}
    flags.sort(key=lambda f: (order.get(f.test_id, len(order)), list(CODES).index(f.code)))
    report = QualityReport(mode, tuple(flags), tests, phases=phases)
    cleaned = campaign
    if mode == "clean":
        copies = {f.test_id for f in flags if f.code == "duplicate" and f.excluded}
        cleaned = _cleaned(campaign, drop, offsets, copies)
        if offsets:
            seated = [np.asarray(f.rows) - 1 for f in flags if f.code == "pre-contact"]
            kept = {
                "sinkage": [np.setdiff1d(np.concatenate(drop["sinkage"]), np.concatenate(seated))],
                "shear": drop["shear"],
            }
            report = replace(report, unseated=_Unseated(campaign, kept, copies, report))
    return replace(report, campaign=ScreenedCampaign.of(cleaned, report))


@dataclass(frozen=True, eq=False)
class _Unseated:
    """The campaign cleaned but for the seating offsets (built when first asked for)."""

    raw: Campaign
    drop: dict
    copies: frozenset | set
    report: QualityReport

    def __call__(self) -> ScreenedCampaign:
        cleaned = _cleaned(self.raw, self.drop, {}, self.copies)
        return ScreenedCampaign.of(cleaned, self.report)


def _cleaned(
    campaign: Campaign,
    drop: dict[str, list[np.ndarray]],
    offsets: dict[str, float],
    copies: frozenset[str] | set[str] = frozenset(),
) -> Campaign:
    """The campaign without the excluded samples (``drop``: labels per table) and without
    the tests that are copies of another (``copies``: their whole record is excluded, so
    they would be tests without samples), z re-zeroed where a contact was found."""

    def without(table: pd.DataFrame, labels: list[np.ndarray]) -> pd.DataFrame:
        if not labels:
            return table
        return table.drop(index=table.index.intersection(np.concatenate(labels)))  # type: ignore[arg-type]  # pandas-stubs: an array of labels is valid

    sink = without(campaign.sinkage, drop["sinkage"])
    shear = without(campaign.shear, drop["shear"])
    if offsets:
        sink = sink.copy()
        shift = sink["test_id"].astype(str).map(offsets).fillna(0.0).to_numpy(float)
        sink["z_m"] = sink["z_m"].to_numpy(float) - shift
    tests = campaign.tests
    if copies:
        tests = tests[~tests["test_id"].astype(str).isin(copies)].reset_index(drop=True)
    return replace(campaign, tests=tests, sinkage=sink, shear=shear)


#: Screened versions of the campaigns analysed in this process, by campaign and mode: the
#: functions that screen what they are given are called many times on one campaign.
_SCREENED: weakref.WeakKeyDictionary[Campaign, dict[str, ScreenedCampaign]] = (
    weakref.WeakKeyDictionary()
)


def screened(
    campaign: Campaign, quality: str = "clean", **selection: Criterion
) -> ScreenedCampaign:
    """``campaign`` (restricted to ``selection``) ready for analysis: screened in mode
    ``quality`` unless it was already (a :class:`ScreenedCampaign`, as :func:`screen`
    returns in its report's ``campaign``, is taken as it is).

    The whole campaign is screened once per campaign and mode, then selected: fits are
    called many times on one campaign with different selections (conditions, folds), and
    ``load-capped`` judges all tests of a soil together.
    """
    if not isinstance(campaign, ScreenedCampaign):
        if quality not in MODES:
            raise CampaignError(f"quality must be one of {MODES}, got {quality!r}")
        cache = _SCREENED.setdefault(campaign, {})
        if quality not in cache:
            cache[quality] = cast(ScreenedCampaign, screen(campaign, quality).campaign)
        campaign = cache[quality]
    return campaign.select(**selection) if selection else campaign
