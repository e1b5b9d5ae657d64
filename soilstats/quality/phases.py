"""The phases of one plate-sinkage record, found from z and force alone.

A real record is more than a loading curve. In sample order it may hold:

``approach``
    the plate in free air or creeping down to the surface: before the contact point;
``contact``
    from the contact point until the force is held clear of its noise floor (the seating
    toe; fitted as part of the loading branch);
``loading``
    the virgin loading branch: z at its running maximum and the force on its running
    maximum (the only phase a pressure–sinkage law describes);
``hold``
    the drive stands still (z within its noise, :data:`STANDING_NOISE_WIDTHS`) while the
    force relaxes below its running maximum by more than :data:`DEFICIT_FRACTION` but less
    than :data:`COLLAPSE_FRACTION` (stress relaxation), or stands at the peak just before an
    unload or release;
``unload`` / ``reload``
    the force falls by more than :data:`COLLAPSE_FRACTION` of its running maximum at
    standing z, or falls while z backs off (elastic rebound); loading then resumes below the
    virgin curve (``reload``) until the force regains its running maximum;
``step``
    the force drops below its running maximum by more than :data:`DEFICIT_FRACTION` and
    :data:`DEFICIT_NOISE_WIDTHS` noise widths while z keeps advancing, and climbs back (a
    local collapse of a dense soil, or a jolt of the rig);
``release``
    the force collapses at standing z and the record ends without loading again: the drive
    let go (or the test was stopped), so z no longer tracks the plate;
``failure``
    bearing failure: z runs away at constant or falling force (decided by
    :func:`~soilstats.quality.records.find_runaway` on the loading branch).

Holds and unload–reload branches are data for an elastic (unload–reload) model, never
loading; :mod:`.screen` leaves them out of every fit in the default mode. The detector works
on one record (numpy arrays in record order; spikes and bursts removed first), is blind to
the sampling clock (records decimated in time, as Cullinan's, keep their phases), and every
threshold is a named constant here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .noise import resolution, robust_width, running_median

__all__ = [
    "EXCLUDED_PHASES",
    "PHASES",
    "Phase",
    "RecordPhases",
    "find_phases",
]

#: Every phase name, in the order a record passes through them.
PHASES = (
    "approach",
    "contact",
    "loading",
    "hold",
    "unload",
    "reload",
    "step",
    "release",
    "failure",
)
#: Phases that are not the loading branch and are left out of fits in the default mode.
EXCLUDED_PHASES = ("hold", "unload", "reload", "step", "release")

#: A force excursion below its running maximum counts when it exceeds this share of the
#: running maximum ...
DEFICIT_FRACTION = 0.05
#: ... and this many robust force-noise widths (loose sand fluctuates by 5-8 widths
#: sample to sample: Cullinan's method-1 records, 30-45 N on a 5 N width).
DEFICIT_NOISE_WIDTHS = 10.0
#: A reload (or a step's recovery) ends where the force is back within this share of its
#: running maximum ...
REJOIN_FRACTION = 0.01
#: ... or this many noise widths of it, whichever is larger.
REJOIN_NOISE_WIDTHS = 3.0
#: At standing z, a force that loses more than this share of its running maximum was
#: unloaded (or released), not relaxed.
COLLAPSE_FRACTION = 0.5
#: Excursions are sought only where the running maximum force carries at least this share
#: of the record's peak: a wobble of a few newtons at first contact is no unload (CMU's
#: small-D80-1 rises to 3 N, 1 % of its peak, falls to 0.1 N, then loads).
EXCURSION_MIN_LOAD = 0.05
#: The drive stands still during a fall when z advances by at most this many z-noise
#: widths (and 3 sensor steps) ...
STANDING_NOISE_WIDTHS = 4.0
#: ... or at most this share of what loading at the record's median rate would have covered
#: (a step falls in one or two samples while z advances at the loading rate).
STANDING_RATE = 0.25
#: A collapse that ends the record is a release when z backs off by less than this share of
#: the travel (the rig's frame springs back: CMU 0.2-0.4 mm of 20-38 mm); farther, the
#: plate was withdrawn (an unload).
RELEASE_MAX_BACKOFF = 0.1
#: A fall of less than COLLAPSE_FRACTION is still an unload (not a hold's relaxation) when z
#: backs off by more than this share of the travel: the plate was lifted. A relaxing hold
#: lets the rig spring back a little (Cullinan's method-5 test: 0.4 mm of 80 mm, 0.5 %).
UNLOAD_BACKOFF = 0.02


@dataclass(frozen=True)
class Phase:
    """One phase of a record: positions ``start`` to ``stop`` (exclusive) of the record.

    ``change`` is the relative force change over the phase where it says something (a
    hold's relaxation, an unload's or a step's drop, as a negative share of the running
    maximum force); ``detail`` says it in words.
    """

    name: str
    start: int
    stop: int
    change: float | None = None
    detail: str = ""

    @property
    def size(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class RecordPhases:
    """The phases of one record, in order, covering every position once."""

    phases: tuple[Phase, ...]
    size: int

    def labels(self) -> np.ndarray:
        """The phase name of every position (object array)."""
        out = np.empty(self.size, dtype=object)
        for p in self.phases:
            out[p.start : p.stop] = p.name
        return out

    def mask(self, *names: str) -> np.ndarray:
        """Positions in any of the named phases."""
        out = np.zeros(self.size, dtype=bool)
        for p in self.phases:
            if p.name in names:
                out[p.start : p.stop] = True
        return out

    def of(self, name: str) -> tuple[Phase, ...]:
        return tuple(p for p in self.phases if p.name == name)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.phases)


def _noise(values: np.ndarray) -> float:
    """Robust width of the white noise on ``values`` (second differences; floored at the
    sensor's step, which a hold's repeated readings do not set)."""
    if values.size < 3:
        return 0.0
    return max(robust_width(np.diff(values, 2)) / np.sqrt(6.0), resolution(values))


def _held_rise(force: np.ndarray, noise: float) -> int:
    """Position of the first sample from which the force is held (three samples) clear of
    the noise floor it starts on: 5 noise widths and 1 % of the peak above the median of
    the first three samples (the floor of ``find_contact``). 0 for a record that starts
    under load or never leaves its floor."""
    if force.size < 8:
        return 0
    base = float(np.median(force[:3]))
    peak = float(force.max())
    if abs(base) > max(0.05 * abs(peak), 5.0 * noise):
        return 0  # starts under load: no floor to leave
    above = force > base + max(5.0 * noise, 0.01 * (peak - base))
    held = above[:-2] & above[1:-1] & above[2:]
    return int(np.argmax(held)) if held.any() else 0


def find_phases(
    z: np.ndarray,
    force: np.ndarray,
    *,
    surface: float = 0.0,
    failure_onset: int | None = None,
    smooth: np.ndarray | None = None,
    noise: float | None = None,
) -> RecordPhases:
    """The phases of one record (module docstring).

    Parameters
    ----------
    z, force : array
        Sinkage [m] (+ into the soil) and force [N] in record order, spikes removed.
    surface : float
        The sinkage [m] at which the plate meets the soil: 0, or the contact point a
        seating-offset rule found. The contact is the first sample past it, or the first
        sample of the held rise off the noise floor when that comes earlier (a late zero).
    failure_onset : int, optional
        Position of the last sample before bearing failure (``find_runaway``'s onset on the
        loading branch, mapped to this record): the loading samples after it form the
        ``failure`` phase.
    smooth : array, optional
        The force's running median of five (``median_filter(force, 5, mode="nearest")``),
        where the caller has it for many records at once.
    noise : float, optional
        The force's noise width (:func:`_noise`), likewise.
    """
    z, force = np.asarray(z, float), np.asarray(force, float)
    n = z.size
    if n == 0:
        return RecordPhases((), 0)
    sigma_f = _noise(force) if noise is None else noise
    rise = _held_rise(force, sigma_f)
    deeper = np.flatnonzero(z > surface)
    contact = min(int(deeper[0]) if deeper.size else n, rise) if rise else 0
    if not deeper.size and not rise:
        contact = n  # never in contact: all approach
    labels = np.full(n, "loading", dtype=object)
    labels[:contact] = "approach"
    labels[contact:rise] = "contact"
    changes: dict[int, float] = {}  # phase start -> relative force change
    if rise < n - 1 and np.isfinite(z).all() and np.isfinite(force).all():
        if smooth is None:
            smooth = running_median(force, 5)
        _label_excursions(z, smooth, sigma_f, rise, labels, changes)
    if failure_onset is not None:
        tail = np.arange(n) > failure_onset
        labels[tail & (labels == "loading")] = "failure"
    return _as_phases(labels, changes)


def _label_excursions(
    z: np.ndarray,
    smooth: np.ndarray,
    sigma_f: float,
    start: int,
    labels: np.ndarray,
    changes: dict[int, float],
) -> None:
    """Label the force's excursions below its running maximum from ``start`` on: holds,
    unload–reload branches, steps and the release (module docstring)."""
    n = z.size
    after = np.arange(n) >= start
    envelope = np.maximum.accumulate(np.where(after, smooth, -np.inf))
    deficit = envelope - smooth
    tol = np.maximum(DEFICIT_NOISE_WIDTHS * sigma_f, DEFICIT_FRACTION * np.abs(envelope))
    rejoin = np.maximum(REJOIN_NOISE_WIDTHS * sigma_f, REJOIN_FRACTION * np.abs(envelope))
    # An excursion counts only once the force carries a material load (a toe wobble of a
    # few newtons at first contact is no unload).
    loaded = after & (envelope >= EXCURSION_MIN_LOAD * float(smooth[after].max()))
    triggers = np.flatnonzero(loaded & (deficit > tol))
    if not triggers.size:
        return
    z_after = z[start:]
    band = max(STANDING_NOISE_WIDTHS * _noise(z_after), 3.0 * resolution(z_after), 1e-12)
    steps = np.diff(z_after)
    rate = float(np.median(steps[steps > 0])) if (steps > 0).any() else 0.0
    travel = float(np.ptp(z_after))
    z_top = np.maximum.accumulate(np.where(after, z, -np.inf))
    i = int(triggers[0])
    while True:
        first = i  # back to the last sample on the running maximum: the fall is the event's
        while first > start and deficit[first - 1] > rejoin[first - 1]:
            first -= 1
        rejoined = np.flatnonzero(deficit[i:] <= rejoin[i:])
        back = i + int(rejoined[0]) if rejoined.size else n
        low = int(first + np.argmin(smooth[first:back]))
        drop = float(-deficit[low] / abs(envelope[low]))
        # How far z moved from the last sample on the running maximum to the force's minimum.
        before = max(first - 1, start)
        advance = float(z[low] - z[before])
        backed = float(z_top[first] - z[low])
        standing = advance <= max(band, STANDING_RATE * rate * (low - before))
        if not standing:
            labels[first:back] = "step"  # z kept advancing through the fall
            changes[first] = drop
        else:
            # The drive stood still (or backed off): a hold while z stands at the running
            # maximum, the fall, and loading again from where z advances past the stand.
            hold = first
            while (
                hold > start
                and labels[hold - 1] == "loading"
                and abs(z[hold - 1] - z[first]) <= band
            ):
                hold -= 1
            stand = float(z[first : low + 1].max())
            moving = np.flatnonzero(z[low:back] > stand + band)
            resume = low + int(moving[0]) if moving.size else back
            collapse = -drop > COLLAPSE_FRACTION
            if back == n and collapse and backed < RELEASE_MAX_BACKOFF * travel:
                labels[hold:first] = "hold"
                labels[first:] = "release"
                changes[first] = drop
                return
            if collapse or backed > UNLOAD_BACKOFF * travel:
                labels[hold:first] = "hold"
                labels[first:resume] = "unload"
                changes[first] = drop
            else:
                labels[hold:resume] = "hold"
                changes[hold] = drop
            labels[resume:back] = "reload" if back < n else labels[resume - 1]
        later = triggers[triggers >= back]
        if not later.size:
            return
        i = int(later[0])


def _as_phases(labels: np.ndarray, changes: dict[int, float]) -> RecordPhases:
    """Runs of equal labels as :class:`Phase` records."""
    n = labels.size
    cut = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts = np.r_[0, cut]
    stops = np.r_[cut, n]
    phases = []
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        name = str(labels[a])
        change = changes.get(a)
        phases.append(Phase(name, a, b, change, _detail(name, change)))
    return RecordPhases(tuple(phases), n)


def _detail(name: str, change: float | None) -> str:
    if change is None:
        return ""
    what = {
        "hold": "the force relaxes by",
        "unload": "the force falls by",
        "release": "the force collapses by",
        "step": "the force drops by",
    }.get(name)
    return f"{what} {-change:.1%} of its running maximum" if what else ""
