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


def raw_tables(campaign: Campaign) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The test log and sinkage table as a user writes them (no derived columns)."""
    tests = campaign.tests.drop(columns=list(DERIVED_COLUMNS["tests"]), errors="ignore")
    sinkage = campaign.sinkage.drop(columns=list(DERIVED_COLUMNS["sinkage"]), errors="ignore")
    return tests, sinkage.reset_index(drop=True)
