"""Issue #35: name the cause, extend the model and measure the gain — with the cause fixed.

Truth comes from the simulator's spec (tests/discover_situations.py), never from the code
under test; the bundled CMU plates are real data with a known box/day design.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from discover_situations import (
    BLOCK_DRIFT,
    CRITERIA,
    ONE_CELL,
    SINGLE_LEVEL,
    TWO_LEVELS,
    combined_beats_each,
    flagged_drift_campaign,
    kept,
    raw_frames,
    seated_late,
)

import soilstats
from soilstats.campaign import Campaign
from soilstats.discovery import discover
from soilstats.discovery.candidates import (
    Relation,
    candidate_values,
    determines,
    level_codes,
    relation_text,
)
from soilstats.simulation import simulate


def test_a_level_effect_is_kept_with_the_cause_fixed_and_the_search_reported():
    """A +14 % bin in 30 tests: named, its extension measured with the cause fixed and kept
    with a positive held-out gain; the whole search's gain is reported beside it."""
    result = discover(simulate(SINGLE_LEVEL, seed=0).campaign, seed=0)
    assert kept(result, "bin"), result.summary()
    finding = next(f for f in result.findings if f.cause == "bin")
    assert finding.gain.selected_folds is None and finding.gain.kept
    assert finding.gain_search is not None and 0 <= finding.gain_search.selected_folds <= 5
    doc = finding.to_dict()
    assert doc["gain"]["z"] == pytest.approx(finding.gain.z)
    assert doc["gain_search"]["selected_folds"] == finding.gain_search.selected_folds
    assert "cause fixed" in result.summary() and "whole search" in result.summary()


def test_two_causes_end_in_one_model_better_than_either():
    result = discover(simulate(TWO_LEVELS, seed=1).campaign, seed=0)
    assert {"operator", "bin"} <= {f.cause for f in result.findings}, result.summary()
    assert combined_beats_each(result, ("operator", "bin")), result.summary()


def test_drift_with_two_flagged_tests_is_named_not_an_artefact():
    """Stiffness +3 %/h over a day, ISO start times, two tests seated late (flagged
    pre-contact): each start time is a level of its own, so any flag used to line up 100 %
    and the drift was filed as an artefact.  The trend is compared with and without the
    flagged tests instead, and stands."""
    result = discover(flagged_drift_campaign(0), seed=0)
    assert result.quality["counts"].get("pre-contact") == 2
    assert not result.artefacts, result.summary()
    drift = next(f for f in result.findings if f.cause == "started_at")
    assert drift.extension == "started_at (linear)"
    assert any("stands without the flagged tests" in c for c in drift.caveats)


def _trend_group(y, flagged):
    """A one-group stand-in for :func:`soilstats.discovery.artefacts._flagged_trend`."""
    hours = np.arange(y.size, dtype=float)
    tests = pd.DataFrame({"started_at": hours, "_dev_level": y})
    labels = pd.Series(np.where(flagged, "pre-contact", "clean"))
    rows = pd.DataFrame(
        [
            {
                "candidate": "started_at",
                "response": "level",
                "p_value": 1e-4,
                "blocks": "",
                "role": "time/order",
            }
        ]
    )
    return SimpleNamespace(tests=tests), rows, labels


def test_a_trend_the_flagged_tests_carry_is_a_residue_and_one_beside_them_stands():
    from soilstats.discovery.artefacts import _flagged_trend

    rng = np.random.default_rng(2)
    n = 30
    flagged = np.zeros(n, bool)
    flagged[[26, 28, 29]] = True
    # nothing but an offset screening did not remove, in three late tests
    residue = rng.normal(0, 0.02, n) + 0.3 * flagged
    why, caveat = _flagged_trend(*_trend_group(residue, flagged))
    assert why is not None and "rests on the flagged tests" in why and caveat is None
    # a drift of every test, two of them flagged
    drift = 0.01 * np.arange(n) + rng.normal(0, 0.02, n)
    why, caveat = _flagged_trend(*_trend_group(drift, flagged))
    assert why is None and "stands without the flagged tests" in caveat


def test_a_determines_claim_is_checked_against_the_data():
    table = pd.DataFrame({"box": ["s", "s", "s", "l", "l", "l"], "t": [1, 2, 3, 400, 401, 402]})
    text = relation_text(Relation("nested", "box", "t", 0.9999), table)
    assert "determines" not in text and "box explains more than 99.9 %" in text
    table["day"] = ["mon"] * 3 + ["tue"] * 3
    assert relation_text(Relation("nested", "box", "day"), table) == (
        "box determines day (each box has one day)"
    )


