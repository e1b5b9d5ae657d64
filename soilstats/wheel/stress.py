"""Stresses on the contact of a rigid wheel: Wong & Reece's normal stress, Janosi–Hanamoto shear.

Sources: J.Y. Wong, A.R. Reece, "Prediction of rigid wheel performance based on the analysis of
soil-wheel stresses, Part I. Performance of driven rigid wheels", J. Terramechanics 4(1),
81–98, 1967; J.Y. Wong, *Theory of Ground Vehicles*, 4th ed., Wiley 2008, ch. 2;
G. Ishigami, A. Miwa, K. Nagatani, K. Yoshida, "Terramechanics-based model for steering
maneuver of planetary exploration rovers on loose soil", J. Field Robotics 24(3), 233–250, 2007.

Angles θ in rad from the downward vertical, + towards the front (see :mod:`.geometry`).

**Normal stress.**  The wheel of width b carries at angle θ the pressure of a plate of width b
sunk to the local depth R(cos θ − cos θ1): σ(θ) = p(b, R(cos θ − cos θ1)), with p the plate
law's hook in the model record (``Model.plate_law``, :func:`plate_pressure`), so that any
registered law reaches the wheel.  Where the law is a power law p = k_eq·z^n
(:func:`pressure_modulus`) this is the fast path

* Bekker:    σ(θ) = (kc/b + kφ)·R^n·(cos θ − cos θ1)^n
* Bernstein: σ(θ) = k·R^n·(cos θ − cos θ1)^n
* Reece:     σ(θ) = (k1 + k2·b)·(R/b)^n·(cos θ − cos θ1)^n

in front of the maximum-stress angle θm ≤ θ ≤ θ1.  Behind it, θ2 ≤ θ < θm, Wong & Reece mirror
the front distribution onto the rear arc with the equivalent angle
θe = θ1 − (θ − θ2)/(θm − θ2)·(θ1 − θm), σ(θ) = σ_front(θe), so that σ is continuous at θm
and zero at θ2.  R^n is r_s^n for a smooth wheel or a wheel sheared on its grouser tips, or
μ r_s^n + (1 − μ) r^n with CMU's area ratio μ (:meth:`Wheel.stress_radius_power`).

**Stress angles.**  θm = (a0 + a1·s)·θ1 (Wong & Reece 1967: θm/θ1 = c1 + c2·i) and
θ2 = (b0 + b1·s)·θ1 (CMU's θr; b0 = b1 = 0 puts the exit at the bottom dead centre, the classical
assumption of no rebound).  The defaults a0 = 0.4, a1 = 0.15 are the values of Ishigami et al.
(2007, Table of soil parameters for Toyoura sand) and of CMU's ``K10_mini_legacy_ICRA`` soil;
Wong & Reece's measured c1, c2 depend on the soil (their loose sand ≈ 0.18, 0.32; compact sand
≈ 0.43, 0.32, as transcribed from their Table 1 in jcmadsen/pyTerramechanics).  For skid the
same straight line in s is used (CMU's model holds θm constant in skid instead).

**Shear.**  Janosi–Hanamoto, τ = (c + σ tan φ)(1 − exp(−j/K)), with the shear displacement of
the soil along the shearing cylinder (Wong & Reece 1967; Wong 2008, ch. 2)

    j(θ) = r_s(θ1 − θ) − (V/ω)(sin θ1 − sin θ) = r_s(θ1 − θ) − ν·r·(sin θ1 − sin θ)

with ν = V/(rω).  Driving (s ≥ 0, ν = 1 − s, r_s = r): j = r[θ1 − θ − (1 − s)(sin θ1 − sin θ)].
Skid (−1 < s < 0, ν = 1/(1 + s)): j = r[θ1 − θ − (sin θ1 − sin θ)/(1 + s)] (Ishigami et al.
2007), negative over most of the contact, and τ takes the sign of j:
τ = sign(j)(c + σ tan φ)(1 − exp(−|j|/K)).  A locked wheel (s = −1) is the limit j → −∞:
τ = −(c + σ tan φ) over the whole contact (fully mobilised backward shear).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..models import MODELS, get_model, models_of_kind

if TYPE_CHECKING:
    from ..models.base import Model, Value
    from .geometry import Wheel

__all__ = [
    "PARAM_UNITS",
    "SHEAR_PARAMS",
    "SINKAGE_LAWS",
    "StressAngles",
    "normal_stress",
    "plate_pressure",
    "pressure_modulus",
    "shear_displacement",
    "shear_stress",
    "sinkage_law",
    "unit_modulus",
]

RAD_PER_DEG = np.pi / 180.0


def _janosi_params() -> tuple[str, ...]:
    return get_model("janosi").param_names


class _SinkageLaws(Mapping[str, tuple[str, ...]]):
    """Law name → its parameter names, read from the model registry at each look-up: every
    registered sinkage model with a plate hook (``Model.plate_law``), built-in or one's own."""

    def _laws(self) -> dict[str, tuple[str, ...]]:
        return {m.name: m.param_names for m in models_of_kind("sinkage") if m.plate_law()}

    def __getitem__(self, name: str) -> tuple[str, ...]:
        return self._laws()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._laws())

    def __len__(self) -> int:
        return len(self._laws())

    def __repr__(self) -> str:
        return f"SINKAGE_LAWS({self._laws()!r})"


