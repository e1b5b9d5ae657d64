"""Discovery (issue #6): hidden effects planted with the simulator must be named, extended and
shown to predict better out of sample; null campaigns must give no finding.

Truth is independent of the code under test: the simulator plants each effect (docs/simulator.md)
and the assertions compare the named cause and, where the extension has a physical parameter
(K0 of the side walls, z_c and f of the softening), its value with the planted one.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from discover_situations import (
    INTERACTION,
    NULL,
    SITUATIONS,
    SOIL,
    TWO_CAUSES,
    artefact_campaign,
    drift_campaign,
    load_terminated_campaign,
    shear,
    sink,
    spec,
)

import soilstats
from soilstats.discovery import discover
from soilstats.discovery.candidates import enumerate_candidates, relations
from soilstats.discovery.ftests import strata_test
from soilstats.models.extended import SinkageLayout, shear_family, sinkage_family
from soilstats.simulation import simulate
from soilstats.statistics import anova_twoway

_sink, _spec, _shear = sink, spec, shear


PLANTED = {
    # fine soils stiffen at low velocity (Section 3.1.2): k ∝ (v/v_ref)^-0.12
    "velocity": (
        _spec(
            [_sink(velocity_m_s=[4.8e-4, 2.4e-3, 4.8e-3])],
            [{"kind": "velocity", "exponent": -0.12, "reference_m_s": 4.8e-3}],
        ),
        "velocity_m_s",
        "velocity",
    ),
    # an extra categorical covariate no physics names: the south bin is 25 % stiffer
    "bin": (
        _spec(
            [_sink(covariates={"bin": ["north", "south"]}, repetitions=8)],
            [
                {
                    "kind": "covariate",
                    "column": "bin",
                    "parameters": ["kc", "kphi"],
                    "levels": {"south": 1.25},
                }
            ],
        ),
        "bin",
        "bin (levels)",
    ),
    # a continuous covariate on shear: cohesion rises 15 % per % moisture
    "moisture": (
        _spec(
            [_shear(covariates={"moisture_pct": [0.5, 1.5, 2.5, 3.5]})],
            [{"kind": "covariate", "column": "moisture_pct", "parameters": "c", "slope": 0.15}],
        ),
        "moisture_pct",
        "moisture_pct (linear)",
    ),
    # narrow plates (1:5, 1:7) soften beyond 6 mm (Section 3.1.3, Fig. 9)
    "softening": (
        _spec(
            [
                _sink(
                    plates=[
                        {"shape": "rectangle", "aspect": a, "area_m2": 0.00785}
                        for a in (1, 3, 5, 7)
                    ],
                    repetitions=6,
                )
            ],
            [
                {
                    "kind": "softening",
                    "critical_sinkage_m": 0.006,
                    "factor": 0.5,
                    "min_aspect_ratio": 5,
                }
            ],
        ),
        "aspect_ratio",
        "softening",
    ),
    # grouser side walls ignored by Eq. 12 (Section 4.2.3)
    "side-walls": (
        _spec([_shear(grouser_height_m=[0.002, 0.005, 0.01])], [{"kind": "side-walls", "K0": 0.4}]),
        "grouser_height_m",
        "side-walls",
    ),
    # operator-dependent preparation (criterion 2 of Table 1): persistent bias per operator
    "operator": (
        _spec(
            [_sink(operators=["A", "B", "C", "D"], repetitions=8, preparations=["p"])],
            preparations={"p": {"operator_cv": 0.2}},
        ),
        "operator",
        "operator (levels)",
    ),
}


@pytest.mark.parametrize("effect", list(PLANTED))
def test_planted_effect_is_named_extended_and_gains(effect):
    spec, cause, extension = PLANTED[effect]
    sim = simulate(spec, seed=3)
    if effect == "operator":  # the planted biases must be large enough to find at all
        truth = sim.test_truth.merge(sim.campaign.tests[["test_id", "operator"]], on="test_id")
        assert np.ptp(truth.groupby("operator")["operator_bias"].first()) > 0.15
    result = discover(sim.campaign, seed=0)
    assert result.findings, result.summary()
    top = result.findings[0]
    assert top.cause == cause, result.summary()
    assert top.p_adjusted < 1e-3 and top.p_value <= top.p_adjusted
    assert top.extension == extension, result.summary()
    assert top.gain.real and top.gain.relative > 0.1 and top.gain.difference > 2 * top.gain.stderr
    # the cause fixed decides; the whole search re-selects the lead in each fold, and a planted
    # effect this strong is significant on every fold's training tests: the same gain
    assert top.gain.selected_folds is None
    assert top.gain_search.selected_folds == top.gain_search.folds == 5
    assert top.gain_search.relative == pytest.approx(top.gain.relative, rel=1e-12)
    params = dict(zip(top.fit.param_names, top.fit.values, strict=True))
    if effect == "side-walls":
        assert params["K0"] == pytest.approx(0.4, abs=0.05)
        assert params["c"] == pytest.approx(SOIL["c"], rel=0.1)
        assert params["phi"] == pytest.approx(SOIL["phi"], abs=0.5)
    if effect == "softening":
        assert params["z_c"] == pytest.approx(0.006, abs=0.0015)
        assert params["f_soft"] == pytest.approx(0.5, abs=0.1)
    if effect == "velocity":  # (v/v_ref)^a on k: a ≈ −0.12, n unchanged
        assert params["ln k-factor[ln(v/v_ref)]"] == pytest.approx(-0.12, abs=0.04)
        assert params["n-offset[ln(v/v_ref)]"] == pytest.approx(0.0, abs=0.02)
    # JSON shape of the issue
    doc = json.loads(result.to_json())
    first = doc["findings"][0]
    assert {"kind", "soil", "cause", "p_value", "p_adjusted", "extension", "gain"} <= set(first)
    assert {"metric", "base", "extended", "relative"} <= set(first["gain"])


@pytest.mark.slow
def test_null_campaigns_false_positive_rate():
    """No effect planted: any finding is false.  Holm keeps the family-wise rate ≤ 5 %; over
    100 seeds more than 9 false campaigns would be evidence against that (binomial, p < 3 %).
    Measured: 8 of seeds 0–99 (3 kept an extension), 46 of 1000 over seeds 0–999 (4.6 %,
    95 % CI 3.4–6.1 %; 21 kept an extension; ``python benchmarks/discover_power.py --null
    1000``)."""
    false = kept = 0
    for seed in range(100):
        result = discover(simulate(NULL, seed=seed).campaign, seed=0)
        false += bool(result.findings)
        kept += any(f.extension for f in result.findings) or any(
            m.extensions for m in result.models
        )
        assert all(f.p_adjusted < 0.05 for f in result.findings)
    assert false <= 9, f"{false} of 100 null campaigns gave a finding"
    # issue #35: null data keep no extension in at least 95 % of campaigns
    assert kept <= 5, f"{kept} of 100 null campaigns kept an extension"


#: Nothing planted: 16 sinkage tests on one plate, a two-level ``bin`` with no effect.
NULL_BIN = _spec(
    [
        _sink(
            plates=[{"shape": "circle", "radius_m": 0.05}],
            covariates={"bin": ["n", "s"]},
            repetitions=8,
        )
    ]
)


@pytest.mark.slow
def test_gain_of_a_null_lead_is_not_inflated_by_its_selection():
    """A null ``bin`` selected by its F-test (lenient alpha, so that it is selected often)
    has nothing to predict.  The whole search's gain (each fold re-selecting the lead,
    :mod:`soilstats.discovery.nested`) is at most zero on median; the gain that decides (the
    cause fixed) shares the chance pattern that selected the lead, and the keep rule
    (``Z_KEEP`` = 1 SE) keeps some of these false leads: docs/discover.md states the rate
    (``benchmarks/discover_nested_null.py``); here at most 40 % of them.  Measured: 28 leads
    in 300 campaigns, the search's gain −2.4 % on median, the cause-fixed gain +6.8 %, 7 of
    the 28 kept (25 %)."""
    found = []
    for seed in range(300):
        result = discover(simulate(NULL_BIN, seed=seed).campaign, seed=0, alpha=0.3)
        found += [f for f in result.findings if f.cause == "bin" and f.gain is not None]
    assert len(found) >= 20
    assert np.median([f.gain_search.relative for f in found if f.gain_search]) < 0.0
    kept = sum(f.extension is not None for f in found)
    assert kept <= 0.4 * len(found), f"{kept} of {len(found)} null leads kept"


def test_strata_test_matches_two_way_anova():
    """Independent reference: statsmodels' type II ANOVA (via anova_twoway) on the same data."""
    import pandas as pd

    rng = np.random.default_rng(1)
    block = np.repeat(["a", "b", "c"], 8)
    x = np.tile(["u", "v"], 12)
    y = rng.normal(size=24) + (x == "v") * 0.7 + (block == "b") * 2.0
    frame = pd.DataFrame({"y": y, "x": x, "block": block})
    table = anova_twoway(frame, "y", "x", "block")
    res = strata_test(y, pd.factorize(x)[0], categorical=True, strata=pd.factorize(block)[0])
    assert res["statistic"] == pytest.approx(table.loc["x", "F"], rel=1e-10)
    assert res["p_value"] == pytest.approx(table.loc["x", "PR(>F)"], rel=1e-8)
    assert res["df2"] == table.loc["Residual", "df"]


