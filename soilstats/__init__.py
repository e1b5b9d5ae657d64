"""soilstats — Bevameter soil-parameter identification with honest uncertainty.

Turns raw plate-sinkage and shear-ring measurements into Bekker, Bernstein, Reece,
Janosi–Hanamoto and Mohr–Coulomb parameters by the weighted identification of
M. Apfelbeck, S. Kuß, B. Rebele, B. Schäfer, "A systematic approach to reliably characterize
soils based on Bevameter testing", Journal of Terramechanics 48(5), 360–371, 2011
(weighted Levenberg–Marquardt, fit quality ε, σ from the covariance), with health flags on
every fit.

>>> import soilstats
>>> campaign = soilstats.load_campaign("cullinan-sand")          # bundled real data
>>> fit = soilstats.fit_sinkage(campaign, "bernstein", preparation="1")
>>> fit.params["n"], fit.stderr["n"]                               # doctest: +SKIP
>>> print(fit.summary())                                           # doctest: +SKIP

A soil model of one's own is one record, registered once; every layer then takes its name
(docs/conventions.md, "The model record")::

    soilstats.register_model(soilstats.Model(name="my-model", kind="sinkage", ...))

Any model f(x, *params) can be identified the same way::

    result = soilstats.identify(f, x, y, p0=[1.0, 0.1], weights=w)

Importing soilstats is cheap: each public name is loaded from its module on first use
(PEP 562), so ``import soilstats`` and ``soilstats --help`` do not pay for pandas, SciPy,
statsmodels, matplotlib or ArviZ.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._lazy import lazy_names
from ._version import __version__ as __version__
from .errors import (
    CampaignError,
    ConvergenceError,
    ConvergenceWarning,
    IdentifiabilityError,
    ModelError,
    SoilstatsError,
    SoilstatsWarning,
)

#: public name -> module that defines it (loaded on first access)
_LAZY: dict[str, str] = {
    "Campaign": "soilstats.campaign",
    "bundled_campaigns": "soilstats.campaign",
    "load_campaign": "soilstats.campaign",
    "DiscoveryResult": "soilstats.discovery",
    "discover": "soilstats.discovery",
    "FitResult": "soilstats.fitting",
    "identify": "soilstats.fitting",
    "linear_least_squares": "soilstats.fitting",
    "fit_per_test": "soilstats.identification",
    "fit_shear": "soilstats.identification",
    "fit_sinkage": "soilstats.identification",
    "parameter_table": "soilstats.identification",
    "BEKKER": "soilstats.models",
    "BERNSTEIN": "soilstats.models",
    "JANOSI": "soilstats.models",
    "MOHR_COULOMB": "soilstats.models",
    "REECE": "soilstats.models",
    "Model": "soilstats.models",
    "get_model": "soilstats.models",
    "models_of_kind": "soilstats.models",
    "register_model": "soilstats.models",
    "simulate": "soilstats.simulation",
    "anova_oneway": "soilstats.statistics",
    "run_study": "soilstats.study",
    "sample_posterior": "soilstats.bayes",
    "sample_population": "soilstats.bayes",
    "Wheel": "soilstats.wheel",
    "WheelPrediction": "soilstats.wheel",
    "predict_wheel": "soilstats.wheel",
    "wheel_forces": "soilstats.wheel",
}

if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from .bayes import sample_population, sample_posterior
    from .campaign import Campaign, bundled_campaigns, load_campaign
    from .discovery import DiscoveryResult, discover
    from .fitting import FitResult, identify, linear_least_squares
    from .identification import fit_per_test, fit_shear, fit_sinkage, parameter_table
    from .models import (
        BEKKER,
        BERNSTEIN,
        JANOSI,
        MOHR_COULOMB,
        REECE,
        Model,
        get_model,
        models_of_kind,
        register_model,
    )
    from .simulation import simulate
    from .statistics import anova_oneway
    from .study import run_study
    from .wheel import Wheel, WheelPrediction, predict_wheel, wheel_forces


#: subpackages reached as attributes of ``soilstats`` (loaded on first access too)
_SUBPACKAGES = (
    "bayes",
    "campaign",
    "discovery",
    "fitting",
    "identification",
    "models",
    "outputs",
    "quality",
    "report",
    "simulation",
    "statistics",
    "study",
    "wheel",
)

__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals(), _SUBPACKAGES)


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
    "ModelError",
    "SoilstatsError",
    "SoilstatsWarning",
    "Wheel",
    "WheelPrediction",
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
    "models_of_kind",
    "parameter_table",
    "predict_wheel",
    "register_model",
    "run_study",
    "sample_population",
    "sample_posterior",
    "simulate",
    "wheel_forces",
]
