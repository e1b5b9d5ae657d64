"""The wheel model as a function of the calibration's parameter vector, over runs at once.

:class:`RunDesign` holds what the runs fix (wheel, slip, slip angle, load) and what they
measured; :func:`simulate` evaluates the Wong–Reece wheel (:mod:`soilstats.wheel.forces`,
:func:`~soilstats.wheel.solve.solve_entry_angle`) for P parameter sets × R runs in one
vectorised pass per wheel type, with every uncertain input of :mod:`.inputs` per case:

* the plate law's parameters (from the plate posterior; any law of the model record, through
  :func:`~soilstats.wheel.solve.model_cases`),
* θm/θ1 = a0 + a1·s and θ2/θ1 = b0 + b1·s per case,
* the slip-dependent exponent n + n1·s (s ≥ 0), n + n2·|s| (s < 0) (Ding et al. 2011),
* the datum offset added to the model's sinkage,
* c, φ, K where the shear is carried, and at a slip angle β ≠ 0 the lateral shear and side
  face of :mod:`soilstats.wheel.lateral`.

A case whose stress angles are out of order (−1 ≤ θ2/θ1 ≤ θm/θ1 ≤ 1 broken) or whose load the
soil cannot carry is NaN; the likelihood reads a NaN as "this parameter set cannot produce the
run" (log-probability −∞), never as a number.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..forces import contact_forces, gauss_rule
from ..geometry import Wheel, sinkage_from_entry_angle
from ..lateral import LateralSoil, slip_angle_rad
from ..solve import model_cases, solve_entry_angle
from ..stress import sinkage_law

__all__ = ["MEASURED", "RunDesign", "simulate"]

#: Measured quantities a calibration can use: column of the runs file → (name, unit).
MEASURED: dict[str, tuple[str, str]] = {
    "sinkage_m": ("sinkage", "m"),
    "drawbar_pull_N": ("drawbar_pull", "N"),
    "lateral_force_N": ("lateral_force", "N"),
}

#: Gauss–Legendre nodes per contact piece inside the sampler (16 in predictions): 10 nodes
#: agree with 16 to < 1e-5 of the sinkage on the CMU runs, at 60 % of the cost.
SAMPLER_NODES = 10


@dataclass(frozen=True, eq=False)
class RunDesign:
    """The runs a calibration sees: conditions (fixed) and measurements (NaN: not measured).

    ``slip`` [-], ``beta_deg`` [deg], ``load_N`` [N] and ``wheel`` (type names) per run;
    ``measured`` maps a quantity of :data:`MEASURED` to an array (NaN where not measured);
    ``slip_level``, ``beta_level`` label the conditions; ``run_id`` names the runs.
    """

    run_id: np.ndarray
    wheel: np.ndarray
    slip: np.ndarray
    beta_deg: np.ndarray
    load_N: np.ndarray
    slip_level: np.ndarray
    beta_level: np.ndarray
    measured: dict[str, np.ndarray] = field(repr=False)

    @classmethod
    def from_runs(cls, runs: pd.DataFrame, quantities: tuple[str, ...] | None = None) -> RunDesign:
        """From :func:`soilstats.wheel.read_runs`' frame; ``quantities`` (default: every
        measured column of :data:`MEASURED` present with at least one value)."""
        present = [q for q in MEASURED if q in runs and runs[q].notna().any()]
        use = present if quantities is None else [q for q in quantities if q in present]
        return cls(
            run_id=runs["run_id"].astype(str).to_numpy(),
            wheel=runs["wheel"].astype(str).to_numpy(),
            slip=runs["slip"].to_numpy(float),
            beta_deg=_slip_angle(runs),
            load_N=runs["W_N"].to_numpy(float),
            slip_level=runs["slip_level"].to_numpy(float),
            beta_level=runs["beta_level"].to_numpy(float),
            measured={q: pd.to_numeric(runs[q], errors="coerce").to_numpy(float) for q in use},
        )

    def __len__(self) -> int:
        return len(self.slip)

    def take(self, index: np.ndarray) -> RunDesign:
        """The runs at ``index`` (integer array or mask)."""
        return RunDesign(
            **{
                k: getattr(self, k)[index]
                for k in (
                    "run_id",
                    "wheel",
                    "slip",
                    "beta_deg",
                    "load_N",
                    "slip_level",
                    "beta_level",
                )
            },
            measured={q: v[index] for q, v in self.measured.items()},
        )


def _slip_angle(runs: pd.DataFrame) -> np.ndarray:
    """β [deg] of each run as the model takes it: the commanded angle where the file gives it
    (CMU's model uses it; the measured one scatters ±0.6° around it, up to 90.13°), else the
    measured one, else 0."""
    for column in ("beta_cmd_deg", "beta_deg"):
        if column in runs and runs[column].notna().all():
            return runs[column].to_numpy(float)
    return np.zeros(len(runs))


def simulate(
    params: Mapping[str, np.ndarray],
    design: RunDesign,
    wheels: Mapping[str, Wheel],
    law: str,
    *,
    n_nodes: int = SAMPLER_NODES,
    with_shear: bool = True,
    lateral: LateralSoil | None = None,
) -> dict[str, np.ndarray]:
    """Model outputs (P, R) for P parameter sets (arrays of shape (P,)) × the R runs.

    ``params`` holds the law's parameters (the model record's names), ``a0, a1, b0, b1,
    datum_mm, n1, n2`` and, with ``with_shear``, ``c_kPa, phi, log_K``.  Runs at a slip angle
    β ≠ 0 take the lateral terms of :mod:`soilstats.wheel.lateral` (``lateral``: γ and K_y,
    default :class:`LateralSoil`).  Returns ``sinkage_m`` (datum included),
    ``drawbar_pull_N``, ``torque_Nm``, ``lateral_force_N`` and ``ok`` (bool).
    """
    n_sets = len(np.atleast_1d(params["a0"]))
    out = {
        k: np.full((n_sets, len(design)), np.nan)
        for k in ("sinkage_m", "drawbar_pull_N", "torque_Nm", "lateral_force_N")
    }
    rule = gauss_rule(n_nodes)
    model = sinkage_law(law)
    exponent = model.exponent

    def col(name: str) -> np.ndarray:
        return np.asarray(params[name], float).reshape(-1, 1)

    law_params = {k: np.asarray(params[k], float).reshape(-1) for k in model.param_names}
    if with_shear:
        law_params.update(
            c=1e3 * col("c_kPa")[:, 0], phi=col("phi")[:, 0], K=np.exp(col("log_K")[:, 0])
        )
    for name in np.unique(design.wheel):
        wheel = wheels[str(name)]
        idx = np.flatnonzero(design.wheel == name)
        s = design.slip[idx]
        a = col("a0") + col("a1") * s[None, :]
        b = col("b0") + col("b1") * s[None, :]
        shift = col("n1") * np.maximum(s, 0.0) + col("n2") * np.maximum(-s, 0.0)
        ordered = (b >= -1.0) & (b <= a) & (a <= 1.0)
        if exponent is not None:
            ordered &= law_params[exponent][:, None] + shift > 0
        cases, shape = model_cases(
            law_params,
            wheel,
            s,
            law,
            (np.where(ordered, a, 0.4), np.where(ordered, b, 0.0)),
            exponent_shift=np.where(ordered, shift, 0.0) if exponent is not None else None,
        )
        if cases.plate is None:
            ordered &= (cases.prefactor > 0).reshape(shape)
        beta = design.beta_deg[idx]
        if with_shear and np.any(beta != 0):
            soil = LateralSoil() if lateral is None else lateral
            cases = cases.at_slip_angle(
                np.broadcast_to(slip_angle_rad(beta), shape).reshape(-1),
                soil.K_y_m,
                soil.unit_weight_N_m3,
            )
        load = np.broadcast_to(design.load_N[idx][None, :], shape).reshape(-1)
        theta1, status = solve_entry_angle(load, cases, wheel, rule)
        good = (status == 0) & ordered.reshape(-1)
        forces = contact_forces(np.where(good, theta1, 0.1), cases, wheel, rule)
        nan = np.where(good, 1.0, np.nan).reshape(shape)
        h = sinkage_from_entry_angle(np.where(good, theta1, np.nan), wheel.contact_radius_m)
        out["sinkage_m"][:, idx] = h.reshape(shape) + 1e-3 * col("datum_mm") * nan
        if with_shear:
            out["drawbar_pull_N"][:, idx] = forces.drawbar_pull_N.reshape(shape) * nan
            out["torque_Nm"][:, idx] = forces.torque_Nm.reshape(shape) * nan
            out["lateral_force_N"][:, idx] = forces.lateral_force_N.reshape(shape) * nan
    out["ok"] = np.isfinite(out["sinkage_m"])
    return out
