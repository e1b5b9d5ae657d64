"""Simulated plate campaigns and raw tables for the screening tests (test_quality*.py)."""

from __future__ import annotations

import pandas as pd

from soilstats.campaign import Campaign
from soilstats.campaign.schema import DERIVED_COLUMNS


def plate_spec(name: str, soils: dict, *, points: int = 120, repetitions: int = 4) -> dict:
    """A simulator spec: every soil on circular plates of 25, 50 and 75 mm, 30 mm deep."""
    return {
        "name": name,
        "scatter": {"stiffness_cv": 0.1, "n_sd": 0.03},
        "soils": soils,
        "series": [
            {
                "name": "plates",
                "kind": "sinkage",
                "soils": list(soils),
                "plates": [{"shape": "circle", "radius_m": b} for b in (0.025, 0.05, 0.075)],
                "repetitions": repetitions,
                "points": points,
                "sinkage_m": 0.03,
            }
        ],
    }


def artefact_spec(
    name: str,
    soils: dict,
    artefacts: list[dict],
    *,
    points: int,
    noise_N: float,
    radii: tuple[float, ...],
    repetitions: int,
    sinkage_m: float,
) -> dict:
    """A simulator spec with ``artefacts`` planted (``[[artefacts]]``; none: a clean
    campaign): every soil on circular plates of ``radii`` [m], ``noise_N`` of force noise and
    of force offset [N], stiffness cv 0.08 and n sd 0.02 between tests."""
    return {
        **({"artefacts": artefacts} if artefacts else {}),
        "name": name,
        "scatter": {"stiffness_cv": 0.08, "n_sd": 0.02},
        "noise": {"force_N": noise_N, "force_offset_N": noise_N},
        "soils": soils,
        "series": [
            {
                "name": "plates",
                "kind": "sinkage",
                "soils": list(soils),
                "plates": [{"shape": "circle", "radius_m": b} for b in radii],
                "repetitions": repetitions,
                "points": points,
                "sinkage_m": sinkage_m,
            }
        ],
    }


def flagged_rows(report, code: str) -> dict[str, set]:
    """The 1-based file rows of each test's ``code`` findings in a screening ``report``."""
    out: dict[str, set] = {}
    for f in report.flags:
        if f.code == code:
            out.setdefault(f.test_id, set()).update(f.rows)
    return out


def raw_tables(campaign: Campaign) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The test log and sinkage table as a user writes them (no derived columns)."""
    tests = campaign.tests.drop(columns=list(DERIVED_COLUMNS["tests"]), errors="ignore")
    sinkage = campaign.sinkage.drop(columns=list(DERIVED_COLUMNS["sinkage"]), errors="ignore")
    return tests, sinkage.reset_index(drop=True)


def hold_plateau(sinkage: pd.DataFrame, failing, rng) -> tuple[pd.DataFrame, dict[str, float]]:
    """``sinkage`` with the force of the ``failing`` tests held (+-1 %) from 35 % of their
    samples to the end, a plateau the plate sinks into; and where each plateau starts [m]."""
    failing = {str(t) for t in failing}
    parts, start = [], {}
    for tid, group in sinkage.groupby("test_id", sort=False):
        if str(tid) in failing:
            group = group.copy()
            f = group["force_N"].to_numpy().copy()
            k = int(0.35 * f.size)
            start[str(tid)] = float(group["z_m"].iloc[k - 1])
            f[k:] = f[k - 1] * (1 + rng.uniform(-0.01, 0.01, f.size - k))
            group["force_N"] = f
        parts.append(group)
    return pd.concat(parts, ignore_index=True), start
