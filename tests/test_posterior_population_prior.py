"""The population model's default prior: flat in the log of the measured scales, and proper.

Under a prior flat in a modulus k the population posterior is improper: k enters the
marginal likelihood through u = ln k, the prior is e^u in u, and integrating u leaves
e^{s²/(2T)} in the scatter sd s (T tests), which no prior on s outweighs.  Flat in u leaves
s^{1−T}, so with the half-Cauchy prior (∝ s⁻¹ in ln s for large s) the marginal posterior of
ln s falls as s^{−T}.  These tests check that closed form, the Jacobians of the log-flat
prior, and that the bundled GRC-1 campaign, where the improper posterior ran off, converges
to one answer whatever the seed.
"""

from __future__ import annotations

import numpy as np
import pytest
from posterior_sim import bernstein_population
from scipy.special import logsumexp

from soilstats.bayes.population_model import LAYOUTS, PopulationModel, reference_rows
from soilstats.bayes.priors import resolve_priors
from soilstats.bayes.transforms import Coordinates
from soilstats.models import BEKKER, JANOSI
from soilstats.models.shear import RAD_PER_DEG


def _log_marginal_of_scatter(pops: PopulationModel, s_eps: float) -> float:
    """ln ∫ p(k, n, s_ε, s_δ, ρ | data) dk at fixed n, s_δ, ρ = 0, on a wide grid of ln k."""
    u = np.linspace(np.log(8.5e5) - 12 * s_eps, np.log(8.5e5) + 12 * s_eps, 40001)
    with np.errstate(over="ignore"):  # k beyond float range: rejected by the model (−inf)
        k = np.exp(u)
    v = np.column_stack(
        [
            k,
            np.full_like(u, 1.07),
            np.full_like(u, np.log(s_eps)),
            np.full_like(u, np.log(0.04)),
            np.zeros_like(u),
        ]
    )
    # dk = k du: the integral over k on a grid of u.
    return float(logsumexp(pops.log_prob(v) + u) + np.log(u[1] - u[0]))


def test_default_population_prior_is_proper_in_the_scatter():
    pops = bernstein_population()
    t = pops.eta.shape[0]
    # Far above the data's scatter the marginal of ln s falls as s^(-T): slope −T in ln s.
    slope = (_log_marginal_of_scatter(pops, 300.0) - _log_marginal_of_scatter(pops, 30.0)) / (
        np.log(300.0) - np.log(30.0)
    )
    assert slope == pytest.approx(-t, abs=0.15)


def test_a_prior_flat_in_the_modulus_makes_the_scatter_run_off():
    # What the default used to be (flat in k, here given by the caller): the marginal of
    # ln s grows as e^{s²/(2T)} — the improper posterior this module guards against.
    pops = bernstein_population(priors={"k": (0.0, np.inf)})
    assert not pops.log_flat_linear
    rise = _log_marginal_of_scatter(pops, 8.0) - _log_marginal_of_scatter(pops, 4.0)
    t = pops.eta.shape[0]
    closed_form = (8.0**2 - 4.0**2) / (2 * t) - t * np.log(2.0)  # e^{s²/2T}·s^{-T}
    assert rise == pytest.approx(closed_form, abs=0.2)


def _log_density_in(to_logs, theta: np.ndarray, log_prior, step=1e-6) -> np.ndarray:
    """The log-density, in the coordinates ``to_logs(θ)``, of the prior ``log_prior`` on θ:
    log p(θ) − ln|det ∂to_logs/∂θ| (central differences in relative steps)."""
    out = []
    for row in theta:
        h = step * np.abs(row)
        jac = np.column_stack(
            [(to_logs(row + e) - to_logs(row - e)) / (2 * e[i]) for i, e in enumerate(np.diag(h))]
        )
        out.append(log_prior(row[None])[0] - np.log(abs(np.linalg.det(jac))))
    return np.array(out)


def test_janosi_default_is_flat_in_log_strength_at_both_pressures_and_log_k():
    sigma = np.array([5e3, 1e4, 2e4, 4e4])
    design = np.column_stack([np.ones(4), sigma])
    pops = PopulationModel(
        JANOSI,
        LAYOUTS["janosi"],
        np.zeros((4, 2)),
        np.array([np.eye(2)] * 4),
        design,
        0.0,
        resolve_priors("janosi", JANOSI.param_names, None),
        Coordinates(),
        reference_rows=reference_rows(design, sigma),
    )

    def to_logs(theta):  # (ln τ(σ_min), ln τ(σ_max), ln K) of (c [Pa], φ [deg], K [m])
        c, phi, k = theta
        tan = np.tan(phi * RAD_PER_DEG)
        return np.log([c + sigma.min() * tan, c + sigma.max() * tan, k])

    rng = np.random.default_rng(0)
    theta = np.column_stack(
        [rng.uniform(10, 5e3, 30), rng.uniform(15, 45, 30), rng.uniform(2e-3, 5e-2, 30)]
    )

    def log_prior(th):
        return pops.prior_only.log_prior(th) + pops.log_scale_prior(th)

    density = _log_density_in(to_logs, theta, log_prior)
    assert np.ptp(density) < 1e-5  # constant: flat in the three logarithms


def _bekker_population(b: np.ndarray, priors=None) -> PopulationModel:
    """A Bekker population on plates ``b`` (no data needed: only its prior is read)."""
    design = np.column_stack([1.0 / b, np.ones(b.size)])
    return PopulationModel(
        BEKKER,
        LAYOUTS["bekker"],
        np.zeros((b.size, 2)),
        np.array([np.eye(2)] * b.size),
        design,
        -3.0,
        resolve_priors("bekker", BEKKER.param_names, priors),
        Coordinates(),
        reference_rows=reference_rows(design, b),
        log_flat=(priors is None, True),
    )


