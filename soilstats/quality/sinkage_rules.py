"""The rules on every sinkage record (``screen``'s sinkage half): glitches, spikes and bursts,
the phases of each record, then on its loading record a seating offset (``pre-contact``), a
displacement zeroed late (``late-zero``), bearing failure, non-monotone sinkage, the record's
shape (``starts-loaded``, ``gap``) and saturation.

The batch rules of :mod:`.blocks` judge all tests at once; the per-record detectors of
:mod:`.records` run only on the tests the batch code (:mod:`.prescreen`) could not clear.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import pandas as pd

from . import blocks as blocks_mod
from . import glitches, prescreen, records, staging
from .blocks import Blocks
from .drift import start_forces
from .noise import robust_width
from .phases import find_phases
from .report import QualityFlag
from .samples import Records, hits_by_block, merge, rows, spike_findings

#: starts-loaded: the first samples' force (median of 3) above this share of the peak ...
STARTS_LOADED_SHARE = 0.05
#: ... and this many force-noise widths, at a first z beyond this share of the travel.
STARTS_LOADED_WIDTHS = 5.0
STARTS_LOADED_TRAVEL = 0.02
#: gap: a z step more than this many times the record's median step ...
GAP_STEPS = 20.0
#: ... and more than this share of the travel.
GAP_TRAVEL = 0.05

#: Flags per test, in test order (each rule appends to its test's list).
PerTest = list[list[QualityFlag]]


@dataclass
class _Loading:
    """The loading records of every test (approach, contact, loading and failure), end to
    end: the records every rule after the phases runs on."""

    blocks: Blocks
    z: np.ndarray
    force: np.ndarray
    labels: np.ndarray

    def record(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Test ``k``'s z [m], force [N] (copies) and file labels."""
        at = slice(self.blocks.starts[k], self.blocks.starts[k] + self.blocks.sizes[k])
        return self.z[at].copy(), self.force[at].copy(), self.labels[at]


def sinkage_findings(
    sink: pd.DataFrame,
    mode: str,
    progress: bool,
    b_of: dict | None = None,
    soil_of: dict | None = None,
) -> tuple[PerTest, list[np.ndarray], dict[str, float], pd.DataFrame, dict]:
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
    ids, out, drop, good, staged = _staged(sink, clean)
    # The loading records, on which every other rule runs.
    loaded, at = good.keep(staged.loading)
    loading = _Loading(loaded, staged.z[at], staged.force[at], staged.labels[at])
    zg, fg = loading.z, loading.force
    candidates = prescreen.contact_candidates(loaded, zg, fg)
    late = prescreen.late_zero_candidates(loaded, zg, fg)
    runaway = prescreen.runaway_candidates(loaded, zg, fg)
    bar = None
    if progress:
        from tqdm.auto import tqdm  # deferred: tqdm (a progress bar)

        bar = tqdm(
            total=len(candidates) + len(late) + len(runaway), desc="screening records", unit="test"
        )
    soils = [(soil_of or {}).get(t) for t in ids]
    contact_of, offsets = _seating(ids, loading, candidates, soils, clean, out, drop, bar)
    _late_zeros(ids, loading, late, out, bar)
    # The batch cleared the others on their raw records; a seated record is judged again
    # from its contact, where the batch did not look.
    judged = np.union1d(runaway, np.fromiter(contact_of, int, len(contact_of)))
    if bar is not None:
        bar.total = len(candidates) + len(late) + len(judged)
        bar.refresh()
    failure_of = _bearing_failures(ids, loading, judged, contact_of, b_of or {}, clean, out, bar)
    if bar is not None:
        bar.close()
    _contacted_flags(ids, loading, staged, failure_of, out)
    ends = pd.DataFrame({"test_id": ids, "force_end": loaded.max(fg), "z_end": loaded.max(zg)})
    ends["force_start"] = start_forces(good, staged.z, staged.force)
    phases = _final_phases(ids, staged, contact_of, failure_of)
    return out, drop, offsets, ends, phases


