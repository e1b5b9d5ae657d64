"""The report data of a wheel validation: the sensitivity checks (Bekker's b, a rear contact),
the notes that say where the soil came from and what the model leaves out, and the caveats
read from the runs (unsteady sinkage)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from .stress import StressAngles
from .validation_predict import predict_runs
from .validation_scoring import NEAR_ZERO

if TYPE_CHECKING:
    import pandas as pd

    from .geometry import Wheel
    from .soil import PlateDraws

__all__ = ["SENSITIVITY_DRAWS"]

#: Draws used for the sensitivity checks (medians only).
SENSITIVITY_DRAWS = 500


# -- sensitivity -------------------------------------------------------------------------------
def sensitivity_checks(
    frame: pd.DataFrame,
    params: Mapping[str, Any],
    wheels: Mapping[str, Wheel],
    law: str,
    angles: StressAngles,
    seed: int,
) -> list[dict]:
    """Near-zero-slip β = 0 runs under other choices: Bekker's b, rear contact."""
    near = frame[frame["in_scope"] & (frame["slip_level"].abs() <= NEAR_ZERO)]
    if near.empty:
        return []
    n = len(next(iter(params["values"].values())))
    pick = np.random.default_rng([int(seed), 0x5703]).permutation(n)[: min(n, SENSITIVITY_DRAWS)]
    cases: list[tuple[str, float | None, StressAngles]] = [("as predicted", None, angles)]
    if law == "bekker":
        cases.append(("Bekker b = half the wheel width", 0.5, angles))
    rear = StressAngles(angles.a0, angles.a1, -0.5, 0.0)
    cases.append(("rear contact θ2 = −0.5 θ1 (exit behind the bottom)", None, rear))
    out = []
    for label, factor, ang in cases:
        for name, wheel in wheels.items():
            rows = near[near["wheel"] == name]
            if rows.empty:
                continue
            values = {k: v[pick] for k, v in params["values"].items()}
            b = wheel.width_m * (factor or 1.0)
            nonpositive = 0
            if factor is not None:  # kc/b' + kφ on the wheel's own contact width
                values["kc"] = values["kc"] * wheel.width_m / b
                nonpositive = int(np.sum(values["kc"] / wheel.width_m + values["kphi"] <= 0))
                keep = values["kc"] / wheel.width_m + values["kphi"] > 0
                values = {k: v[keep] for k, v in values.items()}
            band = predict_runs(values, wheel, rows["slip"], rows["W_N"], law, ang, 0.9)
            pred = band["sinkage_median"]
            if not np.isfinite(pred).any():
                continue
            out.append(
                {
                    "case": label,
                    "wheel": name,
                    "law_b_m": b,
                    "angles": ang.to_dict(),
                    "runs": len(rows),
                    "measured_mean_m": float(rows["sinkage_measured_m"].mean()),
                    "predicted_mean_m": float(np.nanmean(pred)),
                    "bias_m": float(np.nanmean(pred - rows["sinkage_measured_m"].to_numpy())),
                    "modulus_nonpositive": nonpositive,
                    "draws": len(next(iter(values.values()))),
                }
            )
    return out


# -- notes -------------------------------------------------------------------------------------
def validation_notes(
    plate: PlateDraws,
    params: Mapping[str, Any],
    wheels: Mapping[str, Wheel],
    law: str,
    angles: StressAngles,
    frame: pd.DataFrame,
    priors: Mapping[str, tuple] | None,
) -> list[str]:
    """The validation's notes: where the soil came from, how runs are predicted."""
    notes = [
        f"Soil from the plate tests only ({plate.n_tests} tests of {plate.soil!r}, {law} law): "
        f"{plate.reason}. {len(plate.draws)} draws through the model; no wheel run enters them.",
        "Each run is predicted at its own measured load W and slip; the model is the Wong–Reece "
        "rigid wheel (docs/wheel.md), longitudinal only: β ≠ 0 runs are predicted as if β = 0.",
        f"Stress angles θm/θ1 = {angles.a0:g} + {angles.a1:g}·s, θ2/θ1 = {angles.b0:g} + "
        f"{angles.b1:g}·s (stated inputs, not measured here; defaults of Ishigami et al. 2007).",
    ]
    if law == "bekker":
        widths = ", ".join(f"{n} {1e3 * w.width_m:g} mm" for n, w in wheels.items())
        sizes = plate.plate_sizes_m
        span = f" (plates b = {1e3 * min(sizes):g}–{1e3 * max(sizes):g} mm)" if sizes else ""
        notes.append(
            f"Bekker's b for the wheel is its width ({widths}){span}: the smaller side of the "
            "rectangular contact, as in Wong & Reece (1967) and Wong (2008, ch. 2); a circle's b "
            "is its radius (Eq. 7)."
        )
    if not priors:
        notes.append(
            "Drawbar pull and torque are NOT predicted: no shear test measured c, φ, K and no "
            "prior was given; the sinkage rests on the normal stress alone (τ·sin θ left out of W)."
        )
    return notes


def run_caveats(frame: pd.DataFrame) -> list[str]:
    """Caveats the runs themselves raise (not steady in their averaging window)."""
    unsteady = frame.loc[~frame["steady"], "run_id"].tolist()
    out = []
    if unsteady:
        levels = sorted(frame.loc[~frame["steady"], "beta_level"].unique())
        out.append(
            f"{len(unsteady)} runs still sink faster than 0.1 mm/s in their averaging window "
            f"(β = {', '.join(f'{b}°' for b in levels)}): not steady, their sinkage is a "
            "snapshot."
        )
    return out
