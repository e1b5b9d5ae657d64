"""Posterior draws of a soil's parameters for rover Monte Carlo.

Writes to --out: posterior.nc (ArviZ netCDF; one group set per model, see below),
draws.csv (one row per joint draw, one column per parameter, SI units, phi in degrees),
summary.csv (mean, sd, 90 % equal-tailed interval, MCSE, ESS, R-hat), posterior.json (the
record: priors, convergence, physical support, pooling warnings, provenance), report.pdf
(trace, pair and posterior-predictive plots) and, with --simulator, the draws as a
simulator's parameter sets (CSV) with their record (JSON).

Nothing is written until the draws pass: every sampler converged (R-hat, ESS), at most 1 %
of the draws fall outside the physical support at the stated contact widths
(soilstats.bayes.support), and a population's least-squares start is not flagged
plate-exponents (plates that disagree on n). Otherwise exit 2 with the reasons, unless --force
(exit 1, every file marked). Draws outside the support are never written.

--model takes one model (bekker, bernstein, reece, mohr-coulomb, janosi) or a sinkage and a
shear model joined by '+' (e.g. bekker+janosi): their posteriors are combined as
independent blocks, because plate and shear-ring tests are separate physical tests.
With two models, posterior.nc holds the first and posterior_<model>.nc the second.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from .common import add_common_options, add_data_options, prepared, progress_enabled

#: Simulators whose parameter sets --simulator writes (soilstats.bayes.SIMULATOR_FORMATS; a
#: test keeps the two in step, the bayes package being too heavy to import for --help).
SIMULATORS = ("chrono-scm",)


def _has_population(model: str) -> bool:
    """Whether the model's record has a population layout (``Model.population``)."""
    from ..models import get_model

    return get_model(model).population is not None


def configure(parser: argparse.ArgumentParser) -> None:
    """The posterior subcommand's options."""
    add_common_options(
        parser,
        out="required",
        out_help="write posterior.nc, draws.csv, summary.csv, posterior.json and report.pdf "
        "into DIR (only when the checks pass, or with --force)",
    )
    add_data_options(parser)
    parser.add_argument("--soil", required=True, help="soil name (the soil column of tests.csv)")
    parser.add_argument(
        "--model", required=True, help="model, or sinkage+shear (e.g. bekker+janosi)"
    )
    parser.add_argument(
        "--population",
        action="store_true",
        help="population model: draws for a NEW preparation (bekker, bernstein, janosi; "
        "mohr-coulomb stays pooled)",
    )
    parser.add_argument("--draws", type=int, default=None, help="kept draws (default per model)")
    parser.add_argument(
        "--prior",
        action="append",
        default=[],
        metavar="NAME=SPEC",
        help="prior of one parameter: LO:HI (flat), normal:MU:SD or normal:MU:SD:LO:HI, SI "
        "units, phi in degrees (repeatable; replaces the physics default)",
    )
    parser.add_argument(
        "--priors",
        metavar="FILE.toml",
        help='priors from a TOML file: a [MODEL] table of NAME = "SPEC" (--prior wins)',
    )
    parser.add_argument(
        "--contact-width",
        metavar="B_MIN[:B_MAX]",
        help="contact widths [m] the draws will be used at: every draw must give a positive "
        "plate modulus over them (default: the plate sizes of the data)",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="write the outputs even when convergence or physical-support checks fail "
        "(marked FORCED in every file; unphysical draws are still never written)",
    )
    parser.add_argument(
        "--simulator",
        choices=SIMULATORS,
        help="also write the draws as this simulator's parameter sets (CSV and JSON record)",
    )
    parser.add_argument(
        "--scm-elastic-K",
        type=float,
        metavar="PA_PER_M",
        help="Chrono SCM elastic stiffness [Pa/m] (default 4e7, Chrono's demos; not a "
        "Bevameter parameter)",
    )
    parser.add_argument(
        "--scm-damping-R",
        type=float,
        metavar="PA_S_PER_M",
        help="Chrono SCM damping [Pa s/m] (default 3e4, Chrono's demos)",
    )


