"""What the model gets wrong, with the discipline of ``soilstats discover``: the findings of the
residual tests, the slip-dependent exponent fitted per wheel type on the β = 0 runs, its gain
measured only on runs the fit did not see (whole slip conditions, whole days left out), and
where it still fails."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from .. import evidence
from .discovery import READINGS
from .geometry import Wheel
from .slipsinkage import SlipExponent, fit_slip_exponent
from .stress import StressAngles
from .validation_predict import draws_subset, predict_runs
from .validation_result import WheelDiscovery, with_old_band_columns

if TYPE_CHECKING:
    from ..discovery.crossval import Gain

__all__ = ["CMU_TUNED", "EXTENSION", "METRIC", "SCHEMES"]

#: Ding et al. (2010, 2011) / CMU: the published name of the extension.
EXTENSION = "slip-dependent exponent N = n + n1·s (s ≥ 0), n + n2·|s| (s < 0)"
#: CMU's hand-tuned constants (terramechanics/set_soil_params.m), tuned on these runs.
CMU_TUNED = {
    "smooth": {"n0": 1.4, "n1": 0.01, "n2": 0.55},
    "grouser": {"n0": 1.46, "n1": 0.01, "n2": 0.74},
}


def _point(values: Mapping[str, np.ndarray]) -> dict[str, float]:
    return {k: float(np.median(v)) for k, v in values.items()}


def _fit(
    rows: pd.DataFrame,
    values: Mapping[str, np.ndarray],
    wheel: Wheel,
    law: str,
    angles: StressAngles,
) -> SlipExponent:
    return fit_slip_exponent(
        _point(values),
        wheel,
        rows["slip"],
        rows["W_N"],
        rows["sinkage_measured_m"],
        law=law,
        angles=angles,
    )


def discover_slip_exponent(
    frame: pd.DataFrame,
    tests: pd.DataFrame,
    params: Mapping[str, Any],
    wheels: Mapping[str, Wheel],
    law: str,
    angles: StressAngles,
    prob: float,
    checks: Mapping[str, dict],
    alpha: float,
    bar: Any,
) -> WheelDiscovery:
    """The slip-dependent exponent (:data:`EXTENSION`) fitted per wheel on its β = 0 runs,
    its bands for every run and its held-out gains (:func:`~soilstats.wheel.validate_wheel`'s
    ``discovery``)."""
    scope = frame[frame["in_scope"]]
    fits: dict[str, SlipExponent] = {}
    extended = []
    held = []
    for name, wheel in wheels.items():
        values = draws_subset(params, checks[name]["use"])
        mine = scope[scope["wheel"] == name]
        fit = _fit(mine, values, wheel, law, angles) if len(mine) else SlipExponent()
        fits[name] = fit
        every = frame[(frame["wheel"] == name) & frame["predicted"]]
        band = predict_runs(
            values, wheel, every["slip"], every["W_N"], law, angles, prob, fit.shift(every["slip"])
        )
        extended.append(_band_frame(every["run_id"], band, "sinkage_extended"))
        bar.update()
        for scheme, column in (("slip", "slip_level"), ("day", "date")):
            if column not in mine or mine[column].nunique() < 2:
                bar.update(mine[column].nunique() if column in mine else 0)
                continue
            for level, out in mine.groupby(column, sort=True):
                train = mine[mine[column] != level]
                f = _fit(train, values, wheel, law, angles)
                b = predict_runs(
                    values, wheel, out["slip"], out["W_N"], law, angles, prob, f.shift(out["slip"])
                )
                part = _band_frame(out["run_id"], b, "ext")
                held.append(part.assign(scheme=scheme, fold=f"{name}|{level}", n1=f.n1, n2=f.n2))
                bar.update()
    runs = pd.concat(extended, ignore_index=True)
    gains, cv = _gains(scope, pd.concat(held, ignore_index=True) if held else pd.DataFrame())
    slip_heldout = cv[cv["scheme"] == "slip"] if len(cv) else cv
    if len(slip_heldout):
        runs = runs.merge(
            slip_heldout[["run_id", "ext_median", "ext_lower", "ext_upper"]].rename(
                columns={
                    "ext_median": "sinkage_heldout_median_m",
                    "ext_lower": "sinkage_heldout_lower_m",
                    "ext_upper": "sinkage_heldout_upper_m",
                }
            ),
            on="run_id",
            how="left",
        )
    findings = _findings(tests, frame, gains)
    fails = _still_fails(frame.merge(runs, on="run_id"), cv)
    return WheelDiscovery(
        tests=tests,
        findings=tuple(findings),
        extension=EXTENSION,
        coefficients=fits,
        gains=gains,
        heldout=with_old_band_columns(cv),
        still_fails=fails,
        runs=with_old_band_columns(runs),
        alpha=alpha,
        notes=tuple(_discovery_notes(fits)),
    )


def _band_frame(run_ids: ArrayLike, band: Mapping[str, np.ndarray], prefix: str) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "run_id": np.asarray(run_ids),
            f"{prefix}_median" + ("_m" if prefix != "ext" else ""): band["sinkage_median"],
            f"{prefix}_lower" + ("_m" if prefix != "ext" else ""): band["sinkage_lower"],
            f"{prefix}_upper" + ("_m" if prefix != "ext" else ""): band["sinkage_upper"],
        }
    )


SCHEMES = {
    "slip": "leave one slip condition out (all its β = 0 runs, per wheel)",
    "day": "leave one day out (all its β = 0 runs, per wheel): repeatability — the same slip "
    "conditions are in the fit through other days' repeats; it never supports 'predicts new "
    "slips'",
}
METRIC = "mean absolute error of the median sinkage [m], held-out β = 0 runs"


def _gains(scope: pd.DataFrame, held: pd.DataFrame) -> tuple[dict, pd.DataFrame]:
    if held.empty:
        return {}, held
    cv = held.merge(
        scope[["run_id", "wheel", "slip_level", "sinkage_measured_m", "sinkage_median_m"]],
        on="run_id",
    )
    cv["base_error"] = (cv["sinkage_median_m"] - cv["sinkage_measured_m"]).abs()
    cv["ext_error"] = (cv["ext_median"] - cv["sinkage_measured_m"]).abs()
    cv["ext_covered"] = (cv["ext_lower"] <= cv["sinkage_measured_m"]) & (
        cv["sinkage_measured_m"] <= cv["ext_upper"]
    )
    gains = {}
    for scheme in SCHEMES:
        for wheel in [None, *sorted(cv["wheel"].unique())]:
            rows = cv[(cv["scheme"] == scheme) & ((cv["wheel"] == wheel) if wheel else True)]
            if rows["fold"].nunique() < 2:
                continue
            gains[scheme if wheel is None else f"{scheme}|{wheel}"] = _gain(rows, scheme)
    return gains, cv


def _gain(rows: pd.DataFrame, scheme: str) -> Gain:
    """The held-out comparison of one scheme as discover's :class:`~soilstats.discovery.
    crossval.Gain` (metric, folds, runs, base, extended, relative, difference ± SE, real)."""
    from ..discovery.crossval import Gain  # deferred: statsmodels (discovery's)

    d = rows["base_error"] - rows["ext_error"]
    by_fold = d.groupby(rows["fold"])
    n, total = len(rows), float(d.sum())
    mean = total / n
    k = by_fold.ngroups
    # cluster-robust SE of the mean difference: the folds (whole conditions) are the units
    cluster = by_fold.sum() - by_fold.count() * mean
    stderr = float(np.sqrt(k / (k - 1) * np.sum(cluster**2)) / n)
    base, ext = float(rows["base_error"].mean()), float(rows["ext_error"].mean())
    relative = 1.0 - ext / base if base > 0 else np.nan
    return Gain(
        metric=METRIC,
        scheme=SCHEMES[scheme],
        folds=int(k),
        n_tests=int(n),
        base=base,
        extended=ext,
        relative=float(relative),
        difference=mean,
        stderr=stderr,
        real=evidence.is_real(mean, stderr, relative),
    )


def _level_means(frame: pd.DataFrame, column: str) -> list[dict]:
    rows = frame[frame["predicted"]]
    if column not in rows:
        return []
    g = rows.groupby(column, sort=True)["residual_m"]
    return [
        {"level": lv, "runs": int(c), "mean_residual_m": float(m)}
        for (lv, m), c in zip(g.mean().items(), g.count(), strict=True)
    ]


def _findings(tests: pd.DataFrame, frame: pd.DataFrame, gains: Mapping[str, Gain]) -> list[dict]:
    columns = {"slip": "slip_level", "beta": "beta_level", "wheel": "wheel", "day": "date"}
    found = tests[tests["significant"]].sort_values("effect_size", ascending=False)
    out = []
    for _, row in found.iterrows():
        name = row["candidate"]
        item = {
            "cause": name,
            "reading": READINGS.get(name, ""),
            "p_value": row["p_value"],
            "p_adjusted": row["p_adjusted"],
            "effect_size": row["effect_size"],
            "within": row["within"],
            "level_means": _level_means(frame, columns[name]) if name in columns else [],
            "extension": None,
            "gain": {},
        }
        if name in ("slip", "slip × wheel"):
            item["extension"] = EXTENSION + " (Ding et al. 2010; CMU's skid form), per wheel"
            item["gain"] = {k: g.to_dict() for k, g in gains.items()}
        elif name in ("beta", "slip × beta", "beta × wheel"):
            item["extension"] = None
            item["why_no_extension"] = (
                "the model is longitudinal: a lateral term (Ishigami et al. 2007's side wall, "
                "lateral shear) is not implemented here"
            )
        elif name == "day":
            item["why_no_extension"] = "a day is not a condition a prediction can know in advance"
        out.append(item)
    return out


def _still_fails(frame: pd.DataFrame, cv: pd.DataFrame) -> list[dict]:
    """Where the extended model still misses: per wheel and slip (held out), per β."""
    rows = []
    if len(cv):
        slip = cv[cv["scheme"] == "slip"]
        for (wheel, level), sub in slip.groupby(["wheel", "slip_level"], sort=True):
            rows.append(
                {
                    "where": "β = 0, slip condition held out",
                    "wheel": wheel,
                    "level": f"s = {level:g}",
                    "runs": len(sub),
                    "measured_mean_m": float(sub["sinkage_measured_m"].mean()),
                    "base_mae_m": float(sub["base_error"].mean()),
                    "extended_mae_m": float(sub["ext_error"].mean()),
                    "extended_coverage_90": float(sub["ext_covered"].mean()),
                }
            )
    every = frame[frame["predicted"] & (frame["beta_level"] != 0)]
    for (wheel, beta), sub in every.groupby(["wheel", "beta_level"], sort=True):
        err = (sub["sinkage_extended_median_m"] - sub["sinkage_measured_m"]).abs()
        cov = (sub["sinkage_extended_lower_m"] <= sub["sinkage_measured_m"]) & (
            sub["sinkage_measured_m"] <= sub["sinkage_extended_upper_m"]
        )
        rows.append(
            {
                "where": "β ≠ 0 (never fitted: held out by construction)",
                "wheel": wheel,
                "level": f"β = {beta}°",
                "runs": len(sub),
                "measured_mean_m": float(sub["sinkage_measured_m"].mean()),
                "base_mae_m": float(sub["residual_m"].abs().mean()),
                "extended_mae_m": float(err.mean()),
                "extended_coverage_90": float(cov.mean()),
            }
        )
    return rows


def _discovery_notes(fits: Mapping[str, SlipExponent]) -> list[str]:
    notes = [
        "n1 and n2 are fitted per wheel type on its β = 0 runs (least squares on sinkage at the "
        "median soil); the gains are measured on runs left out of the fit, whole slip "
        "conditions or whole days at a time; β ≠ 0 runs never enter the fit.",
    ]
    for name, fit in fits.items():
        tuned = CMU_TUNED.get(name)
        if tuned:
            notes.append(
                f"{name}: fitted n1 = {fit.n1:.3g}, n2 = {fit.n2:.3g} on n = the plates' exponent; "
                f"CMU's hand-tuned n0 = {tuned['n0']}, n1 = {tuned['n1']}, n2 = {tuned['n2']} were "
                "tuned on these same runs with other stress angles and k (circular if reused; "
                "shown for comparison only)."
            )
    return notes
