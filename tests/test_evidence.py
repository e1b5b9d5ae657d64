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
