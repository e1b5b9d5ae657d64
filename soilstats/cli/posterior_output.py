"""``soilstats posterior``'s decision and output: refuse or write the draws, the export,
the record and what is printed (the command's options and sampling: cli/posterior.py)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..bayes.run_checks import extrapolation_warnings, has_population, prior_seed, tested_widths
from ..bayes.run_sampling import sampling_warnings
from ..outputs import json_safe, output_path, write_atomic, write_csv
from ..outputs.files import netcdf_bytes
from .common import defaults_not_given

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = ["decide_and_write", "refuse", "series_refusal", "series_refused"]


def series_refusal(
    args: argparse.Namespace, models: Sequence[str], campaign: Campaign
) -> str | None:
    """With --simulator, why a shear posterior may not be exported: it pools test series of
    different set-ups (:func:`soilstats.bayes.scm_wheel.series_refusal`); None otherwise."""
    from ..bayes.scm_wheel import series_refusal as refusal  # deferred: pandas (bayes)

    return refusal(campaign, args.soil, models) if args.simulator else None


def series_refused(
    args: argparse.Namespace, models: Sequence[str], campaign: Campaign, out: Path
) -> bool:
    """Whether :func:`series_refusal` refuses the run before sampling (said on stderr)."""
    series = series_refusal(args, models, campaign)
    if series is not None:
        print(
            f"error: nothing written to {out}: {args.simulator}: {series} (or pass --force to "
            "write them anyway, marked FORCED)",
            file=sys.stderr,
        )
    return series is not None


def _scm_warnings(args: argparse.Namespace, export: Any) -> list[str]:
    """SCM's modulus at its own contact width against the wheel's (--scm-contact), printed."""
    from ..bayes.scm_wheel import contact_patch, contact_width_warning  # deferred: pandas

    patch = contact_patch(getattr(args, "scm_contact", None))
    if export is None or patch is None:
        return []
    text = contact_width_warning(export.table, *patch)
    if text is None:
        return []
    print(f"WARNING: {text}", file=sys.stderr)
    return [text]


def _export(args, models, results, kept, stated, campaign):
    """The draws handed out as the simulator's parameter sets (checked, not yet written)."""
    from ..bayes.export import export_simulator  # deferred: scipy.stats

    taken = {
        name: f"posterior draws ({r.model_name}, {r.kind})"
        for r in results
        for name in r.param_names
    }
    return export_simulator(
        kept,
        args.simulator,
        elastic_K=args.scm_elastic_K,
        damping_R=args.scm_damping_R,
        priors=stated,
        seed=prior_seed(args.seed, models),
        repair=args.scm_repair,
        draws_source=taken,
        plate_widths=tested_widths(campaign, args.soil),
        on_failure="return",  # refused below with the CLI's own words (constraint_failures)
    )


def _write_export(
    out: Path, export: Any, record: dict, support: Any, provenance: Any, args: argparse.Namespace
) -> None:
    """``<simulator>.csv`` and ``<simulator>.json`` (:func:`soilstats.bayes.run_record
    .write_export`); the check, repairs and notes also to stderr."""
    from ..bayes.run_record import write_export  # deferred: arviz

    name = export.simulator
    write_export(out, export, record, support, provenance, args.seed)
    repaired = export.check.repair_sentence()
    if repaired:
        print(f"WARNING: {name}: {repaired}", file=sys.stderr)
    for note in export.notes:
        print(f"note: {name}: {note}", file=sys.stderr)


def refuse(
    failures: list[str],
    out: Path,
    args: argparse.Namespace,
    *,
    sampled: bool,
    simulator_only: bool = False,
) -> int:
    """Print why the draws are not handed out; exit 2 (nothing written)."""
    for text in failures:
        print(f"error: {text}", file=sys.stderr)
    if simulator_only:
        print(
            f"error: nothing written to {out}: the posterior draws passed their checks, but "
            f"their {args.simulator} parameter sets break the simulator's constraints. "
            "Apply the fix above, or pass --force to write them anyway (marked FORCED)",
            file=sys.stderr,
        )
        return 2
    advice = (
        "select fewer conditions, window the data (--z-max), state narrower --prior "
        "ranges, or pass --force to write them anyway (marked FORCED; unphysical draws are "
        "left out)"
    )
    if args.population and sampled:
        # Where the tests agree to within their noise, the scatter sds (sd_p_ref, sd_n;
        # sd_strength, sd_lnK) pile up at 0, the boundary of their support, and the chains
        # mix badly there (a review: R-hat up to 2.0 on zero-scatter data).
        advice = (
            "With --population: if the tests agree to within their noise, the scatter "
            "sds sit at 0 and the chains cannot mix there; the pooled posterior (without "
            f"--population) is then the model the data support. Otherwise {advice}"
        )
    elif not sampled:
        advice = (
            "Refused before sampling. Fit each plate size on its own (--select radius_m=…), "
            "or use the pooled posterior (without --population), or pass --force to sample "
            "and write anyway (marked FORCED)"
        )
    else:
        advice = advice[0].upper() + advice[1:]
    print(
        f"error: nothing written to {out}: these draws are not fit for a rover Monte Carlo. "
        f"{advice}",
        file=sys.stderr,
    )
    return 2


