"""A study's z_ref_m / z_window_m left at their defaults move a verdict only where the planted
effect truly depends on the depth (issue #47, item 3; soilstats/study/defaults.py).

Designed case (simulated, known truth): two velocities whose Bekker curves (kc = 0) have
n = 0.6 and n = 1.1 with kφ chosen so that the pressures are *equal at 25 mm*, the default
z_ref: at 25 mm there is no effect on p_ref, at 12.5 mm the slow velocity gives
(0.5)^(0.6−1.1) = 1.41 times the pressure, at 50 mm 1/1.41 — both beyond the relevance margin
(a factor 1.3). Clean case: a velocity factor 2 on kc, kφ (the same ratio at every depth), so
the verdict is "effect" at every depth and nothing is said.
"""

from __future__ import annotations

import json
import re
import warnings
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest

from soilstats.errors import DefaultWarning
from soilstats.simulation import simulate
from soilstats.study import load_spec, run_study
from soilstats.study.defaults import alternatives

STUDY = """
name = "velocity-test"
type = "sinkage"
factor = "velocity_m_s"
blocks = ["operator"]
model = "bernstein"
responses = [{ name = "log10_p_ref", margin = 0.3, margin_kind = "relative" },
             { name = "n", margin = 0.07 }]
"""
SOIL = {"kc": 0.0, "kphi": 1.2e6, "n": 0.8, "c": 100.0, "phi": 30.0, "K": 0.008}
Z0 = 0.025  # the default z_ref [m]


def _campaign(case: str, seed: int, sinkage_m: float = 0.06):
    soil: dict = dict(SOIL)
    effects = []
    if case == "crossing":  # p = kφ z^n equal at Z0: kφ_slow Z0^0.6 = kφ_fast Z0^1.1
        soil["conditions"] = [
            {"where": {"velocity_m_s": 4.8e-4}, "kc": 0.0, "n": 0.6, "kphi": 1.2e6 * Z0**0.5},
            {"where": {"velocity_m_s": 4.8e-3}, "kc": 0.0, "n": 1.1, "kphi": 1.2e6},
        ]
    elif case == "uniform":  # (4.8e-4 / 4.8e-3)^-0.3 = 2.0 on kc, kφ at the slow velocity
        effects = [{"kind": "velocity", "exponent": -0.3, "reference_m_s": 4.8e-3}]
    # "null": the same design with no effect (benchmarks/defaults_verdicts.py)
    spec = {
        "name": f"velocity-{case}",
        "soils": {"sand": soil},
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
                "sinkage_m": sinkage_m,
            }
        ],
        "effects": effects,
    }
    return simulate(spec, seed=seed)


@pytest.fixture
def spec(tmp_path):
    (tmp_path / "v.toml").write_text(STUDY, encoding="utf-8")
    return load_spec(tmp_path / "v.toml")


def test_the_alternatives_are_half_and_twice_each_defaulted_value(spec):
    both = {"spec: z_ref_m": "0.025", "spec: z_window_m": "0.001"}
    assert alternatives(spec, both) == [
        ("z_ref_m", 0.0125),
        ("z_ref_m", 0.05),
        ("z_window_m", 0.0005),
        ("z_window_m", 0.002),
    ]
    assert alternatives(spec, {"spec: alpha": "0.05"}) == []  # α: the user's policy
    no_pressure = replace(spec, responses=tuple(r for r in spec.responses if r.name == "n"))
    assert alternatives(no_pressure, both) == []  # no verdict reads p_ref


def test_a_verdict_resting_on_z_ref_warns(spec):
    with pytest.warns(DefaultWarning, match="z_ref_m moves a verdict") as caught:
        result = run_study(spec, _campaign("crossing", seed=1).campaign, seed=0)
    assert len(caught) == 1
    verdict = result.effects.set_index("response").loc["log10_p_ref", "verdict"]
    assert verdict in ("no relevant effect", "no effect detected")  # equal at 25 mm
    assert list(result.default_warnings) == ["spec: z_ref_m"]  # the window moves nothing
    text = result.default_warnings["spec: z_ref_m"]
    assert "at 0.0125 m 'effect'" in text and "at 0.05 m 'effect'" in text
    assert "Warning: the study's z_ref_m moves a verdict" in result.summary()
    assert "z_ref_m moves a verdict" in result._repr_html_()
    assert result.to_dict()["default_warnings"] == result.default_warnings


