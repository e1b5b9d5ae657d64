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
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError, ModelError
from .common import add_common_options, add_data_options, prepared, progress_enabled
from .posterior_output import (
    decide_and_write,
    has_population,
    model_seed,
    prior_seed,
    refuse,
    series_refused,
    tested_widths,
)

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

#: Simulators whose parameter sets --simulator writes (soilstats.bayes.SIMULATOR_FORMATS; a
#: test keeps the two in step, the bayes package being too heavy to import for --help).
SIMULATORS = ("chrono-scm",)


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
    _simulator_options(parser)


def _simulator_options(parser: argparse.ArgumentParser) -> None:
    """--simulator and the options of its export (Chrono SCM's stated inputs and checks)."""
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


def _checked_model(name: str):
    """The record of one model of ``--model`` (bayes.prior_options.posterior_model)."""
    from ..bayes.prior_options import posterior_model  # bayes: too heavy for --help

    return posterior_model(name)


def _check_models(models) -> None:
    """``--model``: one registered model, or a sinkage and a shear model joined by '+'."""
    kinds = [_checked_model(m).kind for m in models]
    if len(models) > 2 or len(set(kinds)) < len(kinds):
        raise ModelError(
            f"--model {'+'.join(models)}: give one model, or one sinkage and one shear model "
            "joined by '+' (e.g. bekker+janosi)"
        )


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
    if args.population and has_population(model):
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
    from ..bayes.export import REPAIR_MAX, missing_message, scm_plan, stated_inputs
    from ..bayes.scm_wheel import contact_patch
    from ..bayes.stated_priors import sample_priors

    contact_patch(getattr(args, "scm_contact", None))  # LENGTH:WIDTH, positive and finite

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
    return tested_widths(args, campaign) or (1.0, 1.0)


def pooling_warnings(campaign: Campaign, soil: str, models: Iterable[str]) -> list[str]:
    """:func:`soilstats.bayes.pooling.pooling_warnings` (``soilstats wheel`` reads it here)."""
    from ..bayes.pooling import pooling_warnings as pooled  # bayes: too heavy for --help

    return pooled(campaign, soil, models)


def _soil(args, campaign) -> str:
    """--soil, or the campaign's only soil when it was left out."""
    soils = sorted({str(s) for s in campaign.tests["soil"].dropna()})
    if args.soil is not None:
        return args.soil
    if len(soils) == 1:
        return soils[0]
    raise InputError(f"--soil is needed: the campaign has {len(soils)} soils ({', '.join(soils)})")


def run(args: argparse.Namespace) -> int:
    """Check what can be checked, sample, let the library decide (:mod:`soilstats.bayes
    .handout`), and only then write; exit 2 (nothing written, no folder made) when a check
    fails."""
    models = args.model.split("+")
    _check_models(models)
    from ..bayes.prior_options import priors_by_model, split_prior_items  # heavy for --help

    priors = priors_by_model(args.prior, args.priors, models, args.simulator)
    stated = split_prior_items(args.prior, models, args.simulator)[1]
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
    if not args.force and series_refused(args, models, campaign, out):
        return 2
    # Refusals knowable before sampling are made before it (in the time of a least-squares
    # fit), so no sampling is spent on draws that would be refused; the sampler then starts
    # from those very fits instead of making them again.
    # One BLAS thread, as in a worker process: a product's last bits depend on the thread
    # count, and neither the fits nor the draws may depend on --jobs.
    with reused_fits(), one_blas_thread():
        early, _ = preflight(campaign, models, population=args.population, soil=args.soil)
        if early and not args.force:
            return refuse(early, out, args, sampled=False)
        results, caught, figures = _sample(campaign, models, priors, args)
    return decide_and_write(
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


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.posterior ...``: the same as ``soilstats posterior ...``."""
    from .main import run_subcommand

    return run_subcommand("posterior", argv)
