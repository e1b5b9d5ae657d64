"""Screening across tests at once (:mod:`soilstats.quality.blocks`, and the power-law
pre-screens of :mod:`soilstats.quality.prescreen`) finds exactly what the per-record
detectors find, test by test: on planted artefacts of every kind, on odd records
(tiny, constant, tied, quantised, non-finite) and with the rows of a test spread through the
file. The reference below is the per-test screening loop the batch code replaced."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from scipy.ndimage import median_filter

from soilstats.campaign import Campaign
from soilstats.quality import records, screen
from soilstats.quality.blocks import Blocks, non_monotone, saturation, spikes
from soilstats.quality.bursts import find_bursts
from soilstats.quality.phases import EXCLUDED_PHASES, find_phases
from soilstats.quality.prescreen import (
    contact_candidates,
    late_zero_candidates,
    runaway_candidates,
)
from soilstats.quality.sinkage_rules import seating_per_soil

PER_RECORD = (
    "spike",
    "burst",
    "pre-contact",
    "late-zero",
    "bearing-failure",
    "non-monotone",
    "saturation",
    "release",
    "hold",
    "unload-reload",
    "step",
)


def _power_law(rng, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A loading record: z from slightly above the surface, force a noisy power law."""
    z = np.linspace(-rng.uniform(0, 5e-4), rng.uniform(0.01, 0.04), n)
    force = rng.uniform(1e3, 1e5) * np.clip(z, 0, None) ** rng.uniform(0.4, 2.0)
    return z + rng.normal(0, 2e-6, n), force + rng.normal(0, rng.uniform(0.05, 1.0), n)


