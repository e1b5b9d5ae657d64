"""Posterior or population draws through the wheel model: predictive bands against slip.

Each row of the draws is one joint parameter set and is used as a whole, so the correlations
of the draws (kc–kφ–n, c–φ–K) reach the predictions unchanged; the model runs on all
draws × slips at once (:func:`soilstats.wheel.solve.wheel_forces`), with no Python loop per
draw.  Parameters that no draw carries are taken from user-stated priors
(:mod:`soilstats.bayes.stated_priors`) or not at all: without c, φ and K the sinkage is still
predicted (from the normal stress alone) and the drawbar pull and torque are reported as not
predictable, with the reason.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping
from typing import cast

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ..bayes.stated_priors import describe_prior, sample_priors
from ..errors import InputError, SoilstatsWarning
from .forces import N_NODES
from .geometry import Wheel
from .lateral import LateralSoil
from .result import QUANTITIES, WheelPrediction
from .solve import STATUS, WheelState, wheel_forces
from .stress import SHEAR_PARAMS, SINKAGE_LAWS, StressAngles

__all__ = ["predict_wheel"]

LONGITUDINAL_ONLY = (
    "Slip angle β = 0: the longitudinal model (Wong & Reece 1967); no lateral force."
)
SLIP_ANGLE_MODEL = (
    "Slip angle β ≠ 0: lateral shear j_y = ν sin β r (θ1 − θ) (Ishigami et al. 2007), "
    "Janosi–Hanamoto on the resultant displacement split along it (|τ| ≤ c + σ tan φ, as CMU's "
    "3D model), side-face bulldozing force (Hegedus, Ishigami et al. 2007) × sin β with soil unit "
    "weight γ = {gamma:g} N/m³ and K_y = {ky}; lateral_force_N + opposes the sideways sliding."
)


def predict_wheel(
    draws: pd.DataFrame | None,
    wheel: Wheel,
    load_N: ArrayLike,
    slips: ArrayLike,
    *,
    law: str | None = None,
    priors: Mapping[str, tuple] | None = None,
    angles: StressAngles | None = None,
    n_samples: int | None = None,
    seed: int = 0,
    prob: float = 0.9,
    draws_source: str = "posterior draws",
    slip_angle_deg: ArrayLike = 0.0,
    n_nodes: int = N_NODES,
    lateral: LateralSoil | None = None,
) -> WheelPrediction:
    """Predictive bands (median, ``prob`` band) of sinkage, drawbar pull, torque and lateral force.

    Parameters
    ----------
    draws : DataFrame or None
        Joint draws, one row per parameter set, columns named by parameter in SI units with φ
        in degrees (:meth:`PosteriorResult.draws`, :func:`soilstats.bayes.joint_draws`).
        Columns the model does not use are ignored.  None: every parameter from ``priors``.
    wheel : Wheel
    load_N : float or array of len(slips)
        Normal load W [N], per slip if an array.
    slips : array
        Slips s = (rω − V)/max(rω, V) in [−1, 1].
    law : {"bekker", "bernstein", "reece"}, optional
        Pressure–sinkage law; by default the one whose parameters the draws and priors hold.
    priors : mapping, optional
        Parameter → prior tuple for parameters not in the draws, e.g.
        ``{"phi": ("normal", 30, 3), "c": ("uniform", 0, 1000), "K": ("lognormal", 0.01, 0.5)}``
        (c Pa, φ deg, K m; :mod:`soilstats.bayes.stated_priors`), sampled with ``seed`` and attached
        to the draws row by row (independent of them).
    angles : StressAngles, optional
        θm, θ2 coefficients (default a0 = 0.4, a1 = 0.15, b0 = b1 = 0).
    n_samples : int, optional
        Number of prior draws when ``draws`` is None.
    seed : int
        Seed of the prior draws.
    prob : float
        Probability of the equal-tailed band (0.9: 5 %–95 %).
    draws_source : str
        How the draws' parameters are labelled in :attr:`WheelPrediction.sources`
        (``"posterior draws"``, ``"population draws"`` …).
    slip_angle_deg : float or array of len(slips)
        Slip angle β [deg] in [−90, 90], per slip if an array (:mod:`soilstats.wheel.lateral`);
        0: the longitudinal model.
    lateral : LateralSoil, optional
        Soil unit weight γ of the side-face force and K_y at β ≠ 0 (default: γ of the CMU
        sand, 13,047 N/m³, and K_y = K — stated in the notes).

    Returns
    -------
    WheelPrediction

    Raises
    ------
    ValueError
        A parameter the law needs is in neither the draws nor the priors; a prior is given for
        a parameter the draws already hold or the model does not use; non-finite draws.
    ValueError
        ``slip_angle_deg`` outside [−90, 90] or not of len(slips).
    """
    if not 0 < prob < 1:
        raise InputError(f"prob must be in (0, 1), got {prob!r}")
    priors = dict(priors or {})
    columns = [] if draws is None else list(draws.columns)
    law = _law(law, columns, priors)
    used = list(SINKAGE_LAWS[law]) + [k for k in SHEAR_PARAMS if k in columns or k in priors]
    _check_priors(priors, columns, used, law)
    size = _size(draws, n_samples)
    table = cast(pd.DataFrame, draws)  # read only for its columns: none without draws
    values = {k: np.asarray(table[k], dtype=float) for k in used if k in columns}
    for k, v in values.items():
        if not np.all(np.isfinite(v)):
            raise InputError(f"draws column {k!r} has {np.sum(~np.isfinite(v))} non-finite values")
    values.update(sample_priors(priors, size, seed))
    sources = {
        k: draws_source if k in columns else f"user prior {describe_prior(priors[k])}" for k in used
    }
    s = np.atleast_1d(np.asarray(slips, dtype=float))
    if s.ndim != 1 or s.size == 0:
        raise InputError(f"slips must be a 1-D array of slips, got {slips!r}")
    load = np.broadcast_to(np.asarray(load_N, dtype=float), s.shape).astype(float)
    beta = _slip_angles(slip_angle_deg, s)
    lateral = LateralSoil() if lateral is None else lateral
    angles = StressAngles() if angles is None else angles
    state = wheel_forces(
        values,
        wheel,
        s,
        law=law,
        load_N=load[None, :],
        angles=angles,
        slip_angle_deg=beta[None, :],
        n_nodes=n_nodes,
        lateral=lateral,
    )
    unpredictable = {} if state.with_shear else _no_shear_reasons(columns, priors)
    outputs = {
        "sinkage_m": state.sinkage_m,
        "drawbar_pull_N": state.drawbar_pull_N,
        "torque_Nm": state.torque_Nm,
        "lateral_force_N": state.lateral_force_N,
    }
    bands = _bands(outputs, state.status, s, load, prob, unpredictable)
    samples = _samples(outputs, state.status, s)
    notes = _notes(state, s, load, wheel, law, unpredictable)
    notes[0] = _model_note(beta, lateral)
    _warn(state.status, unpredictable)
    return WheelPrediction(
        wheel=wheel,
        law=law,
        slips=tuple(float(v) for v in s),
        load_N=tuple(float(v) for v in load),
        prob=float(prob),
        bands=bands,
        samples=samples,
        sources=sources,
        unpredictable=unpredictable,
        angles=angles,
        n_draws=size,
        seed=int(seed),
        notes=tuple(notes),
        slip_angle_deg=tuple(float(v) for v in beta),
    )


def _slip_angles(slip_angle_deg: ArrayLike, slips: np.ndarray) -> np.ndarray:
    """β [deg] per slip: one angle for all, or one per slip."""
    beta = np.asarray(slip_angle_deg, dtype=float)
    if beta.ndim > 1 or (beta.ndim == 1 and beta.shape != slips.shape):
        raise InputError(
            f"slip_angle_deg must be one angle or one per slip ({slips.size}), "
            f"got {slip_angle_deg!r}"
        )
    return np.broadcast_to(beta, slips.shape).astype(float)


def _model_note(beta: np.ndarray, lateral: LateralSoil) -> str:
    """The first note: the longitudinal model at β = 0, else the slip-angle model's terms."""
    if np.all(beta == 0):
        return LONGITUDINAL_ONLY
    return SLIP_ANGLE_MODEL.format(
        gamma=lateral.unit_weight_N_m3,
        ky="K" if lateral.K_y_m is None else f"{lateral.K_y_m:g} m",
    )


