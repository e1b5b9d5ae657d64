"""The decision whether draws may go to a rover Monte Carlo lives in the library
(:mod:`soilstats.bayes.handout`): a Python caller gets the answer the command line prints, and
what can be known before sampling refuses before it, leaving no output folder behind."""

from __future__ import annotations

import time

import pytest

from soilstats import load_campaign
from soilstats.bayes import sample_posterior
from soilstats.bayes.handout import hand_out, preflight
from soilstats.cli.main import main
from soilstats.errors import ConvergenceWarning


def test_plates_too_close_to_separate_kc_and_kphi_refuse_bekker_before_sampling(
    tmp_path, monkeypatch, capsys
):
    """identify's decision holds for the posterior (issue #35): plates 50 and 60 mm apart by
    less than 1.5x leave kc/b and kphi one ridge; Bekker is refused, never swapped silently,
    and Bernstein on the same tests is not."""
    from posterior_calibration import population_spec

    import soilstats.bayes.posterior as posterior
    from soilstats.simulation import simulate

    spec = population_spec(4, points=40)
    spec["series"][0]["plates"] = [{"shape": "circle", "radius_m": b} for b in (0.05, 0.06)]
    folder = simulate(spec, seed=5).campaign.save(tmp_path / "close")
    campaign = load_campaign(folder)
    failures, _ = preflight(campaign, ["bekker"], population=False)
    assert len(failures) == 1 and "differ by less than 1.5x" in failures[0]
    assert "--model bernstein" in failures[0]
    assert preflight(campaign, ["bernstein"], population=False, b_m=0.05)[0] == []

    def never(*args, **kwargs):
        raise AssertionError("sampled although the refusal was known before")

    monkeypatch.setattr(posterior, "sample_posterior", never)
    out = tmp_path / "never-made"
    argv = ["posterior", "--data", str(folder), "--model", "bekker", "--out", str(out)]
    assert main([*argv, "--progress", "off"]) == 2
    assert "differ by less than 1.5x" in capsys.readouterr().err and not out.exists()


def test_plates_that_disagree_refuse_a_population_before_any_sampling(
    tmp_path, monkeypatch, capsys
):
    """GRC-1's Bekker fit is flagged plate-exponents (n 0.40, 1.10, 1.04 on its three
    plates): its population would hand the misfit out as scatter between preparations. The
    refusal comes from the least-squares fit alone — no sampler runs, no folder is made."""
    import soilstats.bayes.population as population

    def never(*args, **kwargs):
        raise AssertionError("sampled although the refusal was known before")

    monkeypatch.setattr(population, "sample_population", never)
    campaign = load_campaign("grc1-oravec2009")
    # Before any sampling: `never` above fails the test if a sampler runs (its time, about
    # that of a least-squares fit, is a benchmark's business, not a test's).
    failures, health = preflight(campaign, ["bekker"], population=True, soil="GRC-1")
    assert "plate-exponents" in failures[0] and "plate-exponents" in str(health["bekker"])
    assert preflight(campaign, ["bekker"], population=False, soil="GRC-1")[0] == []
    out = tmp_path / "never-made"
    argv = ["posterior", "--data", "grc1-oravec2009", "--model", "bekker", "--population"]
    assert main([*argv, "--out", str(out), "--progress", "off"]) == 2
    err = capsys.readouterr().err
    assert "Refused before sampling" in err and "plate-exponents" in err
    assert not out.exists()


def test_a_python_caller_gets_the_decision_the_command_line_prints():
    """The pooled posterior of GRC-1's 51 mm plate: converged and physical, so handed out;
    the same draws judged at a contact width where k would be extrapolated still pass (the
    Bernstein modulus does not depend on b), and a posterior that did not converge fails
    with the reason."""
    campaign = load_campaign("grc1-oravec2009")
    post = sample_posterior(campaign, "bernstein", soil="GRC-1", radius_m=0.051, seed=3)
    decision = post.handout((0.051, 0.051), seed=1)
    assert decision.passed and decision.failures == ()
    assert len(decision.draws) == decision.n_drawn and set(decision.draws) == {"k", "n"}
    record = decision.to_dict()
    assert record["passed"] and record["draws_written"] == len(decision.draws)
    with pytest.warns(ConvergenceWarning):
        short = sample_posterior(
            campaign, "bernstein", soil="GRC-1", radius_m=0.051, seed=3, draws=50
        )
    assert not short.converged
    failed = hand_out([short], (0.051, 0.051))
    assert not failed.passed and "not converged" in failed.failures[0]


def test_draws_refused_after_sampling_leave_no_folder(tmp_path, monkeypatch, capsys):
    """Whatever refuses the draws after sampling (here: a failure added to the library's
    decision), nothing is written, and the output folder is not even made."""
    from dataclasses import replace

    import soilstats.bayes.handout as handout

    real = handout.hand_out

    def refusing(*args, **kwargs):
        return replace(real(*args, **kwargs), failures=("a planted failure",))

    monkeypatch.setattr(handout, "hand_out", refusing)
    out = tmp_path / "none"
    argv = ["posterior", "--data", "grc1-oravec2009", "--model", "bernstein"]
    argv += ["--select", "radius_m=0.051", "--out", str(out), "--progress", "off"]
    assert main(argv) == 2
    assert "a planted failure" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow  # two posterior runs: CI runs it
def test_the_same_posterior_run_writes_a_byte_identical_netcdf(tmp_path, monkeypatch):
    """No clock in posterior.nc (ArviZ's created_at only with SOURCE_DATE_EPOCH)."""
    out = tmp_path / "nc"
    argv = ["posterior", "--data", "grc1-oravec2009", "--model", "bernstein"]
    argv += ["--select", "radius_m=0.051", "--out", str(out), "--progress", "off", "--overwrite"]
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    assert main(argv) == 0
    first = (out / "posterior.nc").read_bytes()
    time.sleep(1.1)  # a clock read would now differ
    assert main(argv) == 0
    assert (out / "posterior.nc").read_bytes() == first
    assert b"created_at" not in first


def test_source_date_epoch_sets_the_posterior_date(monkeypatch):
    from soilstats.outputs.provenance import source_date

    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    assert source_date() is None
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    assert source_date() == "2026-01-01T00:00:00+00:00"