def _artefact(rng, kind: int) -> tuple[np.ndarray, np.ndarray]:
    """One record with artefact ``kind`` (0: clean ... 18: a force step while z advances)."""
    n = int(rng.choice([30, 80, 120, 300]))
    z, f = _power_law(rng, n)
    if kind == 1:  # one- to three-sample spikes in z or force
        for values in (z, f)[: rng.integers(1, 3)]:
            i, k = rng.integers(3, n - 6), rng.integers(1, 4)
            values[i : i + k] += rng.choice([-1, 1]) * np.ptp(values) * rng.uniform(0.03, 0.6)
    elif kind == 2:  # seating offset: free travel at the noise floor first
        offset, m = rng.uniform(2e-4, 4e-3), rng.integers(3, 25)
        keep = z > 0
        z = np.r_[np.linspace(0, offset, m, endpoint=False), z[keep] + offset]
        f = np.r_[rng.normal(0, 0.3, m), f[keep]]
    elif kind == 3:  # bearing failure: the force plateaus while z runs on
        k, extra = rng.integers(n // 3, n), rng.integers(5, 80)
        step = rng.uniform(0.5, 4) * np.ptp(z) / n
        z = np.r_[z[:k], z[k - 1] + step * np.arange(1, extra + 1)]
        f = np.r_[f[:k], f[k - 1] * (1 + rng.uniform(-0.02, 0.05, extra))]
    elif kind == 4:  # unloading: z falls back for a few samples
        k, m = rng.integers(n // 2, n - 4), rng.integers(2, 10)
        z[k : k + m] -= rng.uniform(0.005, 0.1) * np.ptp(z)
    elif kind == 5:  # a clipped channel
        which = (f, z)[rng.integers(0, 2)]
        np.minimum(which, np.quantile(which, rng.uniform(0.85, 0.99)), out=which)
    elif kind == 6:  # short records, around every length limit of the detectors
        m = int(rng.integers(1, 10))
        z, f = z[:m], f[:m]
    elif kind == 7:  # constant channels
        f = np.full(n, 1.0)
        if rng.random() < 0.5:
            z = np.full(n, z[0])
    elif kind == 8:  # coarse quantisation (many ties)
        z = np.round(z / 2e-4) * 2e-4
        f = np.round(f / 2.0) * 2.0
    elif kind == 9:  # below zero throughout
        f = f - f.max() * rng.uniform(0.2, 1.2)
    elif kind == 10:  # small integer values: ties everywhere
        z = rng.integers(0, 3, n) * 1e-3
        f = rng.integers(0, 3, n).astype(float)
    elif kind == 11:  # a long, dense record with a spike
        m = int(rng.integers(500, 1500))
        t = np.linspace(0, n - 1, m)
        z = np.interp(t, np.arange(n), z) + rng.normal(0, 2e-6, m)
        f = np.interp(t, np.arange(n), f) + rng.normal(0, 0.3, m)
        f[m // 2] += np.ptp(f)
    elif kind == 12:  # a sparse record (20-40 samples) with one spike x2-x4 in z or force
        m = int(rng.integers(20, 41))
        z, f = z[:: max(1, n // m)][:m], f[:: max(1, n // m)][:m]
        which = (z, f)[rng.integers(0, 2)]
        which[rng.integers(2, which.size - 2)] *= rng.uniform(2.0, 4.0)
    elif kind == 13:  # displacement zeroed after contact (0-10 % of the travel), or preloaded
        z = z - rng.uniform(0.0, 0.1) * np.ptp(z)
        if rng.random() < 0.3:
            f = f + rng.uniform(0.0, 0.2) * f.max()
    elif kind == 14:  # the drive lets go: the force collapses at standing z, record ends
        m = int(rng.integers(3, 40))
        z = np.r_[z, z[-1] - rng.uniform(0, 0.02) * np.ptp(z) * np.linspace(0, 1, m)]
        f = np.r_[f, f[-1] * np.maximum(rng.uniform(0.0, 0.3), np.linspace(0.9, 0, m))]
    elif kind in (15, 16):  # a hold that relaxes 6-30 %, or an unload to 0-20 %, then reload
        k, m = int(rng.integers(n // 3, 2 * n // 3)), int(rng.integers(4, 30))
        low = rng.uniform(0.7, 0.94) if kind == 15 else rng.uniform(0.0, 0.2)
        back = int(rng.integers(1, 6))
        hold = f[k] * (low + (1 - low) * np.exp(-np.arange(1, m + 1) / (0.3 * m)))
        reload = f[k + 1 : k + 1 + back] - (f[k] - hold[-1]) * np.linspace(1, 0, back + 2)[1:-1]
        z = np.r_[z[: k + 1], np.full(m, z[k]), z[k + 1 :]]
        f = np.r_[f[: k + 1], hold, reload, f[k + 1 + back :]]
    elif kind == 17:  # 3-4-sample bursts in z, or clustered spikes in either channel
        which = (z, f)[rng.integers(0, 2)] if rng.random() < 0.5 else z
        for _ in range(int(rng.integers(1, 3))):
            i, k = int(rng.integers(5, n - 10)), int(rng.integers(1, 5))
            which[i : i + k] += rng.choice([-1, 1]) * np.ptp(which) * rng.uniform(0.08, 0.5)
    elif kind == 18:  # a step: the force drops 6-20 % while z advances, then recovers
        k = int(rng.integers(n // 3, 2 * n // 3))
        m = min(int(rng.integers(3, 20)), n - k)
        f[k : k + m] -= f[k] * rng.uniform(0.06, 0.2) * np.linspace(1, 0, m)
    return z, f


def _campaign(seed: int, tests: int = 240) -> Campaign:
    rng = np.random.default_rng(seed)
    log, rows = [], []
    for i in range(tests):
        tid = f"t{i:03d}"
        z, f = _artefact(rng, i % 19)
        log.append({"test_id": tid, "kind": "sinkage", "soil": f"s{i % 3}", "shape": "circle"})
        log[-1]["radius_m"] = 0.05
        rows.append(pd.DataFrame({"test_id": tid, "z_m": z, "force_N": f}))
    for i in range(40):
        tid = f"r{i:02d}"
        n = int(rng.choice([3, 30, 120]))
        torque = np.linspace(0, 40, n) + rng.normal(0, 0.05, n)
        if n > 10:
            torque[rng.integers(3, n - 3)] += rng.choice([0.0, 30.0])
        log.append({"test_id": tid, "kind": "shear", "soil": "s0", "r_inner_m": 0.05})
        log[-1] |= {"r_outer_m": 0.15, "grousers": 12, "grouser_height_m": 0.005}
        angle = np.linspace(0, 1, n)
        normal = 500 + rng.normal(0, 1, n)
        rows.append(
            pd.DataFrame(
                {"test_id": tid, "angle_rad": angle, "torque_Nm": torque, "normal_force_N": normal}
            )
        )
    sink = pd.concat([r for r in rows if "z_m" in r], ignore_index=True)
    # Spread some tests' rows through the file: a test's rows need not be contiguous.
    key = np.arange(len(sink), dtype=float)
    for tid in rng.choice(sink["test_id"].unique(), 20, replace=False):
        at = np.flatnonzero(sink["test_id"].to_numpy() == tid)
        key[at] += np.linspace(0, 3000, at.size)
    sink = sink.iloc[np.argsort(key, kind="stable")].reset_index(drop=True)
    shear = pd.concat([r for r in rows if "torque_Nm" in r], ignore_index=True)
    return Campaign.from_frames(pd.DataFrame(log), sink, shear, check_units=False)


def _reference(campaign: Campaign, mode: str) -> list[tuple]:
    """The per-record findings, test by test (the screening loop before batching): spikes,
    then bursts, then the record's phases, then the loading record's rules (the seating
    offset decided soil by soil, as screening decides it)."""
    clean, out = mode == "clean", []

    def rows(labels, positions):
        return tuple(int(labels[i]) + 1 for i in positions)

    sink = campaign.sinkage
    b_of = dict(zip(campaign.tests["test_id"].astype(str), campaign.tests["b_m"], strict=True))
    soil_of = dict(zip(campaign.tests["test_id"].astype(str), campaign.tests["soil"], strict=True))
    staged = []
    for tid, idx in sink.groupby("test_id", sort=False).indices.items():
        labels = sink.index.to_numpy()[idx]
        z, force = sink["z_m"].to_numpy(float)[idx], sink["force_N"].to_numpy(float)[idx]
        spiked = np.union1d(records.find_spikes(z), records.find_spikes(force))
        if spiked.size:
            out.append((tid, "spike", rows(labels, spiked), None))
        good = np.setdiff1d(np.arange(z.size), spiked)
        burst = good[np.union1d(find_bursts(z[good]), find_bursts(force[good])).astype(int)]
        if burst.size:
            out.append((tid, "burst", rows(labels, burst), None))
        good = np.setdiff1d(good, burst)
        phases = find_phases(z[good], force[good])
        excluded = phases.mask(*EXCLUDED_PHASES)
        for code, positions in _events(phases).items():
            # one flag per code: its events' phases, a reload joined to the event it follows
            out.append((tid, code, rows(labels, good[positions]), None))
        contact = next((p.start for p in phases.phases if p.name != "approach"), good.size)
        loaded = good[~excluded]
        weak = records.find_contact(
            z[loaded],
            force[loaded],
            ratio=records.CONTACT_WEAK_RATIO,
            min_travel=records.CONTACT_WEAK_TRAVEL,
        )
        staged.append((tid, labels, z, force, loaded, contact, weak))
    found = {k: item[6] for k, item in enumerate(staged) if item[6] is not None}

    def record(k):
        _, labels, z, force, loaded, _, _ = staged[k]
        return z[loaded], force[loaded], labels[loaded]

    soils = [soil_of[str(item[0])] for item in staged]
    seated_of = seating_per_soil(found, record, soils)
    for k, (tid, labels, z, force, loaded, contact, _) in enumerate(staged):
        zg, fg = z[loaded], force[loaded]
        offset = shift = 0.0
        seated = loaded
        late = records.find_late_zero(zg, fg)
        if late is not None:
            out.append((tid, "late-zero", rows(labels, loaded[late.loaded]), late.z_start))
        chosen = seated_of.get(k)
        if chosen is not None:
            offset = chosen.z_contact if clean else 0.0
            out.append((tid, "pre-contact", rows(labels, loaded[chosen.before]), chosen.z_contact))
            # bearing failure is judged on the loaded record, z from the contact
            shift = chosen.z_contact
            seated = np.delete(loaded, chosen.before)
        runaway = records.find_runaway(z[seated] - shift, force[seated], b_of.get(str(tid)))
        if runaway is not None:
            value = runaway.z_onset + shift - offset
            out.append((tid, "bearing-failure", rows(labels, seated[runaway.after]), value))
        after = loaded[contact:]  # non-monotone and clipping: from the contact on
        fallen = records.find_non_monotone(z[after])
        if fallen.size:
            out.append((tid, "non-monotone", rows(labels, after[fallen]), None))
        for values, other in ((force[after], z[after]), (z[after], force[after])):
            clipped = records.find_saturation(values, other)
            if clipped.size:
                out.append((tid, "saturation", rows(labels, after[clipped]), None))
    shear = campaign.shear
    for tid, idx in shear.groupby("test_id", sort=False).indices.items():
        labels = shear.index.to_numpy()[idx]
        channels = [shear[c].to_numpy(float)[idx] for c in ("torque_Nm", "normal_force_N")]
        spiked = np.unique(np.concatenate([records.find_spikes(c) for c in channels])).astype(int)
        if spiked.size:
            out.append((tid, "spike", rows(labels, spiked), None))
    return sorted(out, key=repr)


#: The flag code of each excluded phase (a hold right before an unload or a release, and a
#: reload, count with the event they belong to: _event_positions).
EVENT_OF = {"hold": "hold", "unload": "unload-reload", "step": "step", "release": "release"}


def _events(phases) -> dict[str, np.ndarray]:
    """Positions of the phases that make up each code's events."""
    parts = [p for p in phases.phases if p.name in EXCLUDED_PHASES]
    owner: list[str] = []
    for i, p in enumerate(parts):
        follows = i and parts[i - 1].stop == p.start
        if follows and p.name == "reload":
            owner.append(owner[-1])
        elif follows and parts[i - 1].name == "hold" and p.name in ("unload", "release"):
            j = i - 1  # the hold and what joined it before become this event
            while j >= 0 and owner[j] == owner[i - 1] and parts[j].stop == parts[j + 1].start:
                owner[j] = EVENT_OF[p.name]
                j -= 1
            owner.append(EVENT_OF[p.name])
        else:
            owner.append(EVENT_OF.get(p.name, "hold"))
    out: dict[str, list] = {}
    for p, o in zip(parts, owner, strict=True):
        out.setdefault(o, []).append(np.arange(p.start, p.stop))
    return {code: np.concatenate(ranges) for code, ranges in out.items()}


def _batch(campaign: Campaign, mode: str) -> list[tuple]:
    flags = screen(campaign, mode).flags
    return sorted(
        ((f.test_id, f.code, f.rows, f.value) for f in flags if f.code in PER_RECORD), key=repr
    )


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("mode", ["clean", "flag"])
def test_screening_across_tests_finds_what_the_per_record_detectors_find(seed, mode):
    campaign = _campaign(seed)
    expected = _reference(campaign, mode)
    assert {code for _, code, *_ in expected} == set(PER_RECORD)  # every artefact is present
    assert _batch(campaign, mode) == expected


def test_records_with_non_finite_values_keep_the_per_record_behaviour():
    """A campaign assembled by hand (not validated) may hold NaN or inf samples; sorting
    networks and np.median treat NaN differently, so such records are screened one by one."""
    campaign = _campaign(2, tests=60)
    sink = campaign.sinkage.copy()
    sink.loc[[40, 700, 1500], "z_m"] = np.nan
    sink.loc[[100, 2000], "force_N"] = [np.inf, -np.inf]
    odd = replace(campaign, sinkage=sink)
    with np.errstate(all="ignore"):
        expected = _reference(odd, "clean")
        assert _batch(odd, "clean") == expected


def _split(blocks: Blocks, values: np.ndarray) -> list[np.ndarray]:
    return [values[s : s + n] for s, n in zip(blocks.starts, blocks.sizes, strict=True)]


def test_batch_detectors_match_and_the_power_law_screens_keep_every_finding():
    rng = np.random.default_rng(7)
    pairs = [_artefact(rng, k % 19) for k in range(420)]
    blocks = Blocks.of_sizes([z.size for z, _ in pairs])
    z, f = np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs])
    for values in (z, f):
        found = [np.flatnonzero(m) for m in _split(blocks, spikes(blocks, values))]
        for got, record in zip(found, _split(blocks, values), strict=True):
            np.testing.assert_array_equal(got, records.find_spikes(record))
    fallen = _split(blocks, non_monotone(blocks, z))
    clipped_f = _split(blocks, saturation(blocks, f, z))
    clipped_z = _split(blocks, saturation(blocks, z, f))
    contact = set(contact_candidates(blocks, z, f).tolist())
    runaway = set(runaway_candidates(blocks, z, f).tolist())
    late = set(late_zero_candidates(blocks, z, f).tolist())
    found = {"contact": set(), "runaway": set(), "late": set()}
    for k, (zk, fk) in enumerate(pairs):
        np.testing.assert_array_equal(np.flatnonzero(fallen[k]), records.find_non_monotone(zk))
        np.testing.assert_array_equal(np.flatnonzero(clipped_f[k]), records.find_saturation(fk, zk))
        np.testing.assert_array_equal(np.flatnonzero(clipped_z[k]), records.find_saturation(zk, fk))
        if records.find_contact(zk, fk) is not None:
            found["contact"].add(k)
        if records.find_runaway(zk, fk) is not None:
            found["runaway"].add(k)
        if records.find_late_zero(zk, fk) is not None:
            found["late"].add(k)
    assert found["contact"] and found["contact"] <= contact
    assert found["runaway"] and found["runaway"] <= runaway
    assert found["late"] and found["late"] <= late
    # ... and the screens do screen: few records besides the findings go one by one.
    assert len(contact - found["contact"]) <= 0.1 * len(pairs)
    assert len(runaway - found["runaway"]) <= 0.1 * len(pairs)
    assert len(late - found["late"]) <= 0.1 * len(pairs)


def test_block_medians_are_numpy_and_scipy_medians_exactly():
    patterns = np.array(list(itertools.product(range(5), repeat=5)), dtype=float)
    blocks = Blocks.of_sizes(np.full(len(patterns), 5))
    got = blocks.rolling_median5(patterns.ravel()).reshape(-1, 5)
    want = np.array([median_filter(p, size=5, mode="nearest") for p in patterns])
    np.testing.assert_array_equal(got, want)
    rng = np.random.default_rng(3)
    sizes = rng.integers(0, 70, 400)
    sizes[[0, 7, -1]] = 0  # empty blocks anywhere
    blocks = Blocks.of_sizes(sizes)
    ties = rng.integers(0, 4, blocks.total).astype(float)
    values = np.where(rng.random(blocks.total) < 0.5, ties, rng.normal(size=blocks.total))
    parts = _split(blocks, values)
    filtered = _split(blocks, blocks.rolling_median5(values))
    medians = blocks.median(values)
    for part, got_filter, got_median in zip(parts, filtered, medians, strict=True):
        if part.size:
            np.testing.assert_array_equal(got_filter, median_filter(part, size=5, mode="nearest"))
            assert got_median == np.median(part)
        else:
            assert np.isnan(got_median)


def test_empty_records_have_no_candidates():
    # contact_statistics returned four values on empty input where contact_candidates
    # unpacks five (a ValueError).
    empty = Blocks.of_sizes([0, 0])
    nothing = np.empty(0)
    assert contact_candidates(empty, nothing, nothing).size == 0
    assert runaway_candidates(empty, nothing, nothing).size == 0
    assert late_zero_candidates(empty, nothing, nothing).size == 0


def test_block_running_medians_and_noise_widths_are_the_per_record_ones_exactly():
    """The staging computes the burst rule's running median of 11, the phases' running
    median of 5 and their force-noise width across all records at once: the same numbers
    as scipy's median_filter and phases._noise on each record (ties, plateaus of repeated
    readings, empty and one-sample records included)."""
    from soilstats.quality.phases import _noise
    from soilstats.quality.staging import noise_widths

    rng = np.random.default_rng(5)
    parts = []
    for i in range(400):
        n = int(rng.integers(0, 80))
        kind = i % 4
        if kind == 0:
            x = rng.normal(size=n)
        elif kind == 1:
            x = np.round(rng.normal(size=n) * 3) / 3  # quantised
        elif kind == 2:
            x = np.r_[np.linspace(0, 1, n // 2), np.full(n - n // 2, 1.0)]  # a hold
        else:
            x = np.repeat(rng.integers(0, 3, n // 3).astype(float), 3)  # ties everywhere
        parts.append(x)
    blocks = Blocks.of_sizes([p.size for p in parts])
    values = np.concatenate(parts)
    for size in (5, 11):
        got = _split(blocks, blocks.rolling_median(values, size))
        for g, p in zip(got, parts, strict=True):
            np.testing.assert_array_equal(g, median_filter(p, size=size, mode="nearest"))
    np.testing.assert_array_equal(noise_widths(blocks, values), [_noise(p) for p in parts])
