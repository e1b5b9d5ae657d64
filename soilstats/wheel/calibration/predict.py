"""A rover team's own wheel: bands against slip, the stall probability, the slip for a pull.

:func:`predict_own_wheel` predicts sinkage, drawbar pull and torque for a wheel of given
geometry at a given load over a grid of slips, from

* a saved calibration (:class:`~.result.WheelCalibration`): its posterior draws and its
  discrepancy (the wheel part τ_w at full variance for a wheel type it never saw); or
* the plate draws alone: every uncertain input of :mod:`.inputs` drawn from its stated prior
  (never fixed), the shear from stated priors, and — only when asked — a stated discrepancy
  prior (:data:`CMU_DISCREPANCY`, learned on the CMU runs and named as such).  Without it the
  band is **parameter uncertainty only**, which on the CMU runs covered 17 % of the measured
  β = 0 runs (issue #43): the result says so.

From the joint draws: the probability that drawbar pull is negative at each slip (the wheel
cannot pull itself: a rover stalls) and, for a requested pull, the smallest slip that gives it
per draw, summarised as a band (draws that never reach it counted apart).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...bayes.stated_priors import sample_priors
from ...errors import InputError
from ..geometry import Wheel
from .discrepancy import Discrepancy
from .inputs import SHEAR_INPUTS, WHEEL_INPUTS, InputPrior, input_priors
from .physics import RunDesign, simulate
from .result import WheelCalibration, quantiles

__all__ = ["CMU_DISCREPANCY", "OwnWheelPrediction", "predict_own_wheel"]

#: The error of the plates-only model on the CMU sand and wheels, as a Gaussian process
#: fitted to its β = 0 sinkage residuals (54 runs, both wheels; type-II maximum likelihood,
#: σ floored at the runs' repeat scatter 0.66 mm; ``fit_discrepancy`` on measured − plate-only
#: median, seed 0, 2026-11-29).  Offered to a plates-only prediction as a *stated prior*
#: (``--discrepancy-prior cmu``), zero-mean: its width only (sd √(τ² + τ_w² + σ²) ≈ 29 mm for
#: a new wheel), not the CMU wheels' error shape.  Sinkage only: the plates predict no force.
CMU_DISCREPANCY: dict[str, Discrepancy] = {
    "sinkage_m": Discrepancy("sinkage_m", 0.0204, 0.55, 360.0, 0.00079, 0.0212),
}
UNITS = {"sinkage_m": "m", "drawbar_pull_N": "N", "torque_Nm": "N·m", "lateral_force_N": "N"}


@dataclass(frozen=True, eq=False)
class OwnWheelPrediction:
    """Bands per slip, stall probability, slip for a pull, sources, and the joint draws.

    ``bands``: slip, quantity, unit, median, lower, upper, not_carried.  ``draws``: one row
    per (draw, slip) with every quantity — the joint draws for a rover Monte Carlo.
    ``band_kind`` says what the band holds.
    """

    wheel: Wheel
    load_N: float
    slip_angle_deg: float
    bands: pd.DataFrame
    p_drawbar_pull_negative: pd.DataFrame
    slip_for_pull: dict | None
    sources: dict[str, str]
    band_kind: str
    notes: list[str]
    draws: pd.DataFrame = field(repr=False)

    def to_dict(self) -> dict:
        return {
            "wheel": self.wheel.to_dict(),
            "load_N": self.load_N,
            "slip_angle_deg": self.slip_angle_deg,
            "band_kind": self.band_kind,
            "bands": self.bands.to_dict("records"),
            "p_drawbar_pull_negative": self.p_drawbar_pull_negative.to_dict("records"),
            "slip_for_pull": self.slip_for_pull,
            "sources": self.sources,
            "notes": self.notes,
        }

    def summary(self) -> str:
        lines = [
            f"Wheel {self.wheel.describe()} at W = {self.load_N:g} N, β = "
            f"{self.slip_angle_deg:g}°: {self.band_kind}",
            "",
            f"{'slip':>6} {'quantity':<16} {'median':>10} {'lower':>10} {'upper':>10}",
        ]
        for r in self.bands.itertuples():
            scale = 1e3 if r.unit == "m" else 1.0
            unit = "mm" if r.unit == "m" else r.unit
            lines.append(
                f"{r.slip:>6.2f} {r.quantity:<16} {scale * r.median:>10.3g} "  # type: ignore[operator]  # pandas-stubs: an itertuples field is any scalar
                f"{scale * r.lower:>10.3g} {scale * r.upper:>10.3g} {unit}"  # type: ignore[operator, str-bytes-safe]  # pandas-stubs: an itertuples field is any scalar
            )
        if len(self.p_drawbar_pull_negative):
            lines.append("")
            lines.append("P(drawbar pull < 0) — the wheel cannot pull itself:")
            lines += [
                f"  s = {r.slip:.2f}: {r.p:.2f}" for r in self.p_drawbar_pull_negative.itertuples()
            ]
        if self.slip_for_pull:
            s = self.slip_for_pull
            lines.append("")
            lines.append(
                f"slip for a pull of {s['pull_N']:g} N: median {s['median']:.3g} "
                f"[{s['lower']:.3g}, {s['upper']:.3g}]; {100 * s['p_unreachable']:.0f} % of "
                "draws never reach it on the grid"
            )
        lines += ["", "sources:"] + [f"  {k}: {v}" for k, v in self.sources.items()]
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)


def _grid_design(wheel: Wheel, load_N: float, slips: np.ndarray, beta: float) -> RunDesign:
    n = len(slips)
    return RunDesign(
        run_id=np.array([f"s={s:g}" for s in slips]),
        wheel=np.full(n, wheel.name),
        slip=slips,
        beta_deg=np.full(n, beta),
        load_N=np.full(n, load_N),
        slip_level=slips,
        beta_level=np.full(n, beta),
        measured={},
    )


def predict_own_wheel(
    wheel: Wheel,
    load_N: float,
    slips: Sequence[float] | np.ndarray,
    *,
    calibration: WheelCalibration | None = None,
    plate_draws: pd.DataFrame | None = None,
    law: str | None = None,
    priors: Mapping[str, Sequence] | None = None,
    discrepancy_prior: Mapping[str, Discrepancy] | None = None,
    wheel_amplitude: Mapping[str, float] | None = None,
    slip_angle_deg: float = 0.0,
    pull_N: float | None = None,
    n_draws: int = 2000,
    prob: float = 0.9,
    seed: int = 0,
    plate_source: str = "plate posterior draws",
) -> OwnWheelPrediction:
    """Predict a wheel of given geometry over ``slips`` (module docstring).

    Give ``calibration``, or ``plate_draws`` and ``law``.  ``priors`` states c [Pa], φ [deg],
    K [m] (and may replace any input prior); without them and without a calibration that
    carries the shear, drawbar pull and torque are not predicted.
    """
    grid = np.asarray(slips, float)
    if (
        grid.ndim != 1
        or grid.size == 0
        or np.any(np.abs(grid) > 1)
        or not np.all(np.isfinite(grid))
    ):
        raise InputError(f"slips must be finite values in [-1, 1], got {slips!r}")
    if not (np.isfinite(load_N) and load_N > 0):
        raise InputError(f"the load must be a positive force in N, got {load_N!r}")
    if not (np.isfinite(slip_angle_deg) and abs(slip_angle_deg) <= 90):
        raise InputError(f"the slip angle must lie in [-90, 90] degrees, got {slip_angle_deg!r}")
    design = _grid_design(wheel, float(load_N), grid, float(slip_angle_deg))
    if calibration is not None:
        samples, band_kind, sources, notes = _calibrated(
            calibration, design, wheel, n_draws, seed, wheel_amplitude
        )
    else:
        if plate_draws is None or law is None:
            raise InputError("give a calibration, or plate draws and their law")
        samples, band_kind, sources, notes = _plates_only(
            design,
            wheel,
            plate_draws,
            law,
            priors,
            discrepancy_prior,
            n_draws,
            seed,
            plate_source,
        )
    return _result(
        wheel,
        float(load_N),
        float(slip_angle_deg),
        grid,
        samples,
        prob,
        pull_N,
        sources,
        band_kind,
        notes,
    )


def _calibrated(
    calibration: WheelCalibration,
    design: RunDesign,
    wheel: Wheel,
    n_draws: int,
    seed: int,
    wheel_amplitude: Mapping[str, float] | None,
) -> tuple[dict[str, np.ndarray], str, dict[str, str], list[str]]:
    """Draws from a saved calibration: its posterior and discrepancy, the datum left out."""
    samples = calibration.samples(
        design,
        wheels={wheel.name: wheel},
        n_draws=n_draws,
        seed=seed,
        wheel_amplitude=wheel_amplitude,
        datum=False,
    )
    seen = wheel.name in set(calibration.design.wheel)
    band_kind = (
        "calibrated on measured runs: parameter uncertainty, the model discrepancy "
        + (
            "of this wheel type"
            if seen
            else "(shared part; this wheel type was not in the "
            "calibration, its own part at full variance τ_w)"
        )
        + " and the repeat scatter"
    )
    sources = {
        p.name: f"calibration posterior (prior {p.describe()}: {p.source})"
        for p in calibration.layout.inputs
    }
    sources["plate law"] = f"calibration posterior (prior: {calibration.layout.plate.source})"
    notes = [
        f"{q} was not measured in the calibration: its band is parameter uncertainty only"
        for q in calibration.uncalibrated
    ]
    return samples, band_kind, sources, notes


def _plates_only(
    design, wheel, plate_draws, law, priors, discrepancy_prior, n_draws, seed, plate_source
):
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(plate_draws), size=n_draws, replace=len(plate_draws) < n_draws)
    params = {k: plate_draws[k].to_numpy(float)[pick] for k in plate_draws.columns}
    stated = input_priors({k: v for k, v in (priors or {}).items()})
    shear = all(k in (priors or {}) for k in ("c", "phi", "K"))
    sources = {k: plate_source for k in plate_draws.columns}
    for name in WHEEL_INPUTS + (SHEAR_INPUTS if shear else ()):
        if name == "datum_mm":  # how runs were measured, not a property of a wheel
            params[name] = np.zeros(n_draws)
            continue
        p = stated[name]
        params[name] = _draw(p, n_draws, rng)
        sources[name] = f"prior {p.describe()} ({p.source})"
    with np.errstate(all="ignore"):
        out = simulate(params, design, {wheel.name: wheel}, law, n_nodes=16, with_shear=shear)
    samples = {"sinkage_m": out["sinkage_m"]}
    if shear:
        samples.update(drawbar_pull_N=out["drawbar_pull_N"], torque_Nm=out["torque_Nm"])
        if np.any(design.beta_deg != 0):
            samples["lateral_force_N"] = out["lateral_force_N"]
    notes = []
    if not shear:
        notes.append(
            "drawbar pull and torque need c, φ and K: no calibration carries them and "
            "no prior states them (--prior c=… --prior phi=… --prior K=…)"
        )
    if discrepancy_prior:
        for q, d in discrepancy_prior.items():
            if q in samples:
                sd = np.sqrt(d.amplitude**2 + np.nan_to_num(d.wheel_amplitude) ** 2 + d.noise**2)
                samples[q] = samples[q] + sd * rng.standard_normal(samples[q].shape)
        kind = (
            "plates only, with the stated discrepancy prior learned on the CMU runs "
            "(zero mean, its width only)"
        )
    else:
        kind = (
            "PARAMETER UNCERTAINTY ONLY (plates and the stated input priors; no model "
            "discrepancy): on the CMU runs such a band covered 17 % of the measured β = 0 "
            "runs — add --discrepancy-prior cmu or calibrate on wheel runs"
        )
    return samples, kind, sources, notes


def _draw(p: InputPrior, size: int, rng: np.random.Generator) -> np.ndarray:
    if p.sd is None:
        return rng.uniform(p.low, p.high, size)
    spec = (
        "truncnormal",
        p.mean,
        p.sd,
        max(p.low, p.mean - 40 * p.sd),
        min(p.high, p.mean + 40 * p.sd),
    )
    return sample_priors({"x": spec}, size, int(rng.integers(2**31)))["x"]


def _result(wheel, load, beta, slips, samples, prob, pull_N, sources, band_kind, notes):
    tail = (1.0 - prob) / 2.0
    rows = []
    for q, y in samples.items():
        lo, med, hi = quantiles(y, (tail, 0.5, 1.0 - tail))
        for i, s in enumerate(slips):
            rows.append(
                {
                    "slip": float(s),
                    "quantity": q,
                    "unit": UNITS[q],
                    "median": med[i],
                    "lower": lo[i],
                    "upper": hi[i],
                    "not_carried": float(np.mean(~np.isfinite(y[:, i]))),
                }
            )
    bands = pd.DataFrame(rows)
    stall = pd.DataFrame(columns=["slip", "p"])
    pull = None
    if "drawbar_pull_N" in samples:
        dp = samples["drawbar_pull_N"]
        finite = np.isfinite(dp)
        stall = pd.DataFrame(
            {
                "slip": slips,
                "p": np.where(finite, dp < 0, False).sum(0) / np.maximum(finite.sum(0), 1),
            }
        )
        if pull_N is not None:
            pull = _slip_for_pull(dp, slips, float(pull_N), prob)
    draws = {
        "draw": np.repeat(np.arange(next(iter(samples.values())).shape[0]), len(slips)),
        "slip": np.tile(slips, next(iter(samples.values())).shape[0]),
    }
    draws.update({q: y.reshape(-1) for q, y in samples.items()})
    return OwnWheelPrediction(
        wheel, load, beta, bands, stall, pull, sources, band_kind, notes, pd.DataFrame(draws)
    )


def _slip_for_pull(dp: np.ndarray, slips: np.ndarray, pull: float, prob: float) -> dict:
    """Per draw, the smallest slip ≥ 0 of the grid (linear between grid points) with DP ≥ pull."""
    order = np.argsort(slips)
    s, y = slips[order], dp[:, order]
    keep = s >= 0
    s, y = s[keep], y[:, keep]
    found = np.full(len(y), np.nan)
    for i, row in enumerate(y):
        above = np.flatnonzero(row >= pull)
        if above.size == 0:
            continue
        k = above[0]
        if k == 0:
            found[i] = s[0]
        else:
            y0, y1 = row[k - 1], row[k]
            found[i] = s[k - 1] + (pull - y0) / (y1 - y0) * (s[k] - s[k - 1])
    tail = (1.0 - prob) / 2.0
    reached = found[np.isfinite(found)]
    lo, med, hi = (
        np.quantile(reached, [tail, 0.5, 1 - tail]) if reached.size else (np.nan, np.nan, np.nan)
    )
    return {
        "pull_N": pull,
        "median": float(med),
        "lower": float(lo),
        "upper": float(hi),
        "p_unreachable": float(1.0 - reached.size / len(found)),
    }
