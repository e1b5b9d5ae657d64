"""The rigid wheel: its dimensions, the contact angles, and slip kinematics.

Conventions (Wong & Reece 1967; Wong, *Theory of Ground Vehicles*, 4th ed., 2008, ch. 2):

* Angles θ are measured at the axle from the downward vertical, **positive towards the front**
  (the direction of travel), in radians.  The contact runs from the entry angle θ1 > 0 (front,
  where the wheel meets the undisturbed surface) back to the exit angle θ2 ≤ θ1 (rear; θ2 < 0
  is behind the bottom dead centre).
* Sinkage h [m] is the depth of the lowest point of the contact circle below the undisturbed
  surface: h = r_c (1 − cos θ1), θ1 = arccos(1 − h/r_c), where r_c is the radius of the
  contact circle (:attr:`Wheel.contact_radius_m`).
* Slip (CMU's definition, ``wheel.md`` of the CMU data): s = (rω − V)/max(rω, V) with r the
  rim radius (:attr:`Wheel.radius_m`), ω the wheel's angular speed and V its forward speed.
  s > 0 driving, s = 0 pure rolling, s < 0 skid, s = −1 a locked wheel, s = 1 spinning in
  place.  The kinematics enter the model only through the ratio ν = V/(rω):
  ν = 1 − s for s ≥ 0 and ν = 1/(1 + s) for s < 0 (ν = ∞ for a locked wheel).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError

__all__ = ["Wheel", "entry_angle", "sinkage_from_entry_angle", "speed_ratio"]


@dataclass(frozen=True)
class Wheel:
    """A rigid wheel, optionally with grousers.

    Attributes
    ----------
    radius_m : float
        Rim radius r [m] (to the base of the grousers); slip is defined with it.
    width_m : float
        Width b [m]; it is also the plate width b of the pressure–sinkage law (Bekker's kc/b,
        Reece's (z/b)^n), as in Wong & Reece (1967).
    shear_radius_m : float, optional
        Shearing radius r_s ≥ r [m]: the cylinder through the grouser tips, along which the soil
        shears (Wong 2008, ch. 2, the "effective radius" of a wheel with lugs; CMU's
        ``r_s = r + h_g``).  Default r (a smooth wheel).  With grousers the contact circle,
        the sinkage and every stress integral are taken on this cylinder.
    grouser_area_ratio : float, default 1
        μ in CMU's model (``sigma.m``): the normal stress is averaged over grouser tips (share
        μ, radius r_s) and rim (share 1 − μ, radius r): σ ∝ μ r_s^n + (1 − μ) r^n.  1 takes the
        whole stress on r_s; it changes nothing when r_s = r.
    name : str, optional
        A label for reports.
    """

    radius_m: float
    width_m: float
    shear_radius_m: float | None = None
    grouser_area_ratio: float = 1.0
    name: str = "wheel"

    def __post_init__(self) -> None:
        r, b = float(self.radius_m), float(self.width_m)
        if not (np.isfinite(r) and r > 0 and np.isfinite(b) and b > 0):
            raise InputError(
                f"wheel radius and width must be positive lengths in m, got r={r!r}, b={b!r}"
            )
        rs = r if self.shear_radius_m is None else float(self.shear_radius_m)
        if not (np.isfinite(rs) and rs >= r):
            raise InputError(f"shear_radius_m must be >= radius_m = {r} m, got {rs!r}")
        mu = float(self.grouser_area_ratio)
        if not 0.0 <= mu <= 1.0:
            raise InputError(f"grouser_area_ratio must be in [0, 1], got {mu!r}")
        object.__setattr__(self, "radius_m", r)
        object.__setattr__(self, "width_m", b)
        object.__setattr__(self, "shear_radius_m", rs)
        object.__setattr__(self, "grouser_area_ratio", mu)

    @property
    def contact_radius_m(self) -> float:
        """Radius of the contact circle [m]: r_s (equal to r for a smooth wheel)."""
        return float(cast(float, self.shear_radius_m))  # r where None: set by __post_init__

    @property
    def diameter_m(self) -> float:
        """Contact-circle diameter D = 2 r_c [m] (Bekker's D)."""
        return 2.0 * self.contact_radius_m

    def stress_radius_power(self, n: ArrayLike) -> np.ndarray:
        """μ r_s^n + (1 − μ) r^n [m^n]: the radius factor of the normal stress (CMU's μ)."""
        mu, r, rs = self.grouser_area_ratio, self.radius_m, self.contact_radius_m
        n = np.asarray(n, dtype=float)
        if mu == 1.0 or rs == r:
            return rs**n
        return mu * rs**n + (1.0 - mu) * r**n

    def describe(self) -> str:
        """One line: name, r, b and (if grousered) r_s and μ, in mm."""
        text = f"{self.name}: r = {1e3 * self.radius_m:g} mm, b = {1e3 * self.width_m:g} mm"
        if self.contact_radius_m != self.radius_m:
            text += f", r_s = {1e3 * self.contact_radius_m:g} mm, μ = {self.grouser_area_ratio:g}"
        return text

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "radius_m": self.radius_m,
            "width_m": self.width_m,
            "shear_radius_m": self.contact_radius_m,
            "grouser_area_ratio": self.grouser_area_ratio,
        }


def entry_angle(sinkage_m: ArrayLike, contact_radius_m: float) -> np.ndarray:
    """θ1 = arccos(1 − h/r_c) [rad] for sinkage h [m] (0 ≤ h ≤ r_c)."""
    h = np.asarray(sinkage_m, dtype=float)
    if np.any(h < 0) or np.any(h > contact_radius_m):
        raise InputError(
            f"sinkage must lie in [0, {contact_radius_m}] m (θ1 ≤ 90°), got {h.min()}..{h.max()} m"
        )
    return np.arccos(1.0 - h / contact_radius_m)


def sinkage_from_entry_angle(theta1_rad: ArrayLike, contact_radius_m: float) -> np.ndarray:
    """h = r_c (1 − cos θ1) [m]."""
    return contact_radius_m * (1.0 - np.cos(np.asarray(theta1_rad, dtype=float)))


def speed_ratio(slip: ArrayLike) -> np.ndarray:
    """ν = V/(rω) from slip s = (rω − V)/max(rω, V): 1 − s (s ≥ 0), 1/(1 + s) (s < 0), ∞ at −1.

    Raises ValueError outside −1 ≤ s ≤ 1.
    """
    s = np.asarray(slip, dtype=float)
    if np.any(~np.isfinite(s)) or np.any(s < -1.0) or np.any(s > 1.0):
        raise InputError(f"slip must lie in [-1, 1] (s = (rω − V)/max(rω, V)), got {slip!r}")
    nu = np.full(s.shape, np.inf)
    skid = (s < 0) & (s > -1.0)
    nu[skid] = 1.0 / (1.0 + s[skid])
    drive = s >= 0
    nu[drive] = 1.0 - s[drive]
    return nu
