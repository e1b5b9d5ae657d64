"""soilstats — Bevameter soil-parameter identification with honest uncertainty.

Turns raw plate-sinkage and shear-ring measurements into Bekker, Bernstein, Reece,
Janosi–Hanamoto and Mohr–Coulomb parameters by the weighted identification of
Holz et al.'s "systematic approach" (weighted Levenberg–Marquardt, fit quality ε, σ from the
covariance), with health flags on every fit.

>>> import soilstats
>>> campaign = soilstats.load_campaign("cullinan-sand")          # bundled real data
>>> fit = soilstats.fit_sinkage(campaign, "bernstein", preparation="1")
>>> fit.params["n"], fit.stderr["n"]                               # doctest: +SKIP
>>> print(fit.summary())                                           # doctest: +SKIP

Any model f(x, *params) can be identified the same way::

    result = soilstats.identify(f, x, y, p0=[1.0, 0.1], weights=w)
"""

from __future__ import annotations

from .campaign import Campaign, bundled_campaigns, load_campaign
from .discovery import DiscoveryResult, discover
from .errors import (
    CampaignError,
    ConvergenceError,
    ConvergenceWarning,
    IdentifiabilityError,
    SoilstatsWarning,
)
from .fitting import FitResult, identify, linear_least_squares
from .identification import fit_per_test, fit_shear, fit_sinkage, parameter_table
from .models import BEKKER, BERNSTEIN, JANOSI, MOHR_COULOMB, REECE, Model, get_model
from .simulation import simulate
from .statistics import anova_oneway

__version__ = "0.1.0"


def __getattr__(name: str):
    # The Bayesian layer imports arviz/xarray (seconds); load it only when asked for.
    if name == "sample_posterior":
        from .bayes import sample_posterior

        return sample_posterior
    if name == "run_study":  # the study layer imports matplotlib/seaborn for its reports
        from .study import run_study

        return run_study
    raise AttributeError(f"module 'soilstats' has no attribute {name!r}")


__all__ = [
    "BEKKER",
    "BERNSTEIN",
    "JANOSI",
    "MOHR_COULOMB",
    "REECE",
    "Campaign",
    "CampaignError",
    "ConvergenceError",
    "ConvergenceWarning",
    "DiscoveryResult",
    "FitResult",
    "IdentifiabilityError",
    "Model",
    "SoilstatsWarning",
    "anova_oneway",
    "bundled_campaigns",
    "discover",
    "fit_per_test",
    "fit_shear",
    "fit_sinkage",
    "get_model",
    "identify",
    "linear_least_squares",
    "load_campaign",
    "parameter_table",
    "sample_posterior",
    "simulate",
]
