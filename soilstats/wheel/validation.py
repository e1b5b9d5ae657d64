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
from numpy.typing import ArrayLike  # noqa: F401

from ..bayes.stated_priors import describe_prior, sample_priors
from ..campaign import load_campaign
from ..errors import InputError, SoilstatsError
from ..quality import screen
from .discovery import READINGS, residual_tests  # noqa: F401
from .geometry import Wheel
from .runs import read_caveats, read_runs, read_wheels, warn_load_units, wheel_geometry
from .slipsinkage import SlipExponent, fit_slip_exponent  # noqa: F401
from .soil import PlateDraws, plate_draws
from .solve import wheel_forces  # noqa: F401
from .stress import SHEAR_PARAMS, SINKAGE_LAWS, StressAngles, unit_modulus

# Split along its concerns (prediction of runs, scoring, discovery, report data); every public
# name importable from this module before the split is importable here still.
from .validation_discovery import (  # noqa: F401
    CMU_TUNED,
    EXTENSION,
    METRIC,
    SCHEMES,
    discover_slip_exponent,
)
from .validation_predict import draws_subset, predict_all_runs, predict_runs, runs_frame  # noqa: F401
from .validation_report import SENSITIVITY_DRAWS, run_caveats, sensitivity_checks, validation_notes  # noqa: F401
from .validation_result import (
    OLD_BAND_COLUMNS,
    WheelDiscovery,
    WheelValidation,
    with_old_band_columns,
)
from .validation_scoring import (  # noqa: F401
    GROUPINGS,
    NEAR_ZERO,
    group_scores,
    headline_scores,
)

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = ["check_priors", "predict_runs", "validate_wheel"]


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
    if not 0 < prob < 1:
        raise InputError(f"prob must be in (0, 1), got {prob!r}")
    plates = _campaign(campaign)
    table, wheels, caveats = _runs_and_wheels(runs, wheels, caveats)
    angles = StressAngles() if angles is None else angles
    priors = dict(priors or {})
    check_priors(priors)
    bar = _progress_bar(_steps(table, wheels, extension, sensitivity), progress)
    notes: list[str] = []
    plate = _plate(plates, draws, soil, law, n_draws, seed, progress)
    bar.update()
    params = _parameters(plate, priors, seed)
    law = plate.law
    checks = _moduli(params, law, wheels, notes)
    predicted = predict_all_runs(table, params, wheels, law, angles, prob, checks, bar)
    frame, excluded = runs_frame(table, predicted, notes)
    if not frame["predicted"].any():
        raise SoilstatsError(_none_carried(table, wheels, law))
    notes += _undated_note(table)
    unpredictable = {} if _has_shear(params) else _no_shear_reasons()
    groups = group_scores(frame, with_dp="drawbar_pull_median_N" in frame)
    coverage, bias = headline_scores(frame, groups)
    tests = residual_tests(frame[frame["predicted"]], alpha=alpha)
    bar.update()
    disc = None
    if extension:
        disc = discover_slip_exponent(
            frame, tests, params, wheels, law, angles, prob, checks, alpha, bar
        )
        frame = _with_extension_bands(frame, disc)
    sens = sensitivity_checks(frame, params, wheels, law, angles, seed) if sensitivity else []
    bar.update(bool(sensitivity))
    bar.close()
    notes += validation_notes(plate, params, wheels, law, angles, frame, priors)
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
        caveats=(*caveats, *run_caveats(frame)),
    )


def _progress_bar(total: int, progress: bool) -> Any:
    """The validation's tqdm bar over its ``total`` steps (hidden unless ``progress``)."""
    from tqdm.auto import tqdm  # deferred: tqdm (a progress bar)

    return tqdm(
        total=total, desc="wheel validation", unit="step", disable=not progress, leave=False
    )


def _with_extension_bands(frame: pd.DataFrame, disc: WheelDiscovery) -> pd.DataFrame:
    """The runs with the slip-sinkage extension's columns of ``disc`` joined by run_id
    (its copies of the old band columns left out: the frame has them)."""
    new = disc.runs.drop(columns=list(OLD_BAND_COLUMNS.values()), errors="ignore")
    return frame.merge(new, on="run_id", how="left")


