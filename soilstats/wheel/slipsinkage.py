"""Slip sinkage: a slip-dependent exponent of the normal stress, fitted on wheel runs.

A static pressure–sinkage law fixes the sinkage of a wheel by its load; the Wong–Reece model
lets slip move it only through the stress angles and the vertical part of the shear.  Measured
wheels sink more the more they slip or skid (CMU sand at β = 0: ≈ 15 mm at s ≈ 0, ≈ 50 mm
locked).  The extension chosen here makes the exponent of the normal stress depend on slip,

    σ(θ) = k_eq · R^N · (cos θ − cos θ1)^N,   N = n + n1·s (s ≥ 0),   N = n + n2·|s| (s < 0),

with n the plate-identified exponent (N = n at s = 0, where a rolling wheel loads the soil as
a plate does).  The driving form is that of L. Ding, H. Gao, Z. Deng, J. Tao, "Wheel
slip-sinkage and its prediction model of lunar rover", J. Cent. South Univ. Technol. 17(1),
129–135, 2010 ("a formula of changing the sinkage exponent with the slip ratio"), used as
N = n0 + n1·s by Ding et al. (2011, J. Terramechanics 48(1)) and by the CMU authors; the skid
branch n0 + n2·|s| is CMU's (``terramechanics/sigma.m``: N = n0 − n2·s in skid).  With z in
metres and z < 1 m, a larger N lowers the pressure at every depth, so the wheel sinks deeper.

Why this and not another published form: it stays inside the Wong–Reece stress model (drawbar
pull and torque follow from the same σ), it has one coefficient per slip direction (each fitted
by a one-dimensional search), it reduces to the plate law at s = 0, and it is the form the
data's own authors chose, so its limits on these runs are worth knowing.  Lyasko's (2010)
slip-sinkage factor and Reece/Wong's dynamic sinkage were not implemented.

The coefficients are fitted on wheel runs (least squares on sinkage, one point soil: the
median of each parameter's draws), so any gain must be measured on runs the fit did not see
(:mod:`soilstats.wheel.validation`: whole slip conditions or whole days left out).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize

from .geometry import Wheel
from .solve import wheel_forces
from .stress import StressAngles

__all__ = ["BOUNDS", "SlipExponent", "exponent_shift", "fit_slip_exponent"]

#: Search interval of n1 and n2.
BOUNDS = (-0.5, 3.0)
#: Runs with |s| below this carry no information on n1 or n2 (Δn ≈ 0 there).
SLIP_TOL = 0.02


def exponent_shift(slip: ArrayLike, n1: float, n2: float) -> np.ndarray:
    """Δn(s) = n1·s for s ≥ 0, n2·|s| for s < 0."""
    s = np.asarray(slip, dtype=float)
    return np.where(s >= 0, n1 * s, -n2 * s)


@dataclass(frozen=True)
class SlipExponent:
    """The fitted coefficients of N = n + n1·s (s ≥ 0), n + n2·|s| (s < 0) of one wheel.

    ``n_drive`` and ``n_skid`` are the numbers of runs each coefficient was fitted on (0: the
    coefficient is 0, nothing to fit it on).
    """

    n1: float = 0.0
    n2: float = 0.0
    n_drive: int = 0
    n_skid: int = 0

    def shift(self, slip: ArrayLike) -> np.ndarray:
        """Δn at each slip."""
        return exponent_shift(slip, self.n1, self.n2)

    def to_dict(self) -> dict:
        return {"n1": self.n1, "n2": self.n2, "runs_drive": self.n_drive, "runs_skid": self.n_skid}


def _sinkage(point, wheel, slip, load, law, angles, n1, n2):
    state = wheel_forces(
        point,
        wheel,
        slip,
        law=law,
        load_N=load,
        angles=angles,
        exponent_shift=exponent_shift(slip, n1, n2),
    )
    # A soil that cannot carry the load within θ1 < 90° is at least buried to r_s.
    return np.where(state.status == 0, state.sinkage_m, wheel.contact_radius_m)


def fit_slip_exponent(
    point: Mapping[str, float],
    wheel: Wheel,
    slip: ArrayLike,
    load_N: ArrayLike,
    sinkage_m: ArrayLike,
    *,
    law: str,
    angles: StressAngles | None = None,
) -> SlipExponent:
    """Least-squares n1 (from the runs with s > 0.02) and n2 (s < −0.02) for one wheel.

    ``point`` holds one value per soil parameter (e.g. the median of the draws); each run is
    predicted at its own load.  Each coefficient is a bounded one-dimensional search
    (:data:`BOUNDS`); a direction without runs keeps 0.
    """
    slip, load, z = (np.asarray(v, dtype=float) for v in (slip, load_N, sinkage_m))
    angles = StressAngles() if angles is None else angles
    point = {k: float(v) for k, v in point.items()}
    out = {}
    for name, mask in (("n1", slip > SLIP_TOL), ("n2", slip < -SLIP_TOL)):
        if not mask.any():
            out[name] = 0.0
            continue
        s, w, h = slip[mask], load[mask], z[mask]

        def loss(x, s=s, w=w, h=h, name=name):
            n1, n2 = (x, 0.0) if name == "n1" else (0.0, x)
            return float(np.sum((_sinkage(point, wheel, s, w, law, angles, n1, n2) - h) ** 2))

        res = optimize.minimize_scalar(
            loss, bounds=BOUNDS, method="bounded", options={"xatol": 1e-4}
        )
        out[name] = float(res.x)
    return SlipExponent(
        n1=out["n1"],
        n2=out["n2"],
        n_drive=int(np.sum(slip > SLIP_TOL)),
        n_skid=int(np.sum(slip < -SLIP_TOL)),
    )
