"""The stages of a sinkage record before the loading-branch rules, across all records.

After the spike rule, :func:`stage` removes bursts (:mod:`.bursts`), then finds the phases
of every record (:mod:`.phases`) and turns the events that are not loading — a hold's
relaxation, an unload–reload, a step, the release at the end — into flags whose samples
leave every fit in the default mode. What stays (approach, contact, loading, failure) is the
*loading record* that :mod:`.screen`'s other rules judge: pre-contact, late zero and bearing
failure on it whole, non-monotone and saturation from its contact on.

Records are laid end to end (:class:`.blocks.Blocks`); positions below are positions in
those arrays, ``labels`` the 0-based data rows of the sample file.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .blocks import Blocks, unfinite
from .bursts import BURST_MIN_SAMPLES, BURST_WINDOW, find_bursts
from .noise import PLATEAU_RUN
from .phases import EXCLUDED_PHASES, Phase, RecordPhases, find_phases
from .report import QualityFlag
from .spikes import SPIKE_SPAN_FRACTION

__all__ = ["PhaseSpan", "Staged", "TestPhases", "stage"]

#: The flag code of each excluded phase event (a reload belongs to the hold or unload it
#: follows; a hold at the peak just before an unload or a release belongs to that event).
EVENT_CODES = {"hold": "hold", "unload": "unload-reload", "step": "step", "release": "release"}


@dataclass(frozen=True)
class PhaseSpan:
    """One phase of a test's record as the outputs state it: the 1-based data rows of its
    first and last sample, how many samples it holds, z [m] and force [N] at both ends, and
    the relative force change (a hold's relaxation, a drop) where it has one."""

    phase: str
    rows: tuple[int, int]
    samples: int
    z_m: tuple[float, float]
    force_N: tuple[float, float]
    change: float | None = None

    def to_dict(self) -> dict:
        out = {
            "phase": self.phase,
            "rows": list(self.rows),
            "samples": self.samples,
            "z_m": list(self.z_m),
            "force_N": list(self.force_N),
        }
        if self.change is not None:
            out["force_change"] = self.change
        return out

    def describe(self) -> str:
        """``loading rows 12-140 (129 samples, z 0.1-38.0 mm)``."""
        what = f"{self.phase} rows {self.rows[0]}-{self.rows[1]} ({self.samples} samples, "
        what += f"z {self.z_m[0] * 1e3:.3g}-{self.z_m[1] * 1e3:.3g} mm"
        if self.change is not None:
            what += f", force {self.change:+.1%}"
        return what + ")"


@dataclass(frozen=True)
class TestPhases:
    """The phases of one test's record, in order."""

    test_id: str
    spans: tuple[PhaseSpan, ...]

    def to_list(self) -> list[dict]:
        return [s.to_dict() for s in self.spans]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.phase for s in self.spans)


@dataclass
class Staged:
    """The records after the staging: ``good`` lays out the records without spikes and
    bursts; ``loading`` marks the positions of the loading record (not an excluded phase);
    ``phases`` holds each record's phases (positions inside its good record) and
    ``contact`` the position of its contact there."""

    good: Blocks
    z: np.ndarray
    force: np.ndarray
    labels: np.ndarray
    phases: list[RecordPhases]
    loading: np.ndarray
    contact: np.ndarray


def _rows(labels: np.ndarray) -> tuple[int, ...]:
    return tuple(int(label) + 1 for label in labels.tolist())


def burst_flags(
    ids: list[str], blocks: Blocks, columns: dict[str, np.ndarray], labels: np.ndarray, clean: bool
) -> tuple[list[list[QualityFlag]], list[np.ndarray], np.ndarray]:
    """``burst`` flags of every record (either channel), the labels they drop in mode
    ``clean``, and the mask of burst positions."""
    mask = np.zeros(blocks.total, dtype=bool)
    out: list[list[QualityFlag]] = [[] for _ in ids]
    drop: list[np.ndarray] = []
    for k in _burst_candidates(blocks, columns):
        at = slice(blocks.starts[k], blocks.starts[k] + blocks.sizes[k])
        hits = {name: find_bursts(values[at]) for name, values in columns.items()}
        found = np.unique(np.concatenate(list(hits.values()))).astype(int)
        if not found.size:
            continue
        mask[blocks.starts[k] + found] = True
        rows = labels[at][found]
        where = ", ".join(f"{h.size} in {name}" for name, h in hits.items() if h.size)
        message = (
            f"{found.size} samples in bursts of 1-5 samples off the record's local trend and "
            f"back ({where}); rule: burst"
        )
        leave_out(
            out[k], drop, QualityFlag(ids[k], "sinkage", "burst", _rows(rows), message), clean
        )
    return out, drop, mask


