"""The windows ``bearing-failure`` proposes fit the evidence: a window for each failed test
where its plate's other tests ran on intact, one for the whole plate only where most of the
plate failed; and a proposed window, applied, cuts off exactly what it was proposed for."""

from __future__ import annotations

import json

import numpy as np
import pytest
from quality_sim import hold_plateau, plate_spec, raw_tables

from soilstats import load_campaign
from soilstats.campaign import Campaign
from soilstats.cli.main import main
from soilstats.identification import fit_sinkage
from soilstats.quality import screen
from soilstats.simulation import simulate

SOILS = {
    "loose": {"kc": 2.0e3, "kphi": 4.0e5, "n": 0.45},
    "sand": {"kc": -9.8e3, "kphi": 1.2e6, "n": 0.82},
}


def _planted(failed: dict[tuple[str, float], int], seed: int = 3):
    """A simulated campaign (2 soils x 3 plates x 4 repetitions) in which the first
    ``failed[(soil, b)]`` tests of those plates fail: the force is held (+-1 %) from 35 %
    of the samples to the end, a plateau the plate sinks into.  Returns the campaign and the
    planted tests with the sinkage where their plateau starts."""
    campaign = simulate(plate_spec("windows", SOILS), seed=seed).campaign
    tests, sinkage = raw_tables(campaign)
    failing = []
    for (soil, b), count in failed.items():
        plate = tests[(tests["soil"] == soil) & np.isclose(tests["radius_m"], b)]
        assert len(plate) == 4
        failing += [str(t) for t in plate["test_id"].iloc[:count]]
    held, planted = hold_plateau(sinkage, failing, np.random.default_rng(seed))
    return Campaign.from_frames(tests, held), planted


def _outside(campaign, report) -> dict[str, int]:
    """Samples per test that the report's proposed window leaves out."""
    applied = report.campaign.windowed(report.proposed_window()).window
    per = applied.per_test
    return dict(zip(per["test_id"], per["outside"], strict=True))


def test_one_failed_test_gets_its_own_window_most_of_a_plate_one_for_the_plate():
    # loose/75 mm: 1 of 4 failed; sand/50 mm: 2 of 4 (half: not most); sand/75 mm: 3 of 4.
    campaign, planted = _planted({("loose", 0.075): 1, ("sand", 0.05): 2, ("sand", 0.075): 3})
    report = screen(campaign)
    onsets = {f.test_id: f.value for f in report.flags if f.code == "bearing-failure"}
    assert set(onsets) == set(planted)  # the rule finds what was planted, nothing else
    windows = report.proposed_windows()
    per_test = windows[windows["scope"] == "test"]
    tests = report.tests.set_index("test_id")
    single = {t for t in planted if tests.loc[t, "soil"] == "loose"}
    halves = {t for t in planted if tests.loc[t, "soil"] == "sand" and tests.loc[t, "b_m"] < 0.06}
    most = set(planted) - single - halves
    assert (len(single), len(halves), len(most)) == (1, 2, 3)
    assert set(per_test["test_id"]) == single | halves
    plate = windows[windows["scope"] == "plate"]
    assert len(plate) == 1 and plate["tests"].iloc[0] == 3 and plate["plate_tests"].iloc[0] == 4
    assert plate["z_max_m"].iloc[0] == min(onsets[t] for t in most)
    # Applied: every sample past a failed test's onset goes, and no sample of an intact test
    # of a plate most of which held.
    outside = _outside(campaign, report)
    sink = campaign.sinkage
    for tid, n in outside.items():
        z = sink.loc[sink["test_id"] == tid, "z_m"].to_numpy()
        if tid in single | halves:
            assert n == int((z > onsets[tid] * 1.001).sum()) > 0, tid
        elif tests.loc[tid, "soil"] == "sand" and tests.loc[tid, "b_m"] > 0.06:
            assert n == int((z > plate["z_max_m"].iloc[0] * 1.001).sum()) > 0, tid
        else:
            assert n == 0, tid


