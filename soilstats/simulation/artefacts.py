"""Record phases and glitches planted in simulated sinkage records (``[[artefacts]]``).

Real plate records hold more than a loading curve (docs/quality.md, "Phases of a record"):
the drive lets go at the end, pauses while the force relaxes, unloads and reloads, the force
steps down while z advances, and the sensors burst. Each kind below plants one of them in a
simulated record, so that every screening rule has a campaign with a known truth — which
tests carry it, at which samples — to be measured on (``benchmarks/quality_rates.py``) and a
test that fails without the rule.

============== =================================================================================
kind            options (defaults)
============== =================================================================================
``release``     ``drop`` (0.9: share of the peak force lost), ``samples`` (40),
                ``backoff`` (0.01: share of the travel z springs back)
``hold``        ``at`` (0.6: where, as a share of the record's samples), ``samples`` (30),
                ``relaxation`` (0.08: share of the force lost), ``reload`` (3 samples)
``unload-reload`` ``at`` (0.5), ``samples`` (20: at the bottom), ``to`` (0.05: force left,
                as a share), ``reload`` (3 samples)
``step``        ``at`` (0.7), ``drop`` (0.12), ``recovery`` (15 samples)
``burst``       ``channel`` ("z_m" or "force_N"), ``count`` (2), ``length`` ([3, 4]: fewest
                and most samples), ``size`` (0.1: share of the record's span), ``cluster``
                (false: true plants ``length`` one-sample spikes two samples apart instead)
``glitch-cluster`` ``channel`` ("z_m" or "force_N"), ``count`` (1), ``length`` ([5, 60]:
                fewest and most samples; all of a record's together at most a quarter of
                it), ``times`` ([3, 15]:
                each sample's value, as a multiple of the record's depth or peak force)
============== =================================================================================

Every kind also takes ``share`` (1.0: the probability that a matching test gets it),
``soils`` and ``series`` (limit it, as effects are limited). Planted samples carry the
record's own white force noise (``[noise] force_N``) and are quantised as the record is.
Randomness comes from a stream of its own, so a SPEC without artefacts simulates exactly as
before and adding one leaves every test's parameters and noise unchanged.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import refuse_unknown_keys
from .records import SpecError

__all__ = ["ARTEFACT_KINDS", "check_artefact", "plant"]

#: Each kind's options and their defaults.
ARTEFACT_KINDS: dict[str, dict[str, Any]] = {
    "release": {"drop": 0.9, "samples": 40, "backoff": 0.01},
    "hold": {"at": 0.6, "samples": 30, "relaxation": 0.08, "reload": 3},
    "unload-reload": {"at": 0.5, "samples": 20, "to": 0.05, "reload": 3},
    "step": {"at": 0.7, "drop": 0.12, "recovery": 15},
    "burst": {"channel": "z_m", "count": 2, "length": [3, 4], "size": 0.1, "cluster": False},
    "glitch-cluster": {"channel": "z_m", "count": 1, "length": [5, 60], "times": [3.0, 15.0]},
}
_COMMON = ("kind", "share", "soils", "series")


def _fraction(value: Any, where: str, low: float = 0.0, high: float = 1.0) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SpecError(f"{where} must be a number, got {value!r}")
    if not low <= float(value) <= high:
        raise SpecError(f"{where} must lie in [{low:g}, {high:g}], got {value!r}")
    return float(value)


def _count(value: Any, where: str, low: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise SpecError(f"{where} must be a whole number >= {low}, got {value!r}")
    return int(value)


def check_artefact(kind: str, options: dict[str, Any], where: str) -> dict[str, Any]:
    """The options of an ``[[artefacts]]`` entry with defaults filled in; a
    :class:`~soilstats.simulation.records.SpecError` naming the key for a bad one."""
    if kind not in ARTEFACT_KINDS:
        raise SpecError(
            f"{where}.kind: unknown artefact {kind!r}; choose one of {list(ARTEFACT_KINDS)}"
        )
    defaults = ARTEFACT_KINDS[kind]
    refuse_unknown_keys(
        options,
        {*defaults, "share"},
        lambda unknown: SpecError(
            f"{where}: unknown option(s) {sorted(unknown)} for artefact {kind!r}; it takes "
            f"{sorted(defaults)} and share"
        ),
    )
    out = {**defaults, **options}
    out["share"] = _fraction(out.get("share", 1.0), f"{where}.share")
    for key in ("drop", "backoff", "relaxation", "to", "size"):
        if key in defaults:
            out[key] = _fraction(out[key], f"{where}.{key}")
    for key in ("at",):
        if key in defaults:
            out[key] = _fraction(out[key], f"{where}.{key}", 0.05, 0.95)
    for key in ("samples", "reload", "recovery", "count"):
        if key in defaults:
            out[key] = _count(out[key], f"{where}.{key}")
    if kind == "burst":
        if out["channel"] not in ("z_m", "force_N"):
            raise SpecError(f"{where}.channel must be 'z_m' or 'force_N', got {out['channel']!r}")
        length = out["length"]
        if not (isinstance(length, list) and len(length) == 2):
            raise SpecError(f"{where}.length must be [fewest, most], got {length!r}")
        lo, hi = (_count(v, f"{where}.length") for v in length)
        if not lo <= hi <= 5:
            raise SpecError(f"{where}.length must satisfy fewest <= most <= 5, got {length!r}")
        out["length"] = [lo, hi]
        if not isinstance(out["cluster"], bool):
            raise SpecError(f"{where}.cluster must be true or false, got {out['cluster']!r}")
    if kind == "glitch-cluster":
        if out["channel"] not in ("z_m", "force_N"):
            raise SpecError(f"{where}.channel must be 'z_m' or 'force_N', got {out['channel']!r}")
        length, times = out["length"], out["times"]
        if not (isinstance(length, list) and len(length) == 2):
            raise SpecError(f"{where}.length must be [fewest, most], got {length!r}")
        lo, hi = (_count(v, f"{where}.length", 5) for v in length)
        if lo > hi:
            raise SpecError(f"{where}.length must satisfy 5 <= fewest <= most, got {length!r}")
        out["length"] = [lo, hi]
        if not (isinstance(times, list) and len(times) == 2):
            raise SpecError(f"{where}.times must be [lowest, highest], got {times!r}")
        t_lo, t_hi = (_fraction(v, f"{where}.times", 2.0, 1000.0) for v in times)
        if t_lo > t_hi:
            raise SpecError(f"{where}.times must satisfy lowest <= highest, got {times!r}")
        out["times"] = [t_lo, t_hi]
    return out


def plant(
    kind: str,
    options: dict[str, Any],
    z: np.ndarray,
    force: np.ndarray,
    rng: np.random.Generator,
    noise_N: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Plant one artefact in a record: (z, force, planted, inserted) with ``planted`` the
    mask of the samples it concerns and ``inserted`` the mask of the samples it added (so
    that the masks of earlier artefacts can be stretched to the new record)."""
    return _PLANTERS[kind](options, z.copy(), force.copy(), rng, noise_N)