def _cmu_seated_late(ids):
    campaign = soilstats.load_campaign("cmu-3d-terramechanics")
    tests, sinkage = raw_frames(campaign)
    rng = np.random.default_rng(0)
    parts = [
        seated_late(tid, g[g["z_m"] > 0], 1.5e-3, rng) if tid in ids else g
        for tid, g in sinkage.groupby("test_id", sort=False)
    ]
    return Campaign.from_frames(tests, pd.concat(parts, ignore_index=True))


@pytest.mark.parametrize("late", [(), ("small-D60-1", "large-D100-2")])
def test_cmu_box_day_effect_is_a_finding_and_no_claim_of_determination_is_false(late):
    """The CMU plates: the two boxes were tested on two days, and n differs between them.
    The box/day effect is a finding (named box or start_time, the other confounded), never
    an artefact — also with two tests seated late — and every 'determines' printed holds."""
    campaign = _cmu_seated_late(late) if late else "cmu-3d-terramechanics"
    result = discover(campaign, seed=0)
    day = [f for f in result.findings if f.cause in ("box", "start_time")]
    assert day and {"box", "start_time"} <= {day[0].cause, *day[0].confounded_with}
    assert not result.artefacts, result.summary()
    tests = soilstats.load_campaign("cmu-3d-terramechanics").tests
    tests = soilstats.discovery.candidates.with_time_hours(tests)[0]
    for record in result.confounded:
        if "determines" in record["text"]:
            a, b = record["columns"]
            codes = [level_codes(candidate_values(tests, c)) for c in (a, b)]
            assert determines(*codes), record["text"]
    assert not any("box determines" in r["text"] for r in result.confounded)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CRITERIA))
def test_issue35_criteria_over_20_seeds(name):
    """Issue #35's criteria (docs/discover.md, "Issue #35"): each over seeds 0-19."""
    build, judge, minimum = CRITERIA[name]
    good = sum(bool(judge(discover(build(seed), seed=0))) for seed in range(20))
    assert good >= minimum, f"{name}: {good} of 20"


def test_power_statements_are_capped_to_what_the_data_can_express():
    """An effect larger than the tests' whole spread in the response is 'not testable here',
    not '±86 %' (the CMU test_number trend across 1..9, each plate block spanning three)."""
    from soilstats.discovery.power import describe

    assert describe("sinkage", "level", 0.2, "for one level", observed=0.5).startswith("±22.1 %")
    text = describe("sinkage", "level", 3.4, "for one level", observed=0.5)
    assert text.startswith("not testable here") and "64.9 %" in text and "2900" not in text
    result = discover("cmu-3d-terramechanics", seed=0)
    power = {p["candidate"]: p["responses"] for p in result.power}
    order = power["test_number"]["level"]
    assert not order["testable"] and order["mde"] is None
    assert order["mde_uncapped"] > order["observed_range"] > 0
    assert order["statement"].startswith("not testable here")
    assert power["repetition"]["level"]["testable"]  # the same tests, a range they span
    assert "not testable here" in result.summary()


@pytest.mark.slow  # many seeded campaigns: CI runs it
def test_one_cell_and_within_block_tests_have_at_least_the_stated_power():
    """The one-cell interaction test and the drift-within-blocks test take the largest of K
    one-degree-of-freedom tests at α/K: a shift of the stated MDE in the hardest pattern is
    found with at least 80 % power (the other patterns only add), by simulation."""
    from soilstats.discovery.ftests import interaction_test, within_blocks_test
    from soilstats.discovery.power import minimum_detectable

    rng = np.random.default_rng(12)
    a, b = np.repeat([0, 1], 27), np.tile(np.repeat([0, 1, 2], 3), 6)
    strata = np.tile([0, 1, 2], 18)
    alpha = 0.005
    ref = interaction_test(rng.normal(size=a.size), a, b, strata=strata)
    assert (ref["df1"], ref["patterns"]) == (1, 3)
    delta = minimum_detectable(1.0, ref["mde_norm2"], 1, ref["df2"], alpha / ref["patterns"])
    cell = (a == 1) & (b == 2)
    hits = sum(
        interaction_test(rng.normal(size=a.size) + delta * cell, a, b, strata=strata)["p_value"]
        < alpha
        for _ in range(600)
    )
    assert 0.77 <= hits / 600 <= 0.9
    # in a 3 × 3 table the omnibus F spends four degrees of freedom on one cell: less power
    a3, b3 = np.repeat([0, 1, 2], 18), np.tile(np.repeat([0, 1, 2], 6), 3)
    ref = interaction_test(rng.normal(size=a3.size), a3, b3, strata=strata)
    assert ref["patterns"] == 9
    delta = minimum_detectable(1.0, ref["mde_norm2"], 1, ref["df2"], alpha / ref["patterns"])
    shifted = delta * ((a3 == 1) & (b3 == 2))
    found = {
        test: sum(
            interaction_test(rng.normal(size=a3.size) + shifted, a3, b3, strata=strata, test=test)[
                "p_value"
            ]
            < alpha
            for _ in range(600)
        )
        / 600
        for test in ("cell", "omnibus")
    }
    assert found["cell"] >= 0.77 and found["omnibus"] < found["cell"] - 0.03, found
    # a drift inside one of three blocks of eight tests, against the common trend
    blocks, order = np.repeat([0, 1, 2], 8), np.tile(np.arange(1.0, 9.0), 3)
    ref = within_blocks_test(rng.normal(size=24), order, strata=blocks)
    delta = minimum_detectable(1.0, ref["mde_norm2"], 1, ref["df2"], alpha / ref["patterns"])
    drift = np.where(blocks == 1, delta * (order - 1) / 7, 0.0)
    hits = sum(
        within_blocks_test(rng.normal(size=24) + drift, order, strata=blocks)["p_value"] < alpha
        for _ in range(600)
    )
    assert 0.77 <= hits / 600 <= 0.9