def test_cullinan_sand_one_failed_test_keeps_the_other_twelve_whole():
    """Truth: of the 13 Cullinan tests only method5-test1 fails (the force plateaus from
    ~11 mm to 80 mm; docs/quality.md).  The plate's proposal was z_max = 10.8 mm for all
    13, leaving out ~87 % of the other 12 intact records' depth."""
    campaign = load_campaign("cullinan-sand")
    report = screen(campaign)
    windows = report.proposed_windows()
    assert list(windows["scope"]) == ["test"] and list(windows["test_id"]) == ["method5-test1"]
    assert windows["plate_tests"].iloc[0] == 13
    outside = _outside(campaign, report)
    assert {t for t, n in outside.items() if n} == {"method5-test1"}
    (flag,) = [f for f in report.flags if f.code == "bearing-failure"]
    assert outside["method5-test1"] == len(flag.rows)  # exactly the run-on
    # The proposal, applied, resolves the finding; unapplied, the fit's flag names it.
    fit = fit_sinkage(report.campaign.windowed(report.proposed_window()), "bernstein")
    assert "bearing-failure" not in {f.code for f in fit.flags}
    assert any("lies outside the window (resolved)" in n for n in fit.notes)
    bare = fit_sinkage(report.campaign, "bernstein")
    (health,) = [f for f in bare.flags if f.code == "bearing-failure"]
    assert "--z-max test_id=method5-test1:0.01077" in health.message


def test_grc1_all_small_plates_fail_one_window_for_the_plate(capsys):
    """Truth: GRC-1's five small plates (b = 38 mm) all punch through at 3.4-5.4 mm; the
    medium and large plates do not.  One window for the plate, at the smallest onset."""
    campaign = load_campaign("grc1-oravec2009")
    report = screen(campaign)
    windows = report.proposed_windows()
    assert list(windows["scope"]) == ["plate"] and list(windows["b_m"]) == [0.038]
    assert (windows["tests"].iloc[0], windows["plate_tests"].iloc[0]) == (5, 5)
    assert 3.3e-3 < windows["z_max_m"].iloc[0] < 3.5e-3
    outside = _outside(campaign, report)
    assert {t for t, n in outside.items() if n} == {f"small-{i}" for i in range(1, 6)}
    fit = fit_sinkage(report.campaign.windowed(report.proposed_window()), "bekker")
    assert "bearing-failure" not in {f.code for f in fit.flags}
    assert main(["check", "--data", "grc1-oravec2009", "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    (row,) = document["proposed_windows"]
    assert {"soil", "b_m", "z_max_m", "tests"} <= set(row)  # the keys it always had
    assert document["proposed_z_max"] == [row["z_max_item"]]


@pytest.mark.parametrize("z", [0.0107697453, 0.0045813596, 0.0099996, 0.003436])
def test_the_printed_window_keeps_the_onset_and_resolves_it(z):
    from soilstats.identification.result import ONSET_TOLERANCE
    from soilstats.quality.report import _ceil4

    printed = float(_ceil4(z))
    assert z <= printed <= z * (1 + ONSET_TOLERANCE)


def test_identify_report_states_the_window_it_fitted_in(tmp_path, capsys):
    # The PDF's notes table printed the window record as a dict and crashed (unhashable).
    out = tmp_path / "out"
    args = ["identify", "--data", "grc1-oravec2009", "--z-max", "radius_m=0.038:0.0034"]
    assert main([*args, "--out", str(out)]) == 0
    capsys.readouterr()
    pdfplumber = pytest.importorskip("pdfplumber")
    with pdfplumber.open(out / "identify.pdf") as pdf:
        text = " ".join(page.extract_text() or "" for page in pdf.pages)
    record = json.loads((out / "identify.json").read_text())["fits"][0]["window"]
    beyond = sum(record["outside"].values())
    assert "radius_m = 0.038: z ≤ 3.4 mm" in text and f"{beyond} samples beyond" in text
