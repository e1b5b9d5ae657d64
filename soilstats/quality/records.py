"""Detectors on one test's record (numpy arrays in record order; no campaign, no pandas).

Each returns what it found as positions in the record; :mod:`.screen` turns them into flags.
The spike detector is in :mod:`.spikes` (``find_spikes`` is importable from here too), the
noise width and sensor step every detector reads in :mod:`.noise`.
Every threshold is a named constant here, chosen so that clean simulated records (white
force noise, quantised sensors, exponents 0.3-2) are never flagged — ``tests/test_quality.py``
checks that over many seeds — while the artefacts of real records are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter
from scipy.optimize import minimize_scalar

from .noise import quantum, robust_width, runs
from .spikes import find_spikes

__all__ = [
    "ContactPoint",
    "LateZero",
    "Runaway",
    "find_contact",
    "find_late_zero",
    "find_non_monotone",
    "find_runaway",
    "find_saturation",
    "find_spikes",
]

#: Pre-contact: the force threshold above the starting baseline, in noise widths ...
CONTACT_NOISE_WIDTHS = 5.0
#: ... the free travel that matters, as a fraction of the test's travel ...
CONTACT_MIN_TRAVEL = 0.02
#: ... and how much better (residual ratio) a power law from the contact must fit.
CONTACT_RESIDUAL_RATIO = 0.5
#: A shifted law that leaves at most this share of the residual is evidence of a toe, if
#: weak: clean records of exponents 0.5-1.8 never go below 0.9 (0 of 4,720 simulated tests
#: below 0.8), but a record whose toe sits in noise (a small plate's first newtons) may show
#: no more. Weak evidence re-zeroes a test only where most tests of its soil show a toe
#: (:func:`soilstats.quality.screen`: one rule for the same toe in every test).
CONTACT_WEAK_RATIO = 0.8
#: The weak pass looks for toes down to this share of the travel: whether a soil's toe is
#: material (CONTACT_MIN_TRAVEL) is decided on the soil's median, so that tests whose own
#: travel puts the same toe just above or below 2 % are treated alike.
CONTACT_WEAK_TRAVEL = 0.01
#: ... or, for a curve that no shift of origin fits better (near-linear), how far above the
#: noise-floor threshold a power law measured from z = 0 puts the force at the deepest free
#: sample, as a multiple of the threshold: a curve loaded from z = 0 would have risen that far
#: by then. The law is fitted to the early loaded record only (up to CONTACT_EARLY_FRACTION
#: of the peak force), so that a tail of bearing failure or clipping does not bend it.
CONTACT_LAW_EXCESS = 3.0
CONTACT_EARLY_FRACTION = 0.35
#: ... and only where the early force never falls back by more than this share of the peak.
CONTACT_GLITCH_FRACTION = 0.10
#: A record whose first samples carry more than this share of its peak force (and more than
#: CONTACT_NOISE_WIDTHS noise widths) started under load (a seating preload, a record cut
#: after contact): no pre-contact segment is sought.
CONTACT_MAX_START = 0.05
#: Late zero (a displacement zeroed after first contact, find_late_zero) takes the floor,
#: rise threshold and three held samples of find_contact, and the branch at z <= 0 must
#: start at least CONTACT_MIN_TRAVEL of the test's travel (from the branch's start to the
#: deepest sample) before z = 0: the seating-offset rule's 2 %, mirrored. Below it a branch
#: lies within a sample step or two of z = 0 (120 samples over 30 mm: a step of 0.25 mm,
#: 0.85 % of the travel), where the contact falling between samples and z's own noise put
#: loaded samples at z <= 0 without a zero worth moving. A zero 1.5 mm late on 30 mm (5 %)
#: leaves a branch of 0.72-1.23 mm (2.4-4.1 %) in the reviewer's simulated campaign; 0.3 mm
#: leaves none.
#: Fewest samples of the loaded record for a shifted law's residual ratio to re-zero a
#: test on its own (beside its soil's tests, weaker evidence still counts).
CONTACT_MIN_LOADED = 20
#: Runaway: how many times deeper than the early law the record may end ...
RUNAWAY_EXCESS = 2.0
#: ... once its early law's standard error at the record's end (this many of them, in
#: log-force) is allowed for ...
RUNAWAY_LAW_SE = 2.5
#: ... the departure from the early law that marks the onset ...
RUNAWAY_ONSET = 1.25
#: ... and the least excess travel, as a fraction of the final sinkage.
RUNAWAY_MIN_TRAVEL = 0.25
#: A run-on counts as bearing failure when the plate sinks at least this many plate sizes b
#: beyond its early law (punch-through) ...
RUNAWAY_MIN_TRAVEL_B = 0.5
#: ... or, when shorter, when the force sits on a plateau at the end: it gains less than this
#: fraction over the last RUNAWAY_MIN_TRAVEL of the final sinkage. A shorter run-on whose
#: force keeps rising is the bend of a record stopped early (its early law then covers only
#: the first millimetres).
RUNAWAY_PLATEAU_GAIN = 0.10
#: A force that gains less than this over the last RUNAWAY_MIN_TRAVEL of the final sinkage
#: is flat whatever the early law says: the soil failed or the rig reached a force limit
#: (a relief valve). No clean record comes near (Cullinan's least gain 10.6 %, simulated
#: 20 %; a power law needs n < 0.07 to gain so little).
RUNAWAY_FLAT_GAIN = 0.02
#: Non-monotone: a fall below the running maximum, as a fraction of the travel ...
FALLBACK_FRACTION = 0.02
#: ... lasting this many samples at least (shorter is a spike's business).
FALLBACK_MIN_RUN = 3
#: Saturation: samples exactly at the maximum.
SATURATION_MIN_SAMPLES = 4


def _noise_floor(force: np.ndarray) -> tuple[float, float, float, np.ndarray] | None:
    """(base, noise, rise, above) of the noise floor a record starts on, or None when it
    starts off one: the house conventions of :func:`find_contact` and :func:`find_late_zero`.

    ``base`` is the median of the first 3 forces; ``noise`` the robust width of the second
    differences (blind to ramps and curvature; white noise: sqrt(6) sigma), at least the
    sensor's step; the rise threshold is :data:`CONTACT_NOISE_WIDTHS` noise widths or 1 % of
    the peak above ``base``, whichever is larger; ``above`` marks the samples above
    ``base + rise``. None for a record of fewer than 8 samples, and for one that starts
    under load (its first samples above :data:`CONTACT_MAX_START` of the peak and
    CONTACT_NOISE_WIDTHS noise widths: a seating preload, a record cut after contact): its
    flat start is no noise floor.
    """
    if force.size < 8:
        return None  # too short to tell a floor from a rise
    base = float(np.median(force[:3]))
    noise = max(robust_width(np.diff(force, 2)) / np.sqrt(6.0), quantum(force))
    if abs(base) > max(CONTACT_MAX_START * abs(float(force.max())), CONTACT_NOISE_WIDTHS * noise):
        return None  # the record starts under load: its flat start is not a noise floor
    rise = max(CONTACT_NOISE_WIDTHS * noise, 0.01 * float(force.max() - base))
    return base, noise, rise, force > base + rise


def _power_law(z: np.ndarray, force: np.ndarray, z_ref: float) -> tuple[float, float, float]:
    """(residual sum of squares, n, ln k) of force ≈ k (z − z_ref)^n fitted by p²-weighted
    log–log least squares (Wong's weighting), on the samples with z > z_ref and force > 0;
    (inf, nan, nan) where no fit."""
    depth = z - z_ref
    use = (depth > 0) & (force > 0)
    if use.sum() < 3:
        return np.inf, np.nan, np.nan
    f = force[use]
    x, y, w = np.log(depth[use]), np.log(f), f * f
    # The 2 × 2 weighted normal equations in closed form (called ~30 times per record).
    sw, sx, sy = w.sum(), w @ x, w @ y
    sxx, sxy = w @ (x * x), w @ (x * y)
    det = sw * sxx - sx * sx
    if det <= 0:
        return np.inf, np.nan, np.nan
    n = (sw * sxy - sx * sy) / det
    log_k = (sy - n * sx) / sw
    return float(np.sum((f - np.exp(log_k + n * x)) ** 2)), float(n), float(log_k)


def _power_law_residual(z: np.ndarray, force: np.ndarray, z_ref: float) -> float:
    """Residual sum of squares of :func:`_power_law`."""
    return _power_law(z, force, z_ref)[0]


@dataclass(frozen=True)
class ContactPoint:
    """A seating offset found in a record: re-zero z at ``z_contact`` [m].

    ``evidence`` says how it was found: ``"shift"`` (a power law from the contact fits the
    loaded record with ``residual_ratio`` of the residual of one from z = 0), ``"floor"``
    (the force stayed at its noise floor where a power law from z = 0 puts ``law_excess``
    times the floor's threshold) or ``"soil"`` (the record cannot place its own contact, and
    is re-zeroed at the median contact of its soil's other tests, which show a toe).
    """

    z_contact: float
    before: np.ndarray  # positions with 0 < z <= z_contact (free travel), excluded
    residual_ratio: float  # residual from the contact / residual from z = 0
    law_excess: float = np.nan  # law-from-zero force at the deepest free sample / threshold
    evidence: str = "shift"
    loaded_samples: int = CONTACT_MIN_LOADED  # samples of the loaded record the laws fit

    def describe(self) -> str:
        """What showed the offset, in words (the flag's message)."""
        if self.evidence == "floor":
            return (
                f"a power law from z = 0 would have reached {self.law_excess:.1f}x the noise "
                "floor's threshold there"
            )
        if self.evidence == "soil":
            return (
                "the record cannot place its own contact; most tests of its soil show a toe, "
                "and it is re-zeroed at their median contact (or where its own force leaves "
                "the floor, if that comes first)"
            )
        strength = "" if self.residual_ratio <= CONTACT_RESIDUAL_RATIO else " (weak: most tests "
        strength += "of its soil show a toe)" if strength else ""
        return (
            f"a power law from a shifted origin leaves {self.residual_ratio:.0%} of the "
            f"residual{strength}"
        )

    @property
    def strong(self) -> bool:
        """Evidence that re-zeroes the record on its own (not only beside its soil's)."""
        if self.evidence == "floor":
            return True
        # A shifted law fitted to a dozen samples halves the residual by chance: 10 of 1,800
        # clean 15-sample tests (3 N + 2 % noise) were re-zeroed at 2-9 mm of 20.
        return (
            self.residual_ratio <= CONTACT_RESIDUAL_RATIO
            and self.loaded_samples >= CONTACT_MIN_LOADED
        )


def floor_end(z: np.ndarray, force: np.ndarray) -> float | None:
    """The deepest z > 0 [m] before the force first rises (three samples held) off the noise
    floor the record starts on (:func:`_noise_floor`), or None where the record has no floor,
    never rises, or has no free sample: how far a seating toe can reach."""
    z, force = np.asarray(z, float), np.asarray(force, float)
    floor = _noise_floor(force)
    if floor is None:
        return None
    above = floor[3]
    rising = above[:-2] & above[1:-1] & above[2:]
    if not rising.any():
        return None
    free = z[: int(np.argmax(rising))]
    free = free[free > 0]
    return float(free.max()) if free.size else None


def _clean_rise(zl: np.ndarray, fl: np.ndarray, early: int) -> bool:
    """Whether the early law from z = 0 can be trusted for the ``floor`` evidence: up to
    the peak the force never falls back from its running maximum by more than
    :data:`CONTACT_GLITCH_FRACTION` of the peak (a three-sample glitch is no rise; real sand
    gives way by 1–3 %), and over the early record the sinkage never by more than
    :data:`FALLBACK_FRACTION` of the travel (a z glitch bends the law)."""
    f_rise = fl[: int(np.argmax(fl)) + 1]
    z_early = zl[:early]
    force_back = (np.maximum.accumulate(f_rise) - f_rise).max()
    z_back = (np.maximum.accumulate(z_early) - z_early).max()
    return bool(
        force_back <= CONTACT_GLITCH_FRACTION * f_rise[-1]
        and z_back <= FALLBACK_FRACTION * np.ptp(zl)
    )


def _free_travel(
    z: np.ndarray, force: np.ndarray, min_travel: float
) -> tuple[float, float, float, int, np.ndarray, float] | None:
    """The candidate pre-contact segment of :func:`find_contact`: (base, noise, rise of the
    noise floor, the first loaded position, the free positions with z > 0, the travel [m]),
    or None where the record has no floor, never rises, or its free travel is shorter than
    ``min_travel`` of the travel."""
    floor = _noise_floor(force)
    if floor is None:
        return None
    base, noise, rise, above = floor
    head = force[:4]
    if (np.diff(head) > 0).all() and head[-1] - head[0] > CONTACT_NOISE_WIDTHS * noise:
        return None  # the record starts climbing (logged from inside contact): no floor
    rising = above[:-2] & above[1:-1] & above[2:]
    if not rising.any():
        return None
    first = int(np.argmax(rising))
    travel = float(z.max() - max(z.min(), 0.0))
    free = np.flatnonzero((np.arange(z.size) < first) & (z > 0))
    if free.size < 3 or travel <= 0:
        return None
    z_free = float(z[free].max())
    if z_free < min_travel * travel:
        return None
    return base, noise, rise, first, free, travel


@dataclass(frozen=True)
class _ShiftSearch:
    """The search for the best shifted power law of :func:`find_contact` on the loaded record
    ``zl`` [m], ``fl`` [N] (force above the floor's base) of a record of ``travel`` [m]."""

    zl: np.ndarray
    fl: np.ndarray
    travel: float

    def coarse(self, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
        """Contact points evenly over [lo, hi) and the residuals of the laws from them."""
        grid = lo + (hi - lo) * np.linspace(0.0, 1.0, 12, endpoint=False)
        if lo <= 0:
            grid = grid[1:]  # z = 0 is the law every shift is compared with
        return grid, np.array([_power_law_residual(self.zl, self.fl, ref) for ref in grid])

    def best_in(self, lo: float, hi: float, grid: np.ndarray, residual: np.ndarray) -> tuple:
        """(residual, contact) of the best shifted law with its contact in [lo, hi]."""
        found = minimize_scalar(
            lambda ref: _power_law_residual(self.zl, self.fl, ref),
            bounds=(lo, hi * (1 - 1e-9)),
            method="bounded",
            options={"xatol": 1e-6 * self.travel},
        )
        k = int(residual.argmin())
        return min((float(found.fun), float(found.x)), (float(residual[k]), float(grid[k])))


def find_contact(
    z: np.ndarray,
    force: np.ndarray,
    *,
    ratio: float = CONTACT_RESIDUAL_RATIO,
    min_travel: float = CONTACT_MIN_TRAVEL,
) -> ContactPoint | None:
    """A pre-contact segment (force at its noise floor while z > 0 grows), or None.

    The candidate is the free travel before the force first rises (and stays, three samples)
    :data:`CONTACT_NOISE_WIDTHS` noise widths (and 1 % of the peak) above its starting level.
    It is a seating offset only if it is material (:data:`CONTACT_MIN_TRAVEL` of the travel)
    and either

    * a power law measured from a contact point inside it fits the loaded record with at
      most :data:`CONTACT_RESIDUAL_RATIO` of the residual of one measured from z = 0 (a
      steep power law, n > 1, also starts near the noise floor, but shifting its origin
      fits worse), or
    * the power law measured from z = 0 (fitted to the loaded record up to
      :data:`CONTACT_EARLY_FRACTION` of its peak) puts :data:`CONTACT_LAW_EXCESS` times the
      rise threshold at the last free sample: the curve is near-linear, no shift fits much
      better, but loaded from z = 0 it would have left the floor long before. Only where
      neither the force (up to its peak) nor the early sinkage falls back
      (:func:`_clean_rise`): a glitch would bend the law.

    No contact lies beyond the first sample held clearly off the floor (more than
    CONTACT_NOISE_WIDTHS noise widths above the start, with the next two): the 1 %-of-peak
    part of the rise threshold can leave a sparse record's first loaded sample among the
    "free" ones. A shifted law is judged with its contact anywhere from z = 0 to the first
    loaded sample (a steep law stays near the floor well after contact) and, when its best
    contact lies past that held sample, placed before it; a near-linear curve leaves the
    floor at once, so its contact is sought after the last sample at the floor proper.
    """
    z, force = np.asarray(z, float), np.asarray(force, float)
    candidate = _free_travel(z, force, min_travel)
    if candidate is None:
        return None
    base, noise, rise, first, free, travel = candidate
    loaded = np.arange(z.size) >= first
    zl, fl = z[loaded], force[loaded] - base
    from_zero = _power_law_residual(zl, fl, 0.0)
    # The early law from z = 0: loaded samples up to CONTACT_EARLY_FRACTION of the peak
    # (at least four).
    reach = np.flatnonzero(fl >= CONTACT_EARLY_FRACTION * float(fl.max()))
    early = max(int(reach[0]) if reach.size else zl.size, 3) + 1
    _, n0, log_k0 = _power_law(zl[:early], fl[:early], 0.0)
    first_loaded = float(zl[zl > 0].min()) if (zl > 0).any() else 0.0
    if not from_zero > 0 or first_loaded <= 0:
        return None
    # At the last free sample (in record order: a z glitch in the free travel is no depth).
    law_excess = float(np.exp(log_k0 + n0 * np.log(z[free[-1]]))) / rise
    # No contact lies beyond the first sample held clearly off the floor.
    held = (force - base > CONTACT_NOISE_WIDTHS * noise) & (z > 0)
    lifted = held[:-2] & held[1:-1] & held[2:]
    lift = int(np.argmax(lifted)) if lifted.any() else z.size
    upper = min(float(z[lift]), first_loaded) if lift < z.size else first_loaded
    search = _ShiftSearch(zl, fl, travel)
    coarse, best_in = search.coarse, search.best_in
    # A coarse grid first: most candidates are steep power laws that no offset improves.
    grid, residual = coarse(0.0, first_loaded)
    contact = None
    if residual.min() <= CONTACT_WEAK_RATIO * from_zero:
        fun, z_contact = best_in(0.0, first_loaded, grid, residual)
        if fun / from_zero <= ratio:
            if z_contact > upper:  # the best shift lies past a loaded sample: placed before it
                z_contact = best_in(0.0, upper, *coarse(0.0, upper))[1]
            contact = (z_contact, fun / from_zero, "shift")
    if contact is None and law_excess >= CONTACT_LAW_EXCESS and _clean_rise(zl, fl, early):
        # After the last sample at the floor proper that precedes the lift (z may jitter).
        at_floor = free[(force[free] - base <= CONTACT_NOISE_WIDTHS * noise) & (free < lift)]
        lower = min(float(z[at_floor].max()), upper) if at_floor.size else 0.0
        if upper > lower:
            fun, z_contact = best_in(lower, upper, *coarse(lower, upper))
        else:
            fun, z_contact = _power_law_residual(zl, fl, upper), upper
        contact = (z_contact, fun / from_zero, "floor")
    if contact is None or contact[0] < min_travel * travel:
        return None
    z_contact, ratio, evidence = contact
    before = np.flatnonzero((z > 0) & (z <= z_contact))
    return ContactPoint(z_contact, before, ratio, law_excess, evidence, int(zl.size))


@dataclass(frozen=True)
class LateZero:
    """A displacement zeroed after the plate touched the soil: the force leaves its noise
    floor and is held above the rise threshold while z is still <= 0, up to z = 0."""

    loaded: np.ndarray  # positions of the branch's samples at z <= 0
    z_start: float  # z [m] of the branch's first sample (<= 0): the contact lies at or before
    share: float  # the branch's largest force above the start, as a share of the peak's

    @property
    def extent(self) -> float:
        """How far [m] before z = 0 the branch starts."""
        return -self.z_start


def find_late_zero(z: np.ndarray, force: np.ndarray) -> LateZero | None:
    """A loading branch at z <= 0 (the displacement zeroed after first contact), or None.

    On the noise floor of :func:`find_contact` (none for a record that starts under load),
    the branch is the run of samples held above the rise threshold that ends at
    the first sample with z > 0, which must be above it too (the branch is continuous with
    the loaded record: a bump that falls back to the floor before z = 0 is none). It is a
    late zero when it holds three samples or more (the held rise of find_contact) and starts
    at least :data:`CONTACT_MIN_TRAVEL` of the test's travel before z = 0, the travel
    measured from the branch's start to the deepest sample. A rise within a sample step or
    two of z = 0 is therefore not one. Unlike find_contact, a record whose first four
    samples climb is judged: its base (the median of three climbing samples) lies above the
    floor, which only shortens the branch, and a simulated record of two floor samples and
    one at contact climbs by chance (10 of 36 tests zeroed 1.5 mm late were missed with that
    exit). Flag only: the contact itself lies somewhere before
    the branch, where the force was still within the threshold, and cannot be placed
    reliably.
    """
    z, force = np.asarray(z, float), np.asarray(force, float)
    floor = _noise_floor(force)
    if floor is None:
        return None
    base, _, _, above = floor
    below_surface = np.flatnonzero(z > 0)
    if not below_surface.size:
        return None
    cross = int(below_surface[0])
    if cross < 3 or not above[cross]:
        return None
    # Back from the crossing: the run held above the threshold at z <= 0.
    off = np.flatnonzero(~above[:cross])
    start = int(off[-1]) + 1 if off.size else 0
    if cross - start < 3:
        return None
    z_start = float(z[start])
    travel = float(z.max()) - z_start
    if not -z_start >= CONTACT_MIN_TRAVEL * travel or travel <= 0:
        return None
    share = float(force[start:cross].max() - base) / float(force.max() - base)
    return LateZero(np.arange(start, cross), z_start, share)


@dataclass(frozen=True)
class Runaway:
    """Sinkage far beyond the record's own early power law (bearing failure)."""

    z_onset: float  # last sinkage [m] the early law still describes (the proposed z_max)
    after: np.ndarray  # positions past the onset
    excess: float  # final sinkage / the early law's sinkage at the final force
    travel: float = np.nan  # final sinkage - the early law's sinkage at the final force [m]
    gain: float = np.nan  # force gained over the last RUNAWAY_MIN_TRAVEL of the sinkage
    flat: bool = False  # found by the flat force alone (RUNAWAY_FLAT_GAIN), not the excess


def find_runaway(z: np.ndarray, force: np.ndarray, b: float | None = None) -> Runaway | None:
    """Bearing failure: at the end of the record the plate sits :data:`RUNAWAY_EXCESS` times
    deeper than the record's own early power law puts it at the same force, and has run on
    either far (:data:`RUNAWAY_MIN_TRAVEL_B` plate sizes ``b`` beyond the law) or onto a force
    plateau (less than :data:`RUNAWAY_PLATEAU_GAIN` force gained over the last
    :data:`RUNAWAY_MIN_TRAVEL` of the final sinkage).

    The early law is F = k z^n, fitted in log–log space to the samples up to the sinkage
    where the force first reaches 35 % of its peak (and above 5 % of it). Comparing sinkage
    at equal force makes the rule hold for load- and displacement-controlled tests alike: a
    force plateau and a sinkage jump at one load step both show as excess sinkage. The
    onset is the last sample within :data:`RUNAWAY_ONSET` of that law; the excess travel must
    also exceed :data:`RUNAWAY_MIN_TRAVEL` of the final sinkage.

    The 35 %-of-peak window depends on where the test was stopped: a record stopped early has
    a lower peak, so its early law is fitted to the first millimetres alone (on the Cullinan
    sand records cut at 24 mm: 1-2.5 mm, where seating makes the log-log slope 0.9-1.6 for
    0.4-0.7 later), and the ordinary bend of the curve then reads as a 2-13x excess. That
    run-on is short (0.18-0.29 b beyond the law; GRC-1's punch-through runs 1.1-1.4 b and
    Cullinan's method 5 test 0.86 b) and its force keeps rising (by 2-3x), so with the plate
    size ``b`` [m] known it is not flagged. Without ``b`` (None, NaN) only the excess rules.
    """
    z, force = np.asarray(z, float), np.asarray(force, float)
    if z.size < 8:
        return None
    f = median_filter(force, size=5, mode="nearest")
    start = float(np.median(force[:3]))
    if abs(start) < 0.02 * abs(float(f.max())):  # a sensor offset, not a test begun loaded
        f = f - start
    peak = float(f.max())
    if peak <= 0:
        return None
    reach = int(np.argmax(f >= 0.35 * peak))
    early = (z > 0) & (np.arange(z.size) <= reach) & (f > 0.05 * peak)
    if early.sum() < 4 or np.ptp(np.log(z[early])) <= 0:
        return None
    log_z, log_f = np.log(z[early]), np.log(f[early])
    n, log_k = np.polyfit(log_z, log_f, 1)
    if not n > 0:
        return None
    loaded = f > 0
    ratio = np.full(z.size, np.nan)
    ratio[loaded] = z[loaded] / np.exp((np.log(f[loaded]) - log_k) / n)
    last = int(np.flatnonzero(np.isfinite(ratio))[-1])
    z_end = float(z[last])
    excess = float(ratio[last])
    # The excess the early law's own uncertainty allows for: its log-force at z_end is known
    # to a standard error that grows with the extrapolation, and a soft soil's law (n 0.3)
    # turns a 19 % force deficit into a 2x sinkage excess. A noisy early window (3 N + 2 %
    # on a 25 mm plate) then read as bearing failure on 12 of 80 clean soft tests.
    # Its scatter is read from the raw force (the running median's residuals hide it).
    raw = force[early] - (median_filter(force, size=5, mode="nearest")[early] - f[early])
    log_raw = np.log(raw) if (raw > 0).all() else log_f
    excess_sure = excess * np.exp(-RUNAWAY_LAW_SE * _law_se(log_z, log_raw, n, log_k, z_end) / n)
    travel = z_end * (1 - 1 / excess)
    # The force gained over the last RUNAWAY_MIN_TRAVEL of the sinkage (median-filtered), and
    # no less by a straight line through the tail's samples: two single samples carry the
    # noise of two, and 3 N + 2 % made a soft soil's 9 % gain read as a 1 % plateau.
    tail = int(np.argmax(z >= (1 - RUNAWAY_MIN_TRAVEL) * z_end))
    gain = float(f[last] / f[tail] - 1) if f[tail] > 0 else np.inf
    shift = float(median_filter(force, size=5, mode="nearest")[0] - f[0])  # the offset taken off
    fitted, gain_se = _tail_gain(z[tail : last + 1], force[tail : last + 1] - shift)
    gain = max(gain, fitted)
    # A plateau is a plateau beyond the noise: its gain, plus two standard errors, is still
    # below RUNAWAY_PLATEAU_GAIN (a soft soil's 9 % gain read 0.6 % on a noisy 50-sample test).
    sure_flat = fitted + 2.0 * gain_se < RUNAWAY_PLATEAU_GAIN
    if not (excess > RUNAWAY_EXCESS and excess_sure > RUNAWAY_EXCESS) or (
        travel <= RUNAWAY_MIN_TRAVEL * z_end
    ):
        if not (gain < RUNAWAY_FLAT_GAIN and sure_flat):
            return None
        # Flat alone: valid up to where the force first comes within that gain of its end.
        onset = max(int(np.argmax(f >= (1 - RUNAWAY_FLAT_GAIN) * f[last])) - 1, 0)
        return Runaway(float(z[onset]), np.arange(onset + 1, z.size), excess, travel, gain, True)
    within = np.flatnonzero(np.nan_to_num(ratio, nan=0.0) <= RUNAWAY_ONSET)
    onset = int(within[-1]) if within.size else 0
    if b is not None and b > 0 and travel < RUNAWAY_MIN_TRAVEL_B * b:
        if not gain < RUNAWAY_PLATEAU_GAIN:
            return None
    return Runaway(float(z[onset]), np.arange(onset + 1, z.size), excess, travel, gain)


def _law_se(log_z: np.ndarray, log_f: np.ndarray, n: float, log_k: float, z_end: float) -> float:
    """Standard error of the early law's mean log-force at ``z_end`` (extrapolated)."""
    m = log_z.size
    if m < 3:
        return 0.0
    residual = log_f - (n * log_z + log_k)
    s2 = float(residual @ residual) / (m - 2)
    sxx = float(((log_z - log_z.mean()) ** 2).sum())
    if sxx <= 0:
        return 0.0
    return float(np.sqrt(s2 * (1.0 / m + (np.log(z_end) - log_z.mean()) ** 2 / sxx)))


def _tail_gain(z: np.ndarray, f: np.ndarray) -> tuple[float, float]:
    """The force gained from the first to the last sinkage of the tail, by a straight line
    through its samples, and its standard error (the two end samples and no error where
    there are fewer than 4)."""
    if z.size >= 4 and np.ptp(z) > 0:
        (slope, intercept), cov = np.polyfit(z, f, 1, cov="unscaled")
        residual = f - (slope * z + intercept)
        s2 = float(residual @ residual) / (z.size - 2)
        start, end = slope * z[0] + intercept, slope * z[-1] + intercept
        se = float(np.sqrt(max(s2 * cov[0, 0], 0.0))) * float(z[-1] - z[0])
    else:
        start, end, se = f[0], f[-1], 0.0
    return (float(end / start - 1), se / float(start)) if start > 0 else (np.inf, 0.0)


def find_non_monotone(z: np.ndarray) -> np.ndarray:
    """Positions where z lies below its running maximum by more than
    :data:`FALLBACK_FRACTION` of the travel, in runs of :data:`FALLBACK_MIN_RUN` or more."""
    z = np.asarray(z, float)
    if z.size < FALLBACK_MIN_RUN + 1:
        return np.array([], int)
    travel = float(z.max() - z.min())
    if travel <= 0:
        return np.array([], int)
    fallen = (np.maximum.accumulate(z) - z) > FALLBACK_FRACTION * travel
    keep = [np.arange(a, b) for a, b in runs(fallen) if b - a >= FALLBACK_MIN_RUN]
    return np.concatenate(keep) if keep else np.array([], int)


def find_saturation(values: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Positions where ``values`` sit exactly at their maximum (≥ :data:`SATURATION_MIN_SAMPLES`
    samples) while ``other`` changes across them by more than 1 % of its span."""
    x, y = np.asarray(values, float), np.asarray(other, float)
    if x.size < SATURATION_MIN_SAMPLES:
        return np.array([], int)
    at_max = np.flatnonzero(x == x.max())
    if at_max.size < SATURATION_MIN_SAMPLES:
        return np.array([], int)
    span = float(y.max() - y.min())
    if span <= 0 or float(np.ptp(y[at_max])) <= 0.01 * span:
        return np.array([], int)
    return at_max