def priors_by_model(args, models) -> dict[str, dict]:
    """Each model's priors, read once: its ``[MODEL]`` table of ``--priors``, then the
    ``--prior`` items naming its parameters (they win). A name that belongs to no model — or,
    in a file, not to its table's model — is an error before any sampling."""
    from ..bayes.priors import priors_from_items, priors_from_toml

    items = priors_from_items(args.prior)
    params = {m: _checked_model(m).param_names for m in models}
    known = {n for names in params.values() for n in names}
    unknown = sorted(set(items) - known)
    if unknown:
        raise ValueError(
            f"--prior names {unknown}, not parameters of {'+'.join(models)} "
            f"(parameters: {sorted(known)})"
        )
    out = {}
    for model, names in params.items():
        table = priors_from_toml(args.priors, model) if args.priors else {}
        stray = sorted(set(table) - set(names))
        if stray:
            raise ValueError(
                f"{args.priors}, [{model}]: {stray} are not parameters of {model} "
                f"(parameters: {list(names)})"
            )
        out[model] = table | {k: v for k, v in items.items() if k in names}
    return out


def _checked_model(name: str):
    """The record of one model of ``--model``: a registered sinkage or shear model."""
    from ..errors import ModelError
    from ..models import get_model, model_names

    spec = get_model(name)
    if spec.kind not in ("sinkage", "shear"):
        raise ModelError(
            f"--model {name}: a {spec.kind or 'non-soil'} model has no posterior; choose "
            f"from {model_names('sinkage') + model_names('shear')}"
        )
    return spec


def _check_models(models) -> None:
    """``--model``: one registered model, or a sinkage and a shear model joined by '+'."""
    from ..errors import ModelError

    kinds = [_checked_model(m).kind for m in models]
    if len(models) > 2 or len(set(kinds)) < len(kinds):
        raise ModelError(
            f"--model {'+'.join(models)}: give one model, or one sinkage and one shear model "
            "joined by '+' (e.g. bekker+janosi)"
        )


def model_seed(seed: int, index: int) -> int:
    """The seed of the ``index``-th model of one run: ``seed`` itself for the first, one
    drawn from ``SeedSequence([seed, index])`` for the others.  With one seed for both, the
    sinkage and shear samplers drew the same random streams, and rows of their draws with
    the same index were coupled (Spearman 0.9 between kφ and φ)."""
    import numpy as np

    if index == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), index]).generate_state(1, np.uint32)[0])


def _run(campaign, model, priors, args, index=0):
    from ..bayes import sample_population, sample_posterior

    kw = {
        "seed": model_seed(args.seed, index),
        "progress": progress_enabled(args.progress),
        "soil": args.soil,
    }
    if args.draws is not None:
        kw["draws"] = args.draws
    if priors:
        kw["priors"] = priors
    if args.population and _has_population(model):
        return sample_population(campaign, model, **kw)
    return sample_posterior(campaign, model, **kw)


def _check_simulator(args, models) -> None:
    """--simulator needs the parameters it writes: refuse before sampling, not after."""
    from ..bayes import SIMULATOR_FORMATS
    from ..models import get_model

    if not args.simulator:
        return
    have = {n for m in models for n in get_model(m).param_names}
    missing = [k for k in SIMULATOR_FORMATS[args.simulator] if k not in have]
    if missing:
        raise ValueError(
            f"--simulator {args.simulator} needs {list(SIMULATOR_FORMATS[args.simulator])}; "
            f"{'+'.join(models)} lacks {missing}: use --model bekker+janosi"
        )


def _check_draws(args) -> None:
    """--draws below the convergence check's ESS floor: refuse before sampling, not after.

    N draws carry an effective sample size of about N at most, so fewer than
    :data:`~soilstats.bayes.result.ESS_MIN` fail the check and exit 2 after all the
    sampling; with --force the user has accepted unconverged (FORCED) draws.
    """
    from ..bayes.population import POPULATION_DRAWS
    from ..bayes.posterior import DEFAULT_DRAWS
    from ..bayes.result import ESS_MIN

    if args.draws is not None and args.draws < ESS_MIN and not args.force:
        raise ValueError(
            f"--draws {args.draws} is below {ESS_MIN}, the effective sample size (bulk and "
            f"tail ESS) per parameter the convergence check needs: {args.draws} draws can "
            f"carry at most about {args.draws}. Ask for at least {ESS_MIN} (default "
            f"{DEFAULT_DRAWS}, {POPULATION_DRAWS} with --population), or pass --force to "
            "write unconverged draws anyway"
        )


