"""The record of one posterior run (``posterior.json``): the run, the decision to hand the
draws out or not (:mod:`soilstats.bayes.handout`) and what that decision rests on."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from ..outputs import json_safe
from .band_check import band_calibration

__all__ = ["posterior_record"]


def posterior_record(
    soil: str,
    models: Sequence[str],
    results: Sequence[Any],
    handout: Any,
    failures: list[str],
    warnings: list[str],
    pooling_warnings: list[str],
    selection: list[str],
    provenance: Any,
    defaults: Mapping[str, str] | None = None,
) -> dict:
    """posterior.json's content: ``results`` (one posterior per model), ``handout`` (the
    decision: a :class:`soilstats.bayes.handout.Handout`), the ``failures`` that refused
    the draws (non-empty only for a forced run), the run's ``warnings`` and the conditions it
    pools (:func:`soilstats.bayes.pooling.pooling_warnings`), the ``selection`` as given and
    the ``provenance`` (:class:`soilstats.outputs.Provenance`) and the ``defaults`` the run rests
    on unsaid (``{"--walkers": "32"}``: the options left at their defaults, printed on page 1
    of the report); NaN written as null."""
    decision = handout.to_dict()
    checks = {r.model_name: band_calibration(r) for r in results if r.kind == "population"}
    return json_safe(
        {
            "soil": soil,
            "defaults": dict(defaults or {}),
            "models": models,
            "kind": [r.kind for r in results],
            "converged": all(r.converged for r in results),
            "forced": bool(failures),
            "failures": failures,
            "support": decision["support"],
            "draws_written": decision["draws_written"],
            "negative_modulus_below_m": decision["negative_modulus_below_m"],
            "priors": {r.model_name: r.idata.posterior.attrs.get("priors", "") for r in results},
            "pooling_warnings": pooling_warnings,
            "least_squares_health": decision["least_squares_health"],
            # The population band against its own tests (issue #36): which criterion fails.
            "band_check": {
                name: json.loads(check.to_json()) for name, check in checks.items() if check
            },
            "warnings": warnings,
            "selection": selection,
            "provenance": provenance.to_dict(),
        }
    )
