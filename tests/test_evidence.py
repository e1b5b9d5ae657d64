"""One vocabulary for the evidence of a held-out gain (issue #47 item 1): one threshold
(2 standard errors), the word "real" only at or above it, and every gain printed with its
standard error — the same words from discover's Gain as from soilstats.evidence."""

from __future__ import annotations

import math

import numpy as np
import pytest

from soilstats import evidence
from soilstats.discovery.crossval import Z_KEEP, compare


@pytest.mark.parametrize(
    ("difference", "stderr", "relative", "word"),
    [
        (2.0, 1.0, None, "real"),  # exactly at the threshold
        (1.99, 1.0, None, "weak"),
        (1.4, 1.0, 0.2, "weak"),
        (0.0, 1.0, None, "none"),
        (-3.0, 1.0, None, "none"),
        (5.0, 1.0, -0.01, "none"),  # the relative error is not lower
        (1e-6, 0.0, None, "real"),  # no scatter at all: infinitely many SE
    ],
)
def test_the_word_follows_the_one_threshold(difference, stderr, relative, word):
    assert evidence.REAL_SE == 2.0
    assert evidence.verdict(difference, stderr, relative) == word
    assert evidence.is_real(difference, stderr, relative) == (word == "real")


def test_every_gain_is_printed_with_its_standard_error_and_z():
    assert evidence.gain_text(0.0021, 0.00052, unit="mm", scale=1e3) == "2.1 ± 0.52 mm (4.0 SE)"
    assert evidence.describe(0.021, 0.0052) == "real: 0.021 ± 0.0052 (4.0 SE)"
    assert evidence.describe(1.4, 1.0) == "weak: 1.4 ± 1 (1.4 SE; real needs 2)"
    assert evidence.describe(-1.0, 1.0).startswith("none: -1 ± 1 (-1.0 SE)")
    assert math.isnan(evidence.z_score(1.0, float("nan")))


@pytest.mark.parametrize(
    ("difference", "z_text"),
    [(1.96, "1.96 SE"), (1.9999, "1.99 SE"), (1.94, "1.9 SE"), (2.0, "2.0 SE"), (2.04, "2.0 SE")],
)
def test_a_weak_gain_never_prints_as_two_standard_errors(difference, z_text):
    """A weak gain of 1.96 SE printed "(2.0 SE; real needs 2)" on discover's page 1 (the
    simulated-paper campaign): the printed z stays below the threshold it did not reach."""
    text = evidence.describe(difference, 1.0)
    assert f"({z_text}" in text
    assert text.startswith("real") == (difference >= 2.0)


def _errors(mean_difference: float, stderr: float, n: int = 25, seed: int = 0):
    """Held-out errors whose paired differences have exactly this mean and standard error."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=n)
    d = (d - d.mean()) / (d.std(ddof=1) / np.sqrt(n)) * stderr + mean_difference
    base = np.full(n, 10.0)
    return base, base - d


def test_discover_keeps_at_its_rule_but_calls_a_gain_real_only_at_two_standard_errors():
    base, ext = _errors(1.4e-2, 1e-2)  # 1.4 SE: the example
    gain = compare(base, ext, scheme="tests", folds=np.arange(25) % 5)
    assert gain.z == pytest.approx(1.4)
    assert Z_KEEP < 1.4 < evidence.REAL_SE
    assert gain.kept and not gain.real and gain.verdict == "weak"
    assert "not real" not in gain.summary() and "weak: 0.014 ± 0.01 (1.4 SE" in gain.summary()
    record = gain.to_dict()
    assert record["real"] is False and record["verdict"] == "weak" and record["kept"] is True
    base, ext = _errors(2.5e-2, 1e-2)
    strong = compare(base, ext, scheme="tests", folds=np.arange(25) % 5)
    assert (
        strong.real
        and strong.verdict == "real"
        and "real: 0.025 ± 0.01 (2.5 SE)" in (strong.summary())
    )


def test_a_combined_parameter_far_from_the_findings_own_fit_is_flagged_and_explained():
    """Item 2: K0 of the combined model 7 σ from the finding's is said, with why; one within
    its σ is not; the base law's parameters are never compared."""
    from types import SimpleNamespace

    from soilstats import identify
    from soilstats.discovery.result import DISAGREE_SIGMA, DiscoveryResult

    rng = np.random.default_rng(2)
    x = np.linspace(0.0, 1.0, 50)

    def fit_with(k0: float, n: float):
        y = k0 + n * x + rng.normal(0, 0.05, x.size)
        return identify(lambda x, K0, n: K0 + n * x, x, y, [0.5, 1.0])

    finding_fit, far, near = fit_with(0.42, 1.0), fit_with(0.92, 2.0), fit_with(0.43, 1.0)

    def result(combined):
        finding = SimpleNamespace(
            kind="shear", soil="s", fit=finding_fit, test_level=None, extension="side-walls"
        )
        model = SimpleNamespace(
            kind="shear",
            soil="s",
            fit=combined,
            test_level=None,
            extensions=("side-walls", "velocity"),
        )
        return SimpleNamespace(models=[model], findings=[finding])

    flagged = DiscoveryResult.disagreements(result(far))
    assert [d["parameter"] for d in flagged] == ["K0"]  # n is the base law's: not compared
    d = flagged[0]
    expected = abs(far.params["K0"] - finding_fit.params["K0"]) / np.hypot(
        far.stderr["K0"], finding_fit.stderr["K0"]
    )
    assert d["sigmas"] == pytest.approx(expected) and d["sigmas"] > DISAGREE_SIGMA
    assert "also carries velocity" in d["explanation"]
    assert DiscoveryResult.disagreements(result(near)) == []


def test_study_posterior_and_identify_reports_never_say_real_of_anything():
    """Study, posterior and identify make no held-out-gain claim, so the word "real" (reserved
    for a gain of 2 SE or more) must not appear in their texts."""
    import re

    from soilstats import fit_sinkage, load_campaign, run_study

    study = run_study("preparation", "cullinan-sand")
    fit = fit_sinkage(load_campaign("simulated-paper"), "bekker", soil="soil01", series="velocity")
    for text in (study.summary(), fit.summary(), study._repr_html_(), fit._repr_html_()):
        assert not re.search(r"\breal\b", text), re.findall(r".{30}\breal\b.{30}", text)
