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
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, cast

import numpy as np
import pandas as pd

from ..campaign.units import implausible_units
from ..errors import CampaignError, InputError
from . import blocks as blocks_mod
from . import glitches, prescreen, records, staging
from .blocks import Blocks
from .codes import CODES, MODES
from .copies import RECORDS, find_copies
from .drift import find_drift, start_forces
from .phases import find_phases
from .report import QualityFlag, QualityReport, ScreenedCampaign

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion

__all__ = ["QualityFlag", "QualityReport", "ScreenedCampaign", "screen", "screened"]

#: Load-capped: the spread (max/min − 1) of the end force or pressure that counts as "the
#: same load" ...
LOAD_CAP_SPREAD = 0.10
#: ... and the spread of the depth reached that shows the depth was not the stop criterion
#: (at least this, and five times the load's spread).
LOAD_CAP_DEPTH_SPREAD = 0.25
LOAD_CAP_MIN_TESTS = 3


def _rows(labels: np.ndarray) -> tuple[int, ...]:
    """1-based data rows of the sample file from its 0-based labels."""
    return tuple(int(label) + 1 for label in labels.tolist())


@dataclass
class _Records:
    """The records of one sample table, test by test, laid end to end (see :mod:`.blocks`).

    Tests are in the order of their first sample (``groupby(sort=False)``), each record in
    file order; ``labels`` are the 0-based data rows of the file.
    """

    ids: list[str]
    blocks: Blocks
    labels: np.ndarray
    columns: dict[str, np.ndarray]

    @classmethod
    def of(cls, table: pd.DataFrame, columns: tuple[str, ...]) -> _Records:
        codes, uniques = pd.factorize(table["test_id"], sort=False)
        # A stable sort by test keeps every record in file order (rows need not be
        # contiguous); rows without a test_id (code -1) are left out, as groupby does.
        order = np.argsort(codes, kind="stable")
        order = order[codes[order] >= 0]
        codes = codes[codes >= 0]
        blocks = Blocks.of_sizes(np.bincount(codes, minlength=len(uniques)))
        labels = table.index.to_numpy()[order]
        values = {c: table[c].to_numpy(float)[order] for c in columns}
        return cls([str(t) for t in uniques], blocks, labels, values)


def _hits_by_block(blocks: Blocks, mask: np.ndarray) -> dict[int, np.ndarray]:
    """Block number → the positions (in the blocks' arrays) where ``mask`` holds, only
    blocks with any."""
    hits = np.flatnonzero(mask)
    if not hits.size:
        return {}
    block = blocks.block_of[hits]
    cut = np.flatnonzero(np.diff(block)) + 1
    return {int(b[0]): h for b, h in zip(np.split(block, cut), np.split(hits, cut), strict=True)}


def _spike_findings(rec: _Records, kind: str, columns: tuple[str, str], clean: bool):
    """``spike`` flags of every record (a spike in either column), per test in test order,
    the labels they drop in mode ``clean``, and the mask of spiked positions."""
    spiked = blocks_mod.spikes(rec.blocks, rec.columns[columns[0]]) | blocks_mod.spikes(
        rec.blocks, rec.columns[columns[1]]
    )
    out: list[list[QualityFlag]] = [[] for _ in rec.ids]
    drop: list[np.ndarray] = []
    for k, hits in _hits_by_block(rec.blocks, spiked).items():
        message = f"{hits.size} isolated spiked sample(s) in {columns[0]} or {columns[1]}"
        flag = QualityFlag(rec.ids[k], kind, "spike", _rows(rec.labels[hits]), message)
        staging.leave_out(out[k], drop, flag, clean)
    return out, drop, spiked


