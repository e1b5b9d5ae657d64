"""Integrating the contact stresses into load, drawbar pull and torque, vectorised over cases.

Wong & Reece (1967, Part I, Eqs. for W, DP and T; Wong 2008, ch. 2), on the contact cylinder of
radius R = r_s (:attr:`Wheel.contact_radius_m`) and width b:

    W  = R b ∫[θ2, θ1] (σ cos θ + τ sin θ) dθ          normal load [N], + pressing on the soil
    H  = R b ∫ τ cos θ dθ                               thrust [N]
    Rc = R b ∫ σ sin θ dθ                               resistance from the normal stress [N]
    DP = H − Rc = R b ∫ (τ cos θ − σ sin θ) dθ          drawbar pull [N], + forward
    T  = R² b ∫ τ dθ                                    driving torque [N·m] the axle applies

At a slip angle β (:mod:`.lateral`) τ_x replaces τ (the shear split along the resultant
displacement) and the lateral force F_y = R b ∫ τ_y dθ + sin β ∫ R_b(h)(R − h cos θ) dθ is added;
with no β set on the cases the code path is the longitudinal one, unchanged.

A *case* is one (parameter set, slip) pair; the arrays of :class:`Cases` hold one value per
case, so a batch of draws × slips is integrated in one pass of numpy and a root-finder can
work on the cases that have not converged yet (:meth:`Cases.take`).

**Quadrature.**  On a grid normalised to θ1, separately on the two smooth pieces (σ has a kink
at θm): the front θ = θ1 − (θ1 − θm)v² and the rear θ = θ2 + (θm − θ2)v², v in [0, 1], with
Gauss–Legendre nodes in v.  The substitution turns the end behaviour (θ1 − θ)^n of σ into
v^(2n+1), which Gauss–Legendre integrates accurately with few nodes, and it makes Wong and
Reece's equivalent angle of the rear node v the front node v itself, so σ is evaluated once
for both pieces.  With 16 nodes a piece, W, DP and T agree with adaptive quadrature (scipy
``quad``) to < 1e-8 of W when j keeps one sign over the contact (driving, s ≥ 0, and the
locked wheel).  In skid (−1 < s < 0) j changes sign at an interior angle, where τ turns from
backward to forward within a displacement ~K: a near-kink that the rule does not resolve;
the error there stays below 1 % of W down to K/r = 0.03 at θ1 = 86°, and below 1e-4 of W
for K/r ≥ 0.3 (``tests/test_wheel_model.py``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any, Literal, overload

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from .geometry import Wheel
from .lateral import bulldozing_resistance, combined_shear
from .stress import RAD_PER_DEG, displacement

__all__ = [
    "N_NODES",
    "Cases",
    "ContactForces",
    "PlateStress",
    "contact_forces",
    "gauss_rule",
    "stack_cases",
    "stackable",
]

#: Gauss–Legendre nodes on each piece of the contact (front and rear).
N_NODES = 16
#: Cases integrated in one block (temporaries of BLOCK × N_NODES floats stay in cache).
BLOCK = 2048


@functools.lru_cache(maxsize=16)
def gauss_rule(n_nodes: int = N_NODES) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights on [0, 1] (read-only arrays, computed once per count:
    a calibration asks for them at every one of its ~10⁴ model evaluations)."""
    x, w = np.polynomial.legendre.leggauss(n_nodes)
    nodes, weights = 0.5 * (x + 1.0), 0.5 * w
    nodes.flags.writeable = weights.flags.writeable = False
    return nodes, weights


