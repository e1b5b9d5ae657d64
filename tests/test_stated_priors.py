"""Stated priors are sampled right in the far tails (issue #44, item 1).

Truth is the closed form of the truncated normal written with ``erfcx`` (independent of the
sampler, which goes through scipy's ``truncnorm``): for a standard window [a, b] with a ≥ 0,

    Q(a) - Q(x) = ½ e^{-a²/2} (erfcx(a/√2) - e^{-(x²-a²)/2} erfcx(x/√2)),

so the CDF and the mean (√(2/π) (1 - e^{-(b²-a²)/2}) / (erfcx(a/√2) - e^{-(b²-a²)/2}
erfcx(b/√2))) stay exact however far the window lies in the tail.  A lower-tail window is
the mirror image.  The old sampler (inverse ndtr) gave every draw == high at [50, 60].
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import erfcx

from soilstats.bayes.stated_priors import sample_priors
from soilstats.errors import InputError

R2 = np.sqrt(2.0)


def _upper_cdf(x: np.ndarray, a: float, b: float) -> np.ndarray:
    """CDF of the standard normal truncated to [a, b], 0 ≤ a < b (b may be inf)."""
    tail = lambda t: np.exp(-(t**2 - a**2) / 2) * erfcx(t / R2)  # noqa: E731
    top = erfcx(a / R2) - tail(np.asarray(x, float))
    return top / (erfcx(a / R2) - (0.0 if np.isinf(b) else tail(b)))


def _upper_mean(a: float, b: float) -> float:
    e = 0.0 if np.isinf(b) else np.exp(-(b**2 - a**2) / 2)
    tail_b = 0.0 if np.isinf(b) else e * erfcx(b / R2)
    return float(np.sqrt(2 / np.pi) * (1 - e) / (erfcx(a / R2) - tail_b))


@pytest.mark.parametrize(
    ("a", "b"),
    [(0.0, 1.0), (3.0, 4.0), (8.0, 60.0), (20.0, 21.0), (40.0, 45.0), (50.0, 60.0), (39.0, np.inf)],
)
@pytest.mark.parametrize("side", [1, -1])
def test_truncnormal_far_in_either_tail_matches_closed_form(a, b, side):
    mean, sd, n = 100.0, 2.0, 20_000
    low, high = (a, b) if side == 1 else (-b, -a)
    if np.isinf(high):
        high = 1e300
    if np.isinf(low):
        low = -1e300
    spec = ("truncnormal", mean, sd, mean + sd * low, mean + sd * high)
    x = sample_priors({"x": spec}, n, seed=7)["x"]
    z = side * (x - mean) / sd  # mapped onto the upper window [a, b]
    assert np.all(z >= a) and np.all(z <= b)
    assert not np.any(x == spec[3]) and not np.any(x == spec[4])  # no pile-up on a bound
    # Mean within 5 standard errors of the closed form.
    assert abs(z.mean() - _upper_mean(a, b)) < 5 * z.std() / np.sqrt(n) + 1e-12
    # The sample quantiles sit where the closed-form CDF says (binomial error of F at each).
    q = np.array([0.01, 0.1, 0.5, 0.9, 0.99])
    F = _upper_cdf(np.quantile(z, q), a, b)
    assert np.all(np.abs(F - q) < 5 * np.sqrt(q * (1 - q) / n)), F


def test_truncnormal_is_seeded():
    spec = {"c": ("truncnormal", 0.0, 1.0, 50.0, 60.0)}
    np.testing.assert_array_equal(
        sample_priors(spec, 100, 3)["c"], sample_priors(spec, 100, 3)["c"]
    )


def test_truncnormal_beyond_double_precision_is_an_error_not_a_wall():
    with pytest.raises(InputError, match="cannot be sampled: its window lies 1e\\+200 sd"):
        sample_priors({"x": ("truncnormal", 0.0, 1.0, 1e200, 2e200)}, 10, 1)


# Python's float reads any Unicode decimal digit (float("٣") == 3.0): every prior parser must
# refuse such text instead of taking the number silently (issue #44).
@pytest.mark.parametrize("digit", ["٣", "３", "३"])  # Arabic-Indic, fullwidth, Devanagari 3
def test_prior_parsers_refuse_non_ascii_digits_and_name_them(digit):
    from soilstats.bayes.priors import parse_prior
    from soilstats.bayes.stated_priors import parse_stated_prior
    from soilstats.wheel.run_options import parse_prior_item

    assert float(digit) == 3.0  # the silent reading this guards against
    for parse, text in (
        (parse_prior, f"normal:{digit}:1"),
        (parse_prior, f"0:{digit}"),
        (parse_stated_prior, f"normal:{digit}:1"),
        (parse_stated_prior, f"1:{digit}"),
        (parse_prior_item, f"c=normal:{digit}:1"),
    ):
        with pytest.raises(InputError, match="ASCII digits only") as err:
            parse(text)
        assert digit in str(err.value)
    # The same priors written in ASCII are still read, to the value.
    assert parse_prior_item("c=normal:3:1") == ("c", ("normal", 3.0, 1.0))
    assert parse_stated_prior("normal:3:1") == ("normal", 3.0, 1.0)
    assert (parse_prior("normal:3:1").mu, parse_prior("0:3").upper) == (3.0, 3.0)
