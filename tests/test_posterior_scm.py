"""The Chrono SCM export (issue #34 item 5): SCM's own constraints, user priors for what no
test measured, the Bernstein mapping, page 1 of the report, and the example loop."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pypdf import PdfReader

from soilstats.bayes import simulator_parameters
from soilstats.bayes.export import (
    REPAIRED,
    SCM_CONSTRAINTS,
    SimulatorConstraintError,
    check_scm,
    export_simulator,
)
from soilstats.bayes.stated_priors import parse_stated_prior
from soilstats.cli.main import main

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "chrono_scm_loop.py"
PRIORS = {"c": ("uniform", 0, 2000), "phi": ("normal", 30, 3), "K": ("lognormal", 0.02, 0.5)}
PRIOR_ITEMS = ["c=uniform:0:2000", "phi=normal:30:3", "K=lognormal:0.02:0.5"]


def _squeeze(text: str) -> str:
    return re.sub(r"[\s\u200b\u00ad]+", "", text)


def _page_one(pdf: Path) -> str:
    return _squeeze(PdfReader(pdf).pages[0].extract_text())


def _sinkage(n: int = 200, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    return pd.DataFrame(
        {
            "kc": rng.normal(-2e3, 500, n),
            "kphi": rng.uniform(1e6, 2e6, n),
            "n": rng.uniform(0.9, 1.1, n),
        }
    )


# --- SCM's constraints ------------------------------------------------------------------------


def test_each_scm_constraint_names_its_rows_and_chronos_line():
    table = pd.DataFrame(
        {
            "Bekker_Kphi": [1e6, 5e7, -1.0, 1e6, 1e6, 1e6, 1e6],
            "Bekker_Kc": [0.0] * 7,
            "Bekker_n": [1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0],
            "Mohr_cohesion": [0.0, 0.0, 0.0, 0.0, -5.0, 0.0, 0.0],
            "Mohr_friction": [30.0, 30.0, 30.0, 30.0, 30.0, 90.0, 30.0],
            "Janosi_shear": [0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.0],
            "elastic_K": [4e7] * 7,
            "damping_R": [3e4] * 7,
        }
    )
    _, check = check_scm(table)
    assert check.failing.tolist() == [False] + [True] * 6
    assert check.counts() == {
        "elastic_K > Bekker_Kphi": 1,
        "finite": 0,
        "Bekker_Kphi > 0": 1,
        "Bekker_n > 0": 1,
        "Mohr_cohesion >= 0": 1,
        "0 <= Mohr_friction < 90": 1,
        "Janosi_shear > 0": 1,
    }
    assert not check.passed and len(check.failures) == 6
    # The old name of failures (a method, a list) still answers until 0.3.0, with a warning.
    with pytest.warns(FutureWarning, match=r"ConstraintCheck\.problems\(\) is renamed"):
        assert check.problems() == list(check.failures)
    # each sentence counts its sets and says where in Chrono's source the rule stands
    elastic = check.failures[0]
    assert elastic.startswith("1 of 7 parameter sets break SCM's elastic_K > Bekker_Kphi")
    assert "SCMTerrain.cpp:193" in elastic and "silently" in elastic
    assert all("SCMTerrain" in c.chrono for c in SCM_CONSTRAINTS)


def test_repair_sets_elastic_K_to_the_stated_multiple_and_marks_each_row():
    table = pd.DataFrame(
        {
            "Bekker_Kphi": [1e6, 5e7, 8e7],
            "Bekker_Kc": 0.0,
            "Bekker_n": 1.0,
            "Mohr_cohesion": 0.0,
            "Mohr_friction": 30.0,
            "Janosi_shear": 0.01,
            "elastic_K": 4e7,
            "damping_R": 0.0,  # Chrono's own default: the original SCM
        }
    )
    repaired, check = check_scm(table, repair=1.5)
    assert repaired["elastic_K"].tolist() == [4e7, 7.5e7, 1.2e8]
    assert repaired[REPAIRED].tolist() == [0, 1, 1]
    assert check.passed and check.counts()["elastic_K > Bekker_Kphi"] == 2
    assert "elastic_K repaired in 2 of 3 parameter sets" in check.describe()
    assert table["elastic_K"].tolist() == [4e7] * 3  # the input is not changed
    for bad in (1.0, 0.5, np.nan, 1001.0, 1e308, np.inf):
        with pytest.raises(ValueError, match=r"multiple must be a number in \(1, 1000\]"):
            check_scm(table, repair=bad)


def test_a_table_chrono_would_change_is_never_returned_silently():
    draws = _sinkage().assign(c=0.0, phi=30.0, K=0.01)
    with pytest.raises(SimulatorConstraintError, match="elastic_K > Bekker_Kphi") as err:
        simulator_parameters(draws, elastic_K=1.5e6)
    assert err.value.check.counts()["elastic_K > Bekker_Kphi"] > 0
    table = simulator_parameters(draws, elastic_K=1.5e6, repair=2.0)
    assert (table["elastic_K"] > table["Bekker_Kphi"]).all()
    assert simulator_parameters(draws, damping_R=0.0)["damping_R"].eq(0).all()
    with pytest.raises(ValueError, match="damping_R must be zero or positive"):
        simulator_parameters(draws, damping_R=-1.0)


# --- sources: user priors, the Bernstein mapping ------------------------------------------------


def test_sinkage_only_draws_take_the_shear_part_from_user_priors_and_say_so():
    draws = _sinkage()
    with pytest.raises(ValueError, match=r"Mohr_cohesion \(c \[Pa\]\).*--prior c=uniform:0:2000"):
        export_simulator(draws)
    export = export_simulator(draws, priors=PRIORS, seed=7)
    assert export.check.passed
    assert export.sources["Mohr_cohesion"].startswith("user prior uniform(0, 2000) Pa")
    assert export.sources["Janosi_shear"].startswith("user prior lognormal(0.02, 0.5) m")
    assert export.sources["Bekker_Kphi"] == "posterior draws"
    assert export.from_priors() == ["Mohr_cohesion", "Mohr_friction", "Janosi_shear"]
    assert any("independently of the posterior draws" in n for n in export.notes)
    # The priors' draws do not depend on the sinkage draws (independent blocks), only on the seed.
    other = export_simulator(_sinkage(seed=1), priors=PRIORS, seed=7)
    cols = ["Mohr_cohesion", "Mohr_friction", "Janosi_shear"]
    pd.testing.assert_frame_equal(export.table[cols], other.table[cols])
    assert not export.table[cols].equals(export_simulator(draws, priors=PRIORS, seed=8).table[cols])
    assert export.table["Mohr_cohesion"].between(0, 2000).all()
    lines = export.comment_lines()
    assert any(
        line.startswith("source Mohr_friction: user prior normal(30, 3) deg") for line in lines
    )
    with pytest.raises(ValueError, match="priors given for"):
        export_simulator(draws.assign(c=1.0, phi=30.0, K=0.01), priors=PRIORS, seed=7)


def test_bernstein_maps_onto_scm_with_kc_zero_and_is_marked():
    draws = pd.DataFrame({"k": [3e7, 2e7], "n": [1.1, 1.0]})
    export = export_simulator(
        draws, priors=PRIORS, seed=0, elastic_K=1e8, plate_widths=(0.051, 0.051)
    )
    assert export.table["Bekker_Kc"].eq(0).all()
    assert export.table["Bekker_Kphi"].tolist() == [3e7, 2e7]
    assert "Bernstein mapping" in export.sources["Bekker_Kphi"]
    assert export.sources["Bekker_Kc"].startswith("0 by the Bernstein mapping")
    assert any("b = 0.051 m" in n and "Bekker_Kc = 0" in n for n in export.notes)


def test_negative_kc_names_the_patch_size_below_which_scm_pressure_turns_negative():
    export = export_simulator(_sinkage(), priors=PRIORS, seed=0)
    assert export.negative_modulus_below_m == pytest.approx(
        np.quantile(-_sinkage()["kc"] / _sinkage()["kphi"], 0.99), rel=1e-12
    )
    assert "perimeter / (2 area)" in export.notes[0]
    assert export.record()["negative_modulus_below_m"] == export.negative_modulus_below_m


def test_user_prior_text_forms():
    assert parse_stated_prior("uniform:0:2000") == ("uniform", 0.0, 2000.0)
    assert parse_stated_prior("0:2000") == ("uniform", 0.0, 2000.0)
    assert parse_stated_prior("normal:30:3") == ("normal", 30.0, 3.0)
    assert parse_stated_prior("normal:30:3:20:40") == ("truncnormal", 30.0, 3.0, 20.0, 40.0)
    assert parse_stated_prior("lognormal:0.02:0.5") == ("lognormal", 0.02, 0.5)
    for bad in ("gamma:1:2", "normal:a:b", "x"):
        with pytest.raises(ValueError, match="cannot read the prior"):
            parse_stated_prior(bad)


# --- the command line: a sinkage-only campaign (GRC-1) -------------------------------------------


def test_a_sinkage_only_export_without_priors_is_refused_before_sampling(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["posterior", "--data", "grc1-oravec2009", "--model", "bernstein"]
    assert main([*argv, "--simulator", "chrono-scm", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1  # one line: what is missing and the option that gives it
    assert "Mohr_cohesion" in err[0] and "Janosi_shear" in err[0]
    assert "--prior c=uniform:0:2000" in err[0] and "--model bekker+janosi" in err[0]
    assert not out.exists()
    # without --simulator, a prior on a parameter no model has is still an error, with the hint
    assert main([*argv, "--prior", "c=uniform:0:2000", "--out", str(out)]) == 2
    assert "--simulator chrono-scm" in capsys.readouterr().err


@pytest.fixture(scope="module")
def grc1_export(tmp_path_factory):
    """GRC-1's 51 mm plate (Bernstein; no shear tests) exported with user priors for c, φ, K
    and --scm-repair; --soil left out (the campaign has one soil)."""
    out = tmp_path_factory.mktemp("grc1") / "out"
    argv = ["posterior", "--data", "grc1-oravec2009", "--model", "bernstein"]
    argv += ["--select", "radius_m=0.051", "--simulator", "chrono-scm", "--scm-repair", "2"]
    argv += [a for item in PRIOR_ITEMS for a in ("--prior", item)]
    assert main([*argv, "--out", str(out), "--progress", "off"]) == 0
    return out


def test_the_sinkage_only_export_carries_its_marks(grc1_export):
    out = grc1_export
    text = (out / "chrono-scm.csv").read_text(encoding="utf-8")
    comments = [line for line in text.splitlines() if line.startswith("#")]
    assert (
        "# source Mohr_cohesion: user prior uniform(0, 2000) Pa, drawn independently of the "
        "posterior draws (not measured)" in comments
    )
    assert any(c.startswith("# source Bekker_Kc: 0 by the Bernstein mapping") for c in comments)
    sim = pd.read_csv(out / "chrono-scm.csv", comment="#")
    draws = pd.read_csv(out / "draws.csv", comment="#")
    assert list(sim.columns[:8]) == [
        "Bekker_Kphi", "Bekker_Kc", "Bekker_n", "Mohr_cohesion", "Mohr_friction",
        "Janosi_shear", "elastic_K", "damping_R",
    ]  # fmt: skip
    np.testing.assert_allclose(sim["Bekker_Kphi"], draws["k"], rtol=1e-9)
    np.testing.assert_allclose(sim["Bekker_n"], draws["n"], rtol=1e-9)
    assert sim["Bekker_Kc"].eq(0).all() and list(draws.columns) == ["k", "n"]
    record = json.loads((out / "chrono-scm.json").read_text())
    assert record["sources"]["Mohr_friction"].startswith("user prior normal(30, 3) deg")
    assert record["sources"]["Bekker_Kphi"].endswith("(Bernstein mapping: Kphi = k)")
    assert record["soil"] == "GRC-1" and record["selection"] == ["radius_m=0.051"]
    # GRC-1's k reaches past the demos' elastic_K = 4e7: those sets were repaired, row by row.
    repaired = sim[REPAIRED] == 1
    assert record["constraints"]["repaired"] == repaired.sum() > 0
    np.testing.assert_allclose(sim.loc[repaired, "elastic_K"], 2 * sim.loc[repaired, "Bekker_Kphi"])
    assert (sim.loc[~repaired, "elastic_K"] == 4e7).all()
    assert (sim["elastic_K"] > sim["Bekker_Kphi"]).all() and record["constraints"]["passed"]
    page = _page_one(out / "report.pdf")
    assert "passeverycheck" not in page
    assert _squeeze("elastic_K repaired to 2 x Bekker_Kphi in") in page
    assert _squeeze("user priors, not tests: Mohr_cohesion ~ uniform(0, 2000) Pa") in page
    assert _squeeze("Bernstein mapping: Bekker_Kphi = k, Bekker_Kc = 0") in page
    posterior = json.loads((out / "posterior.json").read_text())
    assert posterior["simulator"]["sources"] == record["sources"]
    # the SCM inputs nobody stated are defaults the sets rest on (issue #47, item 3)
    stated = record["stated_inputs"]
    for name, option in (("elastic_K", "--scm-elastic-K"), ("damping_R", "--scm-damping-R")):
        assert stated[name]["source"] != "stated by user"
        assert posterior["defaults"][option].startswith(f"{stated[name]['value']:g} ")


def test_the_example_loops_over_a_fresh_export(grc1_export):
    run = subprocess.run(
        [sys.executable, str(EXAMPLE), str(grc1_export), "--rows", "4"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    calls = [line for line in run.stdout.splitlines() if line.startswith("row ")]
    assert len(calls) == 4 and all("SetSoilParameters(" in line for line in calls)
    sim = pd.read_csv(grc1_export / "chrono-scm.csv", comment="#")
    first = [float(v) for v in calls[0].split("(", 1)[1].split(")")[0].split(",")]
    np.testing.assert_allclose(first, sim.iloc[0, :8].to_numpy(float), rtol=1e-5)
    assert "user prior uniform(0, 2000) Pa" in run.stdout and "4 of 4 rows used" in run.stdout


# --- the command line: simulated soil02, every set breaking elastic_K > Kphi ---------------------

SOIL02 = [
    "posterior",
    "--data",
    "simulated-paper",
    "--soil",
    "soil02",
    "--model",
    "bekker+janosi",
    "--select",  # one shear series: pooled series of different set-ups are refused (#43)
    "shear:series=shear-ring",
    "--population",
    "--simulator",
    "chrono-scm",
    "--draws",
    "1000",
    "--progress",
    "off",
]


@pytest.mark.slow  # two population runs of two models: ~20 s
def test_soil02_with_the_demo_elastic_K_is_refused_and_then_forced_loudly(tmp_path, capsys):
    # soil02's n is about 3.2, so Kphi [Pa/m^n] is ~1e10 against the demos' elastic_K 4e7.
    out = tmp_path / "refused"
    assert main([*SOIL02, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.search(
        r"chrono-scm: \d+ of \d+ parameter sets break SCM's elastic_K > Bekker_Kphi", err
    )
    assert "--scm-elastic-K above" in err and "--scm-repair MULTIPLE" in err
    assert not out.exists() or not any(out.iterdir())  # nothing written

    out = tmp_path / "forced"
    assert main([*SOIL02, "--out", str(out), "--force"]) == 1
    page = _page_one(out / "report.pdf")
    assert "passeverycheck" not in page
    assert _squeeze("FORCED:") in page
    assert re.search(r"elastic_K>Bekker_Kphi:brokenin\d+of\d+sets", page)
    assert _squeeze("turns negative on contact patches with b below") in page  # kc < 0
    record = json.loads((out / "chrono-scm.json").read_text())
    assert record["forced"] and not record["constraints"]["passed"]
    broken = record["constraints"]["broken"]["elastic_K > Bekker_Kphi"]
    sim = pd.read_csv(out / "chrono-scm.csv", comment="#")
    assert broken == (sim["elastic_K"] <= sim["Bekker_Kphi"]).sum() > 0.9 * len(sim)
    forced = next(
        line
        for line in (out / "chrono-scm.csv").read_text().splitlines()
        if line.startswith("# FORCED: written although:")
    )
    assert "chrono-scm: " in forced and "elastic_K > Bekker_Kphi" in forced
    # the example refuses the rows Chrono would change, loudly
    run = subprocess.run(
        [sys.executable, str(EXAMPLE), str(out), "--rows", "20"], capture_output=True, text=True
    )
    assert run.returncode == 1 and "rows skipped" in run.stderr and "FORCED" in run.stderr


def test_page_one_says_pass_every_check_only_when_nothing_is_flagged():
    from soilstats.report.posterior_pdf import _verdict

    class Clean:
        model_name = "bernstein"

        def least_squares_health(self):
            return []

    record = {"draws_written": 10, "failures": [], "warnings": [], "pooling_warnings": []}
    assert "pass every check" in _verdict([Clean()], record)[0]
    for change in (
        {"warnings": ["numerical warnings"]},
        {"pooling_warnings": ["pools 2 values of velocity_m_s"]},
        {"simulator": {"constraints": {"repaired": 3, "passed": True}}},
    ):
        said = "".join(str(p) for p in _verdict([Clean()], record | change))
        assert "pass every check" not in said, change

    class Flagged(Clean):
        def least_squares_health(self):
            return [{"code": "lack-of-fit", "message": "a shared residual pattern"}]

    said = "".join(str(p) for p in _verdict([Flagged()], record))
    assert "pass every check" not in said and "least-squares start of bernstein" in said


def test_constraint_failures_name_the_fix_with_or_without_the_api_arguments():
    """One wording for the API's error and the CLI's refusal: the API's argument names
    (elastic_K=, repair=) only where they can be given (issue #45: the CLI had a copy)."""
    from soilstats.bayes.export import constraint_failures

    table = pd.DataFrame(
        {
            "Bekker_Kphi": [5e7, 1e6],
            "Bekker_Kc": [0.0, 0.0],
            "Bekker_n": [1.0, 0.0],
            "Mohr_cohesion": [0.0, 0.0],
            "Mohr_friction": [30.0, 30.0],
            "Janosi_shear": [0.01, 0.01],
            "elastic_K": [4e7, 4e7],
            "damping_R": [3e4, 3e4],
        }
    )
    _, check = check_scm(table)
    api, cli = (
        constraint_failures("chrono-scm", check),
        constraint_failures("chrono-scm", check, arguments=False),
    )
    assert len(api) == len(cli) == 2
    fixed = [text for text in cli if "Fix:" in text]
    assert len(fixed) == 1 and "above 5e+07 Pa/m" in fixed[0]  # the largest Bekker_Kphi
    assert "--scm-elastic-K above" in fixed[0] and "--scm-repair MULTIPLE to set" in fixed[0]
    assert "(elastic_K=)" in "".join(api) and "(repair=)" in "".join(api)
    assert "(elastic_K=)" not in "".join(cli)
    assert [a.replace(" (elastic_K=)", "").replace(" (repair=)", "") for a in api] == cli
