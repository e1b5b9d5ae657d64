"""The model-discrepancy term: a Gaussian process in slip and slip angle (Kennedy & O'Hagan).

M.C. Kennedy, A. O'Hagan, "Bayesian calibration of computer models", J. R. Statist. Soc. B
63(3), 425–464, 2001: measured = model(x, θ) + δ(x) + ε, with δ a Gaussian process over the
run conditions x and ε the scatter of repeated runs.  Here x = (slip s, slip angle β) and

    cov(δ(x), δ(x')) = (τ² + τ_w²·[same wheel]) exp(−(s − s')²/(2ℓ_s²) − (β − β')²/(2ℓ_β²)),
    ε ~ N(0, σ²).

**Why a GP.**  The plate-only wheel's error is smooth and U-shaped in slip (issue #43), not an
offset and not independent per condition: a GP in slip interpolates it between measured slips
and its variance grows away from them, so a slip the calibration never saw gets a wider band —
and a slip outside the measured range (the locked wheel) the prior's full variance τ².  A
hierarchical offset per condition would give every new condition the same width, near or far.
The discrepancy has a part shared by the wheel types of a campaign (τ: the soil–wheel model's
error) and a part of each wheel type (τ_w: what the model gets wrong about one wheel and not
another).  A wheel the calibration never saw gets the shared part's conditional mean and the
wheel part's full variance τ_w² — so its band is wider than a calibrated wheel's by what
wheels were seen to differ.  τ_w is estimated where the runs hold two or more wheel types;
with one it cannot be, and a prediction for another wheel needs it stated
(``wheel_amplitude``); whether the transfer holds is measured, not assumed (:mod:`.heldout`).

**The scatter σ** is fitted with the repeat scatter of the runs as its floor (the pooled
within-condition SD, :func:`repeat_scatter`): σ may exceed it — it then also holds what a
smooth δ cannot follow, such as the step to a locked wheel — but never claims less scatter
than repeated runs show.  (Held at the repeat scatter instead, the held-out coverage on the
CMU runs fell from 80 % to 59 %: the squared-exponential δ cannot follow the locked wheel's
step and the bands in between became too narrow.)  **All hyperparameters** (τ, ℓ_s, ℓ_β, σ,
τ_w) are estimated by maximising the marginal likelihood of
the residuals at the least-squares start and then held fixed, as Kennedy & O'Hagan do (their
Section 4.5, "plug-in" estimates); the physical parameters are then sampled with δ integrated
out (a Gaussian likelihood with covariance K + σ²I).  Bounds: ℓ_s in [0.15, 3] (a slip scale
shorter than the spacing of the measured slips is not identifiable), ℓ_β in [10°, 360°],
σ at least the smallest resolution of the measurement (``floor``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize

from ...errors import SoilstatsError

__all__ = ["Discrepancy", "fit_discrepancy", "repeat_scatter"]

LENGTH_SLIP = (0.15, 3.0)
LENGTH_BETA = (10.0, 360.0)


@dataclass(frozen=True)
class Discrepancy:
    """GP hyperparameters of one quantity (its unit: that of the quantity)."""

    quantity: str
    amplitude: float  # τ
    length_slip: float  # ℓ_s [-]
    length_beta_deg: float  # ℓ_β [deg]
    noise: float  # σ, the scatter of a repeated run
    wheel_amplitude: float = float("nan")  # τ_w; NaN: not estimable (one wheel type)

    def kernel(self, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """K(x1, x2) of the discrepancy only (no noise); x = columns (slip, β deg, wheel code).

        A NaN τ_w counts as 0 between runs of one wheel (there is no second wheel to tell it).
        """
        ds = (x1[:, None, 0] - x2[None, :, 0]) / self.length_slip
        db = (x1[:, None, 1] - x2[None, :, 1]) / self.length_beta_deg
        same = x1[:, None, 2] == x2[None, :, 2]
        tau_w2 = 0.0 if not np.isfinite(self.wheel_amplitude) else self.wheel_amplitude**2
        return (self.amplitude**2 + tau_w2 * same) * np.exp(-0.5 * (ds * ds + db * db))

    def prior_variance(self, new_wheel: np.ndarray) -> np.ndarray:
        """Var δ(x) before any run: τ² + τ_w² (NaN τ_w where a new wheel needs it)."""
        tau_w2 = self.wheel_amplitude**2
        return self.amplitude**2 + np.where(
            new_wheel, tau_w2, 0.0 if not np.isfinite(tau_w2) else tau_w2
        )

    def covariance(self, x: np.ndarray) -> np.ndarray:
        """K(x, x) + σ²I: the covariance of measured − model at the runs x."""
        return self.kernel(x, x) + self.noise**2 * np.eye(len(x))

    def conditional(
        self, x_train: np.ndarray, residuals: np.ndarray, x_new: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Mean (P, M) of δ(x_new) given residuals (P, N) at x_train, and its variance (M,).

        The variance is that of δ alone; a new run adds σ² (:meth:`predictive`).
        """
        factor = cho_factor(self.covariance(x_train), lower=True)
        cross = self.kernel(x_train, x_new)  # (N, M)
        mean = cho_solve(factor, residuals.T).T @ cross
        new_wheel = ~np.isin(x_new[:, 2], x_train[:, 2])
        prior = self.prior_variance(new_wheel)
        var = prior - np.einsum("nm,nm->m", cross, cho_solve(factor, cross))
        return mean, np.maximum(var, 0.0)

    def to_dict(self) -> dict:
        return {
            "quantity": self.quantity,
            "amplitude": self.amplitude,
            "length_slip": self.length_slip,
            "length_beta_deg": self.length_beta_deg,
            "noise": self.noise,
            "wheel_amplitude": self.wheel_amplitude,
        }


