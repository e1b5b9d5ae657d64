"""``anova_oneway`` against the eleven NIST StRD one-way ANOVA sets.

Certified values are parsed by label from NIST's files (``tests/reference/nist.py``).  The
thresholds follow from the data: SiRstv, AtmWtAg and SmLs01–06 are held by float64 to better
than 10 significant digits of their deviations, so we ask for 9; SmLs07–09 have 13 constant
leading digits, and 1000000000000.4 stored in float64 is off by up to 6·10⁻⁵ (its spacing
is 2⁻¹³), which leaves about 4 digits in the deviations, so we ask for 3.5.  A second check
shows that the loss is the input's and not the algorithm's: against an exact rational
ANOVA of the very float64 values received, every set agrees to ≥ 12 digits.
"""

from __future__ import annotations

from fractions import Fraction

import pandas as pd
import pytest
from reference.nist import ANOVA_NAMES, load_anova, lre

from soilstats.statistics import anova_oneway

HARD = {"SmLs07", "SmLs08", "SmLs09"}


def _frame(s):
    return pd.DataFrame({"treatment": s.treatment, "response": s.response})


def _exact_anova(treatment, values):
    """SS_between, SS_within and F in exact rational arithmetic."""
    groups: dict[int, list[Fraction]] = {}
    for t, v in zip(treatment, values, strict=True):
        groups.setdefault(int(t), []).append(Fraction(v))
    n = sum(len(g) for g in groups.values())
    grand = sum(sum(g) for g in groups.values()) / n
    ssb = ssw = Fraction(0)
    for g in groups.values():
        m = sum(g) / len(g)
        ssb += len(g) * (m - grand) ** 2
        ssw += sum((v - m) ** 2 for v in g)
    k = len(groups)
    return ssb, ssw, (ssb / (k - 1)) / (ssw / (n - k))


@pytest.mark.parametrize("name", ANOVA_NAMES)
def test_nist_certified_values(name, nist_record):
    s = load_anova(name)
    table = anova_oneway(_frame(s), "response", "treatment")
    between, within = table.loc["between"], table.loc["within"]
    lre_f = lre(between["F"], s.f)
    lre_ss = min(lre(between["sum_sq"], s.ss_between), lre(within["sum_sq"], s.ss_within))
    nist_record(("anova", name, "-", lre_f, lre_ss))
    assert (between["df"], within["df"]) == (s.df_between, s.df_within)
    need = 3.5 if name in HARD else 9.0
    assert lre_f >= need
    assert lre_ss >= need
    assert lre(between["mean_sq"], s.ms_between) >= need
    assert lre(within["mean_sq"], s.ms_within) >= need
    assert 0.0 <= between["PR(>F)"] <= 1.0


@pytest.mark.parametrize("name", ANOVA_NAMES)
def test_exact_for_the_float64_input(name):
    """The algorithm loses nothing beyond rounding: it matches exact arithmetic on its input."""
    s = load_anova(name)
    table = anova_oneway(_frame(s), "response", "treatment")
    ssb, ssw, f = _exact_anova(s.treatment, s.response)
    assert lre(table.loc["between", "sum_sq"], float(ssb)) >= 12
    assert lre(table.loc["within", "sum_sq"], float(ssw)) >= 12
    assert lre(table.loc["between", "F"], float(f)) >= 12


@pytest.mark.parametrize("name", ["SiRstv", "SmLs03", "AtmWtAg"])
def test_certified_text_is_exactly_reproducible(name):
    """Sanity of the loader: exact arithmetic on the printed decimals gives NIST's numbers."""
    s = load_anova(name)
    ssb, ssw, f = _exact_anova(s.treatment, s.response_text)
    assert lre(float(ssb), s.ss_between) >= 14
    assert lre(float(ssw), s.ss_within) >= 14
    assert lre(float(f), s.f) >= 14


@pytest.mark.parametrize("name", ["SiRstv", "SmLs06", "AtmWtAg"])
def test_nist_r_squared_is_eta_squared(name):
    """η² of a one-way table is NIST's certified R²."""
    from soilstats.statistics import effect_sizes

    s = load_anova(name)
    sizes = effect_sizes(anova_oneway(_frame(s), "response", "treatment"))
    assert lre(sizes.loc["between", "eta_sq"], s.r_squared) >= 9