def test_bekker_default_is_flat_in_log_plate_moduli_at_the_smallest_and_largest_plate():
    b = np.array([0.05, 0.025, 0.075, 0.05])
    pops = _bekker_population(b)

    def to_logs(theta):
        kc, kphi, n = theta
        return np.array([np.log(kc / b.min() + kphi), np.log(kc / b.max() + kphi), n])

    rng = np.random.default_rng(1)
    theta = np.column_stack(
        [rng.uniform(-4e3, 5e4, 30), rng.uniform(2e5, 2e6, 30), rng.uniform(0.5, 1.5, 30)]
    )

    def log_prior(th):
        return pops.prior_only.log_prior(th) + pops.log_scale_prior(th)

    density = _log_density_in(to_logs, theta, log_prior)
    assert np.ptp(density) < 1e-5
    # A caller's prior on either modulus replaces the factor for both (kc, kφ).
    given = _bekker_population(b, {"kphi": (1e5, 1e7)})
    np.testing.assert_array_equal(given.log_scale_prior(theta), 0.0)


@pytest.mark.slow
def test_grc1_population_bekker_converges_to_one_answer_whatever_the_seed():
    # Under the old flat prior on the moduli, seed 1 ran off to kφ ≈ 1e307 and seed 0 sat in
    # a local mode (μ_kc 4.7e5 against 3.0e5 here); docs/posterior.md.
    import warnings

    from soilstats import load_campaign
    from soilstats.bayes import sample_population
    from soilstats.data import bundled_path

    campaign = load_campaign(bundled_path("grc1-oravec2009"))
    results = []
    for seed in (0, 1):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # ArviZ on a run that ran off (old code)
            results.append(sample_population(campaign, "bekker", seed=seed, draws=6000))
    for r in results:
        assert r.converged, r.flags
        assert np.all(np.isfinite(r.draws().to_numpy()))
    post = [r.idata.posterior for r in results]
    for name in ("mu_kc", "mu_kphi", "mu_n", "sd_p_ref"):
        a, b = (np.median(p[name]) for p in post)
        spread = float(np.std(post[0][name]))
        assert abs(a - b) < 0.2 * spread, (name, a, b, spread)


def test_scatter_sits_where_the_tests_curves_cross_within_the_measured_range():
    # Curves p_t = p*(b)·(z/z*)^(n_t) all pass through p*(b) at z* = 8 mm: there ln p̂_t(z)
    # does not vary with n̂_t, so that is z_s — whatever each plate's own level p*(b), which
    # is Eq. 7's plate effect, not preparation scatter.
    from soilstats.bayes.reduction import PerTestFits, scatter_sinkage

    n = np.array([0.9, 1.1, 1.3, 1.0, 1.2, 0.8])
    b = np.array([0.05, 0.05, 0.05, 0.1, 0.1, 0.1])
    ln_p_star = np.where(b == 0.05, np.log(6e4), np.log(3e4))
    z = np.linspace(0.001, 0.03, 200)

    def fits(ln_z_star):
        params = np.column_stack([np.exp(ln_p_star - n * ln_z_star), n])
        cov = np.repeat(np.eye(2)[None], n.size, axis=0)
        return PerTestFits(params, cov, np.ones((n.size, 1)), b, list("abcdef"), [])

    assert scatter_sinkage(fits(np.log(0.008)), z, -5.0) == pytest.approx(np.log(0.008))
    # Curves that would cross at 1 m (the scatter independent on ln k) sit at the edge of the
    # measured sinkages, not beyond them.
    assert scatter_sinkage(fits(0.0), z, -5.0) == pytest.approx(np.log(np.quantile(z, 0.95)))
    # One test per plate: no spread of n within a plate locates z_s; the reduction's z_ref does.
    one = PerTestFits(fits(0.0).params[:2], fits(0.0).cov[:2], np.ones((2, 1)), b[[0, 3]], [], [])
    assert scatter_sinkage(one, z, -5.0) == pytest.approx(-5.0)


def test_laplace_finds_the_mode_and_covariance_of_a_known_gaussian():
    # A correlated Gaussian (closed-form mode and covariance), vectorised like the population
    # log-density, from a start far off in the scaled coordinates (the gradient search); and
    # from a start just outside a support where the density is -inf (the gradient search
    # stops there at once: the derivative-free fallback).
    from soilstats.bayes.population import laplace_mode

    mean = np.array([1.0e6, -3.0, 0.5, 2.0])
    sd = np.array([1.0e4, 0.2, 0.05, 0.3])
    corr = np.array(
        [[1, 0.6, 0, 0], [0.6, 1, -0.3, 0], [0, -0.3, 1, 0.2], [0, 0, 0.2, 1]], dtype=float
    )
    cov = corr * np.outer(sd, sd)
    precision = np.linalg.inv(cov)

    def log_prob(theta):
        r = np.atleast_2d(theta) - mean
        return -0.5 * np.einsum("wi,ij,wj->w", r, precision, r)

    def bounded(theta):  # the same density, but -inf for a first coordinate below 5e5
        lp = log_prob(theta)
        return np.where(np.atleast_2d(theta)[:, 0] < 5.0e5, -np.inf, lp)

    for density, start in ((log_prob, mean + 3 * sd), (bounded, np.array([4.9e5, 0, 1, 1]))):
        mode, got = laplace_mode(density, start, n_mu=2)
        np.testing.assert_allclose(mode, mean, atol=1e-4 * sd.max(), rtol=1e-6)
        np.testing.assert_allclose(got, cov, rtol=2e-3, atol=1e-9 * sd.max() ** 2)