def test_a_drift_inside_one_plate_block_is_named_and_extended():
    """The middle plate's tests stiffen 5 % per test in run order, the others do not: a
    common trend over all blocks dilutes it; the drift within blocks names the block and
    its per-block extension gains (seed 7; over seeds: docs/discover.md)."""
    result = discover(simulate(BLOCK_DRIFT, seed=7).campaign, seed=0)
    finding = next(f for f in result.findings if f.cause.startswith("repetition within"))
    assert finding.extension == f"{finding.cause} (linear per block)"
    assert finding.gain.kept and finding.gain.relative > 0.1
    row = result.tests[(result.tests["candidate"] == finding.cause)].iloc[0]
    assert row["deviating"].endswith("0.004418")  # the middle plate, 37.5 mm: area 4.4e-3 m²
    fitted = dict(zip(finding.fit.param_names, finding.fit.values, strict=True))
    drift = {k: v for k, v in fitted.items() if "drift in" in k}
    mid = next(k for k in drift if "0.004418" in k)
    assert len(drift) == 3 and drift[mid] > 0
    assert all(abs(v) < drift[mid] for k, v in drift.items() if k != mid), drift


def test_one_deviating_cell_is_tested_as_one_cell():
    """Operator C with preparation p2 18 % stiffer (one cell of six): the interaction row
    names the cell that deviates and tests it on one degree of freedom."""
    result = discover(simulate(ONE_CELL, seed=4).campaign, seed=0)
    rows = result.tests[result.tests["candidate"] == "preparation × operator"]
    level = rows[rows["response"] == "level"].iloc[0]
    assert level["df1"] == 1 and level["patterns"] == 3
    assert "p2 × C" in level["deviating"] and level["significant"]


#: Two plates too close to separate kc from kφ (20 and 22.5 mm: identify refuses Bekker).
CLOSE_PLATES = [{"shape": "circle", "radius_m": 0.02}, {"shape": "circle", "radius_m": 0.0225}]


def test_a_design_identify_refuses_bekker_for_is_discovered_as_bernstein():
    """identify refuses Bekker where the plates are closer than 1.5×; discover's base model
    follows it: Bernstein, with the reason, and no kc–kφ collinearity red flag."""
    from discover_situations import sink, spec

    campaign = simulate(spec([sink(plates=CLOSE_PLATES, repetitions=4)]), seed=1)
    result = discover(campaign.campaign, seed=0)
    assert not any(f["code"] == "kc-kphi-collinear" for f in result.flags)
    assert any("base model Bernstein (Eq. 8), as identify decides" in n for n in result.notes)


def test_a_drift_in_one_grc1_plate_block_is_beyond_what_its_tests_can_show():
    """GRC-1 (real): a drift of +8 % per test planted in the 51 mm plate's five tests (ρ = 0.8
    with run order there) is not named — the plates' own tests scatter too much (σ of the
    level response 0.18) — and the power statement says so instead of quoting a number."""
    campaign = soilstats.load_campaign("grc1-oravec2009")
    tests, sinkage = raw_frames(campaign)
    repetition = dict(zip(tests["test_id"], tests["repetition"], strict=True))
    factor = sinkage["test_id"].map(
        lambda t: 1 + 0.08 * (repetition[t] - 3) if t.startswith("medium") else 1.0
    )
    planted = Campaign.from_frames(tests, sinkage.assign(force_N=sinkage["force_N"] * factor))
    result = discover(planted, seed=0)
    assert [f.cause for f in result.findings] == ["b_m"]
    power = {p["candidate"]: p["responses"] for p in result.power}
    within = power["repetition within area_m2"]["level"]
    assert not within["testable"] and within["statement"].startswith("not testable here")
