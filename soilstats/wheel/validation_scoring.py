"""Scoring of the predicted runs: coverage of the band and bias (predicted − measured), per
wheel type, slip condition, slip angle and day (the groups table), the headline coverage and
bias, and the bias trend against slip and slip angle."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from .band_scores import BandColumns, score_bands

__all__ = ["GROUPINGS", "NEAR_ZERO"]

#: Slip conditions within this of 0 are "near zero slip".
NEAR_ZERO = 0.05


#: The columns of one quantity's band in the runs table: {prefix}_{column}_{unit}.
_BAND = ("measured", "median", "lower", "upper")


def _summ(rows: pd.DataFrame, prefix: str = "sinkage", unit: str = "m") -> dict:
    """Coverage and bias of the plate-only bands of ``prefix`` (columns
    ``{prefix}_measured_{unit}``, ``_median_``, ``_lower_``, ``_upper_``;
    :func:`soilstats.wheel.band_scores.score_bands`)."""
    s = score_bands(rows, BandColumns(*(f"{prefix}_{c}_{unit}" for c in _BAND)))
    return {
        "runs": s.runs,
        "covered": s.covered,
        "coverage_90": s.coverage,
        f"bias_{unit}": s.bias,
        f"median_bias_{unit}": s.median_bias,
        f"mae_{unit}": s.mae,
        f"measured_mean_{unit}": s.measured_mean,
        f"predicted_mean_{unit}": s.predicted_mean,
    }


GROUPINGS = (
    ("wheel", "β = 0", ("wheel",)),
    ("wheel", "all runs", ("wheel",)),
    ("wheel × slip", "β = 0", ("wheel", "slip_level")),
    ("wheel × β", "all runs", ("wheel", "beta_level")),
    ("wheel × day", "β = 0", ("wheel", "date")),
    ("wheel × day", "all runs", ("wheel", "date")),
)


def group_scores(frame: pd.DataFrame, with_dp: bool) -> pd.DataFrame:
    """Coverage and bias per grouping (:data:`GROUPINGS`) of the predicted runs."""
    rows = []
    quantities = [("sinkage", "m")]
    if with_dp and "drawbar_pull_measured_N" in frame:
        quantities.append(("drawbar_pull", "N"))
    for quantity, unit in quantities:
        for by, scope, keys in GROUPINGS:
            if quantity != "sinkage" and scope != "β = 0":
                continue
            chosen = frame[frame["in_scope"]] if scope == "β = 0" else frame[frame["predicted"]]
            for key, sub in chosen.groupby(list(keys), sort=True):
                key = key if isinstance(key, tuple) else (key,)
                s = _summ(sub, quantity, unit)
                rows.append(
                    {
                        "quantity": quantity,
                        "by": by,
                        "scope": scope,
                        "wheel": key[0],
                        "level": "all" if len(key) == 1 else key[1],
                        "runs": s["runs"],
                        "covered": s["covered"],
                        "coverage_90": s["coverage_90"],
                        "bias": s[f"bias_{unit}"],
                        "mae": s[f"mae_{unit}"],
                        "measured_mean": s[f"measured_mean_{unit}"],
                        "predicted_mean": s[f"predicted_mean_{unit}"],
                        "unit": unit,
                    }
                )
    return pd.DataFrame(rows)


def _trend(rows: pd.DataFrame, x: str) -> dict:
    """Least-squares slope of the bias (predicted − measured) against ``x``, with its SE."""
    xv = rows[x].to_numpy(float)
    y = (rows["sinkage_median_m"] - rows["sinkage_measured_m"]).to_numpy(float)
    if len(y) < 3 or np.ptp(xv) == 0:
        return {"slope": np.nan, "stderr": np.nan, "runs": len(y)}
    design = np.column_stack([np.ones_like(xv), xv])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    resid = y - design @ coef
    s2 = float(resid @ resid) / (len(y) - 2)
    cov = s2 * np.linalg.inv(design.T @ design)
    return {"slope": float(coef[1]), "stderr": float(np.sqrt(cov[1, 1])), "runs": len(y)}


def headline_scores(frame: pd.DataFrame, groups: pd.DataFrame) -> tuple[dict, dict]:
    """(coverage, bias): the headline figures of the validation."""
    scope, every = frame[frame["in_scope"]], frame[frame["predicted"]]
    near = scope[scope["slip_level"].abs() <= NEAR_ZERO]
    coverage: dict[str, Any] = {
        "definition": "share of runs whose measured sinkage lies inside the predicted band "
        "(5 %–95 % quantiles of the draws at the run's own measured load W)",
        "scope": "β = 0 runs (the longitudinal model's domain); all_runs includes β ≠ 0",
        "beta_0": _pick(_summ(scope), "coverage"),
        "all_runs": _pick(_summ(every), "coverage"),
        "near_zero_slip_beta_0": _pick(_summ(near), "coverage"),
        "by_wheel": {},
    }
    bias: dict[str, Any] = {
        "definition": "predicted median − measured sinkage [m]; > 0: the model sinks too deep",
        "beta_0": _pick(_summ(scope), "bias"),
        "all_runs": _pick(_summ(every), "bias"),
        "near_zero_slip_beta_0": _pick(_summ(near), "bias"),
        "by_wheel": {},
        "trend": [],
    }
    for wheel in sorted(frame["wheel"].unique()):
        ws, wa, wn = (d[d["wheel"] == wheel] for d in (scope, every, near))
        coverage["by_wheel"][wheel] = {
            "beta_0": _pick(_summ(ws), "coverage"),
            "all_runs": _pick(_summ(wa), "coverage"),
            "near_zero_slip_beta_0": _pick(_summ(wn), "coverage"),
        }
        bias["by_wheel"][wheel] = {
            "beta_0": _pick(_summ(ws), "bias"),
            "all_runs": _pick(_summ(wa), "bias"),
            "near_zero_slip_beta_0": _pick(_summ(wn), "bias"),
        }
        for label, rows, x, unit in (
            ("slip, driving (s ≥ 0, β = 0)", ws[ws["slip"] >= -0.01], "slip", "m per unit slip"),
            ("slip, skid (s ≤ 0, β = 0)", ws[ws["slip"] <= 0.01], "slip", "m per unit slip"),
            ("slip angle β (all slips)", wa, "beta_deg", "m per degree"),
        ):
            bias["trend"].append({"wheel": wheel, "against": label, "unit": unit} | _trend(rows, x))
    if "drawbar_pull_measured_N" in frame:
        coverage["drawbar_pull_beta_0"] = {
            wheel: _pick(_summ(scope[scope["wheel"] == wheel], "drawbar_pull", "N"), "coverage")
            for wheel in sorted(frame["wheel"].unique())
        }
        bias["drawbar_pull_beta_0"] = {
            wheel: _pick(_summ(scope[scope["wheel"] == wheel], "drawbar_pull", "N"), "bias", "N")
            for wheel in sorted(frame["wheel"].unique())
        }
    return coverage, bias


def _pick(summary: dict, what: str, unit: str = "m") -> dict:
    if what == "coverage":
        return {k: summary[k] for k in ("runs", "covered", "coverage_90")}
    return {
        "runs": summary["runs"],
        f"mean_{unit}": summary[f"bias_{unit}"],
        f"median_{unit}": summary[f"median_bias_{unit}"],
        f"mae_{unit}": summary[f"mae_{unit}"],
        f"measured_mean_{unit}": summary[f"measured_mean_{unit}"],
        f"predicted_mean_{unit}": summary[f"predicted_mean_{unit}"],
    }
