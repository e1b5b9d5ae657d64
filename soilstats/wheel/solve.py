"""The wheel's state at a given load (entry angle θ1 solved) or at a given sinkage.

:func:`wheel_forces` is the model of :mod:`soilstats.wheel` for one parameter set or arrays of
them (draws) at one or many slips.  Load-controlled: the entry angle θ1 is the root of
W(θ1) = W_target on 0 < θ1 ≤ 90° (Wong & Reece 1967; the CMU model's ``find_sinkage.m`` does
the same by bisection on the sinkage).  The root is found for all cases at once by a
bracketed secant on ln W against ln θ1 (:func:`solve_entry_angle`), vectorised over the cases
that have not converged yet (about five evaluations of W per case).  A case whose W at
θ1 = 90° (sinkage r_s) is still below the load cannot be carried by the soil in this model:
it is flagged ``not_carried`` and its outputs are NaN, never a number.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from .forces import N_NODES, Cases, ContactForces, PlateStress, contact_forces, gauss_rule
from .geometry import Wheel, entry_angle, sinkage_from_entry_angle, speed_ratio
from .lateral import LateralSoil, slip_angle_rad
from .stress import SHEAR_PARAMS, StressAngles, sinkage_law

__all__ = ["STATUS", "WheelState", "solve_entry_angle", "wheel_forces"]

#: Status codes of each case.
STATUS = {0: "ok", 1: "not_carried", 2: "not_converged"}
OK, NOT_CARRIED, NOT_CONVERGED = 0, 1, 2

THETA1_MAX = 0.5 * np.pi


def solve_entry_angle(
    load_N: ArrayLike,
    cases: Cases,
    wheel: Wheel,
    rule: tuple[np.ndarray, np.ndarray] | None = None,
    *,
    xtol: float = 1e-10,
    rtol_load: float = 1e-10,
    max_iter: int = 100,
) -> tuple[np.ndarray, np.ndarray]:
    """θ1 [rad] with W(θ1) = load for every case, and a status code per case (:data:`STATUS`).

    A safeguarded secant on ln W against ln θ1 (W grows about as θ1^(2n+1)), inside a bracket
    that starts as (0, π/2] and shrinks with every evaluation; a step that leaves the bracket,
    and every step after 30, is a bisection.  The first point is the power law W ∝ θ1^(2n+1)
    through W(π/2).  Stops per case when |W − load| ≤ ``rtol_load``·load or the bracket is
    narrower than ``xtol`` rad.
    """
    rule = gauss_rule() if rule is None else rule
    target = np.broadcast_to(np.asarray(load_N, dtype=float), (len(cases),)).copy()
    if np.any(~(target > 0)):
        raise InputError(f"the load must be a positive force in N, got {load_N!r}")
    theta1 = np.full(len(cases), np.nan)
    status = np.full(len(cases), OK, dtype=np.int8)
    top = contact_forces(np.full(len(cases), THETA1_MAX), cases, wheel, rule, load_only=True)
    carried = top >= target
    status[~carried] = NOT_CARRIED
    lo, hi = np.zeros(len(cases)), np.full(len(cases), THETA1_MAX)
    x_prev, w_prev = hi.copy(), top
    with np.errstate(divide="ignore", invalid="ignore"):
        x = THETA1_MAX * (target / top) ** (1.0 / (2.0 * cases.n + 1.0))
    active = np.flatnonzero(carried)
    for iteration in range(max_iter):
        if active.size == 0:
            break
        i = active
        # every case still active (the usual first steps): no copy of the cases
        active_cases = cases if i.size == len(cases) else cases.take(i)
        w = contact_forces(x[i], active_cases, wheel, rule, load_only=True)
        below = w < target[i]
        lo[i] = np.where(below, x[i], lo[i])
        hi[i] = np.where(below, hi[i], x[i])
        done = (np.abs(w - target[i]) <= rtol_load * target[i]) | (hi[i] - lo[i] <= xtol)
        theta1[i[done]] = x[i[done]]
        i, w = i[~done], w[~done]
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = np.log(w / w_prev[i]) / np.log(x[i] / x_prev[i])
            step = x[i] * np.exp(np.log(target[i] / w) / slope)
        bisect = ~((step > lo[i]) & (step < hi[i])) | (iteration >= 30)
        x_prev[i], w_prev[i] = x[i], w
        x[i] = np.where(bisect, 0.5 * (lo[i] + hi[i]), step)
        active = i
    status[active] = NOT_CONVERGED
    return theta1, status


@dataclass(frozen=True)
class WheelState:
    """The wheel at each case: arrays of the broadcast shape (parameters × slips).

    Lengths in m, angles in rad, forces in N, torque in N·m.  ``load_N`` is the load the
    model carries (the target when solved for a load; the integrated W at a given sinkage).
    ``drawbar_pull_N`` = ``thrust_N`` − ``resistance_N`` (+ forward); ``torque_Nm`` is the
    torque the axle applies (+ driving).  Entries whose ``status`` is not 0 (:data:`STATUS`)
    are NaN.  Without shear parameters ``thrust_N``, ``drawbar_pull_N`` and ``torque_Nm`` are
    NaN and the load is carried by the normal stress alone (``with_shear`` False).

    At a slip angle β (:mod:`.lateral`): ``slip_angle_deg`` (broadcast), ``lateral_force_N`` =
    ``lateral_shear_N`` + ``side_force_N`` [N] along the axle, + opposing the wheel's sideways
    sliding (the CMU data's sign; odd in β, 0 at β = 0); NaN without shear parameters.
    """

    slip: np.ndarray
    sinkage_m: np.ndarray
    theta1_rad: np.ndarray
    theta_m_rad: np.ndarray
    theta2_rad: np.ndarray
    load_N: np.ndarray
    thrust_N: np.ndarray
    resistance_N: np.ndarray
    drawbar_pull_N: np.ndarray
    torque_Nm: np.ndarray
    status: np.ndarray
    with_shear: bool
    slip_angle_deg: np.ndarray
    lateral_force_N: np.ndarray
    lateral_shear_N: np.ndarray
    side_force_N: np.ndarray


def model_cases(
    params: Mapping,
    wheel: Wheel,
    slip: ArrayLike,
    law: str,
    angles: StressAngles | tuple[np.ndarray, np.ndarray],
    exponent_shift: ArrayLike | None = None,
) -> tuple[Cases, tuple[int, ...]]:
    """(Cases, shape) for the parameter arrays × the slips (outer product, slips last).

    ``angles`` is a :class:`StressAngles`, or per case the ratios (θm/θ1, θ2/θ1) as two
    arrays broadcast to P + S (a calibration's stress angles differ by draw; the caller
    checks their order).  ``exponent_shift`` (broadcast to P + S) is added to each case's
    exponent n: a slip-dependent exponent n + Δn(s) (Ding et al. 2010;
    :mod:`soilstats.wheel.slipsinkage`).
    """
    model = sinkage_law(law)
    law_params = model.param_names
    missing = [k for k in law_params if k not in params]
    if missing:
        raise InputError(f"the {law} law needs parameters {list(law_params)}; missing {missing}")
    given = [k for k in SHEAR_PARAMS if k in params]
    if given and len(given) < len(SHEAR_PARAMS):
        raise InputError(
            f"shear needs all of c [Pa], phi [deg], K [m]; got only {given}: give all three or none"
        )
    names = list(law_params) + given
    values = np.broadcast_arrays(*(np.asarray(params[k], dtype=float) for k in names))
    pshape = values[0].shape
    p = {k: v[..., None] for k, v in zip(names, (v.reshape(-1) for v in values), strict=True)}
    s = np.asarray(slip, dtype=float)
    if isinstance(angles, StressAngles):
        a, b = angles.ratios(s.reshape(-1))
    else:
        a, b = (
            np.broadcast_to(np.asarray(r, float), pshape + s.shape).reshape(-1, s.size)
            for r in angles
        )
    nu = speed_ratio(s.reshape(-1))
    exponent = model.exponent
    if exponent_shift is not None:
        if exponent is None:
            raise InputError(f"the {law} law has no exponent n for a slip-dependent exponent")
        shift = np.broadcast_to(np.asarray(exponent_shift, dtype=float), pshape + s.shape)
        p[exponent] = p[exponent] + shift.reshape(p[exponent].shape[0], -1)
    n = p[exponent] if exponent is not None else np.ones_like(p[names[0]])
    shear = {"c": p["c"], "phi_deg": p["phi"], "K": p["K"]} if given else {}
    k_eq = model.plate_modulus(wheel.width_m, *(p[k] for k in law_params))
    if k_eq is not None:  # a power law: σ = k_eq·R^n·(cos θe − cos θ1)^n, the fast path
        prefactor = k_eq * wheel.stress_radius_power(n)
        cases = Cases.build(prefactor=prefactor, n=n, a=a, b=b, nu=nu, **shear)
        return cases, pshape + s.shape
    # any other law: its pressure at each node's local depth (PlateStress)
    cases = Cases.build(prefactor=np.nan, n=n, a=a, b=b, nu=nu, **shear)
    stacked = np.broadcast_arrays(*(p[k] for k in law_params), np.empty((1, a.size)))[:-1]
    plate_params = np.column_stack([v.reshape(-1) for v in stacked])
    pressure = model.plate_law()
    assert pressure is not None  # sinkage_law() admits only laws with a plate hook
    cases = replace(cases, plate=PlateStress(pressure, wheel), plate_params=plate_params)
    return cases, pshape + s.shape


def wheel_forces(
    params: Mapping,
    wheel: Wheel,
    slip: ArrayLike,
    *,
    law: str,
    load_N: ArrayLike | None = None,
    sinkage_m: ArrayLike | None = None,
    angles: StressAngles | None = None,
    slip_angle_deg: ArrayLike = 0.0,
    n_nodes: int = N_NODES,
    exponent_shift: ArrayLike | None = None,
    lateral: LateralSoil | None = None,
) -> WheelState:
    """The Wong–Reece rigid wheel at a given load or a given sinkage, over parameter sets × slips.

    Parameters
    ----------
    params : mapping
        The law's parameters (Bekker ``kc`` N/m^(n+1), ``kphi`` N/m^(n+2), ``n``; Bernstein
        ``k`` N/m^(n+2), ``n``; Reece ``k1`` Pa, ``k2`` Pa/m, ``n``) and optionally the shear
        parameters ``c`` [Pa], ``phi`` [deg], ``K`` [m] — floats or arrays of one shape P
        (e.g. the columns of a DataFrame of draws).
    wheel : Wheel
    slip : float or array of shape S
        s = (rω − V)/max(rω, V) in [−1, 1].
    law : {"bekker", "bernstein", "reece"}
    load_N, sinkage_m : float or array broadcastable to P + S
        Exactly one: the normal load W [N] (θ1 solved), or the sinkage h [m] (θ1 =
        arccos(1 − h/r_s)).
    angles : StressAngles, optional
        θm and θ2 as fractions of θ1 (default a0 = 0.4, a1 = 0.15, b0 = b1 = 0).
    slip_angle_deg : float or array broadcastable with P + S
        Slip angle β [deg] in [−90, 90] between the heading and the travel direction; an array
        that adds axes (e.g. shape (B, 1) against S slips) extends the outputs to them
        (:mod:`.lateral`: lateral shear on the resultant displacement, Ishigami et al. 2007's
        side-face force × sin β).  0 (default) is the longitudinal model, unchanged.
    exponent_shift : float or array broadcastable to P + S, optional
        Δn added to the exponent n of every case: a slip-dependent exponent n + Δn(s)
        (:func:`soilstats.wheel.slipsinkage.exponent_shift`). Default none.
    lateral : LateralSoil, optional
        Soil unit weight γ of the side-face force and K_y (default :class:`LateralSoil`():
        γ of the CMU sand, K_y = K); used only where β ≠ 0.

    Returns
    -------
    WheelState
        Arrays of shape P + S.
    """
    if (load_N is None) == (sinkage_m is None):
        raise InputError("give exactly one of load_N (load-controlled) or sinkage_m")
    angles = StressAngles() if angles is None else angles
    beta = slip_angle_rad(slip_angle_deg)
    cases, shape = model_cases(params, wheel, slip, law, angles, exponent_shift)
    try:
        full = np.broadcast_shapes(shape, beta.shape)
    except ValueError:
        raise InputError(
            f"slip_angle_deg of shape {beta.shape} does not broadcast with the cases' shape "
            f"{shape} (parameters × slips)"
        ) from None
    if full != shape:  # β adds axes (e.g. a column of angles): repeat the cases along them
        index = np.broadcast_to(np.arange(len(cases)).reshape(shape), full).reshape(-1)
        cases, shape = cases.take(index), full
    beta = np.broadcast_to(beta, shape)
    if np.any(beta != 0):  # β = 0 everywhere: the longitudinal code path, unchanged
        lateral = LateralSoil() if lateral is None else lateral
        cases = cases.at_slip_angle(beta.reshape(-1), lateral.K_y_m, lateral.unit_weight_N_m3)
    rule = gauss_rule(n_nodes)
    rc = wheel.contact_radius_m
    if load_N is not None:
        load = np.broadcast_to(np.asarray(load_N, dtype=float), shape).reshape(-1)
        theta1, status = solve_entry_angle(load, cases, wheel, rule)
    else:
        h = np.broadcast_to(np.asarray(sinkage_m, dtype=float), shape).reshape(-1)
        theta1, status = entry_angle(h, rc), np.zeros(h.shape, dtype=np.int8)
    ok = status == 0
    forces = contact_forces(np.where(ok, theta1, 0.0), cases, wheel, rule)
    out = _state_arrays(forces, theta1, cases, ok, rc)
    out = {k: v.reshape(shape) for k, v in out.items()}
    slip_b = np.broadcast_to(np.asarray(slip, dtype=float), shape)
    return WheelState(
        slip=slip_b,
        status=status.reshape(shape),
        with_shear=cases.with_shear,
        slip_angle_deg=np.rad2deg(beta),
        **out,
    )


def _state_arrays(
    forces: ContactForces, theta1: np.ndarray, cases: Cases, ok: np.ndarray, rc: float
) -> dict:
    nan = np.where(ok, 1.0, np.nan)
    shear_nan = nan if cases.with_shear else np.full(nan.shape, np.nan)
    theta1 = theta1 * nan
    return {
        "sinkage_m": sinkage_from_entry_angle(theta1, rc),
        "theta1_rad": theta1,
        "theta_m_rad": cases.a * theta1,
        "theta2_rad": cases.b * theta1,
        "load_N": forces.load_N * nan,
        "thrust_N": forces.thrust_N * shear_nan,
        "resistance_N": forces.resistance_N * nan,
        "drawbar_pull_N": forces.drawbar_pull_N * shear_nan,
        "torque_Nm": forces.torque_Nm * shear_nan,
        "lateral_force_N": forces.lateral_force_N * shear_nan,
        "lateral_shear_N": _or_zero(forces.lateral_shear_N, forces.load_N) * shear_nan,
        "side_force_N": _or_zero(forces.side_force_N, forces.load_N) * shear_nan,
    }


def _or_zero(value: np.ndarray | None, like: np.ndarray) -> np.ndarray:
    return np.zeros_like(like) if value is None else value
