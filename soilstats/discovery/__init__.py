"""Discovery: what the soil model gets wrong in a campaign, the cause, the extension, the gain.

>>> import soilstats
>>> result = soilstats.discover("simulated-paper")     # doctest: +SKIP
>>> print(result.summary())                             # doctest: +SKIP
>>> result.to_json()                                    # doctest: +SKIP

=================  ========================================================================
``candidates``     test-log and derived covariates; categorical or continuous; confounding
``data``           per (kind, soil): per-test fits and pooled samples (Section 2.1 weights)
``diagnose``       base fit, per-test deviations, F-tests within strata, Holm
``flags``          physical red flags (negative kc/kφ, implausible n, kc–kφ collinear)
``extensions``     the library: velocity, softening, Reece, side walls, generic covariate
``crossval``       leave-whole-tests / conditions-out gain with its uncertainty, AIC/BIC
``selection``      forward selection of one combined model per (kind, soil)
``work``           the fits in waves over ``jobs`` workers; identical results for any jobs
``result``         :class:`DiscoveryResult`, :class:`Finding`
=================  ========================================================================

The PDF report is :mod:`soilstats.report.discovery_pdf`; the extended equations are in
:mod:`soilstats.models.extended`.
"""

from __future__ import annotations

from .pipeline import discover
from .result import DiscoveryResult, Finding

__all__ = ["DiscoveryResult", "Finding", "discover"]