def test_family_jacobians_match_finite_differences():
    rng = np.random.default_rng(2)
    n = 40
    b = rng.choice([0.025, 0.05], n)
    z = rng.uniform(0.001, 0.03, n)
    f = rng.normal(size=(n, 1))
    soft = rng.random(n) > 0.5
    layout = SinkageLayout(True, 1, 1, True)
    fun, jac = sinkage_family(layout, b, z, f, f, soft)
    theta = np.array([7e3, 5e5, 1.2, 0.1, 0.05, 0.008, 0.6])
    fun2, jac2 = shear_family(
        __import__("soilstats.models.extended", fromlist=["ShearLayout"]).ShearLayout(1, 1, 1),
        rng.uniform(3e3, 2e4, n),
        rng.uniform(0, 0.1, n),
        f,
        f,
        f,
    )
    theta2 = np.array([800.0, 30.0, 0.01, 0.1, -0.05, 0.2])
    for fn, jc, th in ((fun, jac, theta), (fun2, jac2, theta2)):
        num = np.column_stack(
            [(fn(th + h) - fn(th - h)) / (2 * h[i]) for i, h in enumerate(np.diag(th * 1e-6))]
        )
        assert np.allclose(jc(th), num, rtol=1e-5, atol=1e-6 * np.abs(num).max())


