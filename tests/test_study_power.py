"""Studies on small simulated campaigns: a planted effect is found, no effect gives no verdict.

The campaigns come from :func:`soilstats.simulate` with a known truth; the study runs exactly
as ``python -m soilstats.study`` does (same spec format, same code).  A null study makes
several tests (soils × responses) and Holm keeps the chance of *any* significant verdict at
or below α = 0.05: over R null studies the count of studies with a verdict is at most
Binomial(R, 0.05) — the bounds below fail by chance with probability < 10⁻³.
"""

from __future__ import annotations

import numpy as np
import pytest

from soilstats.simulation import simulate
from soilstats.study import load_spec, run_study

SHEAR_STUDY = """
name = "ring-test"
type = "shear"
factor = "grouser_height_m"
model = "mohr-coulomb"
responses = ["phi", "c", "line"]
"""

SINKAGE_STUDY = """
name = "velocity-test"
type = "sinkage"
factor = "velocity_m_s"
blocks = ["operator"]
model = "bernstein"
z_ref_m = 0.02
responses = [{ name = "log10_p_ref", margin = 0.3, margin_kind = "relative" },
             { name = "n", margin = 0.07 }]
"""

SOIL = {"kc": -9.8e3, "kphi": 1.2e6, "n": 0.82, "c": 100.0, "phi": 30.0, "K": 0.008}


def _shear_campaign(seed: int, side_walls: bool):
    spec = {
        "name": "shear-power",
        "soils": {"sand": SOIL},
        "series": [
            {
                "name": "heights",
                "kind": "shear",
                "soils": ["sand"],
                "rings": [{"r_inner_m": 0.10, "r_outer_m": 0.15}],
                "grouser_height_m": [0.002, 0.010],
                "normal_pressure_Pa": [3e3, 8e3, 14e3, 20e3],
                "repetitions": 2,
                "points": 60,
            }
        ],
        "effects": [{"kind": "side-walls", "K0": 0.4}] if side_walls else [],
    }
    return simulate(spec, seed=seed).campaign


def _sinkage_campaign(seed: int, exponent: float):
    spec = {
        "name": "velocity-power",
        "soils": {"sand": SOIL},
        "series": [
            {
                "name": "velocity",
                "kind": "sinkage",
                "soils": ["sand"],
                "plates": [{"shape": "circle", "radius_m": 0.05}],
                "velocity_m_s": [4.8e-4, 4.8e-3],
                "operators": ["A", "B"],
                "repetitions": 6,
                "points": 60,
            }
        ],
        "effects": [{"kind": "velocity", "exponent": exponent, "reference_m_s": 4.8e-3}]
        if exponent
        else [],
    }
    return simulate(spec, seed=seed).campaign


@pytest.fixture
def specs(tmp_path):
    (tmp_path / "shear.toml").write_text(SHEAR_STUDY)
    (tmp_path / "sinkage.toml").write_text(SINKAGE_STUDY)
    return load_spec(tmp_path / "shear.toml"), load_spec(tmp_path / "sinkage.toml")


def test_planted_side_walls_are_found_in_phi(specs):
    # side walls K0 = 0.4: tanφ × 1.03 at 2 mm, × 1.16 at 10 mm grousers (docs/simulator.md)
    for seed in range(3):
        result = run_study(specs[0], _shear_campaign(seed, side_walls=True))
        effects = result.effects.set_index("response")
        assert effects.loc["phi", "verdict"] == "effect"
        lines = result.lines.set_index("level")
        assert lines.loc["0.01", "phi_deg"] > lines.loc["0.002", "phi_deg"]


def test_planted_velocity_effect_is_found_and_relevant(specs):
    # exponent -0.3: kc, kφ × (4.8e-4/4.8e-3)^-0.3 = 2.0 at the slow velocity
    for seed in range(3):
        result = run_study(specs[1], _sinkage_campaign(seed, exponent=-0.3))
        effects = result.effects.set_index("response")
        assert effects.loc["log10_p_ref", "verdict"] == "effect"
        assert effects.loc["n", "verdict"] != "effect"  # a velocity factor on k leaves n alone


@pytest.mark.slow
def test_null_studies_give_no_verdict_at_alpha(specs):
    shear_hits = [
        bool(
            run_study(specs[0], _shear_campaign(100 + s, side_walls=False))
            .effects["significant"]
            .any()
        )
        for s in range(40)
    ]
    sinkage_hits = [
        bool(
            run_study(specs[1], _sinkage_campaign(200 + s, exponent=0.0))
            .effects["significant"]
            .any()
        )
        for s in range(30)
    ]
    # Binomial(40, 0.05): P(≥ 7) < 10⁻³; Binomial(30, 0.05): P(≥ 6) < 10⁻³
    assert np.sum(shear_hits) <= 6, shear_hits
    assert np.sum(sinkage_hits) <= 5, sinkage_hits
