"""Linear least squares against the NIST StRD linear regression sets (certified values)."""

from __future__ import annotations

import pytest
from reference.nist import LINEAR_NAMES, load_linear, lre

from soilstats import linear_least_squares

# Digits float64 can deliver on each set: Wampler5's huge residuals leave ~6 digits in its
# coefficients (its σ are still matched to > 13); all others ≥ 7.
PARAM_DIGITS = {"Wampler5": 5.5}


@pytest.mark.parametrize("name", LINEAR_NAMES)
def test_linear_certified_values(name, nist_record):
    data = load_linear(name)
    fit = linear_least_squares(data.design, data.y)
    lp = min(lre(a, b) for a, b in zip(fit.params, data.certified, strict=True))
    ls = min(lre(a, b) for a, b in zip(fit.stderr, data.certified_sd, strict=True))
    nist_record(("linear", name, "-", lp, ls))
    assert lp >= PARAM_DIGITS.get(name, 7.0)
    assert ls >= 7.0
    assert lre(fit.residual_sd, data.residual_sd) >= 7.0
    assert lre(fit.r_squared, data.r_squared) >= 7.0


def test_rank_deficient_design_is_refused():
    import numpy as np

    x = np.linspace(0, 1, 20)
    with pytest.raises(ValueError, match="rank-deficient"):
        linear_least_squares(np.column_stack([x, 2 * x]), x)
