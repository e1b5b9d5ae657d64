"""The slip-angle model against the CMU runs at s ≈ 0: a sanity figure, not a target.

``python benchmarks/wheel_slip_angle_cmu.py [--slip-max 0.05] [--all-slips]``

Every run of ``cmu-3d-terramechanics/wheel.csv`` with |s| ≤ ``--slip-max`` (s ≈ 0) is
predicted at its own measured W, slip and commanded β with one plate-like soil, the CMU
authors' constants of ``docs/wheel.md`` (Bernstein k = 8e6 N/m^(n+2), n = 1.46, c = 1 kPa,
φ = 29°, K = 0.021 m; γ = 1330·9.81 N/m³, K_y = K), the default stress angles
(θm/θ1 = 0.4 + 0.15 s, θ2 = 0; ``--cmu-angles``: CMU's tuned β = 0 angles, held at every β)
and the wheels of ``wheels.toml`` (smooth r = 58 mm; grouser
r_s = 63 mm, μ = 0.1).  The constants were hand-tuned by CMU on these runs at β = 0 (K, c, n),
so even the β = 0 rows are not independent; β ≠ 0 was never used for them.  Prints, per
wheel and β: runs, measured / predicted lateral force and sinkage (means), and the sinkage the
same runs get with β set to 0 (what the slip-angle terms change); ``fy_at_h_N`` and ``W_at_h_N``
are the lateral force and vertical load the model gives at the *measured* sinkage (NaN where it
exceeds r_s: the model's contact ends at θ1 = 90°).
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from soilstats.data import bundled_path
from soilstats.wheel import LateralSoil, StressAngles, Wheel, wheel_forces

DATA = bundled_path("cmu-3d-terramechanics") / "wheel.csv"
SOIL = {"k": 8e6, "n": 1.46, "c": 1000.0, "phi": 29.0, "K": 0.021}
WHEELS = {
    "smooth": Wheel(radius_m=0.058, width_m=0.05, name="smooth"),
    "grouser": Wheel(0.058, 0.05, shear_radius_m=0.063, grouser_area_ratio=0.1, name="grouser"),
}


#: CMU's tuned β = 0 stress angles per wheel (wheel.md of the data; tuned on these runs).
CMU_BETA0_ANGLES = {
    "smooth": StressAngles(0.202, 0.705, -0.476, 0.0),
    "grouser": StressAngles(0.273, 0.673, -0.664, -0.177),
}


def predict(runs: pd.DataFrame, cmu_angles: bool = False) -> pd.DataFrame:
    out = []
    for name, wheel in WHEELS.items():
        sub = runs[runs["wheel"] == name].copy()
        angles = CMU_BETA0_ANGLES[name] if cmu_angles else StressAngles()
        kw = {
            "law": "bernstein",
            "load_N": sub["W_N"].to_numpy(),
            "lateral": LateralSoil(),
            "angles": angles,
        }
        slip = sub["slip"].to_numpy()
        st = wheel_forces(SOIL, wheel, slip, slip_angle_deg=sub["beta_cmd_deg"].to_numpy(), **kw)
        st0 = wheel_forces(SOIL, wheel, slip, **kw)
        sub["fy_pred_N"] = st.lateral_force_N
        sub["fy_side_N"] = st.side_force_N
        sub["dp_pred_N"] = st.drawbar_pull_N
        sub["h_pred_mm"] = 1e3 * st.sinkage_m
        sub["h_beta0_mm"] = 1e3 * st0.sinkage_m
        sub["h_mm"] = 1e3 * sub["sinkage_m"]
        # the force terms alone: at the measured sinkage (where it lies within θ1 ≤ 90°)
        h = sub["sinkage_m"].to_numpy()
        inside = h <= wheel.contact_radius_m
        at_h = {k: v for k, v in kw.items() if k != "load_N"}
        sub["fy_at_h_N"] = np.nan
        sub["W_at_h_N"] = np.nan
        if inside.any():
            sh = wheel_forces(
                SOIL,
                wheel,
                slip[inside],
                slip_angle_deg=sub["beta_cmd_deg"].to_numpy()[inside],
                sinkage_m=h[inside],
                **at_h,
            )
            sub.loc[inside, "fy_at_h_N"] = sh.lateral_force_N
            sub.loc[inside, "W_at_h_N"] = sh.load_N
        out.append(sub)
    return pd.concat(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slip-max", type=float, default=0.05)
    ap.add_argument("--all-slips", action="store_true", help="every slip, grouped by β")
    ap.add_argument(
        "--cmu-angles",
        action="store_true",
        help="CMU's tuned β = 0 stress angles per wheel instead of the defaults",
    )
    ap.add_argument("--smoke", action="store_true", help="two runs per wheel and β: seconds")
    args = ap.parse_args()
    runs = pd.read_csv(DATA)
    if not args.all_slips:
        runs = runs[np.abs(runs["slip"]) <= args.slip_max]
    if args.smoke:
        runs = runs.groupby(["wheel", "beta_cmd_deg"]).head(2)
    pred = predict(runs, args.cmu_angles)
    table = (
        pred.groupby(["wheel", "beta_cmd_deg"])
        .agg(
            runs=("run_id", "size"),
            W_N=("W_N", "mean"),
            fy_meas_N=("lateral_force_N", "mean"),
            fy_pred_N=("fy_pred_N", "mean"),
            fy_side_N=("fy_side_N", "mean"),
            fy_at_h_N=("fy_at_h_N", "mean"),
            W_at_h_N=("W_at_h_N", "mean"),
            dp_meas_N=("drawbar_pull_N", "mean"),
            dp_pred_N=("dp_pred_N", "mean"),
            h_meas_mm=("h_mm", "mean"),
            h_pred_mm=("h_pred_mm", "mean"),
            h_beta0_mm=("h_beta0_mm", "mean"),
        )
        .round(2)
    )
    with pd.option_context("display.width", 160, "display.max_columns", 20):
        print(table)
    for name, sub in pred.groupby("wheel"):
        b = sub[sub["beta_cmd_deg"] > 0]
        slope_meas = np.polyfit(b["beta_cmd_deg"], b["h_mm"], 1)[0]
        slope_pred = np.polyfit(b["beta_cmd_deg"], b["h_pred_mm"], 1)[0]
        ratio = (b["fy_pred_N"] / b["lateral_force_N"]).median()
        print(
            f"{name}: sinkage trend with β (β > 0) measured {slope_meas:+.3f}, predicted "
            f"{slope_pred:+.3f} mm/deg; lateral force predicted/measured median {ratio:.2f}"
        )


if __name__ == "__main__":
    main()
