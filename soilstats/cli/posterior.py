"""Posterior draws of a soil's parameters for rover Monte Carlo.

Writes to --out: posterior.nc (ArviZ netCDF; one group set per model, see below),
draws.csv (one row per joint draw, one column per parameter, SI units, phi in degrees),
summary.csv (mean, sd, 90 % equal-tailed interval, MCSE, ESS, R-hat), posterior.json (the
record: priors, convergence, physical support, pooling warnings, provenance), report.pdf
(trace, pair and posterior-predictive plots) and, with --simulator, the draws as a
simulator's parameter sets (CSV) with their record (JSON).

--simulator chrono-scm writes Chrono SCM's SetSoilParameters arguments per draw. What no test
measured (c, phi, K of a campaign without shear-ring tests) comes from user priors
(--prior c=uniform:0:2000 --prior phi=normal:30:3 --prior K=lognormal:0.02:0.5), drawn
independently of the posterior draws and marked as such in both files; without them the
command refuses and says which are missing. A Bernstein posterior maps onto SCM as
Kphi = k, Kc = 0 (marked). SCM's own constraints are checked on every set: a set Chrono
would silently change (elastic_K <= Bekker_Kphi) is refused, or with --scm-repair M given
elastic_K = M x Bekker_Kphi and marked.

Nothing is written until the draws pass: every sampler converged (R-hat, ESS), at most 1 %
of the draws fall outside the physical support at the stated contact widths
(soilstats.bayes.support), a population's least-squares start is not flagged
plate-exponents (plates that disagree on n), and with --simulator every parameter set meets
the simulator's constraints (or was repaired with --scm-repair). Otherwise exit 2 with the
reasons, unless --force (exit 1, every file marked). Draws outside the support are never written.

--model takes one model (bekker, bernstein, reece, mohr-coulomb, janosi) or a sinkage and a
shear model joined by '+' (e.g. bekker+janosi): their posteriors are combined as
independent blocks, because plate and shear-ring tests are separate physical tests.
With two models, posterior.nc holds the first and posterior_<model>.nc the second.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError, ModelError
from .common import add_common_options, add_data_options, prepared, progress_enabled

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

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
    from .common import add_jobs_option  # (one import line above, not a sixth)

    add_jobs_option(parser, "the models of a MODEL+MODEL run, each sampled and drawn in its own")
    parser.add_argument(
        "--soil",
        help="soil name (the soil column of tests.csv); may be left out when the campaign "
        "(after --select) has one soil",
    )
    parser.add_argument(
        "--model", required=True, help="model, or sinkage+shear (e.g. bekker+janosi)"
    )
    parser.add_argument(
        "--population",
        action="store_true",
        help="population model: draws for a NEW preparation (bekker, bernstein, janosi; "
        "mohr-coulomb stays pooled)",
    )
    parser.add_argument(
        "--draws",
        type=int,
        default=None,
        help="kept draws, >= 1 and within the memory budget (default per model)",
    )
    parser.add_argument(
        "--prior",
        action="append",
        default=[],
        metavar="NAME=SPEC",
        help="prior of one parameter: LO:HI (flat), normal:MU:SD or normal:MU:SD:LO:HI, SI "
        "units, phi in degrees (repeatable; replaces the physics default). With --simulator, "
        "a parameter the simulator needs and no model identifies (c [Pa], phi [deg], K [m] "
        "without a shear model) takes a user prior instead: uniform:LO:HI, normal:MU:SD, "
        "normal:MU:SD:LO:HI or lognormal:MEDIAN:SIGMA_LOG, drawn independently of the "
        "posterior and marked in the export",
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
        "Bevameter parameter); SCM needs it above every set's Bekker_Kphi",
    )
    parser.add_argument(
        "--scm-damping-R",
        type=float,
        metavar="PA_S_PER_M",
        help="Chrono SCM damping [Pa s/m], >= 0 (default 3e4, Chrono's demos; 0 is the "
        "original SCM)",
    )
    parser.add_argument(
        "--scm-repair",
        type=float,
        metavar="MULTIPLE",
        help="where a set breaks SCM's elastic_K > Bekker_Kphi, set its elastic_K to MULTIPLE "
        "x Bekker_Kphi (1 < MULTIPLE <= 1000), marked per row (column elastic_K_repaired), in the "
        "JSON and on page 1 of the report; without it such sets are refused",
    )
    parser.add_argument(
        "--scm-contact",
        metavar="LENGTH:WIDTH",
        help="the wheel's contact patch in SCM [m] (e.g. 0.039:0.05): warns when SCM's modulus "
        "at its width l*w/(l+w) differs by more than 25 %% from the one at the wheel width w",
    )


def split_prior_items(
    args: argparse.Namespace, models: Iterable[str]
) -> tuple[list[str], dict[str, tuple]]:
    """``--prior`` items for the sampled models' parameters, and user priors: with
    ``--simulator``, items naming a parameter the simulator needs that no model identifies
    (c, phi, K without a shear model), as :mod:`soilstats.bayes.stated_priors` tuples."""
    from ..bayes.export import parse_stated_prior, scm_plan

    params = {n for m in models for n in _checked_model(m).param_names}
    unmeasured = set()
    if getattr(args, "simulator", None):
        unmeasured = {k for k, v in scm_plan(params).items() if v == "missing"}
    posterior, stated = [], {}
    for item in args.prior or ():
        name, eq, spec = str(item).partition("=")
        if eq and name.strip() in unmeasured:
            try:
                stated[name.strip()] = parse_stated_prior(spec)
            except ValueError as err:
                raise InputError(f"--prior {item}: {err}") from None
        else:
            posterior.append(item)
    return posterior, stated


def priors_by_model(args: argparse.Namespace, models: Sequence[str]) -> dict[str, dict]:
    """Each model's priors, read once: its ``[MODEL]`` table of ``--priors``, then the
    ``--prior`` items naming its parameters (they win). A name that belongs to no model — or,
    in a file, not to its table's model — is an error before any sampling. Items that are
    user priors for ``--simulator`` (:func:`split_prior_items`) are not the models'."""
    from ..bayes.priors import check_priors_file, priors_from_items, priors_from_toml

    if args.priors:
        check_priors_file(args.priors)
    raw = split_prior_items(args, models)[0]
    params = {m: _checked_model(m).param_names for m in models}
    known = {n for names in params.values() for n in names}
    named = {str(item).partition("=")[0].strip() for item in raw if "=" in str(item)}
    unknown = sorted(named - known)
    if unknown:
        hint = (
            ""
            if getattr(args, "simulator", None)
            else "; with --simulator chrono-scm, the shear parameters a sinkage-only campaign "
            "lacks take user priors (e.g. --prior c=uniform:0:2000)"
        )
        raise ModelError(
            f"--prior names {unknown}, not parameters of {'+'.join(models)} "
            f"(parameters: {sorted(known)}){hint}"
        )
    items = priors_from_items(raw)
    out = {}
    for model, names in params.items():
        table = priors_from_toml(args.priors, model) if args.priors else {}
        stray = sorted(set(table) - set(names))
        if stray:
            raise ModelError(
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


def _run(campaign, model, priors, args, index=0, *, progress=True):
    from ..bayes import sample_population, sample_posterior

    kw = {
        "seed": model_seed(args.seed, index),
        "progress": progress and progress_enabled(args.progress),
        "soil": args.soil,
    }
    if args.draws is not None:
        kw["draws"] = args.draws
    if priors:
        kw["priors"] = priors
    if args.population and _has_population(model):
        return sample_population(campaign, model, **kw)
    return sample_posterior(campaign, model, **kw)


def _check_simulator(args, models, stated: dict) -> None:
    """--simulator needs every parameter it writes, from the models, the Bernstein mapping or
    user priors, and valid stated inputs: refuse before sampling, not after."""
    if not args.simulator:
        if args.scm_repair is not None:
            raise InputError("--scm-repair repairs a simulator export: give --simulator too")
        if getattr(args, "scm_contact", None):
            raise InputError("--scm-contact checks a simulator export: give --simulator too")
        return
    _scm_contact(args)
    from ..bayes.export import REPAIR_MAX, missing_message, scm_plan, stated_inputs
    from ..bayes.stated_priors import sample_priors

    params = [n for m in models for n in _checked_model(m).param_names]
    plan = scm_plan(params, stated)
    sinkage = [m for m in models if _checked_model(m).kind == "sinkage"]
    if sinkage and plan["kphi"] == "missing":
        raise ModelError(
            f"--simulator {args.simulator} takes Bekker's law p = (kc/b + kphi) z^n; "
            f"{sinkage[0]} ({_checked_model(sinkage[0]).equation}) has no such form: use "
            "--model bekker, or bernstein (mapped as Kphi = k, Kc = 0)"
        )
    missing = [k for k, v in plan.items() if v == "missing"]
    if missing:
        raise InputError(f"--simulator {missing_message(args.simulator, missing, params)}")
    stated_inputs(args.scm_elastic_K, args.scm_damping_R)
    if args.scm_repair is not None and not 1 < args.scm_repair <= REPAIR_MAX:
        raise InputError(
            f"--scm-repair takes a multiple in (1, {REPAIR_MAX:g}] (elastic_K = MULTIPLE x "
            f"Bekker_Kphi must exceed Bekker_Kphi), got {args.scm_repair:g}"
        )
    if stated:  # a prior that cannot be drawn, or leaves the support: say so now
        sample_priors(stated, 10_000, prior_seed(args.seed, models))


def prior_seed(seed: int, models: Sequence[str]) -> int:
    """The seed of the user priors' draws: one stream of its own after the models'
    (``SeedSequence([seed, len(models)])``), so they are independent of the posterior."""
    return model_seed(seed, len(models))


#: Bytes per kept draw and column, all copies together: emcee's unthinned chain (thinning
#: τ/2, a few steps), the thinned chain, the InferenceData and the draws table.
_BYTES_PER_DRAW_VALUE = 8 * 8


def _check_draws(args, models: Sequence[str] = ()) -> None:
    """--draws below the convergence check's ESS floor: refuse before sampling, not after.

    N draws carry an effective sample size of about N at most, so fewer than
    :data:`~soilstats.bayes.result.ESS_MIN` fail the check and exit 2 after all the
    sampling; with --force the user has accepted unconverged (FORCED) draws.  A number of
    draws that cannot be held in memory (:mod:`soilstats._budget`) is refused even then.
    """
    if args.draws is not None:
        from .._budget import check_budget

        if args.draws < 1:
            raise InputError(f"--draws takes a whole number >= 1, got {args.draws}")
        columns = sum(len(_checked_model(m).param_names) + 2 for m in models) or 4
        check_budget(
            f"--draws {args.draws}",
            float(args.draws) * columns * _BYTES_PER_DRAW_VALUE,
            "ask for fewer draws (the default is enough for every summary soilstats writes)",
        )
    if args.draws is None or args.force:
        return  # (the bayes modules cost seconds to import: not for a refusal before sampling)
    from ..bayes.population import POPULATION_DRAWS
    from ..bayes.posterior import DEFAULT_DRAWS
    from ..bayes.result import ESS_MIN

    if args.draws < ESS_MIN:
        raise InputError(
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


def extrapolation_warnings(
    widths: tuple[float, float], tested: tuple[float, float] | None, models: Iterable[str]
) -> list[str]:
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


#: Largest contact width --contact-width takes [m]: wider is no wheel or track of a vehicle.
CONTACT_WIDTH_MAX_M = 10.0


def _contact_widths(args, campaign) -> tuple[float, float]:
    if args.contact_width:
        lo, _, hi = args.contact_width.partition(":")
        try:
            widths = (float(lo), float(hi or lo))
        except ValueError:
            raise InputError(
                f"--contact-width takes B_MIN[:B_MAX] in metres, got {args.contact_width!r}"
            ) from None
        if not 0 < widths[0] <= widths[1] <= CONTACT_WIDTH_MAX_M:
            raise InputError(
                f"--contact-width needs 0 < B_MIN <= B_MAX <= {CONTACT_WIDTH_MAX_M:g} m "
                f"(finite), got {args.contact_width!r}"
            )
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


def pooling_warnings(campaign: Campaign, soil: str, models: Iterable[str]) -> list[str]:
    """Say when a posterior pools plate sizes (Bernstein) or test conditions."""
    from .._text import natural_key  # levels in natural order: 1, 2, 10 (not 1, 10, 2)

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
                shown = ", ".join(str(v) for v in sorted(values, key=natural_key)[:6])
                out.append(
                    f"the {kind} posterior pools {len(values)} values of {column} ({shown}): "
                    "its draws describe the mixture, not any one condition; select one with "
                    f"--select {kind}:{column}=VALUE if they differ"
                )
    return out


def _soil(args, campaign) -> str:
    """--soil, or the campaign's only soil when it was left out."""
    soils = sorted({str(s) for s in campaign.tests["soil"].dropna()})
    if args.soil is not None:
        return args.soil
    if len(soils) == 1:
        return soils[0]
    raise InputError(f"--soil is needed: the campaign has {len(soils)} soils ({', '.join(soils)})")


def _scm_contact(args) -> tuple[float, float] | None:
    """--scm-contact LENGTH:WIDTH in m, checked (None when not given)."""
    from ..bayes.export import chrono_contact_width

    text = getattr(args, "scm_contact", None)
    if not text:
        return None
    length, _, width = str(text).partition(":")
    try:
        patch = (float(length), float(width))
    except ValueError:
        raise InputError(f"--scm-contact takes LENGTH:WIDTH in metres, got {text!r}") from None
    chrono_contact_width(*patch)  # positive and finite, or an InputError naming both
    return patch


def _scm_warnings(args, export) -> list[str]:
    """SCM's modulus at its own contact width against the wheel's (--scm-contact), printed."""
    from ..bayes.export import contact_width_warning

    patch = _scm_contact(args)
    if export is None or patch is None:
        return []
    text = contact_width_warning(export.table, *patch)
    if text is None:
        return []
    print(f"WARNING: {text}", file=sys.stderr)
    return [text]


def _series_refusal(args, models, campaign) -> str | None:
    """A shear posterior exported for a simulator must not pool test series of different
    set-ups without --select (docs/posterior.md)."""
    from ..bayes.export import pooled_series_failure
    from ..models import get_model

    if not args.simulator or not any(get_model(m).kind == "shear" for m in models):
        return None
    tests = campaign.tests
    shear = tests[(tests["kind"] == "shear") & (tests["soil"].astype(str) == args.soil)]
    return pooled_series_failure(shear)


def _export(args, models, results, kept, stated, campaign):
    """The draws handed out as the simulator's parameter sets (checked, not yet written)."""
    from ..bayes.export import export_simulator

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
        plate_widths=_tested_widths(args, campaign),
        on_failure="return",  # refused below with the CLI's own words (_export_failures)
    )


def _export_failures(simulator: str, check) -> list[str]:
    """The failed constraints, each with its fix (a larger elastic_K or --scm-repair)."""
    from ..bayes.export import REPAIRABLE

    fix = (
        f". Fix: state --scm-elastic-K above {check.largest_kphi:.3g} Pa/m (the largest "
        "Bekker_Kphi; best a measured unloading stiffness), or pass --scm-repair MULTIPLE to set "
        "elastic_K = MULTIPLE x Bekker_Kphi in each such set (marked per row)"
    )
    return [
        f"{simulator}: {failure}{fix if REPAIRABLE in failure else ''}"
        for failure in check.failures
    ]


class _Annotated:
    """A provenance whose CSV comment header carries more ``key: value`` lines."""

    def __init__(self, provenance, extra: list[str]) -> None:
        self._provenance, self._extra = provenance, extra

    def lines(self) -> list[str]:
        return [*self._provenance.lines(), *self._extra]


def _write_export(out: Path, export, record: dict, support, provenance, args) -> None:
    """``<simulator>.csv`` (each column's source and SCM's check in its comment lines) and
    ``<simulator>.json``; the check, repairs and notes also to stderr."""
    import json

    from ..outputs import json_safe, output_path, write_atomic, write_csv

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
    context |= {"seed": args.seed, "version": provenance.to_dict().get("soilstats_version")}
    write_atomic(
        output_path(out, f"{name}.json", overwrite=True),
        json.dumps(json_safe(export.record(support, context)), indent=2) + "\n",
    )
    repaired = export.check.repair_sentence()
    if repaired:
        print(f"WARNING: {name}: {repaired}", file=sys.stderr)
    for note in export.notes:
        print(f"note: {name}: {note}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Check what can be checked, sample, let the library decide (:mod:`soilstats.bayes
    .handout`), and only then write; exit 2 (nothing written, no folder made) when a check
    fails."""
    models = args.model.split("+")
    _check_models(models)
    priors = priors_by_model(args, models)
    stated = split_prior_items(args, models)[1]
    _check_simulator(args, models, stated)
    _check_draws(args, models)
    if not _in_workers(args, models):
        return _checked_sampled_written(args, models, priors, stated)
    from ..parallel import stop_one_worker, warm_one_worker

    # The worker imports the sampler and the report while this process reads and screens
    # the campaign; a run that ends early (a refusal, an error) stops it at once instead of
    # waiting at exit for its imports, and so does one that is done with it.
    warm_one_worker(("soilstats.bayes.population", "soilstats.report.posterior_pdf"))
    finished = False
    try:
        code = _checked_sampled_written(args, models, priors, stated)
        finished = True
        return code
    finally:
        stop_one_worker(at_once=not finished)


def _checked_sampled_written(args, models, priors, stated) -> int:
    """:func:`run` from reading the campaign on."""
    from ..bayes.handout import preflight
    from ..identification.reuse import reused_fits
    from ..parallel import one_blas_thread

    campaign, provenance = prepared(args)
    args.soil = _soil(args, campaign)
    out = Path(args.out)
    _check_outputs(out, models, args)
    widths = _contact_widths(args, campaign)
    pooled_warnings = pooling_warnings(campaign, args.soil, models)
    series = _series_refusal(args, models, campaign)
    if series is not None and not args.force:
        print(
            f"error: nothing written to {out}: {args.simulator}: {series} (or pass --force to "
            "write them anyway, marked FORCED)",
            file=sys.stderr,
        )
        return 2
    # Refusals knowable before sampling are made before it (in the time of a least-squares
    # fit), so no sampling is spent on draws that would be refused; the sampler then starts
    # from those very fits instead of making them again.
    # One BLAS thread, as in a worker process: a product's last bits depend on the thread
    # count, and neither the fits nor the draws may depend on --jobs.
    with reused_fits(), one_blas_thread():
        early, _ = preflight(campaign, models, population=args.population, soil=args.soil)
        if early and not args.force:
            return _refuse(early, out, args, sampled=False)
        results, caught, figures = _sample(campaign, models, priors, args)
    return _decide_and_write(
        args,
        models,
        results,
        caught,
        widths,
        pooled_warnings,
        stated,
        campaign,
        provenance,
        figures,
    )


def _check_outputs(out: Path, models, args) -> None:
    """Refuse before sampling, not after minutes of work, an output that may not be written
    (an existing file without --overwrite, a link); no folder is made yet."""
    from ..outputs import output_path

    names = ["posterior.nc", "draws.csv", "summary.csv", "posterior.json", "report.pdf"]
    names += [f"posterior_{m}.nc" for m in models[1:]]
    names += [f"{args.simulator}.csv", f"{args.simulator}.json"] if args.simulator else []
    for name in names:
        output_path(out, name, overwrite=args.overwrite, create=False)


def _sample(campaign, models, priors, args):
    """The posterior of every model, the warnings sampling raised, and — where the models
    were sampled in worker processes (``--jobs``) — each model's report figures, drawn there
    too (model name → SVG and caption; empty when sampled here)."""
    if _in_workers(args, models):
        tasks = [(campaign, m, priors[m], args, i) for i, m in enumerate(models)]
        done = _here_and_away(tasks)
        figures = {r.model_name: drawn for r, _, drawn in done}
        sampled = [(r, said) for r, said, _ in done]
    else:
        sampled = [_recorded(campaign, m, priors[m], args, i) for i, m in enumerate(models)]
        figures = {}
    caught = [_Caught(category, message) for _, said in sampled for category, message in said]
    return [r for r, _ in sampled], caught, figures


def _in_workers(args, models) -> bool:
    """Sample the second of two models in a worker process (``--jobs`` of 2 or more); this
    process samples the first."""
    from ..parallel import effective_jobs

    return len(models) == 2 and effective_jobs(getattr(args, "jobs", 1)) > 1


def _recorded(campaign, model, priors, args, index, *, progress=True):
    """:func:`_run` and the warnings it raised, as (class, text) pairs (a worker's travel
    back as such); the convergence warning every time it is raised."""
    from ..errors import ConvergenceWarning

    with warnings.catch_warnings(record=True) as recorded:
        warnings.simplefilter("always", ConvergenceWarning)
        result = _run(campaign, model, priors, args, index, progress=progress)
    return result, [(w.category, str(w.message)) for w in recorded]


def _here_and_away(tasks: list) -> list:
    """:func:`_sample_and_draw` of the first task in this process while the second runs in
    a worker process; the results in the order of ``tasks``."""
    from ..parallel import in_one_worker

    away = in_one_worker(_sample_and_draw, tasks[1])
    here = _sample_and_draw(tasks[0])
    return [here, away.result()]


@dataclass(frozen=True)
class _Caught:
    """A warning raised while sampling (here or in a worker): its class and its text."""

    category: type[Warning]
    message: str


def _sample_and_draw(task):
    """In a worker: one model's posterior (as :func:`_run`), the warnings it raised as
    (class, text), and its report figures (:func:`soilstats.report.posterior_pdf
    .model_figures`) — drawn where the draws are, so only SVG travels back."""
    from ..report.posterior_pdf import model_figures

    campaign, model, priors, args, index = task
    result, said = _recorded(campaign, model, priors, args, index, progress=index == 0)
    return result, said, model_figures(result)


def _refuse(failures, out: Path, args, *, sampled: bool, simulator_only: bool = False) -> int:
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


def _warnings(caught, widths, args, campaign, models, handout, pooled_warnings) -> list[str]:
    """The warnings of a run, printed one line each: the library's own, numerical ones
    summed up, extrapolation, pooling and the flagged least-squares starts."""
    from ..errors import SoilstatsWarning

    ours = [str(w.message) for w in caught if issubclass(w.category, SoilstatsWarning)]
    numeric = len(caught) - len(ours)
    if numeric:  # numpy overflow/invalid while sampling: one line, not hundreds
        ours.append(
            f"{numeric} numerical warnings (overflow, invalid values) while sampling: the "
            "sampler reached extreme parameter values (an improper or very wide posterior)"
        )
    ours += extrapolation_warnings(widths, _tested_widths(args, campaign), models)
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


def _decide_and_write(
    args, models, results, caught, widths, pooled_warnings, stated, campaign, provenance, figures
) -> int:
    """The library's decision on the draws, printed; the files written where it allows."""
    import pandas as pd

    from ..bayes.handout import hand_out

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
        failures += _export_failures(args.simulator, export.check)
    series = _series_refusal(args, models, campaign) if export is not None else None
    if series is not None:  # only with --force: refused before sampling otherwise
        failures.append(f"{args.simulator}: {series}")
    ours = _warnings(caught, widths, args, campaign, models, handout, pooled_warnings)
    ours += _scm_warnings(args, export)
    if failures and not args.force:
        simulator_only = export is not None and len(failures) == len(export.check.failures)
        return _refuse(failures, out, args, sampled=True, simulator_only=simulator_only)
    from ..outputs import json_safe

    record = _record(args, models, results, handout, failures, ours, pooled_warnings, provenance)
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


def _record(args, models, results, handout, failures, ours, pooled_warnings, provenance) -> dict:
    """posterior.json: the run, the decision and what it rests on."""
    import json

    from ..bayes.population import band_calibration
    from ..outputs import json_safe

    decision = handout.to_dict()
    checks = {r.model_name: band_calibration(r) for r in results if r.kind == "population"}
    return json_safe(
        {
            "soil": args.soil,
            "models": models,
            "kind": [r.kind for r in results],
            "converged": all(r.converged for r in results),
            "forced": bool(failures),
            "failures": failures,
            "support": decision["support"],
            "draws_written": decision["draws_written"],
            "negative_modulus_below_m": decision["negative_modulus_below_m"],
            "priors": {r.model_name: r.idata.posterior.attrs.get("priors", "") for r in results},
            "pooling_warnings": pooled_warnings,
            "least_squares_health": decision["least_squares_health"],
            # The population band against its own tests (issue #36): which criterion fails.
            "band_check": {
                name: json.loads(check.to_json()) for name, check in checks.items() if check
            },
            "warnings": ours,
            "selection": list(args.select or []),
            "provenance": provenance.to_dict(),
        }
    )


def _write(out: Path, args, results, record: dict, table, kept, provenance, figures) -> None:
    """posterior*.nc, draws.csv, summary.csv, posterior.json and report.pdf."""
    import json

    from ..outputs import json_safe, output_path, write_atomic, write_csv
    from ..outputs.files import netcdf_bytes
    from ..report.posterior_pdf import write_report

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


def _print(args, out: Path, results, record: dict, table, handout) -> None:
    """The summary on stdout (or one JSON object with --json), and the notes on stderr."""
    import json

    from ..outputs import json_safe

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
    pooled_only = [m for m in record["models"] if not _has_population(m)]
    if args.population and pooled_only:
        print(
            f"note: {', '.join(pooled_only)} has no population model (no per-test curve to "
            "scatter); its block is the pooled posterior",
            file=sys.stderr,
        )


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.posterior ...``: the same as ``soilstats posterior ...``."""
    from .main import run_subcommand

    return run_subcommand("posterior", argv)
