"""Simulated Bevameter campaigns with known truth, for the posterior tests and benchmark.

Noise is *model-matched* to the likelihood of :mod:`soilstats.bayes.likelihood`: a test's
pressure (shear stress) noise has sd σ_w·max f over that test, so the weighted residual
w·(y − f) with w = 1/max(y) has sd ≈ σ_w.  With ``scatter`` each test (preparation) draws its
own parameters θ_t ~ N(θ, Σ) — the population model's assumption.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from soilstats import Campaign
from soilstats.models import BEKKER, JANOSI

BEKKER_TRUTH = {"kc": 2.0e3, "kphi": 8.0e5, "n": 1.1}  # a dry sand, N/m^(n+1), N/m^(n+2), -
JANOSI_TRUTH = {"c": 400.0, "phi": 32.0, "K": 0.012}  # Pa, deg, m
PLATES = (0.05, 0.075, 0.10)  # plate radii b [m]
SIGMAS = (5e3, 10e3, 15e3, 20e3)  # normal pressures [Pa]
RING = (0.08, 0.12)  # r_inner, r_outer [m]


def sinkage_frames(
    rng,
    *,
    truth=None,
    plates=PLATES,
    repetitions=10,
    points=100,
    noise=0.02,
    z_max=0.05,
    scatter=None,
    soil="sim-sand",
    offset=0,
):
    """tests and sinkage tables of a Bekker campaign; returns (tests, sinkage, thetas)."""
    truth = np.array(list((truth or BEKKER_TRUTH).values()), float)
    tests, rows, thetas = [], [], []
    for b in plates:
        for r in range(repetitions):
            tid = f"s{offset + len(tests):03d}"
            theta = truth if scatter is None else rng.multivariate_normal(truth, scatter)
            z = np.linspace(z_max / points, z_max, points)
            p = BEKKER.func((np.full(points, b), z), *theta)
            p = p + noise * p.max() * rng.standard_normal(points)
            tests.append(
                {
                    "test_id": tid,
                    "kind": "sinkage",
                    "soil": soil,
                    "preparation": "1",
                    "repetition": r + 1,
                    "shape": "circle",
                    "radius_m": b,
                }
            )
            rows.append(pd.DataFrame({"test_id": tid, "z_m": z, "force_N": p * np.pi * b * b}))
            thetas.append(theta)
    return pd.DataFrame(tests), pd.concat(rows, ignore_index=True), np.array(thetas)


def shear_frames(
    rng,
    *,
    truth=None,
    sigmas=SIGMAS,
    repetitions=3,
    points=150,
    noise=0.02,
    j_max=0.08,
    soil="sim-sand",
    offset=0,
):
    """tests and shear tables of a Janosi campaign; returns (tests, shear)."""
    c, phi, k = (truth or JANOSI_TRUTH).values()
    ri, ro = RING
    tests, rows = [], []
    for s in sigmas:
        for r in range(repetitions):
            tid = f"h{offset + len(tests):03d}"
            j = np.linspace(j_max / points, j_max, points)
            tau = JANOSI.func((np.full(points, s), j), c, phi, k)
            tau = tau + noise * tau.max() * rng.standard_normal(points)
            tests.append(
                {
                    "test_id": tid,
                    "kind": "shear",
                    "soil": soil,
                    "repetition": r + 1,
                    "r_inner_m": ri,
                    "r_outer_m": ro,
                    "grousers": 8,
                    "grouser_height_m": 0.01,
                }
            )
            rows.append(
                pd.DataFrame(
                    {
                        "test_id": tid,
                        "angle_rad": j / ((ro + ri) / 2),
                        "torque_Nm": tau * 2 * np.pi * (ro**3 - ri**3) / 3,
                        "normal_force_N": np.full(points, s * np.pi * (ro**2 - ri**2)),
                    }
                )
            )
    return pd.DataFrame(tests), pd.concat(rows, ignore_index=True)


def sinkage_campaign(rng, **kwargs) -> Campaign:
    tests, sinkage, _ = sinkage_frames(rng, **kwargs)
    return Campaign.from_frames(tests, sinkage)


def joint_campaign(rng, **kwargs) -> Campaign:
    t1, sinkage, _ = sinkage_frames(rng, **kwargs)
    t2, shear = shear_frames(rng)
    return Campaign.from_frames(pd.concat([t1, t2], ignore_index=True), sinkage, shear)


#: A hand-made Bernstein population: three tests' own fits (k_t [N/m^(n+2)], n_t) and their
#: Eq. 4 covariances, reduced at ln z_ref = -3.5.
POPULATION_FITS = np.array([[8.0e5, 1.05], [9.5e5, 1.12], [7.2e5, 1.02]])
POPULATION_FIT_COV = np.array([[[4e8, 30.0], [30.0, 1e-4]]] * 3)
POPULATION_LN_ZREF = -3.5


def bernstein_population(priors=None, ln_zs=None):
    """The population model of :data:`POPULATION_FITS`, sampled in (k, n) itself; with
    ``priors`` the caller's priors replace the default log-flat factor; ``ln_zs``: where its
    scatter sits (default: at the reduction's z_ref)."""
    from soilstats.bayes.population_model import LAYOUTS, PopulationModel
    from soilstats.bayes.priors import resolve_priors
    from soilstats.bayes.reduction import to_eta
    from soilstats.bayes.transforms import Coordinates
    from soilstats.models import BERNSTEIN

    eta, eta_cov = to_eta(POPULATION_FITS, POPULATION_FIT_COV, POPULATION_LN_ZREF, log_second=False)
    return PopulationModel(
        BERNSTEIN,
        LAYOUTS["bernstein"],
        eta,
        eta_cov,
        np.ones((3, 1)),
        POPULATION_LN_ZREF,
        resolve_priors("bernstein", BERNSTEIN.param_names, priors),
        Coordinates(),
        reference_rows=np.ones((1, 1)),
        log_flat=(priors is None, priors is None),
        ln_zs=ln_zs,
    )
