"""Do plate-identified soil parameters predict a measured wheel? (issue #34, items 3–4)

:func:`validate_wheel` identifies the soil on the plate tests only (:mod:`.soil`), predicts
every measured run at its own measured load W with the Wong–Reece model
(:func:`~soilstats.wheel.wheel_forces`; the draws row by row, so their correlations are kept),
and compares: coverage of the 90 % band and bias, per wheel type, slip condition, slip angle
and day.  The wheel runs never feed the soil parameters that predict them.

Then, with the discipline of ``soilstats discover``: the residuals are tested against slip,
slip angle, wheel type, day and load (:mod:`.discovery`); the slip finding is given the
slip-dependent exponent of :mod:`.slipsinkage`, fitted per wheel type on the β = 0 runs; its
gain is measured only on runs the fit did not see — whole slip conditions left out, and whole
days left out — and where it still fails is said (β > 0 runs, never fitted, are held out by
construction).

Slip angle: the model is longitudinal.  Runs with β ≠ 0 are predicted with it as if β = 0 and
reported per β (the bias trend with β is a finding); the headline coverage is over the β = 0
runs, the model's domain, and the runs left out of it are listed with that reason.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ..bayes.stated_priors import describe_prior, sample_priors
from ..errors import InputError
from .discovery import READINGS, residual_tests
from .geometry import Wheel
from .runs import read_caveats, read_runs, read_wheels, wheel_geometry
from .slipsinkage import SlipExponent, fit_slip_exponent
from .soil import PlateDraws, plate_draws
from .solve import wheel_forces
from .stress import SHEAR_PARAMS, SINKAGE_LAWS, StressAngles, unit_modulus
from .validation_result import (
    OLD_BAND_COLUMNS,
    WheelDiscovery,
    WheelValidation,
    with_old_band_columns,
)

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = ["check_priors", "validate_wheel"]

#: Ding et al. (2010, 2011) / CMU: the published name of the extension.
EXTENSION = "slip-dependent exponent N = n + n1·s (s ≥ 0), n + n2·|s| (s < 0)"
#: Slip conditions within this of 0 are "near zero slip".
NEAR_ZERO = 0.05
#: Draws used for the sensitivity checks (medians only).
SENSITIVITY_DRAWS = 500
#: CMU's hand-tuned constants (terramechanics/set_soil_params.m), tuned on these runs.
CMU_TUNED = {
    "smooth": {"n0": 1.4, "n1": 0.01, "n2": 0.55},
    "grouser": {"n0": 1.46, "n1": 0.01, "n2": 0.74},
}


def validate_wheel(
    campaign: Campaign | str | Path,
    runs: pd.DataFrame | str | Path,
    *,
    wheels: Mapping[str, Wheel] | None = None,
    soil: str | None = None,
    law: str | None = None,
    draws: str | pd.DataFrame | PlateDraws = "auto",
    n_draws: int = 2000,
    priors: Mapping[str, tuple] | None = None,
    angles: StressAngles | None = None,
    prob: float = 0.9,
    alpha: float = 0.05,
    seed: int = 0,
    progress: bool = False,
    extension: bool = True,
    sensitivity: bool = True,
    caveats: Iterable[str] | None = None,
) -> WheelValidation:
    """Predict measured wheel runs from plate tests and say how well (module docstring).

    Parameters
    ----------
    campaign : Campaign, str or path
        The plate tests (a bundled name or folder is loaded and screened, as ``soilstats
        check``'s clean mode; a :class:`~soilstats.campaign.Campaign` is used as given).
    runs : DataFrame, str or path
        The measured runs (:func:`soilstats.wheel.runs.read_runs`; docs/wheel.md, Runs file).
    wheels : mapping, optional
        Wheel type → :class:`Wheel`.  Default: ``wheels.toml`` beside the runs file.
    soil, law : str, optional
        The soil of the plate tests (needed when there are several) and the pressure–sinkage
        law (default Bekker with two or more plate sizes, else Bernstein).
    draws : {"auto", "population", "pooled"} or DataFrame or PlateDraws
        Population draws (a new preparation) where the plates support them, else pooled
        (:func:`soilstats.wheel.soil.plate_draws`); or draws of your own.
    n_draws : int
        Draws carried through the wheel model (default 2000).
    priors : mapping, optional
        Priors for parameters no test measured — the shear c [Pa], phi [deg], K [m]
        (:mod:`soilstats.bayes.stated_priors`); with them drawbar pull and torque are predicted too.
    angles : StressAngles, optional
        θm, θ2 coefficients (default a0 = 0.4, a1 = 0.15, b0 = b1 = 0: Ishigami et al. 2007).
    prob : float
        Probability of the band (0.9: 5 %–95 %).
    alpha : float
        Family-wise error rate of the residual tests.
    seed : int
        Seed of every random step (sampler, draws, priors).
    extension, sensitivity : bool
        Fit the slip-sinkage extension and measure its held-out gain; run the b and
        stress-angle sensitivity checks.
    caveats : sequence of str, optional
        What a reader of the runs must know (an assumed datum, unchecked forces …).  Default:
        the ``caveats`` of the ``wheels.toml`` beside the runs file, if any.

    Returns
    -------
    WheelValidation
    """
    from tqdm.auto import tqdm

    if not 0 < prob < 1:
        raise InputError(f"prob must be in (0, 1), got {prob!r}")
    campaign = _campaign(campaign)
    source = runs if isinstance(runs, str | Path) else None
    table = read_runs(runs)
    wheels = _wheels(wheels, table, source)
    if caveats is None:
        toml = None if source is None else Path(source).with_name("wheels.toml")
        caveats = read_caveats(toml) if toml is not None and toml.is_file() else []
    angles = StressAngles() if angles is None else angles
    priors = dict(priors or {})
    check_priors(priors)
    bar = tqdm(
        total=_steps(table, wheels, extension, sensitivity),
        desc="wheel validation",
        unit="step",
        disable=not progress,
        leave=False,
    )
    notes: list[str] = []
    plate = _plate(campaign, draws, soil, law, n_draws, seed, progress)
    bar.update()
    params = _parameters(plate, priors, seed)
    law = plate.law
    checks = _moduli(params, law, wheels, notes)
    predicted = _predict_all(table, params, wheels, law, angles, prob, checks, bar)
    frame, excluded = _runs_frame(table, predicted, notes)
    unpredictable = {} if _has_shear(params) else _no_shear_reasons()
    groups = _groups(frame, with_dp="drawbar_pull_median_N" in frame)
    coverage, bias = _headline(frame, groups)
    tests = residual_tests(frame[frame["predicted"]], alpha=alpha)
    bar.update()
    disc = None
    if extension:
        disc = _discover(frame, tests, params, wheels, law, angles, prob, checks, alpha, bar)
        new = disc.runs.drop(columns=list(OLD_BAND_COLUMNS.values()), errors="ignore")
        frame = frame.merge(new, on="run_id", how="left")
    sens = _sensitivity(frame, params, wheels, law, angles, seed) if sensitivity else []
    bar.update(bool(sensitivity))
    bar.close()
    notes += _notes(plate, params, wheels, law, angles, frame, priors)
    return WheelValidation(
        runs=with_old_band_columns(frame),
        groups=groups,
        coverage=coverage,
        bias=bias,
        plate=plate,
        sources=params["sources"],
        moduli=checks,
        wheels=wheels,
        law=law,
        angles=angles,
        prob=float(prob),
        seed=int(seed),
        unpredictable=unpredictable,
        tests=tests,
        discovery=disc,
        sensitivity=sens,
        excluded=excluded,
        notes=tuple(notes),
        caveats=(*caveats, *_caveats(frame)),
    )


def _steps(table, wheels, extension, sensitivity) -> int:
    """Progress steps: the plates, each wheel's prediction, the tests, each wheel's extension
    and each held-out fold, the sensitivity checks."""
    steps = 2 + len(wheels) + bool(sensitivity)
    if extension:
        scope = table[table["beta_level"] == 0]
        folds = scope.groupby("wheel")["slip_level"].nunique().sum()
        if "date" in scope:
            folds += scope.groupby("wheel")["date"].nunique().sum()
        steps += len(wheels) + int(folds)
    return steps


# -- inputs ------------------------------------------------------------------------------------
def _campaign(campaign):
    if isinstance(campaign, str | Path):
        from ..campaign import load_campaign
        from ..quality import screen

        return screen(load_campaign(campaign), "clean").campaign
    return campaign


def _wheels(wheels, table, source) -> dict[str, Wheel]:
    types = sorted(table["wheel"].unique())
    if wheels is not None:
        missing = [t for t in types if t not in wheels]
        if missing:
            raise InputError(f"no geometry for wheel type(s) {missing}; wheels has {list(wheels)}")
        return {t: wheels[t] for t in types}
    toml = None if source is None else Path(source).with_name("wheels.toml")
    tables = read_wheels(toml) if toml is not None and toml.is_file() else {}
    return wheel_geometry(types, tables, source=str(toml) if toml else "the wheel geometry")


def _plate(campaign, draws, soil, law, n_draws, seed, progress) -> PlateDraws:
    if isinstance(draws, PlateDraws):
        return draws
    if isinstance(draws, pd.DataFrame):
        found = [k for k, p in SINKAGE_LAWS.items() if set(p) <= set(draws.columns)]
        law = law or (found[0] if len(found) == 1 else None)
        if law is None:
            raise InputError(f"cannot tell the law from the draws' columns {list(draws.columns)}")
        return PlateDraws(
            draws=draws.reset_index(drop=True),
            kind="given",
            reason="draws given by the caller",
            law=law,
            soil=str(soil or ""),
            n_tests=0,
            plate_sizes_m=(),
            posterior=None,
            params={},
        )
    return plate_draws(
        campaign, soil=soil, law=law, kind=draws, n_draws=n_draws, seed=seed, progress=progress
    )


def _parameters(plate: PlateDraws, priors, seed) -> dict:
    """The parameter arrays the model runs on (draws + shear priors) and their sources."""
    law = plate.law
    values = {k: plate.draws[k].to_numpy(float) for k in SINKAGE_LAWS[law]}
    prior_seed = int(np.random.SeedSequence([int(seed), 0x5702]).generate_state(1, np.uint32)[0])
    values.update(sample_priors(priors, len(plate.draws), prior_seed))
    sources = {k: plate.label for k in SINKAGE_LAWS[law]}
    sources.update({k: f"user prior {describe_prior(priors[k])} (not measured)" for k in priors})
    return {"values": values, "sources": sources, "priors": priors}


def check_priors(priors: Mapping[str, tuple]) -> None:
    """Priors are for what no test measured: the shear c, phi, K — all three, or none."""
    plates = sorted(set(priors) & {k for law in SINKAGE_LAWS.values() for k in law})
    if plates:
        raise InputError(f"{plates} come from the plate tests; a prior for them is not taken")
    unknown = sorted(set(priors) - set(SHEAR_PARAMS))
    if unknown:
        raise InputError(
            f"priors for {unknown}: only the shear parameters {list(SHEAR_PARAMS)} take a prior "
            "here (the pressure-sinkage law comes from the plates)"
        )
    if priors and len(priors) < len(SHEAR_PARAMS):
        missing = [k for k in SHEAR_PARAMS if k not in priors]
        raise InputError(
            f"the shear needs c [Pa], phi [deg] and K [m]; priors give {sorted(priors)} but not "
            f"{missing}: state a prior for each (e.g. --prior c=uniform:0:1500), or none"
        )
    sample_priors(priors, 1, 0)  # kinds and numbers checked before any sampling


def _has_shear(params) -> bool:
    return all(k in params["values"] for k in SHEAR_PARAMS)


def _no_shear_reasons() -> dict[str, str]:
    reason = (
        "needs the shear parameters c [Pa], phi [deg] and K [m], which no test here measured "
        "(no shear-ring tests): state them as priors with their uncertainty, e.g. "
        "--prior phi=normal:29:4 --prior c=uniform:0:1500 --prior K=lognormal:0.01:0.8"
    )
    return {"drawbar_pull_N": reason, "torque_Nm": reason}


def _moduli(params, law, wheels, notes) -> dict[str, dict]:
    """The plate modulus of every draw at each wheel's width b; draws where it is ≤ 0 are
    not used for that wheel (named in the notes)."""
    out = {}
    for name, wheel in wheels.items():
        k = unit_modulus(law, params["values"], wheel.width_m)
        bad = ~(k > 0)
        out[name] = {
            "b_m": wheel.width_m,
            "min": float(np.min(k)),
            "q05": float(np.quantile(k, 0.05)),
            "median": float(np.median(k)),
            "nonpositive": int(bad.sum()),
            "draws": int(k.size),
            "use": ~bad,
        }
        if bad.any():
            shown = ", ".join(map(str, np.flatnonzero(bad)[:10]))
            notes.append(
                f"{name}: {int(bad.sum())} of {k.size} draws give a non-positive plate modulus "
                f"at b = {1e3 * wheel.width_m:g} mm (draws {shown}{', …' if bad.sum() > 10 else ''}"
                "); they are not used for this wheel"
            )
    return out


# -- prediction --------------------------------------------------------------------------------
def _subset(params, use) -> dict[str, np.ndarray]:
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


def _predict_all(table, params, wheels, law, angles, prob, checks, bar) -> pd.DataFrame:
    parts = []
    for name, rows in table.groupby("wheel", sort=True):
        values = _subset(params, checks[name]["use"])
        band = predict_runs(values, wheels[name], rows["slip"], rows["W_N"], law, angles, prob)
        parts.append(pd.DataFrame(band, index=rows.index))
        bar.update()
    return pd.concat(parts).loc[table.index]


def _runs_frame(table, predicted, notes) -> tuple[pd.DataFrame, list[dict]]:
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


# -- coverage and bias -------------------------------------------------------------------------
def _summ(rows: pd.DataFrame, prefix: str = "sinkage", unit: str = "m") -> dict:
    measured = rows[f"{prefix}_measured_{unit}"]
    keep = measured.notna()
    rows, measured = rows[keep], measured[keep]
    error = rows[f"{prefix}_median_{unit}"] - measured
    covered = rows[f"{prefix}_covered"].astype(bool)
    return {
        "runs": len(rows),
        "covered": int(covered.sum()),
        "coverage_90": float(covered.mean()) if len(rows) else np.nan,
        f"bias_{unit}": float(error.mean()) if len(rows) else np.nan,
        f"median_bias_{unit}": float(error.median()) if len(rows) else np.nan,
        f"mae_{unit}": float(error.abs().mean()) if len(rows) else np.nan,
        f"measured_mean_{unit}": float(measured.mean()) if len(rows) else np.nan,
        f"predicted_mean_{unit}": float(rows[f"{prefix}_median_{unit}"].mean())
        if len(rows)
        else np.nan,
    }


GROUPINGS = (
    ("wheel", "β = 0", ("wheel",)),
    ("wheel", "all runs", ("wheel",)),
    ("wheel × slip", "β = 0", ("wheel", "slip_level")),
    ("wheel × β", "all runs", ("wheel", "beta_level")),
    ("wheel × day", "β = 0", ("wheel", "date")),
    ("wheel × day", "all runs", ("wheel", "date")),
)


def _groups(frame: pd.DataFrame, with_dp: bool) -> pd.DataFrame:
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


def _headline(frame: pd.DataFrame, groups: pd.DataFrame) -> tuple[dict, dict]:
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


# -- what the model gets wrong: the slip extension and its held-out gain -----------------------
def _point(values: Mapping[str, np.ndarray]) -> dict[str, float]:
    return {k: float(np.median(v)) for k, v in values.items()}


def _fit(rows, values, wheel, law, angles) -> SlipExponent:
    return fit_slip_exponent(
        _point(values),
        wheel,
        rows["slip"],
        rows["W_N"],
        rows["sinkage_measured_m"],
        law=law,
        angles=angles,
    )


def _discover(frame, tests, params, wheels, law, angles, prob, checks, alpha, bar):
    scope = frame[frame["in_scope"]]
    fits: dict[str, SlipExponent] = {}
    extended = []
    held = []
    for name, wheel in wheels.items():
        values = _subset(params, checks[name]["use"])
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
    held = pd.concat(held, ignore_index=True) if held else pd.DataFrame()
    gains, cv = _gains(scope, held)
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


def _band_frame(run_ids, band, prefix) -> pd.DataFrame:
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
    "day": "leave one day out (all its β = 0 runs, per wheel)",
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


def _gain(rows: pd.DataFrame, scheme: str):
    """The held-out comparison of one scheme as discover's :class:`~soilstats.discovery.
    crossval.Gain` (metric, folds, runs, base, extended, relative, difference ± SE, real)."""
    from ..discovery.crossval import Gain

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
        real=bool(mean > 2 * stderr and relative > 0),
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


def _findings(tests, frame, gains) -> list[dict]:
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


def _still_fails(frame, cv) -> list[dict]:
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


def _discovery_notes(fits) -> list[str]:
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


# -- sensitivity -------------------------------------------------------------------------------
def _sensitivity(frame, params, wheels, law, angles, seed) -> list[dict]:
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
def _notes(plate, params, wheels, law, angles, frame, priors) -> list[str]:
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


def _caveats(frame) -> list[str]:
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