def _law(law: str | None, columns: list[str], priors: Mapping[str, tuple]) -> str:
    have = set(columns) | set(priors)
    if law is not None:
        if law not in SINKAGE_LAWS:
            raise InputError(f"unknown law {law!r}; choose one of {sorted(SINKAGE_LAWS)}")
        missing = [k for k in SINKAGE_LAWS[law] if k not in have]
        if missing:
            raise InputError(
                f"the {law} law needs {list(SINKAGE_LAWS[law])}; {missing} are in neither the "
                f"draws (columns {columns}) nor the priors: soilstats does not invent them"
            )
        return law
    fits = [name for name, p in SINKAGE_LAWS.items() if set(p) <= have]
    if len(fits) != 1:
        raise InputError(
            f"cannot tell the pressure-sinkage law from the draws' columns {columns} and priors "
            f"{sorted(priors)} (laws that fit: {fits}); pass law= one of {sorted(SINKAGE_LAWS)}"
        )
    return fits[0]


def _check_priors(
    priors: Mapping[str, tuple], columns: list[str], used: Iterable[str], law: str
) -> None:
    clash = sorted(set(priors) & set(columns))
    if clash:
        raise InputError(f"{clash} are in the draws and also given a prior: give each one once")
    unused = sorted(set(priors) - set(used))
    if unused:
        raise InputError(
            f"priors for {unused} are not parameters of the {law} law + Janosi–Hanamoto shear "
            f"({list(SINKAGE_LAWS[law]) + list(SHEAR_PARAMS)})"
        )
    partial = [k for k in SHEAR_PARAMS if k in used]
    if partial and len(partial) < len(SHEAR_PARAMS):
        missing = [k for k in SHEAR_PARAMS if k not in used]
        raise InputError(
            f"the shear needs c [Pa], phi [deg] and K [m]; {partial} are given but {missing} are "
            "in neither the draws nor the priors: state a prior for them too, or give none"
        )


