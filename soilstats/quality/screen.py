"""``screen``: run every data-quality rule over a campaign; the cleaned campaign analyses use.

One place, used by every analysis: the command-line tools screen a campaign right after
loading it, and the fitting functions screen what they are given unless it was screened
already (:func:`screened`).  In the default mode ``"clean"`` the samples of ``spike`` and
``pre-contact`` findings are left out of the cleaned campaign and z is re-zeroed at the
contact point found; every other finding only flags.  Every finding names its test, its
code and the 1-based data rows of the sample file it concerns; nothing is left out silently.
"""

from __future__ import annotations

import hashlib
import weakref
from collections import Counter
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from ..campaign.units import implausible_units
from ..errors import CampaignError
from ..report.files import json_safe
from ..report.text import notes_block
from . import records
from .codes import CODES, MODES

__all__ = ["QualityFlag", "QualityReport", "screen", "screened"]

#: Load-capped: the spread (max/min − 1) of the end force or pressure that counts as "the
#: same load" ...
LOAD_CAP_SPREAD = 0.10
#: ... and the spread of the depth reached that shows the depth was not the stop criterion
#: (at least this, and five times the load's spread).
LOAD_CAP_DEPTH_SPREAD = 0.25
LOAD_CAP_MIN_TESTS = 3


@dataclass(frozen=True)
class QualityFlag:
    """One finding of one rule in one test.

    ``rows`` are 1-based data rows of the test's sample file (empty: the whole test);
    ``excluded`` says whether they are left out of fits in the screening's mode; ``value``
    is the contact point (``pre-contact``) or the failure onset (``bearing-failure``) in m.
    """

    test_id: str
    kind: str
    code: str
    rows: tuple[int, ...]
    message: str
    excluded: bool = False
    value: float | None = None

    def to_dict(self) -> dict:
        out = {"code": self.code, "rows": list(self.rows), "message": self.message}
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
    campaign : Campaign
        The campaign analyses use: in mode ``clean`` without the excluded samples and with
        re-zeroed sinkage; otherwise the input.  Its ``quality`` is this report.
    """

    mode: str
    flags: tuple[QualityFlag, ...]
    tests: pd.DataFrame
    campaign: object = field(repr=False, default=None)

    def for_tests(self, test_ids) -> QualityReport:
        """The findings of these tests only."""
        keep = set(map(str, test_ids))
        return replace(
            self,
            flags=tuple(f for f in self.flags if f.test_id in keep),
            tests=self.tests[self.tests["test_id"].astype(str).isin(keep)],
        )

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

    def proposed_windows(self) -> pd.DataFrame:
        """Per soil and plate size b, the sinkage window ``bearing-failure`` proposes: the
        smallest failure onset among that plate's flagged tests (``z_max_m``)."""
        onsets = [(f.test_id, f.value) for f in self.flags if f.code == "bearing-failure"]
        if not onsets:
            return pd.DataFrame(columns=["soil", "b_m", "z_max_m", "tests"])
        frame = pd.DataFrame(onsets, columns=["test_id", "z_max_m"]).merge(self.tests, on="test_id")
        return (
            frame.groupby(["soil", "b_m"], sort=True)
            .agg(z_max_m=("z_max_m", "min"), tests=("test_id", "size"))
            .reset_index()
        )

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
        excluded = self.excluded
        notes = []
        if len(excluded):
            notes.append(
                f"{len(excluded)} samples in {excluded['test_id'].nunique()} tests are left out "
                "of every fit (rows listed in the JSON output; --quality flag keeps them)."
            )
        windows = self.proposed_windows()
        for w in windows.itertuples():
            notes.append(
                f"bearing-failure proposes z_max = {w.z_max_m:.4g} m for {w.soil}, "
                f"b = {w.b_m:g} m ({w.tests} tests failed)."
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
                    for t, flags in by_test.items()
                ],
                "counts": dict(self.counts),
                "excluded_samples": len(self.excluded),
                "proposed_windows": self.proposed_windows().to_dict("records"),
                "codes": {c.code: {"what": c.what, "action": c.action} for c in CODES.values()},
            }
        )


def _rows(labels: np.ndarray, positions) -> tuple[int, ...]:
    return tuple(int(labels[i]) + 1 for i in np.asarray(positions, int))


