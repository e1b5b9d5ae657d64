"""Prediction of measured runs for :func:`~soilstats.wheel.validation.validate_wheel`: each run
at its own measured load and slip through the Wong–Reece model over the draws, and the runs
frame (measured beside predicted, which runs have no prediction and why)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from .geometry import Wheel
from .solve import wheel_forces
from .stress import StressAngles

__all__ = ["predict_runs"]


def draws_subset(params: Mapping[str, Any], use: np.ndarray) -> dict[str, np.ndarray]:
    """The parameter draws ``use`` (a mask: those a wheel's modulus check kept)."""
    return {k: v[use] for k, v in params["values"].items()}


def predict_runs(
    values: Mapping[str, np.ndarray],
    wheel: Wheel,
    slip: ArrayLike,
    load: ArrayLike,
    law: str,
    angles: StressAngles | None,
    prob: float,
    shift: ArrayLike | None = None,
) -> dict:
    """Bands of sinkage (and drawbar pull, torque with shear) for runs of one wheel.

    ``values``: parameter arrays (P draws); ``slip``, ``load``: per run (R).  Returns arrays
    of length R: ``{quantity}_{median,lower,upper}`` (``lower``, ``upper``: the
    (1 − prob)/2 and (1 + prob)/2 quantiles), ``n_used``, ``n_not_carried``.
    """
    state = wheel_forces(
        values,
        wheel,
        np.asarray(slip, float),
        law=law,
        load_N=np.asarray(load, float)[None, :],
        angles=angles,
        exponent_shift=None if shift is None else np.asarray(shift, float)[None, :],
    )
    ok = state.status == 0
    out = {"n_used": ok.sum(0), "n_not_carried": (state.status == 1).sum(0)}
    q = [(1 - prob) / 2, 0.5, (1 + prob) / 2]
    quantities = {"sinkage": state.sinkage_m}
    if state.with_shear:
        quantities |= {"drawbar_pull": state.drawbar_pull_N, "torque": state.torque_Nm}
    some = out["n_used"] > 0
    for name, values_ in quantities.items():
        bands = np.full((3, ok.shape[1]), np.nan)
        if some.any():
            bands[:, some] = np.nanquantile(values_[:, some], q, axis=0)
        for key, row in zip(("lower", "median", "upper"), bands, strict=True):
            out[f"{name}_{key}"] = row
    return out


def predict_all_runs(
    table: pd.DataFrame,
    params: Mapping[str, Any],
    wheels: Mapping[str, Wheel],
    law: str,
    angles: StressAngles,
    prob: float,
    checks: Mapping[str, dict],
    bar: Any,  # a tqdm bar (or any object with update())
) -> pd.DataFrame:
    """The bands of every run (``table``), each wheel's runs from its kept draws."""
    parts = []
    for name, rows in table.groupby("wheel", sort=True):
        values = draws_subset(params, checks[name]["use"])  # type: ignore[index]  # pandas-stubs: a groupby key is any scalar (here a wheel name)
        band = predict_runs(values, wheels[name], rows["slip"], rows["W_N"], law, angles, prob)  # type: ignore[index]  # pandas-stubs: as above
        parts.append(pd.DataFrame(band, index=rows.index))
        bar.update()
    return pd.concat(parts).loc[table.index]


def runs_frame(
    table: pd.DataFrame, predicted: pd.DataFrame, notes: list[str]
) -> tuple[pd.DataFrame, list[dict]]:
    """The runs' table with their predicted bands, and the runs left out (with why)."""
    f = pd.DataFrame(
        {
            "run_id": table["run_id"],
            "row": table["row"],
            "wheel": table["wheel"],
            "slip": table["slip"],
            "slip_level": table["slip_level"],
            "beta_deg": table["beta_deg"],
            "beta_level": table["beta_level"],
            "date": table["date"] if "date" in table else "",
            "W_N": table["W_N"],
            "steady": table["steady"],
            "sinkage_measured_m": table["sinkage_m"],
            "sinkage_median_m": predicted["sinkage_median"],
            "sinkage_lower_m": predicted["sinkage_lower"],
            "sinkage_upper_m": predicted["sinkage_upper"],
            "n_draws_used": predicted["n_used"].astype(int),
            "n_not_carried": predicted["n_not_carried"].astype(int),
        }
    ).reset_index(drop=True)
    f["predicted"] = f["n_draws_used"] > 0
    f["in_scope"] = f["predicted"] & (f["beta_level"] == 0)
    f["residual_m"] = f["sinkage_measured_m"] - f["sinkage_median_m"]
    f["sinkage_covered"] = (f["sinkage_lower_m"] <= f["sinkage_measured_m"]) & (
        f["sinkage_measured_m"] <= f["sinkage_upper_m"]
    )
    if "drawbar_pull_median" in predicted:
        for key in ("median", "lower", "upper"):
            f[f"drawbar_pull_{key}_N"] = predicted[f"drawbar_pull_{key}"].to_numpy()
            f[f"torque_{key}_Nm"] = predicted[f"torque_{key}"].to_numpy()
        for column, unit in (("drawbar_pull", "N"), ("torque", "Nm")):
            measured = f"{column}_N" if unit == "N" else "torque_Nm"
            if measured in table:
                f[f"{column}_measured_{unit}"] = table[measured].to_numpy()
                m = f[f"{column}_measured_{unit}"]
                f[f"{column}_covered"] = np.where(
                    m.notna(),
                    (f[f"{column}_lower_{unit}"] <= m) & (m <= f[f"{column}_upper_{unit}"]),
                    np.nan,
                )
    excluded = []
    lost = f.loc[~f["predicted"], "run_id"].tolist()
    if lost:
        excluded.append(
            {
                "reason": "no draw can carry the run's load within θ1 < 90° (sinkage < r_s): "
                "nothing to compare",
                "runs": lost,
            }
        )
        notes.append(
            f"{len(lost)} runs have no prediction (no draw carries their load): {lost[:5]}"
        )
    partial = f[f["predicted"] & (f["n_not_carried"] > 0)]
    if len(partial):
        notes.append(
            f"{len(partial)} runs have draws that cannot carry their load (up to "
            f"{int(partial['n_not_carried'].max())} of {int(f['n_draws_used'].max())}); their "
            "bands are over the draws that can (n_not_carried per run)"
        )
    beta = f.loc[f["predicted"] & (f["beta_level"] != 0), "run_id"].tolist()
    if beta:
        excluded.append(
            {
                "reason": "slip angle β ≠ 0: outside the longitudinal model; predicted as if "
                "β = 0 and reported per β, left out of the headline coverage",
                "runs": beta,
            }
        )
    return f, excluded