def _runs_and_wheels(
    runs: pd.DataFrame | str | Path,
    wheels: Mapping[str, Wheel] | None,
    caveats: Iterable[str] | None,
) -> tuple[pd.DataFrame, dict[str, Wheel], Iterable[str]]:
    """The runs table, the wheels (default: ``wheels.toml`` beside a runs file) with their
    load units checked, and the caveats (default: that file's, if any)."""
    source = runs if isinstance(runs, str | Path) else None
    table = read_runs(runs)
    wheels = _wheels(wheels, table, source)
    warn_load_units(table, wheels, str(table.attrs.get("file", "the runs")))
    if caveats is None:
        toml = None if source is None else Path(source).with_name("wheels.toml")
        caveats = read_caveats(toml) if toml is not None and toml.is_file() else []
    return table, wheels, caveats


def _undated_note(table: pd.DataFrame) -> list[str]:
    """A note on the runs with an empty date cell (none when every run is dated)."""
    if "date" not in table or not table["date"].isna().any():
        return []
    undated = table.loc[table["date"].isna(), "run_id"].tolist()
    return [
        f"{len(undated)} runs are undated (empty date cells: {undated[:5]}"
        f"{', …' if len(undated) > 5 else ''}): they are predicted and scored, and left "
        "out of the by-day groups, the day test and the days-out folds only"
    ]


def _none_carried(table: pd.DataFrame, wheels: Mapping[str, Wheel], law: str) -> str:
    """Why there is nothing to validate: no draw carries any run's load (issue #44: the
    report used to fail half-written)."""
    loads = table["W_N"].to_numpy(float)
    sizes = "; ".join(w.describe() for w in wheels.values())
    return (
        f"no run can be predicted: for none of the {len(table)} runs (loads "
        f"{loads.min():g}–{loads.max():g} N) does any draw of the {law} soil carry the load "
        f"with the wheel sunk less than its radius ({sizes}); nothing is written. Check W_N "
        "is in N and the wheel's radius and width in m, or the soil (a soil this soft "
        "cannot carry these wheels in the model)"
    )


def _steps(
    table: pd.DataFrame, wheels: Mapping[str, Wheel], extension: bool, sensitivity: bool
) -> int:
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
def _campaign(campaign: Campaign | str | Path) -> Campaign:
    if isinstance(campaign, str | Path):
        cleaned = screen(load_campaign(campaign), "clean").campaign
        assert cleaned is not None  # screening returns the campaign it cleaned
        return cleaned
    return campaign


def _wheels(
    wheels: Mapping[str, Wheel] | None, table: pd.DataFrame, source: str | Path | None
) -> dict[str, Wheel]:
    types = sorted(table["wheel"].unique())
    if wheels is not None:
        missing = [t for t in types if t not in wheels]
        if missing:
            raise InputError(f"no geometry for wheel type(s) {missing}; wheels has {list(wheels)}")
        return {t: wheels[t] for t in types}
    toml = None if source is None else Path(source).with_name("wheels.toml")
    tables = read_wheels(toml) if toml is not None and toml.is_file() else {}
    return wheel_geometry(types, tables, source=str(toml) if toml else "the wheel geometry")


def _plate(
    campaign: Campaign,
    draws: str | pd.DataFrame | PlateDraws,
    soil: str | None,
    law: str | None,
    n_draws: int,
    seed: int,
    progress: bool,
) -> PlateDraws:
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


def _parameters(plate: PlateDraws, priors: Mapping[str, tuple], seed: int) -> dict:
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


def _has_shear(params: Mapping[str, Any]) -> bool:
    return all(k in params["values"] for k in SHEAR_PARAMS)


def _no_shear_reasons() -> dict[str, str]:
    reason = (
        "needs the shear parameters c [Pa], phi [deg] and K [m], which no test here measured "
        "(no shear-ring tests): state them as priors with their uncertainty, e.g. "
        "--prior phi=normal:29:4 --prior c=uniform:0:1500 --prior K=lognormal:0.01:0.8"
    )
    return {"drawbar_pull_N": reason, "torque_Nm": reason}


def _moduli(
    params: Mapping[str, Any], law: str, wheels: Mapping[str, Wheel], notes: list[str]
) -> dict[str, dict]:
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