@dataclass(frozen=True)
class Cases:
    """One entry per case (a parameter set at a slip); 1-D float arrays of equal length.

    ``prefactor`` is k_eq·R^n [Pa] (σ = prefactor·(cos θe − cos θ1)^n); ``a`` = θm/θ1 and
    ``b`` = θ2/θ1; ``nu`` = V/(rω) (∞ for a locked wheel); ``c`` [Pa], ``tan_phi`` [-] and
    ``K`` [m] are None when the shear is not modelled (τ = 0).  At a slip angle β
    (:mod:`.lateral`) ``cos_beta``, ``sin_beta``, ``K_y`` [m] and ``unit_weight`` γ [N/m³] are
    set (:meth:`with_slip_angle`); None is the longitudinal model, β = 0.

    A plate law that is no power law (a sinkage offset …) sets ``plate``, a
    :class:`PlateStress` (σ from the depth factor cos θe − cos θ1 and the law's parameters),
    and ``plate_params``, the (cases, p) parameters of each case; ``prefactor`` is then NaN
    and ``n`` only the solver's first guess.

    ``contact_radius``, ``rim_radius`` and ``width`` [m] are each case's wheel geometry where
    one batch holds the cases of several wheels (:func:`stack_cases`); None: the geometry
    of the wheel passed to :func:`contact_forces`.
    """

    prefactor: np.ndarray
    n: np.ndarray
    a: np.ndarray
    b: np.ndarray
    nu: np.ndarray
    c: np.ndarray | None = None
    tan_phi: np.ndarray | None = None
    K: np.ndarray | None = None
    cos_beta: np.ndarray | None = None
    sin_beta: np.ndarray | None = None
    K_y: np.ndarray | None = None
    unit_weight: np.ndarray | None = None
    plate: PlateStress | None = None
    plate_params: np.ndarray | None = None
    contact_radius: np.ndarray | None = None
    rim_radius: np.ndarray | None = None
    width: np.ndarray | None = None

    @property
    def with_shear(self) -> bool:
        return self.c is not None

    @property
    def with_slip_angle(self) -> bool:
        return self.sin_beta is not None

    def at_slip_angle(
        self, beta_rad: ArrayLike, K_y: ArrayLike | None, unit_weight: float
    ) -> Cases:
        """These cases at slip angle β [rad] (one per case or broadcast); K_y None: K."""
        n = len(self)
        beta = np.broadcast_to(np.asarray(beta_rad, dtype=float), (n,))
        ky = self.K if K_y is None else np.broadcast_to(np.asarray(K_y, dtype=float), (n,))
        return replace(
            self,
            cos_beta=np.cos(beta),
            sin_beta=np.sin(beta),
            K_y=None if ky is None else np.array(ky, dtype=float),
            unit_weight=np.full(n, float(unit_weight)),
        )

    def __len__(self) -> int:
        return len(self.prefactor)

    def take(self, index: np.ndarray | slice) -> Cases:
        """The cases at ``index`` (an integer array or boolean mask)."""
        return Cases(*(_take(getattr(self, name), index) for name in _CASE_FIELDS))

    @classmethod
    def build(
        cls,
        *,
        prefactor: ArrayLike,
        n: ArrayLike,
        a: ArrayLike,
        b: ArrayLike,
        nu: ArrayLike,
        c: ArrayLike | None = None,
        phi_deg: ArrayLike | None = None,
        K: ArrayLike | None = None,
    ) -> Cases:
        """Broadcast every argument to one shape and flatten (C order)."""
        shear = None if c is None else (c, np.tan(np.asarray(phi_deg, float) * RAD_PER_DEG), K)
        arrays = [prefactor, n, a, b, nu, *(shear or ())]
        flat = [np.ravel(v).astype(float) for v in np.broadcast_arrays(*map(np.asarray, arrays))]
        if shear is None:
            prefactor, n, a, b, nu = flat
            return cls(prefactor, n, a, b, nu)
        prefactor, n, a, b, nu, c, tan_phi, K = flat
        return cls(prefactor, n, a, b, nu, c=c, tan_phi=tan_phi, K=K)


#: The fields of :class:`Cases` in order (looked up once: ``take`` runs at every solver step).
_CASE_FIELDS = tuple(f.name for f in fields(Cases))


#: The geometry fields of :class:`Cases` (set by :func:`stack_cases`).
_GEOMETRY_FIELDS = ("contact_radius", "rim_radius", "width")


def stack_cases(parts: Sequence[tuple[Cases, Wheel]]) -> Cases:
    """The cases of several wheels as one batch, each case carrying its wheel's geometry.

    One solve of the batch does per case exactly what one solve per wheel did, with fewer
    and larger numpy calls (a calibration's batches are small: their per-call overhead was
    half the cost).  The parts must set the same optional fields (shear, slip angle) and use
    a power law (no :class:`PlateStress`, which holds one wheel); InputError otherwise.
    """
    fields_out: dict[str, Any] = {}
    for name in _CASE_FIELDS:
        if name in _GEOMETRY_FIELDS:
            continue
        values = [getattr(cases, name) for cases, _ in parts]
        if all(v is None for v in values):
            fields_out[name] = None
        elif any(v is None or isinstance(v, PlateStress) for v in values):
            raise InputError(f"cases to stack differ in {name!r} or use a plate law's hook")
        else:
            fields_out[name] = np.concatenate(values)
    wheel_attrs = ("contact_radius_m", "radius_m", "width_m")
    for name, attr in zip(_GEOMETRY_FIELDS, wheel_attrs, strict=True):
        fields_out[name] = np.concatenate(
            [
                np.full(len(cases), getattr(wheel, attr), dtype=float)
                if getattr(cases, name) is None
                else getattr(cases, name)
                for cases, wheel in parts
            ]
        )
    return Cases(**fields_out)


