"""Planted effects: how a test's setup changes what the soil shows (checked, then applied).

Five kinds (the ``kind`` of an ``[[effects]]`` entry of a SPEC, see ``docs/simulator.md``):

``covariate``
    Any test-log column (a named one such as ``operator`` or an extra one such as ``bin`` or
    ``moisture_pct``) scales parameters: categorical, ``levels = {A = 1.0, B = 1.2}`` (a level
    not listed keeps factor 1), or continuous, factor = 1 + ``slope``·(x − ``reference``).
``velocity``
    Penetration-velocity dependence: factor = (v / ``reference_m_s``)^``exponent``.
``size``
    Reece-type plate-size dependence: factor = (b / ``reference_b_m``)^``exponent`` on kc and kφ.
    ``exponent = "reece"`` means 1 − n, which turns Bekker's (kc/b + kφ)·z^n with kc = 0 into
    Reece's frictional term k2·b·(z/b)^n with k2 = kφ·b_ref^(n−1).
``softening``
    The two-stage behaviour of Fig. 9: beyond ``critical_sinkage_m`` z_c, the pressure
    increment of plates with aspect ratio ≥ ``min_aspect_ratio`` is multiplied by ``factor``:
    p(z) = p(z_c) + factor·(p_Bekker(z) − p(z_c)) for z > z_c.
``side-walls``
    Shear on the inner and outer cylindrical walls of a grousered ring (ignored by Eq. 12):
    walls of height h at radii r_i, r_o carry s = c + K0·σ·tan φ, adding torque
    ΔT = 2π·h·(r_i² + r_o²)·s·(1 − e^(−j/K)).  Through Eq. 12 the apparent cohesion becomes
    c·(1 + a) and tan φ becomes tan φ·(1 + a·K0), a = 3h(r_i² + r_o²)/(r_o³ − r_i³).

Factors multiply the parameters (φ in degrees); each effect may be limited to ``soils`` and
``series``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import refuse_unknown_keys
from .records import PARAMS, Effect, SpecError

__all__ = ["apparent_shear", "check_effect", "parameter_factors", "soften"]

_ALLOWED = {
    "covariate": ("column", "parameters", "levels", "slope", "reference"),
    "velocity": ("parameters", "exponent", "reference_m_s"),
    "size": ("parameters", "exponent", "reference_b_m"),
    "softening": ("critical_sinkage_m", "factor", "min_aspect_ratio"),
    "side-walls": ("K0",),
}


def _num(
    options: dict,
    key: str,
    where: str,
    default: float | None = None,
    lo: float | None = None,
    hi: float | None = None,
) -> float:
    value = options.get(key, default)
    if value is None:
        raise SpecError(f"SPEC {where}.{key}: required for this effect kind")
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SpecError(f"SPEC {where}.{key}: must be a finite number, got {value!r}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise SpecError(f"SPEC {where}.{key}: must lie in [{lo}, {hi}], got {value!r}")
    return float(value)


def _parameters(options: dict, where: str, default: tuple[str, ...] | None) -> tuple[str, ...]:
    value = options.get("parameters", default)
    if value is None:
        raise SpecError(f"SPEC {where}.parameters: required; choose from {list(PARAMS)}")
    names = (value,) if isinstance(value, str) else tuple(value)
    for name in names:
        if name not in PARAMS:
            raise SpecError(
                f"SPEC {where}.parameters: {name!r} is not a valid option; choose "
                f"from {list(PARAMS)}"
            )
    return names


def check_effect(kind: str, options: dict[str, Any], where: str) -> dict[str, Any]:
    """Check the options of one effect and return them normalised.

    Raises
    ------
    SpecError
        For an unknown key, a missing or out-of-range value.
    """
    refuse_unknown_keys(
        options,
        _ALLOWED[kind],
        lambda unknown: SpecError(
            f"SPEC {where}.{unknown[0]}: unknown key for a {kind!r} effect; valid keys "
            f"are {[*_ALLOWED[kind], 'soils', 'series']}"
        ),
    )
    if kind == "covariate":
        column = options.get("column")
        if not isinstance(column, str) or not column:
            raise SpecError(f"SPEC {where}.column: required, the test-log column (e.g. 'bin')")
        out: dict[str, Any] = {"column": column, "parameters": _parameters(options, where, None)}
        if ("levels" in options) == ("slope" in options):
            raise SpecError(
                f"SPEC {where}: give exactly one of 'levels' (categorical: "
                "{level = factor}) or 'slope' (continuous, per unit)"
            )
        if "levels" in options:
            levels = options["levels"]
            if not isinstance(levels, dict) or not levels:
                raise SpecError(f"SPEC {where}.levels: must be a table level = factor")
            out["levels"] = {str(k): _num(levels, k, f"{where}.levels", lo=0.0) for k in levels}
        else:
            out["slope"] = _num(options, "slope", where)
            out["reference"] = _num(options, "reference", where, default=0.0)
        return out
    if kind == "velocity":
        return {
            "parameters": _parameters(options, where, ("kc", "kphi")),
            "exponent": _num(options, "exponent", where),
            "reference_m_s": _num(options, "reference_m_s", where, lo=1e-12),
        }
    if kind == "size":
        exponent = options.get("exponent", "reece")
        if exponent != "reece":
            exponent = _num(options, "exponent", where)
        return {
            "parameters": _parameters(options, where, ("kc", "kphi")),
            "exponent": exponent,
            "reference_b_m": _num(options, "reference_b_m", where, lo=1e-9),
        }
    if kind == "softening":
        return {
            "critical_sinkage_m": _num(options, "critical_sinkage_m", where, lo=0.0),
            "factor": _num(options, "factor", where, lo=0.0, hi=1.0),
            "min_aspect_ratio": _num(options, "min_aspect_ratio", where, default=5.0, lo=1.0),
        }
    return {"K0": _num(options, "K0", where, default=0.5, lo=0.0, hi=1.0)}


def _as_float(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def parameter_factors(
    effects: tuple[Effect, ...], row: dict[str, Any], base: dict[str, float]
) -> dict[str, float]:
    """Product of the factors that the covariate, velocity and size effects put on each parameter.

    Parameters
    ----------
    effects : tuple of Effect
    row : dict
        The test's log row (soil, series, geometry, velocity, covariates, ``b_m``).
    base : dict
        The soil's parameters for this test (needed for ``exponent = "reece"``).
    """
    factors = dict.fromkeys(PARAMS, 1.0)
    for effect in effects:
        if not effect.applies(row["soil"], row["series"]):
            continue
        o = effect.options
        if effect.kind == "covariate":
            value = row.get(o["column"])
            if "levels" in o:
                key = _level_key(value)
                factor = o["levels"].get(key, 1.0)
            else:
                x = _as_float(value)
                factor = 1.0 if x is None else 1.0 + o["slope"] * (x - o["reference"])
        elif effect.kind == "velocity" and row["kind"] == "sinkage":
            factor = (row["velocity_m_s"] / o["reference_m_s"]) ** o["exponent"]
        elif effect.kind == "size" and row["kind"] == "sinkage":
            exponent = 1.0 - base["n"] if o["exponent"] == "reece" else o["exponent"]
            factor = (row["b_m"] / o["reference_b_m"]) ** exponent
        else:
            continue
        for name in o["parameters"]:
            factors[name] *= factor
    return factors


def _level_key(value: Any) -> str:
    """Categorical levels are matched as text; whole floats as integers ('12', not '12.0')."""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


def softening_of(effects: tuple[Effect, ...], row: dict[str, Any]) -> tuple[float, float] | None:
    """(z_c, factor) of the first softening effect that applies to this plate, else None."""
    for effect in effects:
        if effect.kind != "softening" or not effect.applies(row["soil"], row["series"]):
            continue
        if row["aspect_ratio"] >= effect.options["min_aspect_ratio"] - 1e-9:
            return effect.options["critical_sinkage_m"], effect.options["factor"]
    return None


def soften(z: np.ndarray, p: np.ndarray, p_at_zc: float, zc: float, factor: float) -> np.ndarray:
    """Reduce the pressure increment beyond z_c by ``factor`` (Fig. 9, second stage)."""
    return np.where(z > zc, p_at_zc + factor * (p - p_at_zc), p)


def side_wall_K0(effects: tuple[Effect, ...], row: dict[str, Any]) -> float | None:
    """K0 of the first side-wall effect that applies to this shear test, else None."""
    for effect in effects:
        if effect.kind == "side-walls" and effect.applies(row["soil"], row["series"]):
            return effect.options["K0"]
    return None


def apparent_shear(c: float, phi_deg: float, a: float, K0: float) -> tuple[float, float]:
    """(c, φ) that Eq. 12 + Eq. 15 report when side walls add a·(c + K0·σ·tan φ) to τ."""
    tan_app = math.tan(math.radians(phi_deg)) * (1.0 + a * K0)
    return c * (1.0 + a), math.degrees(math.atan(tan_app))
