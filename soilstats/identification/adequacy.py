"""Is the sinkage model right for these tests? Lack of fit and aggregation bias.

A pooled fit mixes two things in its residuals: test-to-test scatter (each test its own
curve; the ``test-scatter`` flag and ``stderr_tests`` deal with it) and a *form* the model
cannot follow. To judge the form alone, every test is fitted on its own by the power law
p = k z^n (Eq. 8: one plate, so also Bekker's form; Wong's p²-weighted log regression, a
closed form, so this costs well under a millisecond per test) and two questions are asked:

* ``lack-of-fit`` — does the power law describe a single test? Either it explains little of
  a test's pressure variation (median per-test R² below :data:`MIN_R2`: pure noise gives ~0,
  a clean curve ~1, the paper's campaigns >= 0.95), or the tests share a residual pattern
  along their depth (the mean over tests of the residual profile, in :data:`PROFILE_BINS`
  depth bins, departs from zero by more than :data:`MIN_PATTERN` of the test's largest
  pressure and by more than :data:`PATTERN_T` standard errors) — a curve the model bends the
  wrong way on every test, e.g. bearing failure or a seating toe. Real sands deviate from
  a power law by a few per cent of their largest pressure (Cullinan: ≤ 6 %); that is not
  flagged. For Bekker (Eq. 7: one n for every plate size) the plates' own exponents are also
  compared: a one-way ANOVA of the per-test n by plate size at p < :data:`PLATE_ANOVA_P`,
  with plate means more than :data:`MIN_PLATE_SPREAD` apart (GRC-1: 0.43 against 1.05).
* ``aggregation-bias`` — is the pooled exponent one the tests share? When tests stop at one
  load, soft tests run deeper and the pooled curve is flatter than every single test. Flagged
  when at most :data:`MAX_SIDE_SHARE` of the tests lie on one side of the pooled n, the
  sign test says so at p < :data:`SIGN_TEST_P`, and the pooled n is more than
  :data:`MIN_EXPONENT_GAP` and more than :data:`GAP_SIGMAS` test-level standard errors
  (cluster bootstrap) from the tests' median. The bootstrap is needed: pooling tests of
  different stiffness and depth makes the pooled n scatter more than the tests' own n (sd
  0.05 against 0.04 in a clean simulation), so "outside every test" alone happens by chance
  in 7 % of clean 8-test campaigns. Without ``test_resamples`` the check is not made.

Thresholds were set so that none fires on clean simulated campaigns over many seeds
(tests/test_adequacy.py) and so that planted defects are found.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import binomtest, f_oneway

from ..fitting.result import HealthFlag
from .wong import wong_start

__all__ = ["TestForms", "adequacy_findings", "test_forms"]

MIN_R2 = 0.5
PROFILE_BINS = 6
MIN_PATTERN = 0.08
PATTERN_T = 4.0
MIN_TESTS_PATTERN = 3
MAX_SIDE_SHARE = 0.1
SIGN_TEST_P = 0.01
MIN_EXPONENT_GAP = 0.1
GAP_SIGMAS = 3.0
PLATE_ANOVA_P = 1e-3
MIN_PLATE_SPREAD = 0.2


@dataclass(frozen=True)
class TestForms:
    """Each test fitted alone by p = k z^n: ``n`` and ``r2`` per test (NaN where no fit), and
    ``profile`` (tests × :data:`PROFILE_BINS`): mean residual / the test's largest pressure in
    equal-count depth bins."""

    __test__ = False  # not a pytest class

    n: np.ndarray
    r2: np.ndarray
    profile: np.ndarray


def _one_test(z: np.ndarray, p: np.ndarray) -> tuple[float, float, np.ndarray]:
    blank = (np.nan, np.nan, np.full(PROFILE_BINS, np.nan))
    use = (z > 0) & (p > 0)
    if use.sum() < max(PROFILE_BINS, 4) or np.ptp(np.log(z[use])) == 0:
        return blank
    try:
        k, n = wong_start(None, z[use], p[use])
    except (ValueError, np.linalg.LinAlgError):
        return blank
    residual = p - k * np.power(np.clip(z, 0, None), n)
    spread = np.sum((p - p.mean()) ** 2)
    r2 = 1 - np.sum(residual**2) / spread if spread > 0 else np.nan
    order = np.argsort(z, kind="stable")
    bins = np.array_split(residual[order] / np.max(np.abs(p)), PROFILE_BINS)
    return float(n), float(r2), np.array([b.mean() for b in bins])


def test_forms(z: np.ndarray, p: np.ndarray, test_index: np.ndarray) -> TestForms:
    """Fit every test of pooled arrays (z [m], p [Pa], test position) on its own."""
    order = np.argsort(test_index, kind="stable")
    cuts = np.flatnonzero(np.diff(test_index[order])) + 1
    rows = [_one_test(z[i], p[i]) for i in np.split(order, cuts)]
    return TestForms(
        n=np.array([r[0] for r in rows]),
        r2=np.array([r[1] for r in rows]),
        profile=np.vstack([r[2] for r in rows]) if rows else np.empty((0, PROFILE_BINS)),
    )


def _lack_of_fit(forms: TestForms) -> HealthFlag | None:
    r2 = forms.r2[np.isfinite(forms.r2)]
    if r2.size and np.median(r2) < MIN_R2:
        return HealthFlag(
            "lack-of-fit",
            f"fitted test by test, the power law explains a median {np.median(r2):.0%} of a "
            "test's pressure variation: the records look like noise or another law; look at "
            "the curves before using any parameter",
        )
    profile = forms.profile[np.all(np.isfinite(forms.profile), axis=1)]
    if len(profile) < MIN_TESTS_PATTERN:
        return None
    mean = profile.mean(axis=0)
    se = profile.std(axis=0, ddof=1) / np.sqrt(len(profile))
    t = np.abs(mean) / np.where(se > 0, se, np.inf)
    bad = (np.abs(mean) > MIN_PATTERN) & (t > PATTERN_T)
    if not bad.any():
        return None
    k = int(np.argmax(np.where(bad, np.abs(mean), 0)))
    return HealthFlag(
        "lack-of-fit",
        f"the tests share a residual pattern along their depth the model cannot follow: in "
        f"depth sixth {k + 1} of {PROFILE_BINS} each test's own power law is off by "
        f"{mean[k]:+.1%} of its largest pressure on average ({t[k]:.1f} standard errors); "
        "plot the residuals against sinkage (bearing failure, a seating toe or a wrong model)",
    )


def _aggregation_bias(forms: TestForms, n_pooled: float, se_n: float | None) -> HealthFlag | None:
    n = forms.n[np.isfinite(forms.n)]
    if n.size < 2 or not np.isfinite(n_pooled) or se_n is None or not np.isfinite(se_n):
        return None
    below = int((n < n_pooled).sum())
    side = min(below, n.size - below)
    p_value = binomtest(below, n.size, 0.5).pvalue
    gap = n_pooled - float(np.median(n))
    material = abs(gap) > max(MIN_EXPONENT_GAP, GAP_SIGMAS * se_n)
    if side <= MAX_SIDE_SHARE * n.size and p_value < SIGN_TEST_P and material:
        return HealthFlag(
            "aggregation-bias",
            f"the pooled n = {n_pooled:.3g} is {'below' if gap < 0 else 'above'} "
            f"{n.size - side} of {n.size} tests' own n (median {np.median(n):.3g}; "
            f"{abs(gap) / se_n:.1f} test-level standard errors away): the pooled "
            "curve is no test's curve (tests stopped at one load, or depth ranges differ with "
            "stiffness); quote per-test parameters (fit_per_test) or window all tests alike",
        )
    return None


def _plates_disagree(forms: TestForms, sizes: np.ndarray) -> HealthFlag | None:
    ok = np.isfinite(forms.n)
    groups = {b: forms.n[ok & (sizes == b)] for b in np.unique(sizes[ok])}
    groups = {b: n for b, n in groups.items() if n.size >= 2}
    if len(groups) < 2 or all(np.ptp(n) == 0 for n in groups.values()):
        return None
    means = {b: float(n.mean()) for b, n in groups.items()}
    spread = max(means.values()) - min(means.values())
    p_value = f_oneway(*groups.values()).pvalue
    if not (p_value < PLATE_ANOVA_P and spread > MIN_PLATE_SPREAD):
        return None
    listed = ", ".join(f"{m:.2f} (b = {b:g} m)" for b, m in sorted(means.items()))
    return HealthFlag(
        "lack-of-fit",
        f"the plate sizes disagree on the exponent (mean per-test n {listed}; ANOVA p = "
        f"{p_value:.1g}): Bekker's one n for every plate (Eq. 7) does not hold here, and kc, "
        "kphi are a compromise between plates; fit each plate size (Bernstein) or window "
        "the plates alike",
    )


def adequacy_findings(
    z, p, test_index, n_pooled: float, b=None, n_stderr_tests: float | None = None
) -> tuple[TestForms, list[HealthFlag]]:
    """The per-test forms and the ``lack-of-fit`` / ``aggregation-bias`` flags they raise.

    ``z`` [m], ``p`` [Pa] and ``test_index`` are pooled arrays (one entry per sample); ``b``
    [m], per sample, only for Bekker-type fits (the plate-exponent comparison);
    ``n_stderr_tests``: the test-level stderr of the pooled n (None: no aggregation check).
    """
    test_index = np.asarray(test_index)
    forms = test_forms(np.asarray(z, float), np.asarray(p, float), test_index)
    checks = [_lack_of_fit(forms), _aggregation_bias(forms, n_pooled, n_stderr_tests)]
    if b is not None:
        first = np.unique(test_index, return_index=True)[1]
        checks.insert(1, _plates_disagree(forms, np.asarray(b, float)[first]))
    flags = [f for f in checks if f]
    if sum(f.code == "lack-of-fit" for f in flags) > 1:  # one flag per code, messages joined
        joined = "; and ".join(f.message for f in flags if f.code == "lack-of-fit")
        flags = [HealthFlag("lack-of-fit", joined)] + [f for f in flags if f.code != "lack-of-fit"]
    return forms, flags
