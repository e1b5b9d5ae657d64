"""The record of one posterior run (``posterior.json``): the run, the decision to hand the
draws out or not (:mod:`soilstats.bayes.handout`) and what that decision rests on."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..outputs import json_safe, output_path, write_atomic, write_csv
from .band_check import band_calibration

if TYPE_CHECKING:
    from ..outputs.provenance import Provenance
    from .export import SimulatorExport
    from .support import SupportCheck

__all__ = ["posterior_record", "write_export"]


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
    of the report); ``prior_sensitivity`` per model (power-scaling,
    :mod:`soilstats.bayes.prior_sensitivity`) and ``default_warnings`` where a model's default
    priors are influential (``{"MODEL: priors": warning}``, page 1); NaN written as null."""
    decision = handout.to_dict()
    from .prior_sensitivity import influential_warning  # deferred: arviz

    # Issue #47 item 3: a default prior the draws rest on is a warning (page 1 too).
    moved = {
        f"{r.model_name}: priors": influential_warning(r.model_name, r.prior_sensitivity)
        for r in results
    }
    checks = {r.model_name: band_calibration(r) for r in results if r.kind == "population"}
    return json_safe(
        {
            "soil": soil,
            "defaults": dict(defaults or {}),
            "default_warnings": {k: v for k, v in moved.items() if v},
            "models": models,
            "kind": [r.kind for r in results],
            "converged": all(r.converged for r in results),
            "forced": bool(failures),
            "failures": failures,
            "support": decision["support"],
            "draws_written": decision["draws_written"],
            "negative_modulus_below_m": decision["negative_modulus_below_m"],
            "priors": {r.model_name: r.idata.posterior.attrs.get("priors", "") for r in results},
            "prior_sensitivity": {
                r.model_name: _sensitivity_records(r.prior_sensitivity) for r in results
            },
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


def _sensitivity_records(table: Any) -> list[dict]:
    """The power-scaling table of one posterior as JSON records (none where not checked)."""
    if table is None or table.empty:
        return []
    return [json_safe(row) for row in table.to_dict("records")]


class _Annotated:
    """A provenance whose CSV comment header carries more ``key: value`` lines."""

    def __init__(self, provenance: Provenance, extra: list[str]) -> None:
        self._provenance, self._extra = provenance, extra

    def lines(self) -> list[str]:
        return [*self._provenance.lines(), *self._extra]


def write_export(
    out: Path,
    export: SimulatorExport,
    record: dict[str, Any],
    support: SupportCheck | None,
    provenance: Provenance,
    seed: int,
) -> None:
    """``<simulator>.csv`` (each column's source and the simulator's check in its comment
    lines, FORCED and why where ``record`` says so) and ``<simulator>.json`` (the export's
    record with the run's context) into ``out``, replacing what is there (the command
    checked its outputs before sampling)."""
    name = export.simulator
    extra = export.comment_lines()
    if record["forced"]:
        extra.append("FORCED: written although: " + "; ".join(record["failures"]))
    write_csv(
        out / f"{name}.csv",
        export.table,
        _Annotated(provenance, extra),
        overwrite=True,
        float_format="%.10g",
    )
    context = {k: record[k] for k in ("soil", "models", "kind", "forced", "failures", "selection")}
    context |= {"seed": seed, "version": provenance.to_dict().get("soilstats_version")}
    write_atomic(
        output_path(out, f"{name}.json", overwrite=True),
        json.dumps(json_safe(export.record(support, context)), indent=2) + "\n",
    )