def _sinkage_findings(
    sink: pd.DataFrame,
    mode: str,
    progress: bool,
    b_of: dict | None = None,
    soil_of: dict | None = None,
):
    """Findings of every sinkage record: (flags per test in test order, labels to drop,
    contact offsets by test, each test's end force and depth without its spikes, the phases
    of every record by test). ``b_of``: Bekker's plate size b [m] by test id
    (``bearing-failure`` scales its run-on with it); ``soil_of``: the soil by test id (a
    seating toe is judged soil by soil: :func:`seating_per_soil`).

    Spikes, then bursts, then the phases of each record (:mod:`.staging`); the other rules
    of :mod:`.records` judge the loading record (its approach, contact, loading and failure)
    across all tests at once (:mod:`.blocks`), and the two power-law detectors run per
    record on the tests the batch code could not clear.
    """
    clean = mode == "clean"
    rec = _Records.of(sink, ("z_m", "force_N"))
    # Glitch clusters first: a dense run of impossible samples owns every running median
    # the spike and burst rules compare with.
    glitched_out, drop, glitched = glitches.glitch_flags(
        rec.ids, rec.blocks, rec.columns, rec.labels, clean
    )
    if glitched.any():
        rest, at = rec.blocks.keep(~glitched)
        rec = _Records(rec.ids, rest, rec.labels[at], {c: v[at] for c, v in rec.columns.items()})
    blocks, z, force = rec.blocks, rec.columns["z_m"], rec.columns["force_N"]
    out, spike_drop, spiked = _spike_findings(rec, "sinkage", ("z_m", "force_N"), clean)
    drop += spike_drop
    _merge(out, glitched_out)
    unspiked, kept = blocks.keep(~spiked)
    found, burst_drop, bursts = staging.burst_flags(
        rec.ids, unspiked, {"z_m": z[kept], "force_N": force[kept]}, rec.labels[kept], clean
    )
    _merge(out, found)
    drop += burst_drop
    good, kept2 = unspiked.keep(~bursts)
    kept = kept[kept2]
    staged, found, phase_drop = staging.stage(
        rec.ids, good, z[kept], force[kept], rec.labels[kept], clean
    )
    _merge(out, found)
    drop += phase_drop
    # The loading records, on which every other rule runs.
    loaded, at = good.keep(staged.loading)
    zg, fg, labels = staged.z[at], staged.force[at], staged.labels[at]
    # Each loading record's approach: every position before the contact (a phase that is not
    # loading comes only after it).
    approach = loaded.local < loaded.spread(staged.contact)

    def record(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        at = slice(loaded.starts[k], loaded.starts[k] + loaded.sizes[k])
        return zg[at].copy(), fg[at].copy(), labels[at]

    offsets: dict[str, float] = {}
    candidates = prescreen.contact_candidates(loaded, zg, fg)
    late = prescreen.late_zero_candidates(loaded, zg, fg)
    runaway = prescreen.runaway_candidates(loaded, zg, fg)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(
            total=len(candidates) + len(late) + len(runaway), desc="screening records", unit="test"
        )
    failure_of: dict[int, int | None] = {}
    found_contacts: dict[int, records.ContactPoint] = {}
    for k in candidates:
        zk, fk, _ = record(k)
        contact = records.find_contact(
            zk, fk, ratio=records.CONTACT_WEAK_RATIO, min_travel=records.CONTACT_WEAK_TRAVEL
        )
        if bar is not None:
            bar.update()
        if contact is not None:
            found_contacts[k] = contact
    contact_of = seating_per_soil(found_contacts, record, [(soil_of or {}).get(t) for t in rec.ids])
    for k, contact in sorted(contact_of.items()):
        zk, fk, lk = record(k)
        rows = lk[contact.before]
        if rows.size > 0.5 * lk.size:
            # Leaving out most of a record is a question for the user, never a silent window.
            del contact_of[k]
            out[k].append(
                QualityFlag(
                    rec.ids[k],
                    "sinkage",
                    "pre-contact",
                    _rows(rows),
                    f"a contact at z = {contact.z_contact:.4g} m would leave out {rows.size} of "
                    f"{lk.size} samples (more than half): not applied; is the plate really "
                    "off the soil that long? Re-zero the test by hand if it is",
                    value=contact.z_contact,
                )
            )
            continue
        if clean and contact.z_contact:
            offsets[rec.ids[k]] = float(contact.z_contact)
        effect = _exponent_effect(zk, fk, contact.z_contact)
        out[k].append(
            QualityFlag(
                rec.ids[k],
                "sinkage",
                "pre-contact",
                _rows(rows),
                f"force at its noise floor over the first {contact.z_contact * 1e3:.3g} mm; "
                f"contact found at z = {contact.z_contact:.4g} m ({contact.describe()})"
                + ("; z re-zeroed there" if clean else "")
                + effect,
                excluded=clean,
                value=contact.z_contact,
            )
        )
        if clean:
            drop.append(rows)
    for k in late:
        zk, fk, lk = record(k)
        found_late = records.find_late_zero(zk, fk)
        if bar is not None:
            bar.update()
        if found_late is not None:
            out[k].append(_late_zero_flag(rec.ids[k], lk, found_late))
    # The batch cleared the others on their raw records; a seated record is judged again
    # from its contact, where the batch did not look.
    judged = np.union1d(runaway, np.fromiter(contact_of, int, len(contact_of)))
    if bar is not None:
        bar.total = len(candidates) + len(late) + len(judged)
        bar.refresh()
    for k in judged:
        zk, fk, lk = record(k)
        # Judged on the loaded record, z from the contact, whatever the mode: with the free
        # travel in, the early law is bent and a 1.5 mm seating offset read as bearing
        # failure on every loose test (window proposed at 4 mm of 30).
        seated = contact_of.get(k)
        shift = 0.0
        if seated is not None:
            keep = np.ones(zk.size, bool)
            keep[seated.before] = False
            zk, fk, lk = zk[keep], fk[keep], lk[keep]
            shift = seated.z_contact
        found_run = records.find_runaway(zk - shift, fk, (b_of or {}).get(rec.ids[k]))
        if bar is not None:
            bar.update()
        if found_run is None:
            continue
        onset = found_run.z_onset + shift  # in the record's own z
        offset = shift if clean else 0.0  # clean mode re-zeroes z at the contact
        failed_rows = lk[found_run.after]
        failure_of[k] = int(failed_rows.min()) if failed_rows.size else None
        out[k].append(
            QualityFlag(
                rec.ids[k],
                "sinkage",
                "bearing-failure",
                _rows(failed_rows),
                (
                    f"the force holds within {found_run.gain:+.1%} from z = {onset:.4g} m to "
                    f"{zk.max():.4g} m (a plateau: the soil failed, or the rig reached a force "
                    f"limit); valid up to z = {onset - offset:.4g} m"
                    if found_run.flat
                    else f"sinkage runs on from z = {onset:.4g} m to {zk.max():.4g} m, ending "
                    f"{found_run.excess:.3g}x deeper than the test's early power law at the same "
                    f"force; valid up to z = {onset - offset:.4g} m"
                ),
                value=onset - offset,
            )
        )
    if bar is not None:
        bar.close()
    # Non-monotone sinkage and clipping are judged from the contact on: the approach may lift
    # the plate, and z stands still at its maximum in a hold.
    contacted, cat = loaded.keep(~approach)
    zc, fc, lc = zg[cat], fg[cat], labels[cat]
    for k, hits in _hits_by_block(contacted, blocks_mod.non_monotone(contacted, zc)).items():
        out[k].append(
            QualityFlag(
                rec.ids[k],
                "sinkage",
                "non-monotone",
                _rows(lc[hits]),
                f"z falls back below its running maximum in {hits.size} samples",
            )
        )
    for k in range(loaded.count):
        zk, fk, lk = record(k)
        failed = failure_of.get(k)  # a run-on's load steps jump in z by nature: not gaps
        out[k].extend(_record_shape_flags(rec.ids[k], zk, fk, lk, failed))
    peaks = {"force_N": contacted.max(fc), "z_m": contacted.max(zc)}
    for values, other, column in ((fc, zc, "force_N"), (zc, fc, "z_m")):
        clipped = blocks_mod.saturation(contacted, values, other)
        for k, hits in _hits_by_block(contacted, clipped).items():
            out[k].append(
                QualityFlag(
                    rec.ids[k],
                    "sinkage",
                    "saturation",
                    _rows(lc[hits]),
                    f"{hits.size} samples of {column} sit exactly at its maximum "
                    f"{peaks[column][k]:.6g} while the other channel changes",
                )
            )
    ends = pd.DataFrame({"test_id": rec.ids, "force_end": loaded.max(fg), "z_end": loaded.max(zg)})
    ends["force_start"] = start_forces(good, staged.z, staged.force)
    phases = _final_phases(rec.ids, staged, contact_of, failure_of)
    return out, drop, offsets, ends, phases


def seating_per_soil(
    found: dict[int, records.ContactPoint],
    record: Callable[[int], tuple[np.ndarray, np.ndarray, np.ndarray]],
    soils: list,
) -> dict[int, records.ContactPoint]:
    """The seating offsets to re-zero, by record: one rule for the same toe in every test of
    a soil.

    ``found`` holds each record's contact with at least weak evidence
    (:data:`~.records.CONTACT_WEAK_RATIO`, toes down to :data:`~.records.CONTACT_WEAK_TRAVEL`
    of the travel). A soil *shows a toe* when the median of its sinkage tests' residual
    ratios is at most CONTACT_WEAK_RATIO (a test without evidence counts as 1; ``floor``
    evidence as 0) and its median contact is material: at least
    :data:`~.records.CONTACT_MIN_TRAVEL` of its median travel. There, every test with
    evidence is re-zeroed at its own contact, and one without it at the soil's median
    contact, or where its force leaves the floor if that comes first
    (:func:`~.records.floor_end`) — unless its force leaves the floor before half the median
    contact: that record shows no such toe; a shared toe shorter than that is left alone in every
    test of the soil. In a soil without a shared toe only strong evidence re-zeroes a test
    (``floor``, or a ratio at most :data:`~.records.CONTACT_RESIDUAL_RATIO`, with a contact
    at CONTACT_MIN_TRAVEL of its own travel at least): a seating offset of its own.
    """

    def ratio(k: int) -> float:
        c = found.get(k)
        if c is None:
            return 1.0
        return 0.0 if c.evidence == "floor" else c.residual_ratio

    def travel(k: int) -> float:
        z = record(k)[0]
        return float(z.max() - max(z.min(), 0.0)) if z.size else 0.0

    by_soil: dict = {}
    for k, soil in enumerate(soils):
        by_soil.setdefault(soil, []).append(k)
    chosen: dict = {}
    for members in by_soil.values():
        if np.median([ratio(k) for k in members]) > records.CONTACT_WEAK_RATIO:
            # No toe shared by the soil's tests: a test's own strong evidence decides.
            chosen |= {
                k: found[k]
                for k in members
                if k in found
                and found[k].strong
                and found[k].z_contact >= records.CONTACT_MIN_TRAVEL * travel(k)
            }
            continue
        median = float(np.median([found[k].z_contact for k in members if k in found]))
        reach = float(np.median([travel(k) for k in members]))
        if median < records.CONTACT_MIN_TRAVEL * reach:
            continue  # a toe too short to matter: left alone in every test of the soil
        chosen.update({k: found[k] for k in members if k in found})
        for k in members:
            if k in found:
                continue
            z, force, _ = record(k)
            end = records.floor_end(z, force)
            if end is None or end < 0.5 * median:
                continue  # its force left the floor well before: it shows no such toe
            contact = min(median, end)
            before = np.flatnonzero((z > 0) & (z <= contact))
            chosen[k] = records.ContactPoint(contact, before, np.nan, evidence="soil")
    return chosen


#: starts-loaded: the first samples' force (median of 3) above this share of the peak ...
STARTS_LOADED_SHARE = 0.05
#: ... and this many force-noise widths, at a first z beyond this share of the travel.
STARTS_LOADED_WIDTHS = 5.0
STARTS_LOADED_TRAVEL = 0.02
#: gap: a z step more than this many times the record's median step ...
GAP_STEPS = 20.0
#: ... and more than this share of the travel.
GAP_TRAVEL = 0.05


def _record_shape_flags(
    test_id: str,
    z: np.ndarray,
    force: np.ndarray,
    labels: np.ndarray,
    failed_row: int | None = None,
) -> list[QualityFlag]:
    """``starts-loaded`` and ``gap`` flags of one loading record (flag only); gaps are
    judged before a bearing failure's first failed row (label) only."""
    out: list[QualityFlag] = []
    if z.size < 8:
        return out
    travel = float(z.max() - min(float(z.min()), 0.0))
    peak = float(force.max())
    if travel <= 0 or peak <= 0:
        return out
    start = float(np.median(force[:3]))
    noise = records._robust_width(np.diff(force, 2)) / np.sqrt(6.0)
    z0 = float(z[0])
    if (
        start > STARTS_LOADED_SHARE * peak
        and start > STARTS_LOADED_WIDTHS * noise
        and z0 > STARTS_LOADED_TRAVEL * travel
    ):
        out.append(
            QualityFlag(
                test_id,
                "sinkage",
                "starts-loaded",
                _rows(labels[:1]),
                f"the record starts under load: {start:.4g} N ({start / peak:.0%} of its peak) "
                f"at z = {z0 * 1e3:.3g} mm; its first {z0 * 1e3:.3g} mm are missing",
                value=z0,
            )
        )
    steps = np.diff(z)
    forward = steps[steps > 0]
    if forward.size >= 4:
        usual = float(np.median(forward))
        judged = labels[1:] < failed_row if failed_row is not None else True
        big = np.flatnonzero((steps > GAP_STEPS * usual) & (steps > GAP_TRAVEL * travel) & judged)
        if big.size:
            widest = float(steps[big].max())
            out.append(
                QualityFlag(
                    test_id,
                    "sinkage",
                    "gap",
                    _rows(labels[big + 1]),
                    f"{big.size} gap(s) in z, up to {widest * 1e3:.3g} mm "
                    f"({widest / usual:.0f}x the record's median step of {usual * 1e3:.3g} mm): "
                    "no samples there",
                    value=widest,
                )
            )
    return out


def _exponent_effect(z: np.ndarray, force: np.ndarray, z_contact: float) -> str:
    """The re-zeroing's effect on the record's exponent, for the message: the log-log slope
    of force on sinkage past the contact (force above 5 % of its peak), from z = 0 and from
    the contact."""
    past = (z > z_contact) & (force > 0.05 * float(np.max(force, initial=0.0)))
    if past.sum() < 4 or not z_contact > 0:
        return ""
    log_f = np.log(force[past])
    n_zero = np.polyfit(np.log(z[past]), log_f, 1)[0]
    n_contact = np.polyfit(np.log(z[past] - z_contact), log_f, 1)[0]
    return f"; the record's log-log n {n_zero:.3g} from z = 0, {n_contact:.3g} from the contact"


def _merge(out: list[list[QualityFlag]], found: list[list[QualityFlag]]) -> None:
    """Append each test's new flags to its list."""
    for mine, new in zip(out, found, strict=True):
        mine.extend(new)


def _final_phases(ids, staged: staging.Staged, contact_of: dict, failure_of: dict) -> dict:
    """Each test's phases, the approach ending at a seating offset's contact and the loading
    turned to failure after a bearing failure's onset (rows: the sample file's)."""
    out = {}
    good = staged.good
    for k in range(good.count):
        at = slice(good.starts[k], good.starts[k] + good.sizes[k])
        z, force, labels = staged.z[at], staged.force[at], staged.labels[at]
        found = staged.phases[k]
        seated, failed = contact_of.get(k), failure_of.get(k)
        if seated is not None or failed is not None:
            onset = None
            if failed is not None:
                later = np.flatnonzero(labels >= failed)
                onset = int(later[0]) - 1 if later.size else None
            surface = seated.z_contact if seated is not None else 0.0
            found = find_phases(z, force, surface=surface, failure_onset=onset)
        out[ids[k]] = staging.spans_of(ids[k], found, z, force, labels)
    return out


def _late_zero_flag(test_id: str, labels: np.ndarray, found: records.LateZero) -> QualityFlag:
    """The ``late-zero`` flag of a loading branch at z <= 0 (flag only: nothing excluded)."""
    return QualityFlag(
        test_id,
        "sinkage",
        "late-zero",
        _rows(labels[found.loaded]),
        f"{found.loaded.size} samples at z <= 0 carry force, up to {found.share:.1%} of the "
        f"peak force, over the last {found.extent * 1e3:.3g} mm before z = 0: the "
        "displacement was zeroed after first contact, so z is measured from below the "
        "surface and n and k are biased (the samples at z <= 0 are left out of fits as out "
        "of contact)",
        value=found.z_start,
    )


def _shear_findings(shear: pd.DataFrame, mode: str) -> tuple[list[QualityFlag], list]:
    """Spike findings of every shear record, and the labels they drop."""
    rec = _Records.of(shear, ("torque_Nm", "normal_force_N"))
    per_test, drop, _ = _spike_findings(
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


def _findings(campaign, tests: pd.DataFrame, mode: str, progress: bool):
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
        per_test, drop["sinkage"], offsets, ends, phases = _sinkage_findings(
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


def _duplicates(campaign, *, clean: bool) -> tuple[list[QualityFlag], dict[str, list[np.ndarray]]]:
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
                QualityFlag(copy, kind, "duplicate", _rows(labels), message, excluded=clean)
            )
            if clean:
                drop[kind].append(labels)
    return flags, drop


#: Findings by (mode, content of the records): screening is a pure function of the data, and
#: one campaign is often loaded afresh by every call of a session.
_FINDINGS: dict[tuple, tuple] = {}


def _fingerprint(campaign) -> str:
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
    copies=frozenset(),
) -> Campaign:
    """The campaign without the excluded samples (``drop``: labels per table) and without
    the tests that are copies of another (``copies``: their whole record is excluded, so
    they would be tests without samples), z re-zeroed where a contact was found."""

    def without(table: pd.DataFrame, labels: list[np.ndarray]) -> pd.DataFrame:
        if not labels:
            return table
        return table.drop(index=table.index.intersection(np.concatenate(labels)))

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