def test_cullinan_reports_confounding_and_single_tests():
    result = discover("cullinan-sand")
    text = result.summary()
    assert any(
        c["relation"] == "nested" and set(c["columns"]) == {"preparation", "session"}
        for c in result.confounded
    )
    for f in result.findings:  # any named cause carries its confounding as a caveat
        if f.cause in ("preparation", "session"):
            assert {"preparation", "session"} - {f.cause} <= set(f.confounded_with)
            assert any("single test" in c for c in f.caveats)
    assert "dry_density_kg_m3" in text  # recorded for 3 of 13 tests: said, not tested
    # k and n of one plate correlate at +0.996 only because k is the pressure at z = 1 m;
    # judged where the data measure k (as identify judges it) there is no red flag.
    assert not result.flags, result.flags


def test_candidates_and_aliasing_on_simulated_paper_shear():
    c = soilstats.load_campaign("simulated-paper").select(kind="shear", soil="soil01")
    t = c.tests.assign(sigma_mean_Pa=1.0)
    cands, _ = enumerate_candidates(t, "shear")
    names = {x.name for x in cands}
    assert {"tool", "r_inner_m", "grouser_height_m", "grousers", "omega_rpm"} <= names
    assert "test_id" not in names and "n_samples" not in names  # bookkeeping, outcome
    (rep,) = [x for x in cands if x.name == "repetition"]
    assert rep.role == "time/order" and not rep.categorical  # a trend over the series
    rel = {(r.kind, frozenset((r.finer, r.coarser))) for r in relations(t, cands)}
    assert ("aliased", frozenset({"tool", "r_inner_m"})) in rel


def test_cli_json_and_pdf(tmp_path, capsys):
    from soilstats.cli.main import main

    spec, _, _ = PLANTED["side-walls"]
    folder = simulate(spec, seed=3).campaign.save(tmp_path / "camp")
    args = ["discover", "--data", str(folder), "--json", "--out", str(tmp_path / "rep")]
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["findings"][0]["cause"] == "grouser_height_m"
    assert isinstance(doc["flags"], list)
    pdf = tmp_path / "rep" / "discover.pdf"
    assert pdf.stat().st_size > 10_000
    from pypdf import PdfReader

    text = "".join(p.extract_text() for p in PdfReader(pdf).pages)
    assert "side-walls" in text
    # the combined model, the power statements and the data-quality section are in the PDF
    assert doc["model"]["extensions"] == ["shear / s: side-walls"]
    assert "Combined model" in text and "Data quality" in text
    squeezed = re.sub(r"[\s\u200b]+", "", text)  # a table cell wraps a name anywhere
    assert all(re.sub(r"\s+", "", p["candidate"]) in squeezed for p in doc["power"])