def _loaded_at(force: np.ndarray, at: float) -> int:
    """The sample at share ``at`` of the loaded part of the record (force above 5 % of its
    peak), so that a planted event sits where the plate carries a load."""
    loaded = np.flatnonzero(force > 0.05 * force.max())
    first = int(loaded[0]) if loaded.size else 0
    return min(first + int(at * (force.size - first)), force.size - 2)


def _insert(z, force, k, z_new, f_new):
    """Insert samples after position ``k``; the masks of the new record."""
    z_out = np.r_[z[: k + 1], z_new, z[k + 1 :]]
    f_out = np.r_[force[: k + 1], f_new, force[k + 1 :]]
    inserted = np.zeros(z_out.size, dtype=bool)
    inserted[k + 1 : k + 1 + z_new.size] = True
    return z_out, f_out, inserted


def _release(o, z, force, rng, noise):
    m = o["samples"]
    peak = float(force.max())
    fall = max(2, m // 10)  # the force collapses within a tenth of the phase
    level = np.r_[np.linspace(1.0, 1.0 - o["drop"], fall + 1)[1:], np.full(m - fall, 1 - o["drop"])]
    z_new = z[-1] - o["backoff"] * float(np.ptp(z)) * np.minimum(1.0, np.arange(1, m + 1) / fall)
    f_new = peak * level + noise * rng.standard_normal(m)
    z, force, inserted = _insert(z, force, z.size - 1, z_new, f_new)
    return z, force, inserted.copy(), inserted


def _hold(o, z, force, rng, noise):
    k, m, back = _loaded_at(force, o["at"]), o["samples"], o["reload"]
    t = np.arange(1, m + 1)
    lost = o["relaxation"] * force[k] * (1.0 - np.exp(-3.0 * t / m)) / (1.0 - np.exp(-3.0))
    f_new = force[k] - lost + noise * rng.standard_normal(m)
    z, force, inserted = _insert(z, force, k, np.full(m, z[k]), f_new)
    after = np.arange(k + 1 + m, min(k + 1 + m + back, force.size))
    force[after] -= lost[-1] * np.linspace(1.0, 0.0, after.size + 2)[1:-1]
    planted = inserted.copy()
    planted[after] = True
    return z, force, planted, inserted


def _unload_reload(o, z, force, rng, noise):
    k, m, back = _loaded_at(force, o["at"]), o["samples"], o["reload"]
    fall = max(2, m // 5)
    level = np.r_[np.linspace(1.0, o["to"], fall + 1)[1:], np.full(m - fall, o["to"])]
    f_new = force[k] * level + noise * rng.standard_normal(m)
    z, force, inserted = _insert(z, force, k, np.full(m, z[k]), f_new)
    after = np.arange(k + 1 + m, min(k + 1 + m + back, force.size))
    deficit = force[k] * (1.0 - o["to"])
    force[after] -= deficit * np.linspace(1.0, 0.0, after.size + 2)[1:-1]
    planted = inserted.copy()
    planted[after] = True
    return z, force, planted, inserted


def _step(o, z, force, rng, noise):
    k, m = _loaded_at(force, o["at"]), o["recovery"]
    at = np.arange(k, min(k + m, force.size))
    force[at] -= o["drop"] * force[k] * np.linspace(1.0, 0.0, at.size + 1)[:-1]
    planted = np.zeros(force.size, dtype=bool)
    planted[at] = True
    return z, force, planted, np.zeros(force.size, dtype=bool)


def _burst(o, z, force, rng, noise):
    values = z if o["channel"] == "z_m" else force
    span = float(np.ptp(values))
    planted = np.zeros(values.size, dtype=bool)
    lo, hi = o["length"]
    for _ in range(o["count"]):
        length = int(rng.integers(lo, hi + 1))
        reach = 2 * length if o["cluster"] else length
        start = int(rng.integers(8, max(9, values.size - reach - 8)))
        at = start + (2 * np.arange(length) if o["cluster"] else np.arange(length))
        at = at[at < values.size - 4]
        if planted[max(0, start - 6) : start + reach + 6].any():
            continue  # keep bursts apart: each needs good samples on both sides
        values[at] += rng.choice([-1.0, 1.0]) * o["size"] * span
        planted[at] = True
    return z, force, planted, np.zeros(values.size, dtype=bool)


def _glitch_cluster(o, z, force, rng, noise):
    """Dense clusters: every sample of a run jumps to ``times`` x the record's depth (or peak
    force) and the record comes back after it, inside the record (8 good samples at least
    on each side); a record's clusters together hold at most a quarter of its samples."""
    values = z if o["channel"] == "z_m" else force
    top = float(np.abs(values).max())
    planted = np.zeros(values.size, dtype=bool)
    lo, most = o["length"]
    budget = values.size // 4  # all clusters of a record together: a quarter at most
    for _ in range(o["count"]):
        hi = min(most, budget - int(planted.sum()))
        if hi < lo or values.size - hi - 16 <= 8:
            break  # a record too short for (another) cluster of this length
        length = int(rng.integers(lo, hi + 1))
        start = int(rng.integers(8, values.size - length - 8))
        if planted[max(0, start - 8) : start + length + 8].any():
            continue  # keep clusters apart: each needs good samples on both sides
        at = np.arange(start, start + length)
        values[at] = rng.uniform(*o["times"], size=length) * top
        if o["channel"] == "force_N":
            values[at] += noise * rng.standard_normal(length)
        planted[at] = True
    return z, force, planted, np.zeros(values.size, dtype=bool)


_PLANTERS = {
    "release": _release,
    "hold": _hold,
    "unload-reload": _unload_reload,
    "step": _step,
    "burst": _burst,
    "glitch-cluster": _glitch_cluster,
}
