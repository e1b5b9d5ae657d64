"""The rigid wheel at a slip angle β: lateral shear displacement, combined shear, side-face force.

Sources:

* G. Ishigami, A. Miwa, K. Nagatani, K. Yoshida, "Terramechanics-based model for steering
  maneuver of planetary exploration rovers on loose soil", J. Field Robotics 24(3), 233–250,
  2007: the lateral shear displacement j_y = r(1 − s_I)(θ1 − θ) tan β and the side force of
  the wheel's side face from Hegedus's bulldozing resistance,
  F_s = ∫[θ2, θ1] R_b(h(θ)) (R − h(θ) cos θ) dθ, R_b(h) = D1 (c h + D2 γ h²/2),
  D1 = cot X_c + tan(X_c + φ), D2 = cot X_c + cot² X_c / cot φ, X_c = 45° − φ/2.
* C. Pavlov, A. M. Johnson (CMU, ``robomechanics/3d-terramechanics``, commit 55a6e92, MIT;
  read, not copied): the same side-face term multiplied by sin β (their ``forces.m``,
  ``ishigami_sidewall`` option), the shear mobilised on the *resultant* displacement
  √(j_t² + j_l²) and split between the two directions (their ``tau_t.m``, ``tau_l.m``), and the
  kinematics v_x = V cos β, v_y = V sin β with V the travel speed of the axle (``run_model.m``).

**Kinematics.**  V is the speed of the axle over the ground (the CMU data's carriage speed),
β the angle between the wheel's heading and V, and slip s = (rω − V)/max(rω, V) is defined
with V, not with its heading component (the CMU data's convention, :mod:`.geometry`); ν = V/(rω).
A soil element entering the contact at θ1 reaches θ after the time (θ1 − θ)/ω, so

    j_x(θ) = r_s(θ1 − θ) − ν cos β · r (sin θ1 − sin θ)      (along the heading)
    j_y(θ) = ν sin β · r (θ1 − θ)                            (along the axle)

j_x is Wong & Reece's displacement with the heading component V cos β of the travel speed;
j_y is Ishigami et al.'s r(1 − s_I)(θ1 − θ) tan β, since their slip s_I is defined with the
heading speed: 1 − s_I = V cos β/(rω) = ν cos β.  Both are the displacement of the soil *by*
the wheel, so the shear on the wheel points along (j_x, j_y): + forward and + opposing the
wheel's sideways sliding (the CMU data's ``lateral_force_N`` sign).  A locked wheel (ν = ∞) is
the limit of both, as in :mod:`.stress`.

**How the shear is split (the choice).**  The shear strength is mobilised on the resultant
displacement and directed along it:

    |τ| = (c + σ tan φ)(1 − exp(−ρ)),  ρ = √((j_x/K)² + (j_y/K_y)²),
    (τ_x, τ_y) = |τ| (j_x, j_y)/√(j_x² + j_y²),

so |τ| ≤ c + σ tan φ, the Mohr–Coulomb strength of the shearing surface, at every β.  This is
the CMU model's magnitude (one Janosi–Hanamoto on √(j_t² + j_l²)); the direction is that of
the displacement rather than CMU's slip velocity, so that at β = 0 the split is exactly the
longitudinal model of :mod:`.stress` (τ = sign(j)(c + σ tan φ)(1 − exp(−|j|/K)), skid and
locked wheel included).  Ishigami et al.'s (2007) independent Janosi–Hanamoto laws per
direction, τ_x = τ_max(1 − e^(−|j_x|/K_x)), τ_y = τ_max(1 − e^(−|j_y|/K_y)), were not chosen:
at large displacements both saturate and the resultant reaches √2·(c + σ tan φ) at 45°, a
shear the soil's own strength cannot carry; the load balance (τ_x enters W) and the drawbar
pull would then not shrink as β takes strength away from the heading direction.

**The side face** carries Ishigami's bulldozing force, multiplied by sin β (CMU's form): it is
then zero at β = 0 and odd in β (Ishigami et al. apply it with the sign of β only, which jumps
at β = 0).  h(θ) = R(cos θ − cos θ1) is the depth of the side face's edge at θ, R = r_s.
Neither the lateral shear nor the side force has a vertical component: the load balance is
W = R b ∫ (σ cos θ + τ_x sin θ) dθ, with τ_x reduced by the split above.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError

__all__ = [
    "CMU_SAND_UNIT_WEIGHT_N_M3",
    "LateralSoil",
    "bulldozing_resistance",
    "combined_shear",
    "lateral_displacement",
]

#: γ = ρ g of the CMU sand: ρ = 1330 kg/m³ (CMU ``set_soil_params.m``, "from density"), g = 9.81.
CMU_SAND_UNIT_WEIGHT_N_M3 = 1330.0 * 9.81


@dataclass(frozen=True)
class LateralSoil:
    """The soil inputs the slip-angle terms need beyond c, φ, K.

    Attributes
    ----------
    unit_weight_N_m3 : float
        Soil unit weight γ = ρ g [N/m³] of the side face's bulldozing resistance.  Default
        13,047 N/m³: ρ = 1330 kg/m³ of the CMU sand (``set_soil_params.m`` of
        ``robomechanics/3d-terramechanics``), the only density the bundled data state.  Dry
        sands lie at ≈ 1300–1700 kg/m³; state yours.
    K_y_m : float, optional
        Lateral shear deformation modulus K_y [m].  Default None: K_y = K, one isotropic
        modulus, as in the CMU model (no lateral shear test exists for the CMU sand, and no
        shear test measures K_y separately from K in soilstats' campaigns).  Ishigami et al.
        (2007) allow K_x ≠ K_y.
    """

    unit_weight_N_m3: float = CMU_SAND_UNIT_WEIGHT_N_M3
    K_y_m: float | None = None

    def __post_init__(self) -> None:
        g = float(self.unit_weight_N_m3)
        if not (np.isfinite(g) and g >= 0):
            raise InputError(f"unit_weight_N_m3 must be a weight density >= 0 N/m³, got {g!r}")
        if self.K_y_m is not None and not (np.isfinite(self.K_y_m) and self.K_y_m > 0):
            raise InputError(f"K_y_m must be a positive length in m, got {self.K_y_m!r}")

    def to_dict(self) -> dict:
        return {"unit_weight_N_m3": float(self.unit_weight_N_m3), "K_y_m": self.K_y_m}


def slip_angle_rad(slip_angle_deg: ArrayLike) -> np.ndarray:
    """β [rad] from degrees; InputError outside −90° ≤ β ≤ 90° (beyond: the wheel runs backward)."""
    beta = np.asarray(slip_angle_deg, dtype=float)
    if np.any(~np.isfinite(beta)) or np.any(np.abs(beta) > 90.0):
        raise InputError(
            f"slip_angle_deg must lie in [-90, 90] degrees (the angle between heading and travel), "
            f"got {slip_angle_deg!r}"
        )
    return np.deg2rad(beta)


def lateral_displacement(
    theta: ArrayLike,
    theta1: ArrayLike,
    speed_ratio: ArrayLike,
    beta_rad: ArrayLike,
    radius_m: float,
) -> np.ndarray:
    """j_y(θ) = ν sin β · r (θ1 − θ) [m] (Ishigami et al. 2007 with 1 − s_I = ν cos β).

    ``speed_ratio`` is ν = V/(rω) (∞ for a locked wheel: ±∞ where β ≠ 0 and θ < θ1);
    ``radius_m`` the rim radius r.
    """
    behind = np.asarray(theta1, dtype=float) - np.asarray(theta, dtype=float)
    s = np.sin(np.asarray(beta_rad, dtype=float))
    nu = np.asarray(speed_ratio, dtype=float)
    with np.errstate(invalid="ignore"):
        j = nu * s * radius_m * behind
    return np.where((s == 0) | (behind == 0), 0.0, j)


def combined_shear(
    sigma: ArrayLike,
    j_x: ArrayLike,
    j_y: ArrayLike,
    c: ArrayLike,
    tan_phi: ArrayLike,
    K: ArrayLike,
    K_y: ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(τ_x, τ_y) [Pa]: Janosi–Hanamoto on the resultant displacement, directed along it.

    |τ| = (c + σ tan φ)(1 − exp(−√((j_x/K)² + (j_y/K_y)²))), (τ_x, τ_y) ∥ (j_x, j_y); K_y = K
    when None.  With j_y = 0 this is exactly sign(j_x)(c + σ tan φ)(1 − exp(−|j_x|/K)).
    Infinite or huge displacements (a locked wheel) give |τ| = c + σ tan φ.
    """
    j_x, j_y = np.asarray(j_x, dtype=float), np.asarray(j_y, dtype=float)
    K = np.asarray(K, dtype=float)
    K_y = K if K_y is None else np.asarray(K_y, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        rho = np.hypot(j_x / K, j_y / K_y)  # hypot: no overflow for the locked wheel's 1e200
        norm = np.hypot(j_x, j_y)
    strength = np.asarray(c, dtype=float) + np.asarray(sigma, dtype=float) * tan_phi
    mag = strength * (1.0 - np.exp(-rho))
    safe = np.where(norm > 0, norm, 1.0)
    return mag * (j_x / safe), mag * (j_y / safe)


def bulldozing_coefficients(tan_phi: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Hegedus's D1 = cot X_c + tan(X_c + φ), D2 = cot X_c + cot² X_c / cot φ, X_c = 45° − φ/2."""
    phi = np.arctan(np.asarray(tan_phi, dtype=float))
    xc = 0.25 * np.pi - 0.5 * phi
    cot_xc = 1.0 / np.tan(xc)
    return cot_xc + np.tan(xc + phi), cot_xc + cot_xc**2 * np.tan(phi)


def bulldozing_resistance(
    depth_m: ArrayLike, c: ArrayLike, tan_phi: ArrayLike, unit_weight_N_m3: ArrayLike
) -> np.ndarray:
    """R_b(h) = D1 (c h + D2 γ h²/2) [N/m] (Hegedus, as used by Ishigami et al. 2007).

    The bulldozing resistance per unit length of a face sunk to depth h [m]; c [Pa], γ [N/m³].
    """
    h = np.maximum(np.asarray(depth_m, dtype=float), 0.0)
    d1, d2 = bulldozing_coefficients(tan_phi)
    c, gamma = np.asarray(c, dtype=float), np.asarray(unit_weight_N_m3, dtype=float)
    return d1 * (c * h + 0.5 * d2 * gamma * h * h)