def test_cli_null_prints_empty_findings(tmp_path, capsys):
    from soilstats.cli.main import main

    folder = simulate(NULL, seed=0).campaign.save(tmp_path / "null")
    assert main(["discover", "--data", str(folder), "--json", "--progress", "off"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["findings"] == [] and doc["untested"] == []  # its candidates were tested


@pytest.mark.parametrize(
    ("ids", "why"), [(["large-1"], "1 test: nothing"), (["large-1", "large-2"], "no set-up")]
)
def test_no_finding_where_nothing_could_be_tested_says_so(tmp_path, capsys, ids, why):
    """One test, or tests that differ in no set-up column: 'No finding' alone read as 'the
    model is fine'. The text, the JSON record and its notes say nothing could be tested."""
    from soilstats.cli.main import main

    campaign = soilstats.load_campaign("grc1-oravec2009").select(test_id=ids)
    folder = campaign.save(tmp_path / "few")
    argv = ["discover", str(folder), "--progress", "off"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "NO CANDIDATE CAUSE COULD BE TESTED" in text and why in text
    assert "No finding: no candidate cause passes the test." not in text
    assert main([*argv, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["findings"] == []
    found = [(u["kind"], u["soil"], u["n_tests"]) for u in doc["untested"]]
    assert found == [("sinkage", "GRC-1", len(ids))]
    assert why in doc["untested"][0]["reason"]
    assert any("NO CANDIDATE CAUSE COULD BE TESTED" in n for n in doc["notes"])


@pytest.mark.slow  # discover on the 244-test campaign, ~7 s: CI runs it
def test_simulated_paper_names_the_papers_effects():
    result = discover("simulated-paper", seed=0)
    named = {(f.kind, f.soil, f.cause): f for f in result.findings}
    for soil in ("soil02", "soil08"):  # Table 5: fine soils change with velocity
        f = named[("sinkage", soil, "velocity_m_s")]
        assert f.extension == "velocity" and f.gain.real
    for soil in ("soil01", "soil02"):  # Fig. 16: grouser height, side walls K0 = 0.4
        f = named[("shear", soil, "grouser_height_m")]
        assert f.extension == "side-walls"
        assert dict(zip(f.fit.param_names, f.fit.values, strict=True))["K0"] == pytest.approx(
            0.4, abs=0.05
        )
    assert ("sinkage", "soil02", "aspect_ratio") in named  # Fig. 8: 1:5, 1:7 soften
    assert ("sinkage", "soil01", "aspect_ratio") in named
    assert named[("sinkage", "soil02", "aspect_ratio")].extension == "softening"
    # no effect of grouser count or shear velocity was planted (Tables 7, Section 3.2.4)
    assert not any(f.cause in ("grousers", "omega_rpm") for f in result.findings)
    codes = {(fl["soil"], fl["code"]) for fl in result.flags}
    # frictional sand: a negative kc (Table 5) is what such soils give, not a red flag
    assert not any(code == "implausible-kc" for _, code in codes)
    assert ("soil02", "kc-kphi-collinear") in codes


# ------------------------------------------------------------- issue #13: real-data situations
def test_drift_over_logged_time_is_a_trend_candidate():
    # The soil stiffens 4 % per hour over the day; tests are logged with ISO start times.
    result = discover(drift_campaign(3), seed=0)
    top = result.findings[0]
    assert top.cause == "start_time" and top.extension == "start_time (linear)", result.summary()
    assert top.gain.real and top.gain.relative > 0.1
    roles = {c["column"]: c["role"] for c in result.columns}
    assert roles["start_time"] == "time/order" and roles["repetition"] == "time/order"


def test_depth_of_load_terminated_tests_is_an_outcome_never_a_cause():
    # Every test stops at the same force (as on real rigs): softer preparations run deeper,
    # so z_max is the test's own stiffness. Nothing was planted: nothing may be named.
    result = discover(load_terminated_campaign(5), seed=0)
    depths = [c for c in result.columns if c["column"] == "z_max_m"]
    assert depths and depths[0]["role"] == "outcome" and not depths[0]["tested"]
    assert all(f.cause != "z_max_m" for f in result.findings), result.summary()
    assert "z_max_m" not in set(result.tests["candidate"])


def test_grc1_size_changes_exponent_and_stiffness_and_a_plausible_model_gains():
    result = discover("grc1-oravec2009", seed=0)
    top = result.findings[0]
    assert top.cause in ("b_m", "area_m2") and {"level", "shape"} <= set(top.responses)
    assert top.extension == f"k and n per {top.cause}", result.summary()
    assert top.gain.real and top.gain.relative > 0.3
    reece = [t for t in top.tried if t["extension"] == "reece"]
    assert reece and reece[0]["implausible"]  # k2 < 0: tried, reported, never kept


def test_cullinan_designed_factor_leads_its_confounded_partner():
    result = discover("cullinan-sand", seed=0)
    top = result.findings[0]
    assert top.cause == "preparation" and "session" in top.confounded_with, result.summary()


# ------------------------------------------- issue #13: interactions, combined model, power, DQ
def test_interaction_is_named_and_its_cell_model_kept():
    result = discover(simulate(INTERACTION, seed=0).campaign, seed=0)
    names = [f.cause for f in result.findings]
    assert "preparation × operator" in names, result.summary()
    inter = result.findings[names.index("preparation × operator")]
    assert inter.extension == "preparation × operator (levels)" and inter.gain.real
    # the planted cell (p1, B) is the stiff one: its factor is the largest, about ln 1.5
    params = dict(zip(inter.fit.param_names, inter.fit.values, strict=True))
    cells = {k: v for k, v in params.items() if k.startswith("ln k-factor")}
    assert max(cells, key=cells.get).endswith("p1 × B]")
    assert max(cells.values()) == pytest.approx(np.log(1.5), abs=0.1)
    assert result.model()["causes"] == ["sinkage / s: preparation × operator"]


def test_two_causes_are_combined_into_one_model_that_gains_more():
    result = discover(simulate(TWO_CAUSES, seed=0).campaign, seed=0)
    assert {f.cause for f in result.findings} == {"velocity_m_s", "bin"}, result.summary()
    doc = json.loads(result.to_json())["model"]
    assert set(doc["extensions"]) == {"sinkage / s: velocity", "sinkage / s: bin (levels)"}
    assert {"extensions", "causes", "gain", "groups"} <= set(doc)
    combined = doc["gain"]
    assert combined["real"]
    # the combined model predicts held-out tests better than either extension alone
    assert combined["relative"] > max(f.gain.relative for f in result.findings) + 0.1
    (group,) = doc["groups"]
    params = group["parameters"]
    assert params["ln k-factor[ln(v/v_ref)]"]["value"] == pytest.approx(-0.12, abs=0.04)
    assert params["ln k-factor[bin=south]"]["value"] == pytest.approx(np.log(1.2), abs=0.06)
    assert all(np.isfinite(p["stderr"]) and p["stderr"] > 0 for p in params.values())
    assert "Combined model" in result.summary()


def test_minimum_detectable_effect_has_the_stated_power():
    """Independent check of the noncentral-F power statement by simulation: data with one
    level shifted by exactly the stated MDE must be detected in ~80 % of 600 replicates."""
    from soilstats.discovery.power import minimum_detectable

    rng = np.random.default_rng(11)
    x = np.repeat([0, 1, 2], 6)
    strata = np.tile([0, 1], 9)
    alpha = 0.01
    ref = strata_test(rng.normal(size=x.size), x, categorical=True, strata=strata)
    delta = minimum_detectable(1.0, ref["mde_norm2"], ref["df1"], ref["df2"], alpha)
    counts = np.bincount(x)
    hardest = int(np.argmin(counts))
    hits = 0
    for _ in range(600):
        y = rng.normal(size=x.size) + delta * (x == hardest)
        hits += strata_test(y, x, categorical=True, strata=strata)["p_value"] < alpha
    assert hits / 600 == pytest.approx(0.8, abs=0.05)
    # a trend: the stated change across the observed range
    t = np.linspace(0.0, 3.0, 16)
    ref = strata_test(rng.normal(size=16), t, categorical=False, strata=np.zeros(16, int))
    delta = minimum_detectable(1.0, ref["mde_norm2"], ref["df1"], ref["df2"], alpha)
    hits = sum(
        strata_test(
            rng.normal(size=16) + delta * t / 3.0,
            t,
            categorical=False,
            strata=np.zeros(16, int),
        )["p_value"]
        < alpha
        for _ in range(600)
    )
    assert hits / 600 == pytest.approx(0.8, abs=0.05)


def test_time_order_trends_are_linear_in_time():
    """A drift is linear in test order: a time/order candidate is never tested (nor
    extended) on ln x, although its values 1..34 span more than a factor four. Checked
    against an ordinary least-squares slope test (scipy.stats.linregress)."""
    from scipy.stats import linregress

    from soilstats.discovery.extensions import Features, SinkageExtension, Term
    from soilstats.discovery.library import combine

    rng = np.random.default_rng(5)
    order = np.arange(1.0, 35.0)
    y = 0.03 * order + rng.normal(size=order.size)
    one = np.zeros(order.size, int)
    drift = strata_test(y, order, categorical=False, strata=one, log_scale=False)
    assert drift["p_value"] == pytest.approx(linregress(order, y).pvalue, rel=1e-9)
    logged = strata_test(y, order, categorical=False, strata=one)
    assert logged["p_value"] == pytest.approx(linregress(np.log(order), y).pvalue, rel=1e-9)
    assert logged["p_value"] != pytest.approx(drift["p_value"], rel=1e-3)
    # the extension keeps the scale it was tested on, also when combined with another
    trend = Term(Features("test_number", "linear", log_scale=False), ("k",))
    size = Term(Features("b_m", "linear"), ("n",))
    parts = [SinkageExtension(n, False, "", terms=(t,)) for n, t in (("a", trend), ("b", size))]
    merged = {t.features.column: t.features for t in combine(parts).terms}
    assert merged == {"test_number": trend.features, "b_m": size.features}


def test_undetectable_plate_size_gets_a_power_statement_not_silence():
    # Plates 12 % apart and no effect: nothing is found, and discover says how large a size
    # effect the design could have detected.
    plates = [{"shape": "circle", "radius_m": 0.05}, {"shape": "circle", "radius_m": 0.056}]
    result = discover(simulate(_spec([_sink(plates=plates)]), seed=1).campaign, seed=0)
    assert not result.findings, result.summary()
    power = {(p["candidate"]): p for p in json.loads(result.to_json())["power"]}
    size = power.get("b_m") or power["area_m2"]
    level = size["responses"]["level"]
    assert level["mde_uncapped"] > 0 and "in pressure" in level["statement"]
    # capped to what the data can express: beyond the tests' whole spread, "not testable"
    if level["testable"]:
        assert level["mde"] == level["mde_uncapped"] <= level["observed_range"]
    else:
        assert level["mde"] is None and level["statement"].startswith("not testable here")
    assert size["power"] == 0.8 and size["alpha_level"] < 0.05
    assert "Not found" in result.summary()


def test_spikes_and_seating_offsets_are_data_problems_never_causes():
    """Artefacts planted in the tests of one operator each (so that, fitted raw, they would
    line up with a column): screening removes them, discover names nothing and lists them as
    data-quality findings."""
    campaign = artefact_campaign(4)
    result = discover(campaign, seed=0)
    assert not result.findings, result.summary()
    assert {"spike", "pre-contact"} <= set(result.quality["counts"])
    assert len(result.quality["tests"]) >= 0.75 * len(campaign.tests)  # most are found
    assert "Data quality" in result.summary()


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SITUATIONS))
def test_situations_over_many_seeds(name):
    """Power of each planted situation and false findings of each artefact over 20 seeds
    (docs/discover.md, table from benchmarks/discover_power.py): ≥ 18 of 20 successes."""
    situation = SITUATIONS[name]
    good = sum(bool(situation.judge(discover(situation.build(seed), seed=0))) for seed in range(20))
    assert good >= 18, f"{name}: {good} of 20"


def test_combined_shear_family_jacobian_with_side_walls_and_covariates():
    """Side walls and covariate factors in one model (forward selection combines them): the
    analytic Jacobian against central differences, and the walls-only limit of the family."""
    from soilstats.models.extended import ShearLayout

    rng = np.random.default_rng(4)
    n = 50
    sigma, j = rng.uniform(3e3, 2e4, n), rng.uniform(0, 0.1, n)
    f, a = rng.normal(size=(n, 1)), rng.uniform(0.05, 0.3, n)
    fun, jac = shear_family(ShearLayout(1, 1, 1, True), sigma, j, f, f, f, a)
    theta = np.array([800.0, 30.0, 0.01, 0.1, -0.05, 0.2, 0.4])
    h = np.abs(theta) * 1e-6
    num = np.column_stack(
        [(fun(theta + e) - fun(theta - e)) / (2 * e[i]) for i, e in enumerate(np.diag(h))]
    )
    assert np.allclose(jac(theta), num, rtol=1e-5, atol=1e-6 * np.abs(num).max())
    walls, _ = shear_family(ShearLayout(0, 0, 0, True), sigma, j, a=a)
    assert np.allclose(
        fun(np.array([800.0, 30.0, 0.01, 0, 0, 0, 0.4])), walls([800, 30, 0.01, 0.4])
    )


# --------------------------------------------- issue #15: speed, and --jobs with identical results
#: Two kinds, effects in both: several groups, findings, forward selection in each.


def test_weighted_family_evaluators_match_the_plain_ones():
    """The optimiser's fast path (weights folded in, rows preallocated, softened samples
    only) gives w·f and the rows of w·J, as the plain family does, for every layout."""
    from soilstats.models.extended import ShearLayout

    rng = np.random.default_rng(5)
    n = 300
    b, z = rng.choice([0.025, 0.05, 0.1], n), rng.uniform(0.001, 0.03, n)
    w = rng.uniform(0.5, 2.0, n)
    for bekker in (True, False):
        for n_s, n_d, soften in ((0, 0, False), (2, 1, False), (1, 2, True), (0, 0, True)):
            fs = (rng.random((n, n_s)) < 0.4).astype(float) if n_s else None
            gd = rng.normal(size=(n, n_d)) if n_d else None
            family = sinkage_family(
                SinkageLayout(bekker, n_s, n_d, soften), b, z, fs, gd, rng.random(n) < 0.5
            )
            theta = [7e3, 5e5, 1.1][3 - (2 + bekker) :] + list(rng.normal(0, 0.2, n_s + n_d))
            theta = np.array(theta + ([0.01, 0.6] if soften else []))
            f_w, jac_w = family.weighted(w)
            for th in (theta, theta * 1.01, theta):  # the cached parts follow θ
                assert np.allclose(f_w(th), w * family.f(th), rtol=1e-13, atol=0)
                assert np.allclose(jac_w(th), (w[:, None] * family.jac(th)).T, rtol=1e-13)
                assert np.array_equal(family.rows(th, w), jac_w(th))
    fc = rng.normal(size=(n, 1))
    shear = shear_family(ShearLayout(1, 0, 1, True), rng.uniform(3e3, 2e4, n), z, fc, None, fc, z)
    f_w, jac_w = shear.weighted(w)
    theta = np.array([800.0, 30.0, 0.01, 0.1, 0.2, 0.4])
    assert np.allclose(f_w(theta), w * shear.f(theta), rtol=1e-13, atol=0)
    assert np.allclose(jac_w(theta), (w[:, None] * shear.jac(theta)).T, rtol=1e-13, atol=0)


def test_fast_partitions_match_the_sorting_ones():
    """determines, the strata and the cell codes of the diagnosis (integer arithmetic on
    level codes) against the row-wise ``np.unique`` they replace."""
    import pandas as pd

    from soilstats.discovery.candidates import determines
    from soilstats.discovery.ftests import cell_codes, strata_codes

    rng = np.random.default_rng(6)
    for _ in range(300):
        n = int(rng.integers(1, 60))
        a = rng.integers(0, rng.integers(1, 7), n)
        b = (a * 2) % int(rng.integers(1, 5)) if rng.random() < 0.5 else rng.integers(0, 4, n)
        pairs = np.unique(np.column_stack([a, b]), axis=0)
        assert determines(a, b) == (pairs.shape[0] == np.unique(a).size)
        assert determines(a.astype(float) + 0.5, b) == determines(a, b)
        c = rng.integers(0, 3, n)
        sorted_rows = np.unique(np.column_stack([a, b, c]), axis=0, return_inverse=True)[1]
        assert np.array_equal(strata_codes([a, b, c], n), sorted_rows.ravel())
        text = pd.factorize(pd.Series(a).astype(str) + "|" + pd.Series(b).astype(str))[0]
        assert np.array_equal(cell_codes(a, b), text)


def test_cell_means_f_test_is_the_full_one():
    """The F-test on cell means weighted by their counts (the diagnosis' fast path) gives the
    sums of squares, ranks and p of the one on every row."""
    from soilstats.discovery.ftests import _nested_f, cell_codes

    rng = np.random.default_rng(7)
    for _ in range(100):
        n = int(rng.integers(12, 200))
        a, b = rng.integers(0, 3, n), rng.integers(0, 3, n)
        strata = rng.integers(0, 2, n)
        y = rng.normal(size=n) + 0.5 * (a == 1) * (b == 2)
        cells = cell_codes(a, b)
        design = (cells[:, None] == np.unique(cells)[None, :]).astype(float)
        nuisance = np.hstack([(c[:, None] == np.unique(c)[None, 1:]).astype(float) for c in (a, b)])
        full = _nested_f(y, design, strata, nuisance)
        fast = _nested_f(y, design, strata, nuisance, cells=cell_codes(strata, cells))
        assert (fast["df1"], fast["df2"]) == (full["df1"], full["df2"])
        for key in ("statistic", "p_value", "effect_size", "sigma"):
            assert fast[key] == pytest.approx(full[key], rel=1e-9, nan_ok=True)


def _dummies(codes: np.ndarray) -> np.ndarray:
    return (codes[:, None] == np.unique(codes)[None, 1:]).astype(float)


def test_f_test_counts_no_rank_in_what_the_other_effects_carry():
    """A design the main effects (or the strata) carry entirely leaves rounding noise after
    they are taken out; that noise has no rank, so there is nothing to test — on every row
    and on cell means alike. Counted against the noise itself, it gave F(3, 24) and a p
    anywhere in 0..1 for the interaction of a factor with a function of itself."""
    from soilstats.discovery.ftests import _nested_f, cell_codes

    a = np.repeat([0, 1, 2], 10)
    b = a % 2  # a function of a: the A × B cells are the levels of A
    cells = cell_codes(a, b)
    design = (cells[:, None] == np.unique(cells)[None, :]).astype(float)
    nuisance = np.hstack([_dummies(a), _dummies(b)])
    zeros = np.zeros(a.size, int)
    for seed in range(20):
        y = np.random.default_rng(seed).normal(size=a.size)
        for res in (
            _nested_f(y, design, zeros, nuisance),
            _nested_f(y, design, zeros, nuisance, cells=cell_codes(zeros, cells)),
        ):
            assert res["df1"] == 0 and np.isnan(res["p_value"])
            assert "nothing left to test" in res["reason"]
    # A main effect the strata carry (A constant within each stratum) has no rank either,
    # and takes no degree of freedom from the test of B beside it.
    rng = np.random.default_rng(3)
    strata = np.repeat([0, 1, 2, 3], 12)
    a = strata // 2
    b = np.tile(np.arange(3), 16)
    y = rng.normal(size=strata.size) + 0.8 * (b == 1)
    res = _nested_f(y, _dummies(b), strata, nuisance=_dummies(a))
    assert (res["df1"], res["df2"]) == (2, strata.size - 4 - 2)
    alone = _nested_f(y, _dummies(b), strata)
    assert res["p_value"] == pytest.approx(alone["p_value"], rel=1e-9)


def test_a_lead_is_not_explained_for_want_of_a_retest(monkeypatch):
    """A lead whose significant response cannot be re-tested against the accepted extension
    (p NaN) is examined, not reported as explained with p_after = 1."""
    from types import SimpleNamespace

    from soilstats.discovery import leads

    group = SimpleNamespace(kind="sinkage", soil="s")
    p_after = {}
    monkeypatch.setattr(leads, "conditional_responses", lambda g, fitted: None)
    monkeypatch.setattr(leads, "retest", lambda g, table, row: dict(p_after))

    def explained(**p):
        p_after.clear()
        p_after.update(p)
        return leads._explained_by(
            group, ("ext", None), "bin", None, {"level"}, n_leads=2, alpha=0.05
        )

    assert explained(level=np.nan, shape=0.5) is None  # the level cannot be re-tested
    assert explained(level=0.01, shape=0.5) is None  # still significant (0.01 * 2 < 0.05)
    record = explained(level=0.4, shape=np.nan)  # the shape never showed
    assert record is not None and record["p_after"] == pytest.approx(0.4)


def test_folds_are_seeded_and_stratified():
    """Stratified folds: every fold holds its share of every level (counts differ by at most
    one) and of the tests; and the seed decides them, also when every level is one test
    (a trend in time), where they once followed the levels' order as text."""
    from soilstats.discovery.crossval import make_folds

    levels = np.repeat(["a", "b", "c"], [7, 5, 9])
    for seed in range(5):
        folds = make_folds(levels, "tests", np.random.default_rng(seed))
        sizes = np.bincount(folds, minlength=5)
        assert sizes.max() - sizes.min() <= 1
        for lv in "abc":
            per_fold = np.bincount(folds[levels == lv], minlength=5)
            assert per_fold.max() - per_fold.min() <= 1
    times = np.array([f"{h:.2f}" for h in np.linspace(0.5, 30.0, 20)])
    assignments = {
        tuple(make_folds(times, "tests", np.random.default_rng(seed))) for seed in range(20)
    }
    assert len(assignments) > 10
    assert all(np.bincount(np.array(a), minlength=5).min() == 4 for a in assignments)


def test_a_discovery_shows_its_summary_as_tables_in_a_notebook():
    """``_repr_html_``: the findings, the combined model and the not-found candidates as
    tables, the flags and notes (escaped), as the other results show theirs."""
    import html

    result = discover("grc1-oravec2009")
    page = result._repr_html_()
    assert page.startswith("<div>") and "<table" in page
    for f in result.findings:
        assert f"<td>{html.escape(f.cause)}</td>" in page and html.escape(f.extension) in page
    for m in result.models:
        assert html.escape(" + ".join(m.extensions)) in page
    for p in result.power:
        assert html.escape(p["candidate"]) in page
    assert all(html.escape(fl["message"]) in page for fl in result.flags)
    assert all(html.escape(c) in page for f in result.findings for c in f.caveats)
    assert "<td>n</td>" in page  # the parameters, with the σ the summary quotes