class _ParamUnits(Mapping[str, str]):
    """Parameter name → SI unit, from the registry: the plate laws' (first registered wins
    where two share a name) and the Janosi–Hanamoto shear's."""

    def _units(self) -> dict[str, str]:
        units: dict[str, str] = {}
        for model in (*models_of_kind("sinkage"), get_model("janosi")):
            for name, unit in model.unit_of.items():
                units.setdefault(name, unit)
        return units

    def __getitem__(self, name: str) -> str:
        return self._units()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._units())

    def __len__(self) -> int:
        return len(self._units())


#: Parameters of each pressure–sinkage law the wheel can use: a live view of the model
#: registry (docs/conventions.md, "The model record"), so a law registered through its
#: record alone reaches the wheel.
SINKAGE_LAWS: Mapping[str, tuple[str, ...]] = _SinkageLaws()
#: Janosi–Hanamoto parameters: c [Pa], φ [deg], K [m] — the names of the registry's record.
SHEAR_PARAMS: tuple[str, ...] = _janosi_params()
#: SI unit of every parameter the wheel takes (a live view of the registry).
PARAM_UNITS: Mapping[str, str] = _ParamUnits()


def sinkage_law(law: str) -> Model:
    """The registry's record of a plate law the wheel can use; InputError naming the laws."""
    model = MODELS.get(law)
    if model is None or model.kind != "sinkage" or model.plate_law() is None:
        raise InputError(
            f"unknown pressure-sinkage law {law!r}; choose one of {sorted(SINKAGE_LAWS)}"
        )
    return model


def pressure_modulus(law: str, params: Mapping[str, ArrayLike], width_m: float) -> np.ndarray:
    """k_eq [N/m^(n+2)] with which a power law reads p = k_eq·z^n on a plate of width b [m].

    Bekker kc/b + kφ; Bernstein k; Reece (k1 + k2·b)·b^(−n); any registered power law its
    record's ``PlatePowerLaw`` modulus.  ``params`` maps the law's parameter names to floats
    or arrays (broadcast together).  A law that is no power law in z (e.g. one with a
    sinkage offset) has no k_eq: InputError (ask :func:`plate_pressure` instead).
    """
    model = sinkage_law(law)
    args = [np.asarray(params[k], float) for k in model.param_names]
    k_eq = model.plate_modulus(width_m, *args)
    if k_eq is None:
        raise InputError(
            f"the {law} law is no power law p = k_eq·z^n: it has no pressure modulus; "
            "use its pressure at a depth (plate_pressure)"
        )
    return k_eq


def unit_modulus(law: str, params: Mapping[str, ArrayLike], width_m: float) -> np.ndarray:
    """The plate modulus as the registry's support rules read it: the pressure at unit
    sinkage (z = 1 m) on width b — k_eq for a power law (:func:`pressure_modulus`), the
    law's own pressure there for any other (:func:`plate_pressure`)."""
    model = sinkage_law(law)
    args = [np.asarray(params[k], float) for k in model.param_names]
    k_eq = model.plate_modulus(width_m, *args)
    if k_eq is None:
        k_eq = model.pressure_under_plate(width_m, 1.0, *args)
    return np.asarray(k_eq, dtype=float)


def plate_pressure(
    law: str, params: Mapping[str, ArrayLike], width_m: float, depth_m: ArrayLike
) -> np.ndarray:
    """p [Pa] of the law under a plate of width b [m] at sinkage z [m] (the record's hook)."""
    model = sinkage_law(law)
    args = [np.asarray(params[k], float) for k in model.param_names]
    return model.pressure_under_plate(width_m, np.asarray(depth_m, dtype=float), *args)