def _tested_widths(args, campaign) -> tuple[float, float] | None:
    """Smallest and largest plate dimension b [m] of the soil's sinkage tests, if any."""
    tests = campaign.tests
    b = tests.loc[(tests["kind"] == "sinkage") & (tests["soil"].astype(str) == args.soil), "b_m"]
    b = b.dropna()
    return (float(b.min()), float(b.max())) if len(b) else None


def extrapolation_warnings(widths, tested, models) -> list[str]:
    """Say when --contact-width leaves the tested plate sizes for a model whose modulus
    depends on b (Bekker kc/b + kφ, Reece k1 + k2·b): there it is extrapolated, and the
    support check only says it stays positive, not that it is right."""
    from ..models import get_model

    # The model's own inputs say whether it depends on the plate width b.
    sized = [f"{m} ({spec.equation})" for m in models if "b [m]" in (spec := get_model(m)).inputs]
    if not sized or tested is None or (tested[0] <= widths[0] and widths[1] <= tested[1]):
        return []
    return [
        f"--contact-width {widths[0]:g}–{widths[1]:g} m leaves the plate sizes tested "
        f"(b = {tested[0]:g}–{tested[1]:g} m): {', '.join(sized)} is extrapolated there, "
        "unconstrained by the data; the support check only says it stays positive"
    ]


def _contact_widths(args, campaign) -> tuple[float, float]:
    if args.contact_width:
        lo, _, hi = args.contact_width.partition(":")
        try:
            widths = (float(lo), float(hi or lo))
        except ValueError:
            raise ValueError(
                f"--contact-width takes B_MIN[:B_MAX] in metres, got {args.contact_width!r}"
            ) from None
        if not 0 < widths[0] <= widths[1]:
            raise ValueError(f"--contact-width needs 0 < B_MIN <= B_MAX, got {widths}")
        return widths
    return _tested_widths(args, campaign) or (1.0, 1.0)


def _pooled_columns(kind: str, models) -> tuple[str, ...]:
    """Test-log columns whose different values a posterior should not silently mix: the
    identification's condition columns (one home: identification.conditions) and the setup
    columns of the paper's studies; plate size only where the model has no size term."""
    from ..identification.conditions import DEFAULT_CONDITION_COLUMNS
    from ..models import get_model

    sizeless = any(
        (spec := get_model(m)).kind == "sinkage" and "b_m" not in spec.columns for m in models
    )
    setup = {
        "sinkage": ("shape", "series") + (("b_m",) if sizeless else ()),
        "shear": ("grousers", "grouser_height_m", "omega_rpm", "series"),
    }
    return DEFAULT_CONDITION_COLUMNS[kind] + setup[kind]


def pooling_warnings(campaign, soil: str, models) -> list[str]:
    """Say when a posterior pools plate sizes (Bernstein) or test conditions."""
    tests = campaign.tests[campaign.tests["soil"].astype(str) == soil]
    out = []
    for kind in ("sinkage", "shear"):
        chosen = tests[tests["kind"] == kind]
        if chosen.empty:
            continue
        for column in _pooled_columns(kind, models):
            if column not in chosen:
                continue
            values = chosen[column].dropna().unique()
            if len(values) > 1:
                shown = ", ".join(str(v) for v in sorted(values, key=str)[:6])
                out.append(
                    f"the {kind} posterior pools {len(values)} values of {column} ({shown}): "
                    "its draws describe the mixture, not any one condition; select one with "
                    f"--select {kind}:{column}=VALUE if they differ"
                )
    return out