def noise_widths(blocks: Blocks, values: np.ndarray) -> np.ndarray:
    """:func:`~.phases._noise` of every block, across all blocks at once (the same
    operations in the same order, so the same numbers): the robust width of the second
    differences over sqrt(6), floored at the sensor's step (:func:`~.noise.resolution`,
    whose plateaus of repeated readings do not count)."""
    out = np.zeros(blocks.count)
    second, sb = blocks.diff(values, 2)
    with np.errstate(invalid="ignore"):
        centre = sb.median(second)
        mad = sb.median(np.abs(second - sb.spread(centre)))
    width = np.where(sb.sizes > 0, 1.4826 * mad / np.sqrt(6.0), 0.0)
    steps, st = blocks.diff(values, 1)
    steps = np.abs(steps)
    zero = steps == 0
    start, stop = st.runs(zero)
    run = np.zeros(steps.size, dtype=np.int64)
    run[zero] = np.repeat(stop - start, stop - start)
    plateau = run > PLATEAU_RUN
    repeats = st.total_of(zero & ~plateau)
    counted = st.sizes - st.total_of(plateau)
    smallest = st.min(steps, where=~zero)
    quantised = (st.total_of(zero) > 0) & (counted > 0) & ~(repeats < 0.1 * counted)
    resolution = np.where(quantised & np.isfinite(smallest), smallest, 0.0)
    out[:] = np.where(blocks.sizes >= 3, np.maximum(width, resolution), 0.0)
    return out


def _burst_candidates(blocks: Blocks, columns: dict[str, np.ndarray]) -> np.ndarray:
    """The records in which :func:`~.bursts.find_bursts` can find a burst; it finds none in
    the others. A burst sample departs from the running median of BURST_WINDOW by more
    than its threshold, which is at least SPIKE_SPAN_FRACTION of the median's span: a record
    with no such departure in either channel (computed across all records at once) has
    none. Records too short for the rule, or holding a non-finite value, are left to it."""
    keep = np.zeros(blocks.count, dtype=bool)
    for values in columns.values():
        with np.errstate(invalid="ignore"):
            trend = blocks.rolling_median(values, BURST_WINDOW)
            span = blocks.max(trend) - blocks.min(trend)
            off = np.abs(values - trend) > SPIKE_SPAN_FRACTION * blocks.spread(span)
        keep |= blocks.total_of(off) > 0
    keep &= blocks.sizes >= BURST_MIN_SAMPLES
    return np.union1d(np.flatnonzero(keep), unfinite(blocks, *columns.values()))


def leave_out(flags: list, drop: list, flag: QualityFlag, clean: bool) -> None:
    """Add ``flag`` of a code whose samples leave the fits: marked excluded, and its rows
    (1-based) added to the labels to drop, in mode ``clean``."""
    flags.append(replace(flag, excluded=clean))
    if clean:
        drop.append(np.asarray(flag.rows, dtype=np.int64) - 1)


def stage(
    ids: list[str], good: Blocks, z: np.ndarray, force: np.ndarray, labels: np.ndarray, clean: bool
) -> tuple[Staged, list[list[QualityFlag]], list[np.ndarray]]:
    """Phases of every record and the flags of the events that are not loading (module
    docstring): (staged records, flags per test, labels to drop in mode ``clean``)."""
    phases: list[RecordPhases] = []
    loading = np.ones(good.total, dtype=bool)
    contact = np.zeros(good.count, dtype=np.int64)
    out: list[list[QualityFlag]] = [[] for _ in ids]
    drop: list[np.ndarray] = []
    smooth = good.rolling_median5(force)
    noise = noise_widths(good, force)
    for k in range(good.count):
        at = slice(good.starts[k], good.starts[k] + good.sizes[k])
        found = find_phases(z[at], force[at], smooth=smooth[at], noise=float(noise[k]))
        phases.append(found)
        excluded = found.mask(*EXCLUDED_PHASES)
        loading[at] = ~excluded
        contact[k] = _contact_of(found)
        for flag in _event_flags(ids[k], found, z[at], force[at], labels[at], clean):
            leave_out(out[k], drop, flag, clean)
    staged = Staged(good, z, force, labels, phases, loading, contact)
    return staged, out, drop


