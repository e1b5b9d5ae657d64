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

from .._lazy import lazy_names

# Names load their module on first use: a refusal before sampling (soilstats.bayes.handout)
# must not pay ArviZ's two seconds of import.
_NAMES = {
    "SCM_DEFAULTS": ".export",
    "SIMULATOR_FORMATS": ".export",
    "SimulatorConstraintError": ".export",
    "export_simulator": ".export",
    "simulator_parameters": ".simulator_api",
    "simulator_record": ".simulator_api",
    "joint_draws": ".joint",
    "sample_population": ".population",
    "sample_posterior": ".posterior",
    "DEFAULT_PRIORS": ".priors",
    "Normal": ".priors",
    "Prior": ".priors",
    "Uniform": ".priors",
    "ESS_MIN": ".result",
    "RHAT_MAX": ".result",
    "PosteriorResult": ".result",
}
__getattr__, __dir__ = lazy_names(__name__, _NAMES, globals())

__all__ = [
    "DEFAULT_PRIORS",
    "ESS_MIN",
    "RHAT_MAX",
    "SCM_DEFAULTS",
    "SIMULATOR_FORMATS",
    "Normal",
    "PosteriorResult",
    "Prior",
    "SimulatorConstraintError",
    "Uniform",
    "export_simulator",
    "joint_draws",
    "sample_population",
    "sample_posterior",
    "simulator_parameters",
    "simulator_record",
]