def _sinkage_flags(tid: str, labels, z, force, mode) -> tuple[list[QualityFlag], float]:
    """Findings of one sinkage record, and its contact offset (0 if none)."""
    out: list[QualityFlag] = []
    clean = mode == "clean"
    spikes = np.union1d(records.find_spikes(z), records.find_spikes(force))
    if spikes.size:
        out.append(
            QualityFlag(
                tid,
                "sinkage",
                "spike",
                _rows(labels, spikes),
                f"{spikes.size} isolated spiked sample(s) in z_m or force_N",
                excluded=clean,
            )
        )
    good = np.setdiff1d(np.arange(z.size), spikes)
    zg, fg = z[good], force[good]
    offset = 0.0
    contact = records.find_contact(zg, fg)
    if contact is not None:
        offset = contact.z_contact if clean else 0.0
        out.append(
            QualityFlag(
                tid,
                "sinkage",
                "pre-contact",
                _rows(labels, good[contact.before]),
                f"force at its noise floor over the first {contact.z_contact * 1e3:.3g} mm; "
                f"contact found at z = {contact.z_contact:.4g} m (a power law from there "
                f"leaves {contact.residual_ratio:.0%} of the residual)"
                + ("; z re-zeroed there" if clean else ""),
                excluded=clean,
                value=contact.z_contact,
            )
        )
    runaway = records.find_runaway(zg, fg)
    if runaway is not None:
        out.append(
            QualityFlag(
                tid,
                "sinkage",
                "bearing-failure",
                _rows(labels, good[runaway.after]),
                f"sinkage runs on from z = {runaway.z_onset:.4g} m to {zg.max():.4g} m, ending "
                f"{runaway.excess:.3g}x deeper than the test's early power law at the same "
                f"force; window proposed: z_max = {runaway.z_onset - offset:.4g} m",
                value=runaway.z_onset - offset,
            )
        )
    fallen = records.find_non_monotone(zg)
    if fallen.size:
        out.append(
            QualityFlag(
                tid,
                "sinkage",
                "non-monotone",
                _rows(labels, good[fallen]),
                f"z falls back below its running maximum in {fallen.size} samples",
            )
        )
    for values, other, column in ((fg, zg, "force_N"), (zg, fg, "z_m")):
        clipped = records.find_saturation(values, other)
        if clipped.size:
            out.append(
                QualityFlag(
                    tid,
                    "sinkage",
                    "saturation",
                    _rows(labels, good[clipped]),
                    f"{clipped.size} samples of {column} sit exactly at its maximum "
                    f"{values.max():.6g} while the other channel changes",
                )
            )
    return out, offset


def _shear_flags(tid: str, labels, table: dict[str, np.ndarray], mode) -> list[QualityFlag]:
    spikes = np.unique(
        np.concatenate([records.find_spikes(table[c]) for c in ("torque_Nm", "normal_force_N")])
    ).astype(int)
    if not spikes.size:
        return []
    return [
        QualityFlag(
            tid,
            "shear",
            "spike",
            _rows(labels, spikes),
            f"{spikes.size} isolated spiked sample(s) in torque_Nm or normal_force_N",
            excluded=mode == "clean",
        )
    ]


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


def _findings(campaign, tests: pd.DataFrame, mode: str, progress: bool):
    """(flags, sample labels to drop, z offsets by test) of every rule on ``campaign``."""
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
    drop: list[np.ndarray] = []
    offsets: dict[str, float] = {}
    ends = []
    groups = sink.groupby("test_id", sort=False).indices
    ids = list(groups)
    if progress:
        from tqdm.auto import tqdm

        ids = tqdm(ids, desc="screening sinkage tests", unit="test")
    labels_all = sink.index.to_numpy()
    z_all, f_all = sink["z_m"].to_numpy(float), sink["force_N"].to_numpy(float)
    for tid in ids:
        idx = groups[tid]
        found, offset = _sinkage_flags(str(tid), labels_all[idx], z_all[idx], f_all[idx], mode)
        flags += found
        if offset:
            offsets[str(tid)] = offset
        spiked = [r - 1 for f in found if f.code == "spike" for r in f.rows]
        keep = ~np.isin(labels_all[idx], spiked)
        ends.append((str(tid), f_all[idx][keep].max(), z_all[idx][keep].max()))
        drop += [np.asarray(f.rows, int) - 1 for f in found if f.excluded]
    flags += _load_capped(tests, pd.DataFrame(ends, columns=["test_id", "force_end", "z_end"]))
    shear = campaign.shear
    if len(shear):
        cols = {c: shear[c].to_numpy(float) for c in ("torque_Nm", "normal_force_N")}
        labels_sh = shear.index.to_numpy()
        for tid, idx in shear.groupby("test_id", sort=False).indices.items():
            found = _shear_flags(
                str(tid), labels_sh[idx], {c: v[idx] for c, v in cols.items()}, mode
            )
            flags += found
            drop += [np.asarray(f.rows, int) - 1 for f in found if f.excluded]
    return flags, drop, offsets