def _contact_of(found: RecordPhases) -> int:
    """Position of the first sample past the approach."""
    for p in found.phases:
        if p.name != "approach":
            return p.start
    return found.size


def _event_flags(
    test_id: str,
    found: RecordPhases,
    z: np.ndarray,
    force: np.ndarray,
    labels: np.ndarray,
    clean: bool,
) -> list[QualityFlag]:
    """One flag per test and event code, listing its events (position runs of the excluded
    phases, a reload or a preceding peak hold joined to the event it belongs to)."""
    events: list[tuple[str, list[Phase]]] = []
    for p in found.phases:
        if p.name not in EXCLUDED_PHASES:
            continue
        adjacent = bool(events) and events[-1][1][-1].stop == p.start
        previous = events[-1][1][-1].name if adjacent else None
        if adjacent and p.name == "reload":
            events[-1][1].append(p)
        elif previous == "hold" and p.name in ("unload", "release"):
            events[-1] = (EVENT_CODES[p.name], [*events[-1][1], p])
        else:
            events.append((EVENT_CODES.get(p.name, "hold"), [p]))
    by_code: dict[str, list[list[Phase]]] = {}
    for code, parts in events:
        by_code.setdefault(code, []).append(parts)
    flags = []
    for code, items in by_code.items():
        positions = np.concatenate([np.arange(p.start, p.stop) for parts in items for p in parts])
        what = "; ".join(_describe(code, parts, z, found.size) for parts in items)
        flags.append(
            QualityFlag(
                test_id,
                "sinkage",
                code,
                _rows(labels[positions]),
                what + (" (left out of fits)" if clean else ""),
                excluded=clean,
            )
        )
    return flags


def _describe(code: str, parts: list[Phase], z: np.ndarray, size: int) -> str:
    """One event in words, with z in mm and the force change (``size``: the record's)."""
    main = next((p for p in parts if p.change is not None), parts[0])
    first, last = parts[0].start, parts[-1].stop - 1
    at = f"at z = {z[main.start] * 1e3:.4g} mm"
    change = f" by {-main.change:.1%} of its running maximum" if main.change is not None else ""
    reload = any(p.name == "reload" for p in parts)
    resumes = f"; loading resumes at sample {last + 2}" if last + 1 < size else ""
    if code == "release":
        return (
            f"release {at}: the force collapses{change} at standing z and the record ends "
            f"(samples {first + 1}-{last + 1} of the record; the drive let go)"
        )
    if code == "unload-reload":
        return (
            f"unload {at}: the force falls{change}"
            + (", then reloads below the virgin curve until it regains it" if reload else "")
            + f" (samples {first + 1}-{last + 1}{resumes})"
        )
    if code == "step":
        return (
            f"step {at}: the force drops{change} while z advances, then climbs back "
            f"(samples {first + 1}-{last + 1})"
        )
    return (
        f"hold {at}: the drive stands still and the force relaxes{change}"
        + ("; the reload after it until the force regains its running maximum" if reload else "")
        + f" (samples {first + 1}-{last + 1})"
    )


def spans_of(
    test_id: str, found: RecordPhases, z: np.ndarray, force: np.ndarray, labels: np.ndarray
) -> TestPhases:
    """The phases of one record as :class:`PhaseSpan` records (rows from ``labels``)."""
    spans = []
    for p in found.phases:
        a, b = p.start, p.stop - 1
        spans.append(
            PhaseSpan(
                p.name,
                (int(labels[a]) + 1, int(labels[b]) + 1),
                p.size,
                (float(z[a]), float(z[b])),
                (float(force[a]), float(force[b])),
                p.change,
            )
        )
    return TestPhases(test_id, tuple(spans))