def stackable(cases: Cases) -> tuple[bool, ...] | None:
    """The key of the batches :func:`stack_cases` can join ``cases`` with (which optional
    fields are set), or None where they cannot be stacked (a plate law's hook)."""
    if cases.plate is not None:
        return None
    return tuple(getattr(cases, name) is None for name in _CASE_FIELDS)


@dataclass(frozen=True)
class _Geometry:
    """Per-case wheel geometry [m] as (cases, 1) columns, read like a :class:`Wheel`."""

    contact_radius_m: np.ndarray
    radius_m: np.ndarray
    width_m: np.ndarray


def _geometry(cases: Cases, wheel: Wheel) -> Wheel | _Geometry:
    if cases.contact_radius is None or cases.rim_radius is None or cases.width is None:
        return wheel
    return _Geometry(cases.contact_radius[:, None], cases.rim_radius[:, None], cases.width[:, None])


def _take(value, index):
    if value is None or isinstance(value, PlateStress):
        return value  # the law itself is shared by every case
    return value[index]


@dataclass(frozen=True)
class PlateStress:
    """σ of a general plate law at the contact: σ = μ·p(b, r_s·d) + (1 − μ)·p(b, r·d), with
    d = cos θe − cos θ1 and p the record's plate hook (``Model.plate_law``) — the depth of a
    plate sunk to the local depth, averaged over grouser tips and rim as CMU's μ does (for a
    power law exactly k_eq·(μ r_s^n + (1 − μ) r^n)·d^n, the fast path)."""

    pressure: Callable[..., np.ndarray]
    wheel: Wheel

    def __call__(self, depth_factor: np.ndarray, params: np.ndarray) -> np.ndarray:
        """σ [Pa] at (cases, nodes) depth factors for (cases, p) parameters."""
        wheel = self.wheel
        cols = [params[:, i, None] for i in range(params.shape[1])]
        rs, r, mu = wheel.contact_radius_m, wheel.radius_m, wheel.grouser_area_ratio
        sigma = self.pressure(wheel.width_m, rs * depth_factor, *cols)
        if mu != 1.0 and rs != r:
            sigma = mu * sigma + (1.0 - mu) * self.pressure(wheel.width_m, r * depth_factor, *cols)
        return np.asarray(sigma, dtype=float)


@dataclass(frozen=True)
class ContactForces:
    """Integrated forces of each case [N, N·m] (arrays shaped like θ1)."""

    load_N: np.ndarray
    thrust_N: np.ndarray
    resistance_N: np.ndarray
    torque_Nm: np.ndarray
    #: R b ∫ τ_y dθ and sin β · F_s (:mod:`.lateral`); None for the longitudinal model.
    lateral_shear_N: np.ndarray | None = None
    side_force_N: np.ndarray | None = None

    @property
    def drawbar_pull_N(self) -> np.ndarray:
        """DP = thrust − resistance [N]."""
        return self.thrust_N - self.resistance_N

    @property
    def lateral_force_N(self) -> np.ndarray:
        """F_y = lateral shear + side face [N], + opposing the sideways sliding (0 at β = 0)."""
        if self.lateral_shear_N is None or self.side_force_N is None:
            return np.zeros_like(self.load_N)
        return self.lateral_shear_N + self.side_force_N


