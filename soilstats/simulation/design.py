"""The test log of a simulated campaign, and each test's drawn soil parameters.

:func:`expand` turns the series of a SPEC into test-log rows: the crossed design of soils ×
geometries × conditions × preparations × covariate levels × repetitions, operators assigned
in turn by repetition.  :func:`draw_parameters` gives every test its own soil parameters —
the soil's (with condition overrides), times the planted effects' factors, times the
preparation scatter and the operator's persistent bias ("the soil has some random
characteristic", Section 2.1).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from ..campaign.derived import aspect_ratio, bekker_b, plate_area
from .effects import parameter_factors
from .records import PARAMS, Series, Spec

__all__ = ["draw_parameters", "expand", "operator_biases"]


def _plate_columns(plate: dict[str, Any]) -> dict[str, Any]:
    """The plate's b, area and aspect ratio, from the campaign's own geometry (Eqs. 6–7)."""
    out = dict(plate)
    shape, radius = plate["shape"], plate.get("radius_m", np.nan)
    width, length = plate.get("width_m", np.nan), plate.get("length_m", np.nan)
    out["b_m"] = float(bekker_b(shape, radius, width))
    out["area_m2"] = float(plate_area(shape, radius, width, length))
    out["aspect_ratio"] = float(aspect_ratio(shape, width, length))
    return out


def _conditions(series: Series) -> list[dict[str, Any]]:
    if series.kind == "sinkage":
        return [{"velocity_m_s": v} for v in series.velocity_m_s]
    return [
        {"grousers": g, "grouser_height_m": h, "omega_rpm": w, "normal_pressure_Pa": s}
        for g, h, w, s in itertools.product(
            series.grousers, series.grouser_height_m, series.omega_rpm, series.normal_pressure_Pa
        )
    ]


def expand(spec: Spec) -> list[dict[str, Any]]:
    """One dict per test, in file order: log columns plus private geometry keys.

    Keys ``b_m``, ``area_m2``, ``aspect_ratio`` and ``normal_pressure_Pa`` are used by the
    generators and the truth table; they are not written to ``tests.csv`` (the campaign
    derives the first three itself; the set-point pressure is in ``truth_tests.csv``).
    """
    rows = []
    for series in spec.series:
        count = 0
        cov_names = list(series.covariates)
        cov_levels = list(itertools.product(*series.covariates.values())) or [()]
        geometries = (
            [_plate_columns(g) for g in series.geometries]
            if series.kind == "sinkage"
            else [dict(g) for g in series.geometries]
        )
        for soil, geometry, cond, prep_name, levels in itertools.product(
            series.soils, geometries, _conditions(series), series.preparations, cov_levels
        ):
            prep = spec.preparations[prep_name]
            for rep in range(1, series.repetitions + 1):
                count += 1
                row: dict[str, Any] = {
                    "test_id": f"{series.name}-{count:04d}",
                    "kind": series.kind,
                    "soil": soil,
                    "preparation": prep_name,
                    "operator": series.operators[(rep - 1) % len(series.operators)],
                    "repetition": rep,
                    **geometry,
                    **cond,
                    "series": series.name,
                    **prep.columns,
                    **dict(zip(cov_names, levels, strict=True)),
                }
                rows.append(row)
    return rows


def operator_biases(spec: Spec, rng: np.random.Generator) -> dict[tuple[str, str], float]:
    """Persistent log-factor of each (preparation, operator) pair: N(0, operator_cv²).

    Drawn for every pair of the SPEC in sorted order, so the draw does not depend on which
    tests exist (criterion 2 of Table 1: a method is operator-dependent when this is large).
    """
    operators = sorted({o for s in spec.series for o in s.operators})
    out = {}
    for prep in sorted(spec.preparations):
        for op in operators:
            out[(prep, op)] = spec.preparations[prep].operator_cv * rng.standard_normal()
    return out


def draw_parameters(
    spec: Spec, row: dict[str, Any], rng: np.random.Generator, bias: float
) -> dict[str, float]:
    """The soil parameters of one test (Bekker Eq. 7 and Janosi Eq. 13 sets; φ in degrees).

    Parameters
    ----------
    spec : Spec
    row : dict
        The test's row from :func:`expand`.
    rng : numpy.random.Generator
        Five standard normals are drawn per test, whatever its kind, so that every test's
        draw is independent of the others' kinds and of the noise levels.
    bias : float
        The (preparation, operator) log-factor from :func:`operator_biases`.

    Returns
    -------
    dict
        ``kc, kphi, n, c, phi, K`` (NaN where the soil has no such parameter), the soil-level
        values (``*_soil``: with condition overrides and effects, before scatter) and the
        combined log-normal ``stiffness_factor``.
    """
    soil = spec.soils[row["soil"]]
    base = soil.params_for(row)
    factors = parameter_factors(spec.effects, row, base)
    sc = spec.preparations[row["preparation"]].scatter
    u = rng.standard_normal(5)
    level = {k: base.get(k, math.nan) * factors[k] for k in PARAMS}
    stiffness = math.exp(sc.stiffness_cv * u[0] + bias)
    drawn = {
        "kc": level["kc"] * stiffness,
        "kphi": level["kphi"] * stiffness,
        "n": level["n"] + sc.n_sd * u[1],
        "c": level["c"] * math.exp(sc.c_cv * u[2] + bias),
        "phi": level["phi"] + sc.phi_sd_deg * u[3],
        "K": level["K"] * math.exp(sc.K_cv * u[4]),
    }
    out = dict(drawn)
    out.update({f"{k}_soil": v for k, v in level.items()})
    out["stiffness_factor"] = stiffness
    return out