#: Findings by (mode, content of the records): screening is a pure function of the data, and
#: one campaign is often loaded afresh by every call of a session.
_FINDINGS: dict[tuple, tuple] = {}


def _fingerprint(campaign) -> str:
    """A digest of everything the rules read: the log's identity columns and the samples."""
    digest = hashlib.blake2b(digest_size=16)
    for frame, columns in (
        (campaign.tests, ["test_id", "kind", "soil", "b_m", "area_m2"]),
        (campaign.sinkage, ["test_id", "z_m", "force_N", "pressure_Pa"]),
        (campaign.shear, ["test_id", "torque_Nm", "normal_force_N", "tau_Pa", "angle_rad"]),
    ):
        present = [c for c in columns if c in frame.columns]
        digest.update(pd.util.hash_pandas_object(frame[present], index=True).to_numpy().tobytes())
    return digest.hexdigest()


def screen(campaign, mode: str = "clean", *, progress: bool = False) -> QualityReport:
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
        With ``campaign``, the campaign to analyse (``campaign.quality`` is the report).
    """
    if mode not in MODES:
        raise ValueError(f"quality mode must be one of {MODES}, got {mode!r}")
    log = campaign.tests
    tests = log[["test_id", "kind", "soil", "b_m", "area_m2"]].copy()
    tests["test_id"] = tests["test_id"].astype(str)
    if mode == "off":
        report = QualityReport(mode, (), tests)
        return replace(report, campaign=replace(campaign, quality=report))
    key = (mode, _fingerprint(campaign))
    if key not in _FINDINGS:
        if len(_FINDINGS) >= 16:
            _FINDINGS.pop(next(iter(_FINDINGS)))
        _FINDINGS[key] = _findings(campaign, tests, mode, progress)
    flags, drop, offsets = _FINDINGS[key]
    flags = list(flags)
    order = {t: i for i, t in enumerate(tests["test_id"])}
    flags.sort(key=lambda f: (order.get(f.test_id, len(order)), list(CODES).index(f.code)))
    report = QualityReport(mode, tuple(flags), tests)
    cleaned = campaign
    if mode == "clean":
        cleaned = _cleaned(campaign, np.concatenate(drop) if drop else np.array([], int), offsets)
    return replace(report, campaign=replace(cleaned, quality=report))


def _cleaned(campaign, drop_labels: np.ndarray, offsets: dict[str, float]):
    """The campaign without the excluded samples, z re-zeroed where a contact was found."""
    sink = campaign.sinkage.drop(index=campaign.sinkage.index.intersection(drop_labels))
    shear = campaign.shear.drop(index=campaign.shear.index.intersection(drop_labels))
    if offsets:
        sink = sink.copy()
        shift = sink["test_id"].astype(str).map(offsets).fillna(0.0).to_numpy(float)
        sink["z_m"] = sink["z_m"].to_numpy(float) - shift
    return replace(campaign, sinkage=sink, shear=shear)


#: Screened versions of the campaigns analysed in this process, by campaign and mode: the
#: functions that screen what they are given are called many times on one campaign.
_SCREENED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def screened(campaign, quality: str = "clean", **selection):
    """``campaign`` (restricted to ``selection``) ready for analysis: screened in mode
    ``quality`` unless it was already (a campaign from :func:`screen` carries its report in
    ``campaign.quality``).

    The whole campaign is screened once per campaign and mode, then selected: fits are
    called many times on one campaign with different selections (conditions, folds), and
    ``load-capped`` judges all tests of a soil together.
    """
    if getattr(campaign, "quality", None) is None:
        if quality not in MODES:
            raise CampaignError(f"quality must be one of {MODES}, got {quality!r}")
        cache = _SCREENED.setdefault(campaign, {})
        if quality not in cache:
            cache[quality] = screen(campaign, quality).campaign
        campaign = cache[quality]
    return campaign.select(**selection) if selection else campaign