def _size(draws: pd.DataFrame | None, n_samples: int | None) -> int:
    if draws is not None:
        if n_samples is not None and n_samples != len(draws):
            raise InputError("n_samples is for prior-only predictions; the draws set the size")
        if len(draws) == 0:
            raise InputError("draws has no rows")
        return len(draws)
    if n_samples is None or n_samples < 1:
        raise InputError("without draws, give n_samples (the number of prior draws)")
    return int(n_samples)


def _no_shear_reasons(columns: list[str], priors: Mapping[str, tuple]) -> dict[str, str]:
    reason = (
        "needs the Janosi–Hanamoto shear parameters c [Pa], phi [deg] and K [m], which are in "
        f"neither the draws (columns {columns}) nor the priors ({sorted(priors)}): no shear "
        "test measured them. State them as priors with their uncertainty, e.g. "
        "priors={'c': ('uniform', 0, 1000), 'phi': ('normal', 30, 3), "
        "'K': ('lognormal', 0.01, 0.5)}, to predict it"
    )
    return {"drawbar_pull_N": reason, "torque_Nm": reason, "lateral_force_N": reason}


def _bands(
    outputs: Mapping[str, np.ndarray],
    status: np.ndarray,
    slips: np.ndarray,
    load: np.ndarray,
    prob: float,
    unpredictable: Mapping[str, str],
) -> pd.DataFrame:
    q = [(1 - prob) / 2, 0.5, (1 + prob) / 2]
    ok = status == 0
    n_used = ok.sum(0)
    rows = []
    for name, values in outputs.items():
        if name in unpredictable:
            continue
        quant = np.full((3, len(slips)), np.nan)
        some = n_used > 0
        if np.any(some):
            quant[:, some] = np.nanquantile(values[:, some], q, axis=0)
        for j, s in enumerate(slips):
            rows.append(
                {
                    "slip": float(s),
                    "load_N": float(load[j]),
                    "quantity": name,
                    "unit": QUANTITIES[name],
                    "median": quant[1, j],
                    "lower": quant[0, j],
                    "upper": quant[2, j],
                    "n_used": int(n_used[j]),
                    "n_not_carried": int(np.sum(status[:, j] == 1)),
                    "n_not_converged": int(np.sum(status[:, j] == 2)),
                }
            )
    return pd.DataFrame(rows)