def _warnings(
    caught: Any, widths: tuple[float, float], args: argparse.Namespace, campaign: Campaign,
    models: list[str], handout: Any, pooled_warnings: list[str],
) -> list[str]:  # fmt: skip
    """The warnings of a run, printed one line each: the library's own, numerical ones
    summed up, extrapolation, pooling and the flagged least-squares starts."""
    ours = sampling_warnings(caught)
    ours += extrapolation_warnings(widths, tested_widths(campaign, args.soil), models)
    for text in [*ours, *pooled_warnings]:
        print(f"WARNING: {text}", file=sys.stderr)
    for model, flags in handout.least_squares_health.items():
        if flags:
            codes = ", ".join(sorted({f["code"] for f in flags}))
            print(
                f"WARNING: the {model} least-squares fit these draws start from is flagged "
                f"({codes}); the posterior inherits its data and model problems (messages in "
                "posterior.json, least_squares_health; soilstats identify --verbose)",
                file=sys.stderr,
            )
    return ours


def decide_and_write(
    args: argparse.Namespace,
    models: list[str],
    results: list[Any],
    caught: Any,
    widths: tuple[float, float],
    pooled_warnings: list[str],
    stated: dict,
    campaign: Campaign,
    provenance: Any,
    figures: Any,
) -> int:
    """The library's decision on the draws, printed; the files written where it allows."""
    import pandas as pd  # deferred: pandas

    from ..bayes.export import constraint_failures  # deferred: scipy.stats
    from ..bayes.handout import hand_out  # deferred: pandas

    out = Path(args.out)
    handout = hand_out(results, widths, seed=args.seed, population=args.population)
    kept = handout.draws
    # What a user is handed (draws.csv) is what the summary describes; diagnostics stay the
    # chains' (a review: k's interval started at a draw with n < 0 that draws.csv left out).
    table = pd.concat(
        [r.summary_table(0.9, kept).assign(model=r.model_name, kind=r.kind) for r in results]
    )
    table.index.name = "quantity"
    failures = list(handout.failures)
    export = _export(args, models, results, kept, stated, campaign) if args.simulator else None
    if export is not None and not export.check.passed:
        failures += constraint_failures(args.simulator, export.check, arguments=False)
    series = series_refusal(args, models, campaign) if export is not None else None
    if series is not None:  # only with --force: refused before sampling otherwise
        failures.append(f"{args.simulator}: {series}")
    ours = _warnings(caught, widths, args, campaign, models, handout, pooled_warnings)
    ours += _scm_warnings(args, export)
    if failures and not args.force:
        simulator_only = export is not None and len(failures) == len(export.check.failures)
        return refuse(failures, out, args, sampled=True, simulator_only=simulator_only)
    from ..bayes.run_record import posterior_record  # deferred: arviz; bayes: too heavy for --help

    defaults = defaults_not_given(args)
    if export is not None:  # SCM inputs nobody stated rest on sourced defaults: say which
        defaults |= {
            f"--scm-{name.replace('_', '-')}": f"{value:g} {unit} ({source})"
            for name, (value, unit, source) in export.stated.items()
            if source != "stated by user"
        }
    record = posterior_record(
        args.soil,
        models,
        results,
        handout,
        failures,
        ours,
        pooled_warnings,
        list(args.select or []),
        provenance,
        defaults=defaults,
    )
    if export is not None:
        record = json_safe(record | {"simulator": export.record()})
    _write(out, args, results, record, table, kept, provenance, figures)
    if export is not None:
        _write_export(out, export, record, handout.support, provenance, args)
    _print(args, out, results, record, table, handout)
    if failures:
        print("WARNING: FORCED — written although: " + "; ".join(failures), file=sys.stderr)
        return 1
    return 0


def _write(
    out: Path, args: argparse.Namespace, results: list[Any], record: dict, table: Any,
    kept: Any, provenance: Any, figures: Any,
) -> None:  # fmt: skip
    """posterior*.nc, draws.csv, summary.csv, posterior.json and report.pdf."""
    from ..report.posterior_pdf import write_report  # deferred: arviz

    prov = provenance.to_dict() | {"forced": record["forced"]}
    for i, res in enumerate(results):
        name = "posterior.nc" if i == 0 else f"posterior_{res.model_name}.nc"
        # netCDF attributes take no None: the record travels as JSON strings.
        res.idata.posterior.attrs["soilstats_provenance"] = json.dumps(json_safe(prov))
        res.idata.posterior.attrs["soilstats_record"] = json.dumps(record)
        # Built in memory: no HDF5 handle is left open on a file if the disk is full.
        write_atomic(output_path(out, name, overwrite=True), netcdf_bytes(res.idata))
    write_csv(out / "draws.csv", kept, provenance, overwrite=True, float_format="%.10g")
    write_csv(out / "summary.csv", table.reset_index(), provenance, overwrite=True)
    write_atomic(
        output_path(out, "posterior.json", overwrite=True), json.dumps(record, indent=2) + "\n"
    )
    # Like the files above: the command checked --out before sampling (--overwrite).
    write_report(
        results,
        out / "report.pdf",
        provenance=provenance,
        overwrite=True,
        record=record,
        handed_out=kept,
        figures=figures,
    )


def _print(
    args: argparse.Namespace, out: Path, results: list[Any], record: dict, table: Any, handout: Any
) -> None:
    """The summary on stdout (or one JSON object with --json), and the notes on stderr."""
    if args.json:
        print(
            json.dumps(
                json_safe(
                    record | {"out": str(out), "summary": table.reset_index().to_dict("records")}
                ),
                indent=2,
            )
        )
    else:
        for res in results:
            print(res.summary(handed_out=handout.draws))
        print(f"Physical support: {handout.support.describe()}")
    pooled_only = [m for m in record["models"] if not has_population(m)]
    if args.population and pooled_only:
        print(
            f"note: {', '.join(pooled_only)} has no population model (no per-test curve to "
            "scatter); its block is the pooled posterior",
            file=sys.stderr,
        )
