"""Shear models: Janosi–Hanamoto (Eq. 13) and Mohr–Coulomb (Eq. 15).

Inputs are the normal pressure σ in Pa and the shear deformation j in m (Eq. 14); output is
the shear stress τ in Pa (Eq. 12).  The friction angle φ is a parameter in **degrees** (the
unit every table of the field uses); the Jacobian is with respect to degrees accordingly.
Eq. 13 is used in the Janosi–Hanamoto form with exponent −j/K (the paper's typesetting shows
−σ/K, a misprint: K is a shear deformation modulus in m, so it must divide j).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import overload

import numpy as np
from numpy.typing import ArrayLike

from .base import (
    InputRows,
    Model,
    NonNegative,
    ParamLabel,
    PopulationLayout,
    Positive,
    Value,
    Within,
)
from .priors import NON_NEGATIVE, POSITIVE, Uniform

__all__ = ["JANOSI", "MOHR_COULOMB", "SHEAR_CURVE", "JanosiPopulation", "side_wall_ratio"]

RAD_PER_DEG = np.pi / 180.0


def mohr_coulomb(sigma: ArrayLike, c: Value, phi: Value) -> np.ndarray:
    """τ_max = c + σ·tan φ (Eq. 15).  ``x = σ [Pa]``; c in Pa, φ in degrees."""
    return c + np.asarray(sigma, float) * np.tan(phi * RAD_PER_DEG)


def mohr_coulomb_jac(sigma: ArrayLike, c: Value, phi: Value) -> np.ndarray:
    sigma = np.asarray(sigma, float)
    return np.column_stack(
        [np.ones_like(sigma), sigma * RAD_PER_DEG / np.cos(phi * RAD_PER_DEG) ** 2]
    )


def mohr_coulomb_linear(sigma: ArrayLike) -> tuple[np.ndarray, Callable[[ArrayLike], np.ndarray]]:
    """Mohr–Coulomb as a linear model: the design [1, σ] of (c, tan φ), and the map of
    those coefficients to (c [Pa], φ [deg])."""
    sigma = np.asarray(sigma, float)

    def to_params(beta: ArrayLike) -> np.ndarray:
        beta = np.asarray(beta, float)
        return np.column_stack([beta[:, 0], np.degrees(np.arctan(beta[:, 1]))])

    return np.column_stack([np.ones_like(sigma), sigma]), to_params


def janosi(x: InputRows, c: Value, phi: Value, K: Value) -> np.ndarray:
    """τ = (c + σ tan φ)(1 − exp(−j/K)) (Eq. 13).  ``x = (σ [Pa], j [m])``; K in m."""
    sigma, j = x
    return (c + sigma * np.tan(phi * RAD_PER_DEG)) * -np.expm1(-np.asarray(j, float) / K)


def janosi_jac(x: InputRows, c: Value, phi: Value, K: Value) -> np.ndarray:
    sigma, j = np.asarray(x[0], float), np.asarray(x[1], float)
    growth = -np.expm1(-j / K)
    tau_max = c + sigma * np.tan(phi * RAD_PER_DEG)
    return np.column_stack(
        [
            growth,
            sigma * RAD_PER_DEG / np.cos(phi * RAD_PER_DEG) ** 2 * growth,
            -tau_max * np.exp(-j / K) * j / K**2,
        ]
    )


def _start_janosi(x, tau):
    from .starting_values import janosi_start  # deferred: pandas (Wong's fit)

    sigma, j = x
    return janosi_start(sigma, j, tau)


def _start_shear_curve(j, tau):
    from .starting_values import shear_curve_start  # deferred: pandas (Wong's fit)

    return shear_curve_start(j, tau)


@dataclass(frozen=True)
class JanosiPopulation(PopulationLayout):
    """Janosi–Hanamoto's population layout (:mod:`soilstats.bayes.population_model`): each
    test's Eq. 13 at its own σ, (τ_max,t, K_t), with τ_max linear in (c, tan φ) and K
    entering as ln K."""

    def linear_log_jacobian(self, theta: np.ndarray) -> np.ndarray:
        return -2.0 * np.log(np.cos(theta[:, 1] * RAD_PER_DEG))

    def linear(self, theta: np.ndarray) -> np.ndarray:
        return np.column_stack([theta[:, 0], np.tan(theta[:, 1] * RAD_PER_DEG)])

    def second(self, theta: np.ndarray) -> np.ndarray:
        return np.log(theta[:, 2])

    def assemble(self, m: np.ndarray, g: np.ndarray) -> np.ndarray:
        return np.column_stack([m[:, 0], np.arctan(m[:, 1]) / RAD_PER_DEG, np.exp(g)])


_PHI_PRIOR = Uniform(0.0, 90.0)
_SHEAR_SUPPORT = (NonNegative("c"), Within("phi", 0.0, 90.0, "deg"))
_C_LABEL = ParamLabel("c", r"$c$", "c", "kPa", "kPa", 1e-3)
_PHI_LABEL = ParamLabel("phi", r"$\varphi$", "φ", "°", "degrees", 1.0)
_K_LABEL = ParamLabel("K", r"$K$", "K", "mm", "mm", 1e3)
_SCM_STRENGTH = {"c": ("Mohr_cohesion", "Pa"), "phi": ("Mohr_friction", "deg")}

MOHR_COULOMB = Model(
    name="mohr-coulomb",
    equation="Eq. 15: tau = c + sigma * tan(phi)",
    inputs=("sigma [Pa]",),
    output="tau [Pa]",
    param_names=("c", "phi"),
    units=("Pa", "deg"),
    bounds=((0.0, np.inf), (0.0, 90.0)),
    func=mohr_coulomb,
    jac=mohr_coulomb_jac,
    linear_form=mohr_coulomb_linear,
    kind="shear",
    columns=("sigma_Pa",),
    priors={"c": NON_NEGATIVE, "phi": _PHI_PRIOR},
    support=_SHEAR_SUPPORT,
    design_input="sigma_Pa",
    steady_state=True,
    weighting="none",
    scm=_SCM_STRENGTH,
    labels={"c": _C_LABEL, "phi": _PHI_LABEL},
    signed=("c",),
)

JANOSI = Model(
    name="janosi",
    equation="Eq. 13: tau = (c + sigma * tan(phi)) * (1 - exp(-j/K))",
    inputs=("sigma [Pa]", "j [m]"),
    output="tau [Pa]",
    param_names=("c", "phi", "K"),
    units=("Pa", "deg", "m"),
    bounds=((0.0, np.inf), (0.0, 90.0), (0.0, np.inf)),
    func=janosi,
    jac=janosi_jac,
    kind="shear",
    columns=("sigma_Pa", "j_m"),
    start=_start_janosi,
    priors={"c": NON_NEGATIVE, "phi": _PHI_PRIOR, "K": POSITIVE},
    support=(*_SHEAR_SUPPORT, Positive("K")),
    design_input="sigma_Pa",
    weighting="max-stress",
    population=JanosiPopulation(
        ("tau_max", "K"),
        ("sd_strength", "sd_lnK", "corr_strength_K"),
        "sigma_Pa",
        True,
        "tau_max,t = (c + sigma_t tan phi) exp(eps_t), K_t = K exp(delta_t)",
    ),
    scm={**_SCM_STRENGTH, "K": ("Janosi_shear", "m")},
    labels={"c": _C_LABEL, "phi": _PHI_LABEL, "K": _K_LABEL},
    signed=("c",),
)


def shear_curve(j: ArrayLike, tau_max: Value, K: Value) -> np.ndarray:
    """τ = τ_max·(1 − exp(−j/K)): Eq. 13 for one test at one normal pressure.

    ``x = j [m]``; τ_max in Pa (= c + σ tan φ of that test), K in m.  One test cannot separate
    c from φ, so per-test shear analyses identify (τ_max, K) and leave c, φ to Eq. 15.
    """
    return tau_max * -np.expm1(-np.asarray(j, float) / K)


def shear_curve_jac(j: ArrayLike, tau_max: Value, K: Value) -> np.ndarray:
    j = np.asarray(j, float)
    decay = np.exp(-j / K)
    return np.column_stack([-np.expm1(-j / K), -tau_max * decay * j / K**2])


SHEAR_CURVE = Model(
    name="shear-curve",
    equation="Eq. 13 at one normal pressure: tau = tau_max * (1 - exp(-j/K))",
    inputs=("j [m]",),
    output="tau [Pa]",
    param_names=("tau_max", "K"),
    units=("Pa", "m"),
    bounds=((0.0, np.inf), (0.0, np.inf)),
    func=shear_curve,
    jac=shear_curve_jac,
    kind="shear-test",
    columns=("j_m",),
    start=_start_shear_curve,
    labels={"tau_max": ParamLabel("tau_max"), "K": _K_LABEL},
)


@overload
def side_wall_ratio(r_inner: float, r_outer: float, height: float) -> float: ...
@overload
def side_wall_ratio(
    r_inner: ArrayLike, r_outer: ArrayLike, height: ArrayLike
) -> float | np.ndarray: ...
def side_wall_ratio(
    r_inner: ArrayLike, r_outer: ArrayLike, height: ArrayLike
) -> float | np.ndarray:
    """a = 3h(r_i² + r_o²)/(r_o³ − r_i³) [-]: side-wall over base-area torque per unit stress.

    Eq. 12 turns torque into τ over the ring's annulus only; the cylindrical walls of height h
    [m] at r_i and r_o [m] add a·(c + K0·σ·tan φ) to the apparent τ (Section 4.2.3).  Scalars
    in, a float out; arrays in, an array out.
    """
    r_inner, r_outer, height = (np.asarray(v, float) for v in (r_inner, r_outer, height))
    a = 3.0 * height * (r_inner**2 + r_outer**2) / (r_outer**3 - r_inner**3)
    return float(a) if a.ndim == 0 else a