def _samples(
    outputs: Mapping[str, np.ndarray], status: np.ndarray, slips: np.ndarray
) -> pd.DataFrame:
    n, m = status.shape
    frame = {"draw": np.repeat(np.arange(n), m), "slip": np.tile(slips, n)}
    frame.update({k: v.reshape(-1) for k, v in outputs.items()})
    frame["status"] = pd.Categorical.from_codes(  # type: ignore[call-overload]  # pandas-stubs: categories typed as an Index only
        status.reshape(-1), list(STATUS.values())
    )
    return pd.DataFrame(frame)


def _warn(status: np.ndarray, unpredictable: Mapping[str, str]) -> None:
    """One SoilstatsWarning for what the result cannot give: loud, details in its notes."""
    parts = []
    if unpredictable:
        parts.append(
            "drawbar pull and torque are not predicted, nor the lateral force (no c, phi, K "
            "in draws or priors)"
        )
    for code, what in ((1, "cannot carry the load within θ1 < 90°"), (2, "did not converge")):
        k = int(np.sum(np.any(status == code, axis=1)))
        if k:
            parts.append(f"{k} of {status.shape[0]} draws {what} at some slip")
    if parts:
        warnings.warn("; ".join(parts) + " (see the result's notes)", SoilstatsWarning, 3)


def _notes(
    state: WheelState,
    slips: np.ndarray,
    load: np.ndarray,
    wheel: Wheel,
    law: str,
    unpredictable: Mapping[str, str],
) -> list[str]:
    notes = [LONGITUDINAL_ONLY]
    status = state.status
    for code, what in ((1, "cannot carry"), (2, "did not converge at")):
        bad = status == code
        groups: dict[tuple, list] = {}  # the same failing draws at several slips: one note
        for j in np.flatnonzero(bad.any(0)):
            groups.setdefault((tuple(np.flatnonzero(bad[:, j])), load[j]), []).append(j)
        for (idx, w), cols in groups.items():
            shown = ", ".join(map(str, idx[:10])) + (", …" if len(idx) > 10 else "")
            where = ", ".join(f"{slips[j]:g}" for j in cols)
            tail = f"the load W = {w:g} N"
            if code == 1:
                tail += f" within θ1 < 90° (sinkage < {1e3 * wheel.contact_radius_m:g} mm)"
            notes.append(
                f"At slip {where}: {len(idx)} of {status.shape[0]} draws {what} {tail}: "
                f"draws {shown}. They have no outputs (samples status '{STATUS[code]}'); the "
                "bands there are over the other draws only."
            )
    if unpredictable:
        notes.append(
            "Drawbar pull, torque and lateral force are NOT predicted: c, phi and K "
            "(Janosi–Hanamoto) are in "
            "neither the draws nor the priors, and soilstats does not invent them."
        )
        notes.append(
            "Sinkage without shear parameters: the load is carried by the normal stress alone "
            "(the vertical component of the shear stress, τ·sin θ, is left out of W)."
        )
    notes.append(
        f"Normal stress from the {law} law on a plate of the wheel's width b = "
        f"{1e3 * wheel.width_m:g} mm (Wong & Reece 1967); sinkage measured on the contact "
        f"circle of radius {1e3 * wheel.contact_radius_m:g} mm."
    )
    return notes