@overload
def contact_forces(
    theta1: ArrayLike,
    cases: Cases,
    wheel: Wheel,
    rule: tuple[np.ndarray, np.ndarray] | None = None,
    *,
    load_only: Literal[False] = False,
) -> ContactForces: ...
@overload
def contact_forces(
    theta1: ArrayLike,
    cases: Cases,
    wheel: Wheel,
    rule: tuple[np.ndarray, np.ndarray] | None = None,
    *,
    load_only: Literal[True],
) -> np.ndarray: ...
def contact_forces(
    theta1: ArrayLike,
    cases: Cases,
    wheel: Wheel,
    rule: tuple[np.ndarray, np.ndarray] | None = None,
    *,
    load_only: bool = False,
) -> ContactForces | np.ndarray:
    """Integrate σ and τ over the contact of every case at entry angle ``theta1`` [rad].

    Returns :class:`ContactForces`, or only the load W [N] (an array) with ``load_only``.
    The hot loop of the load solver: one sine per node (cos θ = √(1 − sin²θ) on |θ| ≤ 90°),
    the node sums as matrix–vector products with the weights, and the cases in blocks of
    :data:`BLOCK` so that the temporaries stay in the CPU cache.
    """
    rule = gauss_rule() if rule is None else rule
    theta1 = np.asarray(theta1, dtype=float)
    if len(cases) <= BLOCK:
        return _contact_forces(theta1, cases, wheel, rule, load_only)
    parts = [
        _contact_forces(
            theta1[i : i + BLOCK], cases.take(slice(i, i + BLOCK)), wheel, rule, load_only
        )
        for i in range(0, len(cases), BLOCK)
    ]
    if load_only:
        return np.concatenate(parts)
    return ContactForces(*(_concat(x) for x in zip(*(_astuple(p) for p in parts), strict=True)))


def _astuple(f: ContactForces) -> tuple[np.ndarray | None, ...]:
    return (f.load_N, f.thrust_N, f.resistance_N, f.torque_Nm, f.lateral_shear_N, f.side_force_N)


def _concat(arrays: Sequence[Any]) -> Any:  # None for a lateral field of the longitudinal model

    return None if arrays[0] is None else np.concatenate(arrays)


def _contact_forces(
    theta1: np.ndarray,
    cases: Cases,
    wheel: Wheel,
    rule: tuple[np.ndarray, np.ndarray],
    load_only: bool,
) -> Any:  # ContactForces, or the load W [N] with load_only (contact_forces' overloads)
    v, w = rule
    geo = _geometry(cases, wheel)  # the wheel, or each case's own (stack_cases)
    t1 = theta1[:, None]
    a, b = cases.a[:, None], cases.b[:, None]
    v2, w = v * v, 2.0 * v * w  # θ = θ1 − (θ1 − θm)v² in front, θ2 + (θm − θ2)v² behind
    u_front = 1.0 - (1.0 - a) * v2
    u_rear = b + (a - b) * v2
    len_front, len_rear = 1.0 - cases.a, cases.a - cases.b  # piece lengths in u = θ/θ1
    sin_f, sin_r = np.sin(t1 * u_front), np.sin(t1 * u_rear)
    cos_f, cos_r = np.sqrt(1.0 - sin_f**2), np.sqrt(1.0 - sin_r**2)
    if cases.plate is None:
        with np.errstate(divide="ignore"):
            sig_f = (
                cases.prefactor[:, None] * np.maximum(cos_f - np.cos(t1), 0.0) ** cases.n[:, None]
            )
    else:  # a law that is no power law: its own pressure at each node's depth
        assert cases.plate_params is not None
        sig_f = cases.plate(np.maximum(cos_f - np.cos(t1), 0.0), cases.plate_params)
    sig_r = sig_f  # the rear node v has Wong–Reece's equivalent angle θe = the front node v

    def integral(front: np.ndarray, rear: np.ndarray) -> np.ndarray:
        return len_front * (front @ w) + len_rear * (rear @ w)

    vertical = integral(sig_f * cos_f, sig_r * cos_r)
    scale = (geo.contact_radius_m * geo.width_m * t1)[:, 0]
    lateral = cases.with_shear and cases.with_slip_angle
    if lateral:
        sin1 = np.sin(t1)
        tau_f, tau_y_f = _tau_xy(sig_f, t1, u_front, sin1 - sin_f, cases, geo)
        tau_r, tau_y_r = _tau_xy(sig_r, t1, u_rear, sin1 - sin_r, cases, geo)
        vertical = vertical + integral(tau_f * sin_f, tau_r * sin_r)
    elif cases.with_shear:
        sin1 = np.sin(t1)
        strength, nu = _shear_strength(sig_f, cases)  # one for both pieces, as σ is
        tau_f = strength * _mobilised(t1, u_front, sin1 - sin_f, nu, cases, geo)
        tau_r = strength * _mobilised(t1, u_rear, sin1 - sin_r, nu, cases, geo)
        vertical = vertical + integral(tau_f * sin_f, tau_r * sin_r)
    if load_only:
        return scale * vertical
    resistance = integral(sig_f * sin_f, sig_r * sin_r)
    if cases.with_shear:
        thrust = integral(tau_f * cos_f, tau_r * cos_r)
        torque = integral(tau_f, tau_r)
    else:
        thrust = torque = np.zeros_like(scale)
    side = shear_y = None
    if lateral:
        shear_y = scale * integral(tau_y_f, tau_y_r)
        cos1 = np.cos(t1)
        side_f = _side_face(cos_f, cos1, cases, geo)
        side_r = _side_face(cos_r, cos1, cases, geo)
        assert cases.sin_beta is not None  # lateral
        side = cases.sin_beta * t1[:, 0] * integral(side_f, side_r)
    return ContactForces(
        scale * vertical,
        scale * thrust,
        scale * resistance,
        (geo.contact_radius_m * scale[:, None])[:, 0] * torque,
        shear_y,
        side,
    )


