"""Wong's procedure on ensemble-averaged curves: how published Bekker fits are made.

The classical identification (Wong 1980; as applied by Oravec 2009 to GRC-1), step by step:

1. Per plate, average the repeats onto a pressure grid (:func:`ensemble_curve`) and keep the
   grid points of the plate's pressure window ``p_min <= p <= p_max`` with mean sinkage > 0.
2. Per plate, fit ln p = ln k_b + n_b ln z by linear least squares, each log residual weighted
   by p² (Wong's remedy for a plain log–log fit's bias to small pressures) or uniformly.
3. ``exponent="averaged"``: n is the arithmetic mean of the n_b, and each plate's modulus k_b
   is the weighted mean of ln p − n ln z at that n (what published analyses do).
   ``exponent="common"``: one regression with a common slope and one intercept per plate.
4. k_b = kc/b + kφ (Eq. 7) is a straight line in 1/b: an unweighted fit through the k_b gives
   kc (slope) and kφ (intercept).

No standard deviations: the averaged curves are not independent observations, and the
procedure has no error model. This module exists to reproduce published numbers and to show
how they differ from the paper's weighted LM (Apfelbeck et al. 2011, Eq. 9–11) on the same
data (docs/classical.md). Use :func:`soilstats.fit_sinkage` for parameters with uncertainty.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import pandas as pd

from ..errors import IdentifiabilityError, InputError
from ..outputs.files import json_safe
from .ensemble import EnsembleCurve, ensemble_curve
from .pooling import select_one_soil

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion

__all__ = ["ClassicalFit", "PlateWindow", "classical_bekker"]

WEIGHTINGS = ("pressure-squared", "uniform")
EXPONENTS = ("averaged", "common")


@dataclass(frozen=True)
class PlateWindow:
    """Pressure window of one plate size: grid points p_min <= p <= p_max [Pa] are fitted."""

    b_m: float
    p_max: float
    p_min: float = 0.0

    def describe(self) -> str:
        return f"b = {self.b_m:g} m: {self.p_min / 1e3:g} <= p <= {self.p_max / 1e3:g} kPa"


@dataclass(frozen=True)
class ClassicalFit:
    """Bekker parameters by Wong's procedure on ensemble-averaged curves (module docstring).

    Attributes
    ----------
    params : Series
        ``kc`` [N/m^(n+1)], ``kphi`` [N/m^(n+2)], ``n`` [-] (SI; published values in kN and kPa
        are these / 1000 for the moduli, see :meth:`params_kilo`).
    plate_exponents : Series
        n_b per plate size b [m] (step 2).
    plate_moduli : Series
        k_b [N/m^(n+2)] per plate size at the final n (step 3).
    curves : tuple of EnsembleCurve
        The averaged curves, one per plate, on their full grids.
    windows : tuple of PlateWindow
    points : Series
        Grid points fitted per plate.
    """

    params: pd.Series
    plate_exponents: pd.Series
    plate_moduli: pd.Series
    curves: tuple[EnsembleCurve, ...]
    windows: tuple[PlateWindow, ...]
    points: pd.Series
    weighting: str
    exponent: str
    step: float
    soil: str
    notes: list[str] = field(default_factory=list)

    @property
    def params_kilo(self) -> pd.Series:
        """kc [kN/m^(n+1)], kφ [kN/m^(n+2)], n: the units of published Bekker tables."""
        return self.params * pd.Series({"kc": 1e-3, "kphi": 1e-3, "n": 1.0})

    def relative_deviation(self, published: Mapping[str, float]) -> pd.Series:
        """|fitted − published| / |published| per parameter; ``published`` in kN and kPa units."""
        ref = pd.Series(published, dtype=float)
        mine = self.params_kilo[ref.index]
        return (mine - ref).abs() / ref.abs()

    def observations(self) -> pd.DataFrame:
        """The fitted points: ``b_m``, ``pressure_Pa`` (grid) and ``z_m`` (ensemble mean)."""
        frames = []
        for curve, window in zip(self.curves, self.windows, strict=True):
            keep = _in_window(curve, window)
            frames.append(
                pd.DataFrame(
                    {
                        "b_m": curve.b_m,
                        "pressure_Pa": curve.pressure_Pa[keep],
                        "z_m": curve.z_m[keep],
                    }
                )
            )
        return pd.concat(frames, ignore_index=True)

    def summary(self) -> str:
        kilo = self.params_kilo
        lines = [
            f"Classical Bekker identification (Wong's procedure) — soil {self.soil}",
            f"  exponent: {self.exponent} per-plate n; log residuals weighted "
            f"{'by p^2' if self.weighting == 'pressure-squared' else 'uniformly'}; "
            f"grid step {self.step / 1e3:g} kPa",
            f"  n    = {kilo['n']:.6g}",
            f"  kc   = {kilo['kc']:.6g} kN/m^(n+1)",
            f"  kphi = {kilo['kphi']:.6g} kN/m^(n+2)",
            "  No standard deviations: averaged curves carry no error model "
            "(use fit_sinkage for sigma).",
            "  Plates:",
        ]
        for curve, window in zip(self.curves, self.windows, strict=True):
            b = curve.b_m
            lines.append(
                f"    {window.describe()}; {int(self.points[b])} points from "
                f"{len(curve.test_ids)} repeats; n_b = {self.plate_exponents[b]:.4g}, "
                f"k_b = {self.plate_moduli[b] / 1e3:.6g} kN/m^(n+2)"
            )
        lines += [f"  Note: {note}" for note in self.notes]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return json_safe(
            {
                "method": "classical",
                "soil": self.soil,
                "weighting": self.weighting,
                "exponent": self.exponent,
                "step_Pa": self.step,
                "params": self.params.to_dict(),
                "plates": [
                    {
                        "b_m": c.b_m,
                        "test_ids": list(c.test_ids),
                        "p_min_Pa": w.p_min,
                        "p_max_Pa": w.p_max,
                        "points": int(self.points[c.b_m]),
                        "n_b": float(self.plate_exponents[c.b_m]),
                        "k_b": float(self.plate_moduli[c.b_m]),
                    }
                    for c, w in zip(self.curves, self.windows, strict=True)
                ],
                "notes": list(self.notes),
            }
        )


def _in_window(curve: EnsembleCurve, window: PlateWindow) -> np.ndarray:
    p = curve.pressure_Pa
    return (p >= window.p_min) & (p <= window.p_max) & (p > 0) & (curve.z_m > 0)


def _weights(p: np.ndarray, weighting: str) -> np.ndarray:
    return p**2 if weighting == "pressure-squared" else np.ones_like(p)


def _plate_exponent(z: np.ndarray, p: np.ndarray, w: np.ndarray) -> float:
    """Weighted regression slope of ln p on ln z (step 2)."""
    lz, lp = np.log(z), np.log(p)
    cz = lz - np.sum(w * lz) / w.sum()
    cp = lp - np.sum(w * lp) / w.sum()
    spread = np.sum(w * cz**2)
    if not spread > 1e-12 * np.sum(w * lz**2):
        raise IdentifiabilityError(
            "the plate's sinkages are too close in log space to carry an exponent"
        )
    return float(np.sum(w * cz * cp) / spread)


def _plate_modulus(z: np.ndarray, p: np.ndarray, w: np.ndarray, n: float) -> float:
    """exp of the weighted mean of ln p − n ln z (step 3)."""
    return float(np.exp(np.sum(w * (np.log(p) - n * np.log(z))) / w.sum()))


def _common_exponent(points: Sequence[tuple[np.ndarray, np.ndarray]], weighting: str) -> float:
    """Common slope of one weighted regression with an intercept per plate (step 3, common)."""
    design = np.vstack(
        [
            np.column_stack(
                [np.log(z), *[np.full(z.size, float(i == j)) for j in range(len(points))]]
            )
            for i, (z, _) in enumerate(points)
        ]
    )
    log_p = np.concatenate([np.log(p) for _, p in points])
    root_w = np.sqrt(np.concatenate([_weights(p, weighting) for _, p in points]))
    coef = np.linalg.lstsq(design * root_w[:, None], log_p * root_w, rcond=None)[0]
    return float(coef[0])


def _plate_window(b: float, limits: Any) -> PlateWindow:  # p_max, or (p_min, p_max)
    """From ``p_max`` or ``(p_min, p_max)`` [Pa]."""
    if np.ndim(limits) == 0:
        return PlateWindow(b, p_max=float(limits))
    p_min, p_max = limits
    return PlateWindow(b, p_max=float(p_max), p_min=float(p_min))


def _windows(
    windows: Sequence[PlateWindow] | Mapping[float, float | tuple[float, float]],
    sizes: np.ndarray,
) -> list[PlateWindow]:
    if isinstance(windows, Mapping):
        windows = [_plate_window(float(b), limits) for b, limits in windows.items()]
    by_size = {round(w.b_m, 12): w for w in windows}
    missing = [b for b in sizes if round(b, 12) not in by_size]
    if missing:
        raise InputError(
            f"no pressure window for plate size(s) b = {missing} m; give one PlateWindow per "
            f"plate size of the soil ({sorted(sizes.tolist())})"
        )
    return [by_size[round(b, 12)] for b in sizes]


def classical_bekker(
    campaign: Campaign,
    windows: Sequence[PlateWindow] | Mapping[float, float | tuple[float, float]],
    *,
    step: float = 500.0,
    weighting: Literal["pressure-squared", "uniform"] = "pressure-squared",
    exponent: Literal["averaged", "common"] = "averaged",
    non_increasing: Literal["raise", "drop"] = "raise",
    **selection: Criterion,
) -> ClassicalFit:
    """Bekker (kc, kφ, n) by Wong's procedure on ensemble-averaged curves (module docstring).

    Parameters
    ----------
    campaign : Campaign
        Sinkage tests of one soil (after ``selection``), at least two repeats per plate size
        and two plate sizes. Records are used as given (no screening: to reproduce a
        published analysis, give the raw records).
    windows : sequence of PlateWindow, or mapping b [m] -> p_max or (p_min, p_max) [Pa]
        One pressure window per plate size.
    step : float, default 500
        Pressure grid step [Pa].
    weighting : {"pressure-squared", "uniform"}
        Weight of each log residual (step 2).
    exponent : {"averaged", "common"}
        Step 3 (module docstring).
    non_increasing : {"raise", "drop"}
        See :func:`ensemble_curve`.
    **selection
        Test-log filters; must leave one soil.
    """
    if weighting not in WEIGHTINGS:
        raise InputError(f"weighting must be one of {WEIGHTINGS}, got {weighting!r}")
    if exponent not in EXPONENTS:
        raise InputError(f"exponent must be one of {EXPONENTS}, got {exponent!r}")
    campaign, tests = select_one_soil(campaign, "sinkage", selection)
    soil = str(tests["soil"].iloc[0])
    sizes = np.sort(tests["b_m"].unique())
    if sizes.size < 2:
        raise IdentifiabilityError(
            f"Bekker's kc and kphi need at least two plate sizes; soil {soil!r} has b = "
            f"{sizes.tolist()} m"
        )
    plate_windows = _windows(windows, sizes)
    curves, points, counts, notes = [], [], {}, []
    for b, window in zip(sizes, plate_windows, strict=True):
        ids = tests.loc[tests["b_m"] == b, "test_id"]
        curve = ensemble_curve(
            campaign, ids, p_max=window.p_max, step=step, non_increasing=non_increasing
        )
        keep = _in_window(curve, window)
        if keep.sum() < 3:
            raise IdentifiabilityError(
                f"plate b = {b:g} m has {keep.sum()} grid points in its window"
            )
        curves.append(curve)
        points.append((curve.z_m[keep], curve.pressure_Pa[keep]))
        counts[b] = int(keep.sum())
        over = int((curve.extrapolated & keep).sum())
        if over:
            notes.append(
                f"b = {b:g} m: {over} grid points above the lowest repeat's largest pressure "
                f"({curve.sampled_max_Pa / 1e3:.4g} kPa) are spline extrapolations"
            )
        if any(curve.dropped.values()):
            notes.append(f"b = {b:g} m: samples without rising pressure left out {curve.dropped}")
    plate_n = np.array([_plate_exponent(z, p, _weights(p, weighting)) for z, p in points])
    n = float(plate_n.mean()) if exponent == "averaged" else _common_exponent(points, weighting)
    moduli = np.array([_plate_modulus(z, p, _weights(p, weighting), n) for z, p in points])
    kc, kphi = np.linalg.lstsq(
        np.column_stack([1.0 / sizes, np.ones_like(sizes)]), moduli, rcond=None
    )[0]
    return ClassicalFit(
        params=pd.Series({"kc": float(kc), "kphi": float(kphi), "n": n}),
        plate_exponents=pd.Series(plate_n, index=sizes, name="n_b"),
        plate_moduli=pd.Series(moduli, index=sizes, name="k_b"),
        curves=tuple(curves),
        windows=tuple(plate_windows),
        points=pd.Series(counts),
        weighting=weighting,
        exponent=exponent,
        step=float(step),
        soil=soil,
        notes=notes,
    )
