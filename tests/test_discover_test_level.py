"""Discovery's parameter σ at the level of tests (review finding F11).

Eq. 4's σ, which discovery printed alone, treats the samples of a test as independent; with
test-to-test scatter it is far too small (Cullinan's preparation-1 n: ± 0.044 where
``identify``'s bootstrap over its six tests gives ± 0.17).  Discovery now gives each kept
fit's test-level σ (cluster-robust over tests, :mod:`soilstats.discovery.testlevel`) and a
``TEST-SCATTER`` caveat where it exceeds Eq. 4's by more than 2×.
"""

from __future__ import annotations

import numpy as np
import pytest
from discover_situations import SOIL, sink

import soilstats
from soilstats.discovery import discover
from soilstats.simulation import simulate

#: Tests per bin, all on one plate (Bernstein: k and n); each bin is one level of the
#: kept extension, whose ln k-factor[bin=south] is ln k_south − ln k_north.
PER_LEVEL = 20
NO_SCATTER = {"stiffness_cv": 0.0, "n_sd": 0.0, "c_cv": 0.0, "phi_sd_deg": 0.0, "K_cv": 0.0}


def bin_campaign(stiffness_cv: float, seed: int):
    """Sinkage tests in two bins, the south bin 40 % stiffer (the cause discovery finds);
    each test's stiffness is the soil's times exp(stiffness_cv·u), u standard normal (the
    simulator's preparation scatter) — the only test-to-test scatter: n the same in every
    test, no per-test force offset."""
    spec = {
        "name": "t",
        "soils": {"s": dict(SOIL)},
        "scatter": {**NO_SCATTER, "stiffness_cv": stiffness_cv},
        "noise": {"force_offset_N": 0.0},
        "series": [
            sink(
                plates=[{"shape": "circle", "radius_m": 0.05}],
                covariates={"bin": ["north", "south"]},
                repetitions=PER_LEVEL,
            )
        ],
        "effects": [
            {
                "kind": "covariate",
                "column": "bin",
                "parameters": ["kc", "kphi"],
                "levels": {"south": 1.4},
            }
        ],
    }
    return simulate(spec, seed=seed).campaign


def _bin_finding(result):
    (finding,) = [f for f in result.findings if f.cause == "bin"]
    assert finding.fit is not None, finding.caveats  # the bin extension is kept
    return finding


@pytest.mark.parametrize("seed", [0, 1])
def test_test_scatter_gives_the_test_level_sigma_and_a_caveat(seed):
    """Tests whose stiffness scatters by a known sd of ln k: the bin factor's test-level σ
    is that of a difference of two means of 20 tests, cv·√(2/20) (closed form), within the
    sandwich's own sampling noise (~38 df, ±12 %: ±35 % is three of it); Eq. 4's σ is less
    than half of it, and the caveat names the factor, in text and JSON."""
    cv = 0.15
    finding = _bin_finding(discover(bin_campaign(cv, seed)))
    name = "ln k-factor[bin=south]"
    j = finding.fit.param_names.index(name)
    level = finding.test_level
    assert level.stderr[j] == pytest.approx(cv * np.sqrt(2 / PER_LEVEL), rel=0.35)
    assert finding.fit.stderr_values[j] < level.stderr[j] / 2
    assert level.flagged()[j]
    (caveat,) = [c for c in finding.caveats if c.startswith("TEST-SCATTER")]
    assert f"{name} {level.stderr[j]:.3g} = " in caveat
    row = finding.to_dict()["parameters"][name]
    assert row["stderr_tests"] == pytest.approx(level.stderr[j])
    assert row["stderr"] == row["stderr_tests"] and row["stderr_level"] == "tests"
    assert row["stderr_eq4"] == pytest.approx(finding.fit.stderr_values[j])
    assert row["test_scatter"] is True
    assert f"+/- {level.stderr[j]:<10.3g}" in finding.summary()  # the ± quoted is the test-level σ


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_test_scatter_caveat_where_tests_agree_within_their_noise(seed):
    """No test-to-test scatter at all (only sample noise): the test-level σ agrees with
    Eq. 4's within a factor 2 for every parameter, and neither the finding nor the combined
    model carries the caveat."""
    result = discover(bin_campaign(0.0, seed))
    finding = _bin_finding(result)
    ratio = finding.test_level.ratio
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio
    assert not finding.test_level.flagged().any()
    assert not any(c.startswith("TEST-SCATTER") for c in finding.caveats)
    for model in result.models:
        assert not model.caveats


def test_cullinan_baseline_sigma_is_test_level_and_single_tests_have_none():
    """Real data (the review's repro): preparation 1's six tests scatter; its n carries the
    caveat and a test-level σ of the size identify's bootstrap gives (0.17 over 200
    resamples: here within a factor 2), and the levels of one test get none (JSON null)."""
    result = discover("cullinan-sand")
    (finding,) = result.findings
    params = finding.to_dict()["parameters"]
    assert params["n"]["test_scatter"] is True
    assert 0.085 < params["n"]["stderr_tests"] < 0.34
    assert params["n"]["stderr_tests"] > 2 * params["n"]["stderr_eq4"]
    assert params["n"]["stderr"] == params["n"]["stderr_tests"]  # five tests or more: quoted
    for single in ("3", "4", "5"):
        row = params[f"n-offset[preparation={single}]"]
        assert row["stderr_tests"] is None
        assert row["stderr_level"] == "eq4" and row["stderr"] == row["stderr_eq4"]
    assert any(c.startswith("TEST-SCATTER") for c in finding.caveats)
    (model,) = result.models
    assert model.to_dict()["parameters"]["n"]["test_scatter"] is True
    assert any(c.startswith("TEST-SCATTER") for c in model.caveats)


def test_discovery_pdf_prints_the_test_level_sigma(tmp_path):
    """The PDF's parameter tables carry the test-level σ (Eq. 4's in brackets) and the
    caveat."""
    from pypdf import PdfReader

    from soilstats.report.discovery_pdf import write_report

    path = tmp_path / "discover.pdf"
    assert write_report(soilstats.discover("cullinan-sand"), path) == len(PdfReader(path).pages)
    text = "".join(p.extract_text() for p in PdfReader(path).pages)
    assert "test-level σ" in text and "TEST-SCATTER" in text