def _staged(
    sink: pd.DataFrame, clean: bool
) -> tuple[list[str], PerTest, list[np.ndarray], Blocks, staging.Staged]:
    """Glitch clusters, spikes and bursts of every record, then its phases: (test ids, the
    flags so far, labels to drop, the records without those samples, their phases)."""
    rec = Records.of(sink, ("z_m", "force_N"))
    # Glitch clusters first: a dense run of impossible samples owns every running median
    # the spike and burst rules compare with.
    glitched_out, drop, glitched = glitches.glitch_flags(
        rec.ids, rec.blocks, rec.columns, rec.labels, clean
    )
    if glitched.any():
        rest, at = rec.blocks.keep(~glitched)
        rec = Records(rec.ids, rest, rec.labels[at], {c: v[at] for c, v in rec.columns.items()})
    blocks, z, force = rec.blocks, rec.columns["z_m"], rec.columns["force_N"]
    out, spike_drop, spiked = spike_findings(rec, "sinkage", ("z_m", "force_N"), clean)
    drop += spike_drop
    merge(out, glitched_out)
    unspiked, kept = blocks.keep(~spiked)
    found, burst_drop, bursts = staging.burst_flags(
        rec.ids, unspiked, {"z_m": z[kept], "force_N": force[kept]}, rec.labels[kept], clean
    )
    merge(out, found)
    drop += burst_drop
    good, kept2 = unspiked.keep(~bursts)
    kept = kept[kept2]
    staged, found, phase_drop = staging.stage(
        rec.ids, good, z[kept], force[kept], rec.labels[kept], clean
    )
    merge(out, found)
    drop += phase_drop
    return rec.ids, out, drop, good, staged


def _seating(
    ids: list[str],
    loading: _Loading,
    candidates: np.ndarray,
    soils: list,
    clean: bool,
    out: PerTest,
    drop: list[np.ndarray],
    bar: Any,  # a tqdm bar, or None
) -> tuple[dict[int, records.ContactPoint], dict[str, float]]:
    """``pre-contact`` flags of the seating offsets (:func:`seating_per_soil`): (the contacts
    applied by record, the z offsets to re-zero by test id in mode ``clean``)."""
    offsets: dict[str, float] = {}
    found_contacts: dict[int, records.ContactPoint] = {}
    for k in candidates:
        zk, fk, _ = loading.record(k)
        contact = records.find_contact(
            zk, fk, ratio=records.CONTACT_WEAK_RATIO, min_travel=records.CONTACT_WEAK_TRAVEL
        )
        if bar is not None:
            bar.update()
        if contact is not None:
            found_contacts[k] = contact
    contact_of = seating_per_soil(found_contacts, loading.record, soils)
    for k, contact in sorted(contact_of.items()):
        zk, fk, lk = loading.record(k)
        dropped = lk[contact.before]
        flag = partial(QualityFlag, ids[k], "sinkage", "pre-contact", rows(dropped))
        if dropped.size > 0.5 * lk.size:
            # Leaving out most of a record is a question for the user, never a silent window.
            del contact_of[k]
            out[k].append(
                flag(
                    f"a contact at z = {contact.z_contact:.4g} m would leave out {dropped.size} "
                    f"of {lk.size} samples (more than half): not applied; is the plate really "
                    "off the soil that long? Re-zero the test by hand if it is",
                    value=contact.z_contact,
                )
            )
            continue
        if clean and contact.z_contact:
            offsets[ids[k]] = float(contact.z_contact)
        effect = _exponent_effect(zk, fk, contact.z_contact)
        out[k].append(
            flag(
                f"force at its noise floor over the first {contact.z_contact * 1e3:.3g} mm; "
                f"contact found at z = {contact.z_contact:.4g} m ({contact.describe()})"
                + ("; z re-zeroed there" if clean else "")
                + effect,
                excluded=clean,
                value=contact.z_contact,
            )
        )
        if clean:
            drop.append(dropped)
    return contact_of, offsets


