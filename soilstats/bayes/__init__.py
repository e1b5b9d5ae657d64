"""Bayesian posteriors of soil parameters with emcee and ArviZ (issue #5).

Two models:

* **pooled** (:func:`sample_posterior`): one parameter set for all selected tests, with the
  paper's weighted likelihood — how well the data pin the parameters;
* **population** (:func:`sample_population`): each test (preparation) has its own parameters
  drawn from a soil-level distribution — the spread of a *new* preparation, which is what a
  rover Monte Carlo needs.

Joint (kc, kφ, n, c, φ, K) draws for wheel–soil simulators come from :func:`joint_draws`.

>>> from soilstats.bayes import sample_posterior
>>> post = sample_posterior(campaign, "bekker", seed=1)          # doctest: +SKIP
>>> print(post.summary())                                         # doctest: +SKIP
>>> post.draws(1000, seed=2)                                      # doctest: +SKIP

ArviZ 0.17–0.23 (the 0.x ``InferenceData`` API) is supported.
"""

from __future__ import annotations

from .export import SCM_DEFAULTS, SIMULATOR_FORMATS, simulator_parameters, simulator_record
from .joint import joint_draws
from .population import sample_population
from .posterior import sample_posterior
from .priors import DEFAULT_PRIORS, Normal, Prior, Uniform
from .result import ESS_MIN, RHAT_MAX, PosteriorResult

__all__ = [
    "DEFAULT_PRIORS",
    "ESS_MIN",
    "RHAT_MAX",
    "SCM_DEFAULTS",
    "SIMULATOR_FORMATS",
    "Normal",
    "PosteriorResult",
    "Prior",
    "Uniform",
    "joint_draws",
    "sample_population",
    "sample_posterior",
    "simulator_parameters",
    "simulator_record",
]
