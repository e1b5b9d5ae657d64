"""Force-zero drift (``zero-drift``): found where it is planted (simulated campaigns and the
bundled Cullinan records, with a known offset per test), never on clean campaigns, and
discovery reads a cause that follows test order in drifted data as a residue, not a cause."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from quality_sim import plate_spec, raw_tables

from soilstats import load_campaign
from soilstats.campaign import Campaign
from soilstats.discovery import discover
from soilstats.quality import CODES, screen
from soilstats.quality import drift as drift_mod
from soilstats.simulation import simulate

SOIL = {"loose": {"kc": 2.0e3, "kphi": 4.0e5, "n": 0.45}}


def _spec(repetitions: int = 6) -> dict:
    return plate_spec("drift", SOIL, repetitions=repetitions)


_raw = raw_tables


def drifted(seed: int, step: float, repetitions: int = 6) -> Campaign:
    """A simulated campaign whose force zero drifts by ``step`` × the plate series' median
    peak force per repetition (repetition r reads (r - 1) × step too high)."""
    campaign = simulate(_spec(repetitions), seed=seed).campaign
    tests, sinkage = _raw(campaign)
    log = campaign.tests.set_index("test_id")
    peak = sinkage.groupby("test_id")["force_N"].max()
    series_peak = peak.groupby(log["b_m"]).median()
    offset = log["b_m"].map(series_peak) * step * (log["repetition"] - 1)
    sinkage["force_N"] += sinkage["test_id"].map(offset).to_numpy()
    return Campaign.from_frames(tests, sinkage)


def _drift_flags(campaign) -> set[str]:
    return {f.test_id for f in screen(campaign).flags if f.code == "zero-drift"}


# ----------------------------------------------------------------------------- the test
def test_kendall_p_is_the_exact_permutation_p_value_with_ties_and_strata():
    """Against brute force: every permutation of every series' values (ties included)."""
    rng = np.random.default_rng(3)
    for trial in range(12):
        series = [
            rng.integers(0, 3 if trial % 2 else 100, size=rng.integers(2, 6)).astype(float)
            for _ in range(rng.integers(1, 3))
        ]
        s, p = drift_mod.kendall_p(series)

        def stat(values) -> int:
            v = np.asarray(values)
            return int(np.sign(v[None, :] - v[:, None])[np.triu_indices(v.size, 1)].sum())

        assert s == sum(stat(v) for v in series)
        null = [
            sum(stat(v) for v in combo)
            for combo in itertools.product(*(itertools.permutations(v) for v in series))
        ]
        assert p == pytest.approx(np.mean(np.abs(null) >= abs(s)), abs=1e-12)


# ----------------------------------------------------------------------------- planted drift
def test_a_planted_drift_flags_every_drifted_test_and_no_first_test():
    # 2 % of the peak per test: every test from the second repetition on is off by >= 1 %.
    for seed in (0, 1):
        campaign = drifted(seed, 0.02)
        flagged = _drift_flags(campaign)
        later = set(campaign.tests.loc[campaign.tests["repetition"] > 1, "test_id"])
        assert flagged == later
    # A drift below the threshold per test is flagged only where it has added up to 1 %.
    campaign = drifted(2, 0.004)
    reps = campaign.tests.set_index("test_id")["repetition"]
    assert {int(reps[t]) for t in _drift_flags(campaign)} <= {4, 5, 6}


def _grc_by_repetition(change) -> Campaign:
    """GRC-1 with every record's force changed by ``change(force, repetition)``."""
    tests, sinkage = _raw(load_campaign("grc1-oravec2009"))
    repetition = sinkage["test_id"].map(
        dict(zip(tests["test_id"], tests["repetition"], strict=True))
    )
    sinkage["force_N"] = change(sinkage["force_N"], repetition.to_numpy(float))
    return Campaign.from_frames(tests, sinkage)


def test_a_drift_planted_in_grc1_flags_the_late_repetitions():
    """+4 N per repetition on every real GRC-1 record (peaks 0.3-0.9 kN): repetitions 4 and
    5 of each plate are off by 12-16 N, at least 1 % of their plate's median peak."""
    flagged = _drift_flags(_grc_by_repetition(lambda f, rep: f + 4.0 * (rep - 1)))
    assert flagged == {f"{plate}-{r}" for plate in ("small", "medium", "large") for r in (4, 5)}


def test_a_stiffness_trend_over_the_day_is_not_a_drifting_zero():
    # GRC-1's records start at (0, 0) and are in contact from their second sample: the
    # median of the first three read the soil, and a compaction trend (x 1.5 per
    # repetition, no zero offset) was flagged as drift - then discover discarded the real
    # repetition effect as a residue of the data.
    stiffer = _grc_by_repetition(lambda f, rep: f * (1 + 0.5 * (rep - 1)))
    assert _drift_flags(stiffer) == set()


def test_clean_campaigns_raise_no_drift_flag():
    """No false flag on 6 clean simulated campaigns nor on the three bundled ones."""
    assert "zero-drift" in CODES and CODES["zero-drift"].nature == "artefact"
    for seed in range(6):
        assert _drift_flags(drifted(seed, 0.0)) == set()
    for name in ("cullinan-sand", "grc1-oravec2009", "simulated-paper"):
        assert _drift_flags(load_campaign(name)) == set(), name