def _late_zeros(
    ids: list[str], loading: _Loading, late: np.ndarray, out: PerTest, bar: Any
) -> None:
    """``late-zero`` flags of the records the batch could not clear (``bar``: tqdm or None)."""
    for k in late:
        zk, fk, lk = loading.record(k)
        found_late = records.find_late_zero(zk, fk)
        if bar is not None:
            bar.update()
        if found_late is not None:
            out[k].append(_late_zero_flag(ids[k], lk, found_late))


def _bearing_failures(
    ids: list[str],
    loading: _Loading,
    judged: np.ndarray,
    contact_of: dict[int, records.ContactPoint],
    b_of: dict,
    clean: bool,
    out: PerTest,
    bar: Any,  # a tqdm bar, or None
) -> dict[int, int | None]:
    """``bearing-failure`` flags of the ``judged`` records: the first failed row (label) by
    record."""
    failure_of: dict[int, int | None] = {}
    for k in judged:
        zk, fk, lk = loading.record(k)
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
        found_run = records.find_runaway(zk - shift, fk, b_of.get(ids[k]))
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
                ids[k],
                "sinkage",
                "bearing-failure",
                rows(failed_rows),
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
    return failure_of


def _contacted_flags(
    ids: list[str],
    loading: _Loading,
    staged: staging.Staged,
    failure_of: dict[int, int | None],
    out: PerTest,
) -> None:
    """``non-monotone``, ``starts-loaded``, ``gap`` and ``saturation`` flags of every loading
    record."""
    loaded, zg, fg, labels = loading.blocks, loading.z, loading.force, loading.labels
    # Each loading record's approach: every position before the contact (a phase that is not
    # loading comes only after it).
    approach = loaded.local < loaded.spread(staged.contact)
    # Non-monotone sinkage and clipping are judged from the contact on: the approach may lift
    # the plate, and z stands still at its maximum in a hold.
    contacted, cat = loaded.keep(~approach)
    zc, fc, lc = zg[cat], fg[cat], labels[cat]
    for k, hits in hits_by_block(contacted, blocks_mod.non_monotone(contacted, zc)).items():
        out[k].append(
            QualityFlag(
                ids[k],
                "sinkage",
                "non-monotone",
                rows(lc[hits]),
                f"z falls back below its running maximum in {hits.size} samples",
            )
        )
    for k in range(loaded.count):
        zk, fk, lk = loading.record(k)
        failed = failure_of.get(k)  # a run-on's load steps jump in z by nature: not gaps
        out[k].extend(_record_shape_flags(ids[k], zk, fk, lk, failed))
    peaks = {"force_N": contacted.max(fc), "z_m": contacted.max(zc)}
    for values, other, column in ((fc, zc, "force_N"), (zc, fc, "z_m")):
        clipped = blocks_mod.saturation(contacted, values, other)
        for k, hits in hits_by_block(contacted, clipped).items():
            out[k].append(
                QualityFlag(
                    ids[k],
                    "sinkage",
                    "saturation",
                    rows(lc[hits]),
                    f"{hits.size} samples of {column} sit exactly at its maximum "
                    f"{peaks[column][k]:.6g} while the other channel changes",
                )
            )


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
    noise = robust_width(np.diff(force, 2)) / np.sqrt(6.0)
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
                rows(labels[:1]),
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
                    rows(labels[big + 1]),
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


def _final_phases(
    ids: list[str], staged: staging.Staged, contact_of: dict, failure_of: dict
) -> dict:
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
        rows(labels[found.loaded]),
        f"{found.loaded.size} samples at z <= 0 carry force, up to {found.share:.1%} of the "
        f"peak force, over the last {found.extent * 1e3:.3g} mm before z = 0: the "
        "displacement was zeroed after first contact, so z is measured from below the "
        "surface and n and k are biased (the samples at z <= 0 are left out of fits as out "
        "of contact)",
        value=found.z_start,
    )