def test_a_depth_independent_effect_is_silent(spec):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DefaultWarning)
        result = run_study(spec, _campaign("uniform", seed=1).campaign, seed=0)
    assert result.effects.set_index("response").loc["log10_p_ref", "verdict"] == "effect"
    assert result.default_warnings == {}
    assert {"spec: z_ref_m", "spec: z_window_m"} <= set(result.defaults)  # still printed


def test_a_depth_the_tests_do_not_reach_is_not_tried(spec):
    """30 mm deep tests do not reach 50 mm: only 12.5 mm is tried (with the same tests)."""
    with pytest.warns(DefaultWarning):
        result = run_study(spec, _campaign("crossing", seed=1, sinkage_m=0.03).campaign)
    text = result.default_warnings["spec: z_ref_m"]
    assert "at 0.0125 m 'effect'" in text and "0.05 m" not in text


@pytest.mark.filterwarnings("default::soilstats.errors.DefaultWarning")
def test_the_warning_is_on_page_1_and_in_the_json(spec, tmp_path, capsys):
    from pypdf import PdfReader

    from soilstats.cli.main import main

    folder = _campaign("crossing", seed=1).save(tmp_path / "camp")
    out = tmp_path / "o"
    args = [str(spec.path), "--data", str(folder), "--out", str(out), "--progress", "off"]
    assert main(["study", *args]) == 0
    assert "warning: the study's z_ref_m moves a verdict" in capsys.readouterr().err
    doc = json.loads((out / "velocity-test.json").read_text(encoding="utf-8"))
    assert list(doc["default_warnings"]) == ["spec: z_ref_m"]
    assert {"spec: z_ref_m", "spec: z_window_m"} <= set(doc["defaults"])
    page = re.sub(r"\s+", " ", PdfReader(out / "velocity-test.pdf").pages[0].extract_text())
    assert "Warning: the study's z_ref_m moves a verdict" in page


def test_shipped_velocity_study_on_the_paper_campaign_is_silent():
    """velocity.toml gives z_ref_m; its default window ±1 mm moves no verdict there."""
    result = run_study("velocity", "simulated-paper", seed=0)
    assert "spec: z_window_m" in result.defaults and result.default_warnings == {}


def test_every_spec_key_the_module_re_evaluates_is_a_default_listed(spec):
    from soilstats.study.defaults import SCALES
    from soilstats.study.runner import _SPEC_DEFAULTS

    assert set(SCALES) <= set(_SPEC_DEFAULTS)
    assert Path(spec.path).is_file()


def test_a_default_moving_the_best_preparation_method_is_a_warning(spec):
    """The preparation study's best method is a verdict: a different choice at an alternative
    is named like a moved effect (the effects themselves unchanged here)."""
    from soilstats.study.defaults import moved_verdicts, with_best_method

    effects = pd.DataFrame([{"soil": "sand", "response": "log10_p_ref", "verdict": "effect"}])
    base = with_best_method(effects, {"best": "13"})
    at = {0.0125: "13", 0.05: "9"}  # the deeper reference depth would choose method 9
    moved = moved_verdicts(
        spec,
        {"spec: z_ref_m": "0.025"},
        base,
        lambda alt: with_best_method(effects, {"best": at[alt.z_ref_m]}),
    )
    assert list(moved) == ["spec: z_ref_m"]
    text = moved["spec: z_ref_m"]
    assert "best preparation method is '13', at 0.05 m '9'" in text and "0.0125" not in text
    same = moved_verdicts(spec, {"spec: z_ref_m": "0.025"}, base, lambda alt: base)
    assert same == {}
    assert with_best_method(effects, {"best": None})["verdict"].iloc[-1] == "none"


def test_the_shipped_preparation_study_rechecks_its_best_method_and_is_silent(monkeypatch):
    """preparation.toml leaves z_window_m out: the best method is chosen again at ±0.5 and
    ±2 mm (three choices in all) and stays the same on the paper campaign."""
    import soilstats.study.runner as runner

    calls = []
    original = runner._preparation

    def counting(campaign, per_test, parameters, spec, notes):
        calls.append(spec.z_window_m)
        return original(campaign, per_test, parameters, spec, notes)

    monkeypatch.setattr(runner, "_preparation", counting)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DefaultWarning)
        result = run_study("preparation", "simulated-paper", seed=0)
    assert sorted(calls) == [0.0005, 0.001, 0.002]
    assert "spec: z_window_m" in result.defaults and result.default_warnings == {}