def test_the_code_states_the_thresholds_the_rule_uses():
    what = CODES["zero-drift"].what
    assert f"z <= 0, among the first {drift_mod.START_SAMPLES}" in what
    assert f"below {drift_mod.DRIFT_ALPHA:g} after Bonferroni" in what
    assert f"one-sided p at most {drift_mod.SERIES_P:g}" in what
    assert f"at least {drift_mod.DRIFT_MIN_PEAK:.0%}".replace("%", " %") in what
    text = (Path(__file__).parents[1] / "docs" / "quality.md").read_text(encoding="utf-8")
    assert what in text


# ----------------------------------------------------------------------------- discovery
def test_discovery_reads_a_drift_in_repetition_as_a_residue_not_a_cause():
    """5 % of the peak per test: without the flag discovery named repetition as a cause of
    the soil's behaviour; with it, repetition is a residue of the data."""
    result = discover(drifted(1, 0.05)).to_dict()
    causes = {f["cause"] for f in result["findings"]}
    residues = {r["candidate"]: r["reason"] for r in result["artefacts"]}
    assert "repetition" not in causes
    assert "zero-drift" in residues["repetition"]


def test_a_drift_does_not_hide_a_real_cause_of_the_series_it_sits_in():
    """Cullinan's preparation effect (p ~ 1e-6) stays a finding when method 1 drifts: the
    flag follows test order, not the preparation whose series carries it."""
    campaign = load_campaign("cullinan-sand")
    tests, sinkage = _raw(campaign)
    offsets = {f"method1-test{i}": 10.0 * (i - 1) for i in range(1, 7)}
    sinkage["force_N"] += sinkage["test_id"].map(offsets).fillna(0.0).to_numpy()
    result = json.loads(json.dumps(discover(Campaign.from_frames(tests, sinkage)).to_dict()))
    assert "preparation" in {f["cause"] for f in result["findings"]}
    assert not result["artefacts"]


# ----------------------------------------------------------------------------- rates
@pytest.mark.slow
def test_false_alarm_and_detection_rates_over_many_seeds():
    """0 of 100 clean campaigns flagged; a drift of 1 % of the peak per test found in at
    least 95 of 100 (18 tests: 3 plates x 6 repetitions)."""
    assert sum(bool(_drift_flags(drifted(seed, 0.0))) for seed in range(100, 200)) == 0
    assert sum(bool(_drift_flags(drifted(seed, 0.01))) for seed in range(100, 200)) >= 95


def test_a_fit_of_drifted_tests_carries_the_flag():
    # Screening flagged the drifted tests, but the pooled fit of them said nothing: the
    # code was not among the fit's health codes.
    from soilstats.identification import fit_sinkage

    campaign = drifted(seed=11, step=0.02)
    fit = fit_sinkage(campaign, "bernstein", b_m=0.05)
    flag = next(f for f in fit.flags if f.code == "zero-drift")
    assert flag.message.startswith("5 of 6 tests")
    clean = fit_sinkage(drifted(seed=11, step=0.0), "bernstein", b_m=0.05)
    assert "zero-drift" not in {f.code for f in clean.flags}


def test_a_column_naming_each_test_does_not_silence_the_rule():
    # Every column but a few counted as setup: a date or a notes column with one value per
    # test made each test a series of one, and a 3 % drift went unflagged (15 flags -> 0).
    campaign = drifted(seed=2, step=0.03)
    tests, sinkage = _raw(campaign)
    dated = tests.assign(date=[f"2026-11-{i:02d}" for i in range(1, len(tests) + 1)])
    assert _drift_flags(Campaign.from_frames(dated, sinkage)) == _drift_flags(campaign) != set()


def test_a_start_time_column_orders_the_tests():
    # A log in no particular row order, without repetition numbers, but with the time each
    # test started: the drift follows the clock, and only the clock shows it.
    campaign = drifted(seed=4, step=0.02)
    tests, sinkage = _raw(campaign)
    run = (tests["repetition"] - 1) * 10 + tests.groupby("repetition").cumcount()
    start = pd.Timestamp("2026-11-24 08:00") + pd.to_timedelta(run * 12, unit="min")
    tests = tests.assign(start_time=start.dt.strftime("%Y-%m-%dT%H:%M"))
    shuffled = tests.sample(frac=1.0, random_state=1).drop(columns="repetition")
    log = Campaign.from_frames(shuffled, sinkage)
    later = set(tests.loc[tests["repetition"] > 1, "test_id"])
    flags = [f for f in screen(log).flags if f.code == "zero-drift"]
    assert {f.test_id for f in flags} == later
    assert all(", in start_time)" in f.message for f in flags)
    # Without the clock the shuffled rows are all the order there is: the drift is lost.
    assert _drift_flags(Campaign.from_frames(shuffled.drop(columns="start_time"), sinkage)) != later


def test_one_or_two_drifted_tests_do_not_explain_an_order_effect():
    # Discovery filed a test-order cause as a residue of the data on any flagged test.
    import pandas as pd

    from soilstats.discovery.artefacts import ORDER_SHARE, _drifting

    labels = pd.Series(["clean"] * 13 + ["zero-drift"] * 2)
    assert _drifting(labels) is None
    labels = pd.Series(["clean"] * 9 + ["zero-drift"] * 6)
    assert 6 >= ORDER_SHARE * 15 and "zero-drift in 6 of 15 tests" in _drifting(labels)