def repeat_scatter(values: np.ndarray, groups: np.ndarray) -> tuple[float, int]:
    """Pooled within-condition SD of repeated runs, and its degrees of freedom.

    ``groups`` labels each run's condition (wheel, slip, slip angle); conditions run once
    add nothing.  (NaN, 0) when no condition was repeated.
    """
    frame = pd.DataFrame({"v": values, "g": groups}).dropna()
    stats = frame.groupby("g")["v"].agg(["var", "count"])
    stats = stats[stats["count"] >= 2]
    dof = int((stats["count"] - 1).sum())
    if dof == 0:
        return float("nan"), 0
    return float(np.sqrt(((stats["count"] - 1) * stats["var"]).sum() / dof)), dof


def fit_discrepancy(
    quantity: str,
    x: np.ndarray,
    residuals: np.ndarray,
    *,
    floor: float,
    noise: float | None = None,
) -> Discrepancy:
    """Type-II maximum likelihood of (τ, ℓ_s, ℓ_β, σ, τ_w) for residuals (N,) at x (N, 3).

    The residuals' mean is part of δ (no separate constant): a uniform offset is a long-
    length-scale discrepancy.  With a single slip angle ℓ_β is irrelevant and kept at its
    upper bound; with a single wheel type τ_w is NaN (not estimable).  ``floor``: the smallest
    σ (the repeat scatter where the runs repeat conditions).  ``noise``: σ held fixed instead
    of fitted.  Raises :class:`SoilstatsError` when the optimiser fails.
    """
    residuals = np.asarray(residuals, float)
    scale = max(float(np.std(residuals)), float(np.mean(np.abs(residuals))), floor)
    one_beta = np.ptp(x[:, 1]) == 0
    one_wheel = np.ptp(x[:, 2]) == 0

    def unpack(v: np.ndarray) -> Discrepancy:
        return Discrepancy(
            quantity,
            float(np.exp(v[0])),
            float(np.exp(v[1])),
            LENGTH_BETA[1] if one_beta else float(np.exp(v[2])),
            float(np.hypot(np.exp(v[3]), floor)) if noise is None else max(noise, floor),
            float("nan") if one_wheel else float(np.exp(v[4])),
        )

    def neg_log_marginal(v: np.ndarray) -> float:
        try:
            factor = cho_factor(unpack(v).covariance(x), lower=True)
        except np.linalg.LinAlgError:
            return 1e300
        alpha = cho_solve(factor, residuals)
        return float(0.5 * residuals @ alpha + np.log(np.diag(factor[0])).sum())

    rms = float(np.sqrt(np.mean(residuals**2))) or floor
    start = np.log([rms + floor, 0.5, 45.0, 0.3 * scale, 0.3 * scale])
    bounds = [
        (np.log(floor * 0.1), np.log(50 * scale)),
        tuple(np.log(LENGTH_SLIP)),
        tuple(np.log(LENGTH_BETA)),
        (np.log(floor * 1e-3), np.log(10 * scale)),
        (np.log(floor * 1e-3), np.log(10 * scale)),
    ]
    best = None
    shifts = (np.zeros(5), np.array([0.0, 0.7, 0.7, 0.5, 0.0]), np.array([0, -0.7, 0, 0, -1.0]))
    for s0 in (start + d for d in shifts):
        res = minimize(neg_log_marginal, s0, method="L-BFGS-B", bounds=bounds)
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    if not np.isfinite(best.fun) or best.fun >= 1e299:
        raise SoilstatsError(
            f"the discrepancy of {quantity} could not be fitted (marginal likelihood "
            f"optimiser: {best.message})"
        )
    return unpack(best.x)