def run(args: argparse.Namespace) -> int:
    """Sample, check, and only then write; exit 2 (nothing written) when a check fails."""
    import json

    import pandas as pd

    from ..bayes import joint_draws, simulator_parameters, simulator_record
    from ..bayes.support import check_support
    from ..errors import ConvergenceWarning
    from ..report import json_safe, output_path, write_atomic, write_csv
    from ..report.posterior_pdf import write_report

    models = args.model.split("+")
    _check_models(models)
    priors = priors_by_model(args, models)
    _check_simulator(args, models)
    _check_draws(args)
    campaign, provenance = prepared(args)
    out = Path(args.out)
    names = ["posterior.nc", "draws.csv", "summary.csv", "posterior.json", "report.pdf"]
    names += [f"posterior_{m}.nc" for m in models[1:]]
    names += [f"{args.simulator}.csv", f"{args.simulator}.json"] if args.simulator else []
    for name in names:  # refuse before sampling, not after minutes of work
        output_path(out, name, overwrite=args.overwrite)
    widths = _contact_widths(args, campaign)
    pooled_warnings = pooling_warnings(campaign, args.soil, models)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        results = [_run(campaign, m, priors[m], args, i) for i, m in enumerate(models)]
    # Rows in random order (so any first N rows are a fair sample, not one walker's run);
    # unconverged draws are taken here and refused below unless --force.
    n = min(r.idata.posterior.sizes["chain"] * r.idata.posterior.sizes["draw"] for r in results)
    draws = (
        joint_draws(results[0], results[1], n, seed=args.seed, allow_unconverged=True)
        if len(results) == 2
        else results[0].draws(n, seed=args.seed, allow_unconverged=True)
    )
    support = check_support(draws, widths, models)
    kept = draws[support.inside].reset_index(drop=True)
    # What a user is handed (draws.csv) is what the summary describes; diagnostics stay the
    # chains' (a review: k's interval started at a draw with n < 0 that draws.csv left out).
    table = pd.concat(
        [r.summary_table(0.9, kept).assign(model=r.model_name, kind=r.kind) for r in results]
    )
    table.index.name = "quantity"
    converged = all(r.converged for r in results)
    failures = [
        f"{r.model_name} {r.kind}: not converged ({'; '.join(r.problems)})"
        for r in results
        if not r.converged
    ]
    if not support.passed:
        failures.append(support.describe())
    from ..errors import SoilstatsWarning

    ours = [str(w.message) for w in caught if issubclass(w.category, SoilstatsWarning)]
    numeric = len(caught) - len(ours)
    if numeric:  # numpy overflow/invalid while sampling: one line, not hundreds
        ours.append(
            f"{numeric} numerical warnings (overflow, invalid values) while sampling: the "
            "sampler reached extreme parameter values (an improper or very wide posterior)"
        )
    ours += extrapolation_warnings(widths, _tested_widths(args, campaign), models)
    for text in ours:
        print(f"WARNING: {text}", file=sys.stderr)
    for text in pooled_warnings:
        print(f"WARNING: {text}", file=sys.stderr)
    health = {r.model_name: r.least_squares_health() for r in results}
    for model, flags in health.items():
        if flags:
            codes = ", ".join(sorted({f["code"] for f in flags}))
            print(
                f"WARNING: the {model} least-squares fit these draws start from is flagged "
                f"({codes}); the posterior inherits its data and model problems (messages in "
                "posterior.json, least_squares_health; soilstats identify --verbose)",
                file=sys.stderr,
            )
    if args.population:
        # A population's scatter takes up what differs between tests and the model cannot
        # follow: plates that disagree on n would be handed out as scatter between
        # preparations (GRC-1's Bekker: a stiffness sd of 5.8x). A residual pattern every
        # test shares moves the mean curve, not the scatter: that stays a warning.
        failures += [
            f"{model}: its least-squares fit is flagged plate-exponents, so the population's "
            "scatter would take up the model's misfit between plate sizes as scatter between "
            f"preparations ({f['message']})"
            for model, flags in health.items()
            for f in flags
            if f["code"] == "plate-exponents"
        ]
    if failures and not args.force:
        for text in failures:
            print(f"error: {text}", file=sys.stderr)
        advice = (
            "select fewer conditions, window the data (--z-max), state narrower --prior "
            "ranges, or pass --force to write them anyway (marked FORCED; unphysical draws are "
            "left out)"
        )
        if args.population:
            # Where the tests agree to within their noise, the scatter sds (sd_p_ref,
            # sd_n; sd_strength, sd_lnK) pile up at 0, the boundary of their support, and
            # the chains mix badly there (a review: R-hat up to 2.0 on zero-scatter data).
            advice = (
                "With --population: if the tests agree to within their noise, the scatter "
                "sds sit at 0 and the chains cannot mix there; the pooled posterior (without "
                f"--population) is then the model the data support. Otherwise {advice}"
            )
        else:
            advice = advice[0].upper() + advice[1:]
        print(
            f"error: nothing written to {out}: these draws are not fit for a rover Monte Carlo. "
            f"{advice}",
            file=sys.stderr,
        )
        return 2
    forced = bool(failures)
    record = json_safe(
        {
            "soil": args.soil,
            "models": models,
            "kind": [r.kind for r in results],
            "converged": converged,
            "forced": forced,
            "failures": failures,
            "support": support.to_dict(),
            "draws_written": len(kept),
            "priors": {r.model_name: r.idata.posterior.attrs.get("priors", "") for r in results},
            "pooling_warnings": pooled_warnings,
            "least_squares_health": health,
            "warnings": ours,
            "selection": list(args.select or []),
            "provenance": provenance.to_dict(),
        }
    )
    prov = provenance.to_dict() | {"forced": forced}
    for i, res in enumerate(results):
        name = "posterior.nc" if i == 0 else f"posterior_{res.model_name}.nc"
        # netCDF attributes take no None: the record travels as JSON strings.
        res.idata.posterior.attrs["soilstats_provenance"] = json.dumps(json_safe(prov))
        res.idata.posterior.attrs["soilstats_record"] = json.dumps(record)
        write_atomic(
            output_path(out, name, overwrite=True),
            lambda tmp, idata=res.idata: idata.to_netcdf(str(tmp)),
        )
    write_csv(out / "draws.csv", kept, provenance, overwrite=True, float_format="%.10g")
    write_csv(out / "summary.csv", table.reset_index(), provenance, overwrite=True)
    write_atomic(
        output_path(out, "posterior.json", overwrite=True), json.dumps(record, indent=2) + "\n"
    )
    write_report(results, out / "report.pdf", record=record, provenance=provenance, handed_out=kept)
    if args.simulator:
        stated = {"elastic_K": args.scm_elastic_K, "damping_R": args.scm_damping_R}
        sim = simulator_parameters(kept, args.simulator, **stated)
        write_csv(
            out / f"{args.simulator}.csv", sim, provenance, overwrite=True, float_format="%.10g"
        )
        context = {k: record[k] for k in ("soil", "models", "kind", "forced", "selection")}
        context |= {"seed": args.seed, "version": provenance.to_dict().get("soilstats_version")}
        sim_record = simulator_record(
            kept, args.simulator, support=support, context=context, **stated
        )
        write_atomic(
            output_path(out, f"{args.simulator}.json", overwrite=True),
            json.dumps(json_safe(sim_record), indent=2) + "\n",
        )
        for note in sim_record["notes"]:
            print(f"note: {note}", file=sys.stderr)
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
            print(res.summary(handed_out=kept))
        print(f"Physical support: {support.describe()}")
    pooled_only = [m for m in models if not _has_population(m)]
    if args.population and pooled_only:
        print(
            f"note: {', '.join(pooled_only)} has no population model (no per-test curve to "
            "scatter); its block is the pooled posterior",
            file=sys.stderr,
        )
    if forced:
        print("WARNING: FORCED — written although: " + "; ".join(failures), file=sys.stderr)
        return 1
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.posterior ...``: the same as ``soilstats posterior ...``."""
    from .main import run_subcommand

    return run_subcommand("posterior", argv)
