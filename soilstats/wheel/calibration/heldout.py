"""Validation that holds out what a claim is about: new slip conditions, slip angles, a wheel.

Each scheme calibrates (:func:`~.calibrate.calibrate_wheel`) on the runs it keeps and predicts
the runs it holds out, which never enter that calibration:

* ``slip_condition`` — every repeat of one slip condition out together (all days, both wheels):
  what the calibrated wheel predicts at a slip it has not seen.  A held-out slip inside the
  range of the kept slips is *interpolated*, outside it *extrapolated* (the locked wheel);
  the two are reported apart.
* ``slip_angle`` — every run of one slip angle β out together (where several are measured).
* ``wheel_transfer`` — calibrate on one wheel type, predict another (``smooth->grouser``).

Leaving out single runs or days while their condition stays in the fit through other repeats
measures *repeatability*, not prediction: it is not offered here.

Every scheme is scored beside the **no-physics baseline**: the plate-only model's residuals on
the kept runs, interpolated linearly across slip (per wheel type and slip angle; constant
beyond the outermost kept slip), added to the plate-only prediction.  Scores per quantity:
coverage of the band (share of held-out runs inside it), its median width, the MAE and bias
of the median (predicted − measured) — overall, by slip level, interpolated/extrapolated.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from ..band_scores import BandColumns, score_bands
from ..geometry import Wheel
from ..stress import StressAngles
from .calibrate import calibrate_wheel
from .physics import RunDesign, simulate
from .result import WheelCalibration

__all__ = [
    "baseline_predictions",
    "heldout_predictions",
    "plate_only_median",
    "saved_calibration_scores",
    "score",
    "score_by_slip",
    "slip_angle_folds",
    "slip_condition_folds",
    "wheel_transfer_folds",
]

#: The inputs the plate-only model holds fixed (what `soilstats wheel` without a calibration
#: assumes): the default stress angles of :class:`~soilstats.wheel.StressAngles`, no datum
#: error, no slip-sinkage.
PLATE_ONLY_INPUTS: dict[str, float] = {
    **{k: float(v) for k, v in StressAngles().to_dict().items()},
    "datum_mm": 0.0,
    "n1": 0.0,
    "n2": 0.0,
}
#: Kept draws of each fold's calibration (fewer than a final calibration: only bands needed).
FOLD_DRAWS = 2000


def slip_condition_folds(design: RunDesign) -> list[tuple[str, np.ndarray]]:
    """(label, held-out mask) per slip level."""
    return [(f"s={lv:g}", design.slip_level == lv) for lv in np.unique(design.slip_level)]


def slip_angle_folds(design: RunDesign) -> list[tuple[str, np.ndarray]]:
    """(label, held-out mask) per slip-angle level (none with a single β)."""
    levels = np.unique(design.beta_level)
    if len(levels) < 2:
        return []
    return [(f"beta={lv:g}", design.beta_level == lv) for lv in levels]


def wheel_transfer_folds(design: RunDesign) -> list[tuple[str, np.ndarray]]:
    """(``"a->b"``, mask of wheel b's runs) for every ordered pair of wheel types."""
    types = sorted(set(design.wheel))
    return [
        (f"{a}->{b}", design.wheel == b) for a in types for b in types if a != b and len(types) == 2
    ]


def _interpolated(train: RunDesign, test: RunDesign) -> np.ndarray:
    """Per held-out run: is its slip inside the range of the kept slips of its wheel?"""
    out = np.zeros(len(test), bool)
    for i in range(len(test)):
        kept = train.slip[train.wheel == test.wheel[i]]
        if kept.size == 0:
            kept = train.slip
        out[i] = kept.min() <= test.slip[i] <= kept.max()
    return out


def heldout_predictions(
    design: RunDesign,
    wheels: Mapping[str, Wheel],
    plate_draws: pd.DataFrame,
    law: str,
    folds: Sequence[tuple[str, np.ndarray]],
    *,
    scheme: str,
    priors: Mapping[str, Sequence] | None = None,
    draws: int = FOLD_DRAWS,
    seed: int = 0,
    prob: float = 0.9,
    progress: bool = False,
    wheel_amplitude: Mapping[str, float] | None = None,
) -> pd.DataFrame:
    """Bands of every held-out run, each from a calibration that never saw it.

    ``wheel_amplitude`` (per quantity) is the wheel part τ_w of the discrepancy for a wheel
    type a one-wheel calibration never saw (wheel transfer).

    One row per held-out run: ``fold``, ``scheme``, ``interpolated``, the run's conditions, the
    measured values and the bands (``{q}_median/_lower/_upper``), and ``fold_converged``.
    """
    frames = []
    seeds = np.random.SeedSequence([seed, 0x4E1D]).generate_state(max(len(folds), 1))
    shear = "drawbar_pull_N" in design.measured
    for (label, mask), fold_seed in zip(
        tqdm(folds, desc=f"held out: {scheme}", disable=not progress, leave=False),
        seeds,
        strict=False,
    ):
        train, test = design.take(~mask), design.take(mask)
        cal = calibrate_wheel(
            train,
            wheels,
            plate_draws,
            law,
            priors=priors,
            shear=shear,
            draws=draws,
            seed=int(fold_seed),
        )
        pred = cal.predict(test, prob=prob, seed=int(fold_seed), wheel_amplitude=wheel_amplitude)
        pred.insert(1, "fold", label)
        pred.insert(2, "scheme", scheme)
        pred["interpolated"] = _interpolated(train, test)
        pred["fold_converged"] = cal.converged
        pred["wheel"], pred["slip"], pred["slip_level"] = test.wheel, test.slip, test.slip_level
        pred["beta_level"] = test.beta_level
        for q, v in test.measured.items():
            pred[f"{q}_measured"] = v
        frames.append(pred)
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def plate_only_median(
    design: RunDesign,
    wheels: Mapping[str, Wheel],
    plate_draws: pd.DataFrame,
    law: str,
    n_draws: int = 400,
    seed: int = 0,
) -> np.ndarray:
    """Median sinkage of the plate-only model (default angles, no datum, no slip-sinkage)."""
    rng = np.random.default_rng(seed)
    rows = plate_draws.iloc[
        rng.choice(len(plate_draws), min(n_draws, len(plate_draws)), replace=False)
    ]
    params = {k: rows[k].to_numpy(float) for k in plate_draws.columns}
    params.update({k: np.full(len(rows), v) for k, v in PLATE_ONLY_INPUTS.items()})
    with np.errstate(all="ignore"):
        out = simulate(params, design, wheels, law, n_nodes=16, with_shear=False)
    return np.nanmedian(out["sinkage_m"], axis=0)


def baseline_predictions(
    design: RunDesign,
    plate_only: Mapping[str, np.ndarray],
    folds: Sequence[tuple[str, np.ndarray]],
    *,
    scheme: str,
) -> pd.DataFrame:
    """The no-physics baseline's median for every held-out run (module docstring).

    ``plate_only`` maps a quantity to the plate-only model's median at every run (zeros for a
    quantity the plates cannot predict: then the baseline is the interpolated measurement).
    """
    frames = []
    for label, mask in folds:
        test_idx = np.flatnonzero(mask)
        rows = {"run_id": design.run_id[test_idx], "fold": label, "scheme": scheme}
        for q, base in plate_only.items():
            meas = design.measured[q]
            resid = meas - base
            pred = np.full(test_idx.size, np.nan)
            for k, i in enumerate(test_idx):
                keep = (~mask) & np.isfinite(resid) & (design.beta_level == design.beta_level[i])
                same = keep & (design.wheel == design.wheel[i])
                keep = same if same.any() else keep
                if not keep.any():
                    continue
                levels = pd.Series(resid[keep]).groupby(design.slip[keep].round(2)).mean()
                pred[k] = base[i] + np.interp(design.slip[i], levels.index, levels.to_numpy())
            rows[f"{q}_median"] = pred
            rows[f"{q}_measured"] = meas[test_idx]
        rows["slip_level"] = design.slip_level[test_idx]
        rows["wheel"] = design.wheel[test_idx]
        frames.append(pd.DataFrame(rows))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def score(frame: pd.DataFrame, quantity: str, *, bands: bool = True) -> dict:
    """Coverage, median width, MAE and bias of ``quantity`` over the rows of ``frame``
    (columns ``{quantity}_measured``, ``_median``, ``_lower``, ``_upper``;
    :func:`soilstats.wheel.band_scores.score_bands`)."""
    unit = "m" if quantity.endswith("_m") else "N"
    banded = bands and f"{quantity}_lower" in frame
    ends = (f"{quantity}_lower", f"{quantity}_upper") if banded else (None, None)
    s = score_bands(frame, BandColumns(f"{quantity}_measured", f"{quantity}_median", *ends))
    out: dict = {"runs": s.runs}
    if banded:
        out |= {"covered": s.covered, "coverage_90": s.coverage}
        out[f"median_width_{unit}"] = s.median_width
    return out | {f"mae_{unit}": s.mae, f"bias_{unit}": s.bias}


def score_by_slip(frame: pd.DataFrame, quantity: str, *, bands: bool = True) -> list[dict]:
    """:func:`score` per slip level (the bias as a function of slip, never a lone mean)."""
    return [
        {"slip_level": float(level), **score(rows, quantity, bands=bands)}  # type: ignore[arg-type]  # pandas-stubs: a groupby key is any scalar (here a slip)
        for level, rows in frame.groupby("slip_level")
    ]


def saved_calibration_scores(
    calibration: WheelCalibration, runs: pd.DataFrame, *, seed: int
) -> dict:
    """A saved calibration applied to measured runs: how many runs (those at slip angle 0
    when it was calibrated on those only), whether it had converged, and the :func:`score`
    (with its :func:`score_by_slip`) of each quantity it has a discrepancy for."""
    angles = set(np.unique(calibration.design.beta_level))
    scope = (runs if angles != {0.0} else runs[runs["beta_level"] == 0]).reset_index(drop=True)
    design = RunDesign.from_runs(scope)
    pred = calibration.predict(design, seed=seed)
    out: dict = {"runs": len(design), "converged": calibration.converged}
    for q, values in design.measured.items():
        if q not in calibration.discrepancy:
            continue
        pred[f"{q}_measured"] = values
        pred["slip_level"] = design.slip_level
        out[q] = score(pred, q) | {"by_slip": score_by_slip(pred, q)}
    return out
