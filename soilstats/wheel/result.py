"""The frozen result of a wheel prediction: bands, parameter sources, what is not predicted."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import InputError
from ..outputs import json_safe
from ..outputs.text import notes_block
from .geometry import Wheel
from .stress import PARAM_UNITS, StressAngles

__all__ = ["QUANTITIES", "WheelPrediction"]

#: Predicted quantities and their units.
QUANTITIES: dict[str, str] = {
    "sinkage_m": "m",
    "drawbar_pull_N": "N",
    "torque_Nm": "N·m",
    "lateral_force_N": "N",
}


@dataclass(frozen=True, eq=False)
class WheelPrediction:
    """Predictive bands of a rigid wheel's sinkage, drawbar pull, torque and lateral force.

    Attributes
    ----------
    wheel : Wheel
    law : str
        The pressure–sinkage law (``"bekker"``, ``"bernstein"``, ``"reece"``).
    slips : tuple of float
        Slip s = (rω − V)/max(rω, V) of each column of the prediction.
    load_N : tuple of float
        Normal load W [N] at each slip.
    prob : float
        Probability of the equal-tailed band (0.9: the 5 % and 95 % quantiles).
    bands : DataFrame
        Tidy: one row per (slip, quantity) with ``slip``, ``load_N``, ``quantity``, ``unit``,
        ``median``, ``lower``, ``upper`` (the band), ``n_used`` (draws that carried the load
        and converged), ``n_not_carried``, ``n_not_converged``.  Only quantities that can be
        predicted appear (see :attr:`unpredictable`).
    samples : DataFrame
        Per draw and slip: ``draw`` (row of the input draws), ``slip``, ``sinkage_m``,
        ``drawbar_pull_N``, ``torque_Nm``, ``lateral_force_N`` (+ opposing the sideways
        sliding; 0 at slip angle 0), ``status`` (``ok``, ``not_carried``,
        ``not_converged``; NaN outputs where not ``ok``).
    sources : dict
        Where each parameter came from: the draws (``"posterior draws"`` or the label given)
        or ``"user prior normal(30, 3)"`` …
    unpredictable : dict
        Quantity → the reason it is not predicted (e.g. drawbar pull without shear parameters).
    angles : StressAngles
    n_draws, seed : int
    notes : tuple of str
    slip_angle_deg : tuple of float
        Slip angle β [deg] at each slip (0: the longitudinal model).
    """

    wheel: Wheel
    law: str
    slips: tuple[float, ...]
    load_N: tuple[float, ...]
    prob: float
    bands: pd.DataFrame
    samples: pd.DataFrame = field(repr=False)
    sources: dict[str, str]
    unpredictable: dict[str, str]
    angles: StressAngles
    n_draws: int
    seed: int
    notes: tuple[str, ...] = ()
    slip_angle_deg: tuple[float, ...] = ()

    def band(self, quantity: str) -> pd.DataFrame:
        """``median``, ``lower``, ``upper`` of one quantity, indexed by slip."""
        if quantity in self.unpredictable:
            raise InputError(f"{quantity} is not predicted: {self.unpredictable[quantity]}")
        if quantity not in QUANTITIES:
            raise InputError(f"unknown quantity {quantity!r}; choose one of {list(QUANTITIES)}")
        rows = self.bands[self.bands["quantity"] == quantity]
        return rows.set_index("slip")[["median", "lower", "upper"]]

    @property
    def not_carried(self) -> pd.DataFrame:
        """The (draw, slip) pairs whose soil cannot carry the load within θ1 < 90°."""
        return self.samples.loc[self.samples["status"] == "not_carried", ["draw", "slip"]]

    def to_dict(self) -> dict:
        """The JSON-ready content (no NaN: ``null``); the per-draw samples are left out."""
        return json_safe(
            {
                "model": self._model_name(),
                "slip_angle_deg": list(self.slip_angle_deg),
                "law": self.law,
                "wheel": self.wheel.to_dict(),
                "angles": self.angles.to_dict(),
                "slips": list(self.slips),
                "load_N": list(self.load_N),
                "prob": self.prob,
                "n_draws": self.n_draws,
                "seed": self.seed,
                "sources": dict(self.sources),
                "units": {k: PARAM_UNITS[k] for k in self.sources},
                "quantity_units": dict(QUANTITIES),
                "bands": self.bands.to_dict("records"),
                "unpredictable": dict(self.unpredictable),
                "notes": list(self.notes),
            }
        )

    def summary(self) -> str:
        """Readable report: wheel, load, law, parameter sources, bands with units, notes."""
        width = 92
        lo, hi = 50 * (1 - self.prob), 50 * (1 + self.prob)
        loads = sorted(set(self.load_N))
        load = f"{loads[0]:g} N" if len(loads) == 1 else f"{loads[0]:g}–{loads[-1]:g} N (per slip)"
        lines = [
            " rigid-wheel prediction (Wong & Reece) ".center(width, "="),
            f"Wheel: {self.wheel.describe()}; load W = {load}; {self._beta_text()}",
            f"Soil: {self.law} pressure–sinkage law + Janosi–Hanamoto shear; {self.n_draws} draws;"
            f" θm/θ1 = {self.angles.a0:g} + {self.angles.a1:g}·s,"
            f" θ2/θ1 = {self.angles.b0:g} + {self.angles.b1:g}·s",
            "Parameters (unit: source):",
        ]
        lines.extend(f"  {k:>5} [{PARAM_UNITS[k]}]: {v}" for k, v in self.sources.items())
        lines.append("-" * width)
        header = f"{'slip':>7} {'W [N]':>7}"
        cols = [
            q
            for q in QUANTITIES
            if q not in self.unpredictable and (q != "lateral_force_N" or self._lateral())
        ]
        for q in cols:
            header += f" | {q + ' median [' + f'{lo:g}%, {hi:g}%]':>30}"
        lines.append(header + f" | {'used':>5}")
        for s, rows in self.bands.groupby("slip", sort=True):
            rows = rows.set_index("quantity")
            first = rows.iloc[0]
            text = f"{s + 0.0:>7.3f} {first['load_N']:>7.3g}"  # type: ignore[operator]  # pandas-stubs: a groupby key is any scalar (here the slip, a float)
            for q in cols:
                r = rows.loc[q]
                text += (
                    f" | {_fmt(r['median']):>10} [{_fmt(r['lower'])}, {_fmt(r['upper'])}]".ljust(33)  # type: ignore[arg-type]  # pandas-stubs: .loc[q] may be a frame (one row per quantity)
                )
            lines.append(text + f" | {int(first['n_used']):>5}")
        lines.append("-" * width)
        for q, reason in self.unpredictable.items():
            if q == "lateral_force_N" and not self._lateral():
                continue
            lines.append(f"NOT PREDICTED: {q} — {reason}")
        lines.extend(notes_block(self.notes))
        lines.append("=" * width)
        return "\n".join(lines)

    def _lateral(self) -> bool:
        return any(b != 0 for b in self.slip_angle_deg)

    def _model_name(self) -> str:
        if self._lateral():
            return "Wong-Reece rigid wheel at slip angle (Ishigami et al. 2007 lateral terms)"
        return "Wong-Reece rigid wheel (longitudinal, slip angle 0)"

    def _beta_text(self) -> str:
        betas = sorted(set(self.slip_angle_deg))
        if not self._lateral():
            return "slip angle 0 (longitudinal)"
        if len(betas) == 1:
            return f"slip angle β = {betas[0]:g}°"
        return f"slip angle β = {betas[0]:g}°–{betas[-1]:g}° (per slip)"

    def __str__(self) -> str:
        return self.summary()


def _fmt(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{x:.4g}"