def _shear_strength(sigma: np.ndarray, cases: Cases) -> tuple[np.ndarray, np.ndarray]:
    """(c + σ tan φ [Pa] at the nodes, ν per case as a column, ∞ as a huge finite ν)."""
    c, tan_phi = cases.c, cases.tan_phi
    assert c is not None and tan_phi is not None  # cases.with_shear
    nu = cases.nu[:, None]
    # a locked wheel (ν = ∞) as a huge finite ν: j → −huge, τ = −τ_max exactly, no masking
    return c[:, None] + sigma * tan_phi[:, None], np.where(np.isfinite(nu), nu, 1e200)


def _mobilised(
    t1: np.ndarray,
    u: np.ndarray,
    ahead: np.ndarray,
    nu: np.ndarray,
    cases: Cases,
    wheel: Wheel | _Geometry,
) -> np.ndarray:
    """sign(j)(1 − exp(−|j|/K)) at the nodes: τ / (c + σ tan φ) of Janosi–Hanamoto
    (:func:`~soilstats.wheel.stress.janosi`, the same operations in the same order)."""
    j = displacement(t1 * (1.0 - u), ahead, nu, wheel)
    k = cases.K
    assert k is not None  # cases.with_shear
    return np.copysign(1.0 - np.exp(-np.abs(j) / k[:, None]), j)


def _tau_xy(
    sigma: np.ndarray,
    t1: np.ndarray,
    u: np.ndarray,
    ahead: np.ndarray,
    cases: Cases,
    wheel: Wheel | _Geometry,
) -> tuple[np.ndarray, np.ndarray]:
    """(τ_x, τ_y) at the nodes at slip angle β (:func:`~soilstats.wheel.lateral.combined_shear`).

    j_x with the heading component ν cos β of the travel speed, j_y = ν sin β r (θ1 − θ).
    """
    nu = cases.nu[:, None]
    nu = np.where(np.isfinite(nu), nu, 1e200)  # locked: huge finite ν, as in _tau
    cos_b, sin_b = cases.cos_beta, cases.sin_beta
    assert cos_b is not None and sin_b is not None  # cases.with_slip_angle
    behind = t1 * (1.0 - u)
    j_x = displacement(behind, ahead, nu * cos_b[:, None], wheel)
    j_y = (nu * sin_b[:, None]) * (wheel.radius_m * behind)
    c, tan_phi, k, k_y = cases.c, cases.tan_phi, cases.K, cases.K_y
    assert c is not None and tan_phi is not None and k is not None  # cases.with_shear
    return combined_shear(
        sigma,
        j_x,
        j_y,
        c[:, None],
        tan_phi[:, None],
        k[:, None],
        None if k_y is None else k_y[:, None],
    )


def _side_face(
    cos_theta: np.ndarray, cos1: np.ndarray, cases: Cases, wheel: Wheel | _Geometry
) -> np.ndarray:
    """Ishigami's side-face integrand R_b(h) (R − h cos θ), h = R(cos θ − cos θ1) [N/m]."""
    rc = wheel.contact_radius_m
    h = rc * np.maximum(cos_theta - cos1, 0.0)
    c, tan_phi, gamma = cases.c, cases.tan_phi, cases.unit_weight
    assert c is not None and tan_phi is not None and gamma is not None
    rb = bulldozing_resistance(h, c[:, None], tan_phi[:, None], gamma[:, None])
    return rb * (rc - h * cos_theta)