@dataclass(frozen=True)
class StressAngles:
    """θm = (a0 + a1·s)·θ1 and θ2 = (b0 + b1·s)·θ1 (dimensionless coefficients).

    Defaults a0 = 0.4, a1 = 0.15 (Ishigami et al. 2007) and b0 = b1 = 0 (exit at the bottom
    dead centre).  CMU's tuned values for their wheels (``wheel.md``) have b0 < 0.
    For every slip used, θ2/θ1 ≤ θm/θ1 ≤ 1 and θ2/θ1 ≥ −1 must hold.
    """

    a0: float = 0.4
    a1: float = 0.15
    b0: float = 0.0
    b1: float = 0.0

    def ratios(self, slip: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(θm/θ1, θ2/θ1) at slip s; ValueError naming the slip where they are not ordered."""
        s = np.asarray(slip, dtype=float)
        a = self.a0 + self.a1 * s
        b = self.b0 + self.b1 * s
        bad = ~((b <= a) & (a <= 1.0) & (b >= -1.0))
        if np.any(bad):
            s_bad = np.atleast_1d(s)[np.atleast_1d(bad)][0]
            raise InputError(
                f"stress angles out of order at slip {s_bad:g}: need -1 <= θ2/θ1 <= θm/θ1 <= 1, "
                f"got θm/θ1 = {self.a0} + {self.a1}·s, θ2/θ1 = {self.b0} + {self.b1}·s"
            )
        return a, b

    def to_dict(self) -> dict:
        return {"a0": self.a0, "a1": self.a1, "b0": self.b0, "b1": self.b1}


def depth_factor(theta_e: Value, theta1: Value, n: Value) -> np.ndarray:
    """(cos θe − cos θ1)^n, computed as (2 sin((θ1+θe)/2) sin((θ1−θe)/2))^n (no cancellation)."""
    d = 2.0 * np.sin(0.5 * (theta1 + theta_e)) * np.sin(0.5 * (theta1 - theta_e))
    d = np.maximum(d, 0.0)
    with np.errstate(divide="ignore"):
        return np.where(d > 0, np.exp(n * np.log(np.where(d > 0, d, 1.0))), 0.0)


def equivalent_angle(theta: ArrayLike, theta1: Value, theta_m: Value, theta2: Value) -> np.ndarray:
    """θ in front of θm; Wong & Reece's mirrored θe = θ1 − (θ − θ2)/(θm − θ2)(θ1 − θm) behind."""
    theta = np.asarray(theta, dtype=float)
    span = np.where(theta_m > theta2, theta_m - theta2, 1.0)
    rear = theta1 - (theta - theta2) / span * (theta1 - theta_m)
    return np.where(theta >= theta_m, theta, rear)


def normal_stress(
    theta: ArrayLike,
    theta1: Value,
    theta_m: Value,
    theta2: Value,
    k_eq: Value,
    n: Value,
    radius_power: Value,
) -> np.ndarray:
    """σ(θ) [Pa] of Wong & Reece (1967) for a law p = k_eq·z^n (see :func:`pressure_modulus`).

    ``radius_power`` is R^n [m^n] (:meth:`Wheel.stress_radius_power`).  Zero outside
    θ2 ≤ θ ≤ θ1.  All arguments broadcast.
    """
    theta = np.asarray(theta, dtype=float)
    theta_e = equivalent_angle(theta, theta1, theta_m, theta2)
    sigma = k_eq * radius_power * depth_factor(theta_e, theta1, n)
    return np.where((theta >= theta2) & (theta <= theta1), sigma, 0.0)


def shear_displacement(theta: ArrayLike, theta1: Value, speed_ratio: Value, wheel: Wheel) -> Value:
    """j(θ) = r_s(θ1 − θ) − ν·r·(sin θ1 − sin θ) [m]; −∞ behind θ1 for a locked wheel (ν = ∞)."""
    theta = np.asarray(theta, dtype=float)
    return displacement(theta1 - theta, np.sin(theta1) - np.sin(theta), speed_ratio, wheel)


class Radii(Protocol):
    """What :func:`displacement` reads of a wheel: r_s and r [m] (floats, or one per case)."""

    @property
    def contact_radius_m(self) -> Any: ...
    @property
    def radius_m(self) -> Any: ...


def displacement(behind: Value, ahead: Value, speed_ratio: Value, wheel: Radii) -> Value:
    """j from θ1 − θ (``behind``) and sin θ1 − sin θ (``ahead``): the one formula of j."""
    finite = np.isfinite(speed_ratio)
    if np.all(finite):
        return wheel.contact_radius_m * behind - speed_ratio * wheel.radius_m * ahead
    j = (
        wheel.contact_radius_m * behind
        - np.where(finite, speed_ratio, 0.0) * wheel.radius_m * ahead
    )
    return np.where(finite | (ahead <= 0), j, -np.inf)


def janosi(sigma: Value, j: Value, c: Value, tan_phi: Value, K: Value) -> np.ndarray:
    """τ = sign(j)(c + σ tan φ)(1 − exp(−|j|/K)) [Pa] (Janosi–Hanamoto, signed)."""
    return (c + sigma * tan_phi) * np.copysign(1.0 - np.exp(-np.abs(j) / K), j)


def shear_stress(sigma: Value, j: Value, c: Value, phi_deg: Value, K: Value) -> np.ndarray:
    """Janosi–Hanamoto τ = sign(j)(c + σ tan φ)(1 − exp(−|j|/K)) [Pa]; c Pa, φ deg, K m."""
    return janosi(sigma, j, c, np.tan(np.asarray(phi_deg, float) * RAD_PER_DEG), K)
