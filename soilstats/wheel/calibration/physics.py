"""The wheel model as a function of the calibration's parameter vector, over runs at once.

:class:`RunDesign` holds what the runs fix (wheel, slip, slip angle, load) and what they
measured; :func:`simulate` evaluates the Wong–Reece wheel (:mod:`soilstats.wheel.forces`,
:func:`~soilstats.wheel.solve.solve_entry_angle`) for P parameter sets × R runs in one
vectorised pass (the wheel types' cases stacked: :func:`~soilstats.wheel.forces.stack_cases`),
with every uncertain input of :mod:`.inputs` per case:

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

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..forces import Cases, ContactForces, contact_forces, gauss_rule, stack_cases, stackable
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

    def col(name: str) -> np.ndarray:
        return np.asarray(params[name], float).reshape(-1, 1)

    law_params = {k: np.asarray(params[k], float).reshape(-1) for k in model.param_names}
    if with_shear:
        law_params.update(
            c=1e3 * col("c_kPa")[:, 0], phi=col("phi")[:, 0], K=np.exp(col("log_K")[:, 0])
        )
    batches = [
        _wheel_batch(
            law_params, col, design, str(name), wheels[str(name)], law, with_shear, lateral
        )
        for name in np.unique(design.wheel)
    ]
    # the wheels' cases as one batch where they can be (same optional fields, a power law):
    # one solve instead of one per wheel, each case solved exactly as alone
    groups: dict[object, list[_Batch]] = {}
    for k, batch in enumerate(batches):
        key = stackable(batch.cases)
        groups.setdefault(k if key is None else key, []).append(batch)
    for group in groups.values():
        if len(group) == 1:
            cases, wheel = group[0].cases, group[0].wheel
        else:
            cases, wheel = stack_cases([(b.cases, b.wheel) for b in group]), group[0].wheel
        load = np.concatenate([b.load for b in group])
        theta1, status = solve_entry_angle(load, cases, wheel, rule)
        ordered = np.concatenate([b.ordered.reshape(-1) for b in group])
        good = (status == 0) & ordered
        forces = contact_forces(np.where(good, theta1, 0.1), cases, wheel, rule)
        at = 0
        for b in group:
            part = slice(at, at + len(b.cases))
            at = part.stop
            _write(out, b, good[part], theta1[part], forces, part, col("datum_mm"), with_shear)
    out["ok"] = np.isfinite(out["sinkage_m"])
    return out


@dataclass(frozen=True, eq=False)
class _Batch:
    """The cases of one wheel type's runs: (P, R_w) of ``shape``, runs ``idx`` of the design."""

    wheel: Wheel
    idx: np.ndarray
    cases: Cases
    shape: tuple[int, ...]
    ordered: np.ndarray
    load: np.ndarray


def _wheel_batch(
    law_params: Mapping[str, np.ndarray],
    col: Callable[[str], np.ndarray],
    design: RunDesign,
    name: str,
    wheel: Wheel,
    law: str,
    with_shear: bool,
    lateral: LateralSoil | None,
) -> _Batch:
    """The cases of P parameter sets × one wheel type's runs (:func:`simulate`)."""
    exponent = sinkage_law(law).exponent
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
    return _Batch(wheel, idx, cases, shape, ordered, load)


def _write(
    out: dict[str, np.ndarray],
    batch: _Batch,
    good: np.ndarray,
    theta1: np.ndarray,
    forces: ContactForces,
    part: slice,
    datum_mm: np.ndarray,
    with_shear: bool,
) -> None:
    """One wheel type's outputs (its slice ``part`` of the solved batch) into ``out``."""
    shape, idx = batch.shape, batch.idx
    nan = np.where(good, 1.0, np.nan).reshape(shape)
    h = sinkage_from_entry_angle(np.where(good, theta1, np.nan), batch.wheel.contact_radius_m)
    out["sinkage_m"][:, idx] = h.reshape(shape) + 1e-3 * datum_mm * nan
    if with_shear:
        out["drawbar_pull_N"][:, idx] = forces.drawbar_pull_N[part].reshape(shape) * nan
        out["torque_Nm"][:, idx] = forces.torque_Nm[part].reshape(shape) * nan
        out["lateral_force_N"][:, idx] = forces.lateral_force_N[part].reshape(shape) * nan
