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
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..bayes.run_checks import (
    check_draws,
    check_models,
    check_simulator_request,
    contact_widths,
    only_soil,
)
from ..bayes.run_sampling import SamplingOptions, in_workers, sample_models
from ..outputs import output_path
from ..parallel import one_blas_thread, stop_one_worker, warm_one_worker
from .common import (
    add_common_options,
    add_data_options,
    add_jobs_option,
    prepared,
    progress_enabled,
)
from .main import run_subcommand
from .posterior_output import decide_and_write, refuse, series_refused

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


def pooling_warnings(campaign: Campaign, soil: str, models: Iterable[str]) -> list[str]:
    """:func:`soilstats.bayes.pooling.pooling_warnings` (``soilstats wheel`` reads it here)."""
    from ..bayes.pooling import pooling_warnings as pooled  # deferred: pandas (bayes)

    return pooled(campaign, soil, models)


def run(args: argparse.Namespace) -> int:
    """Check what can be checked, sample, let the library decide (:mod:`soilstats.bayes
    .handout`), and only then write; exit 2 (nothing written, no folder made) when a check
    fails."""
    from ..bayes.prior_options import (  # deferred: scipy.stats; heavy for --help
        priors_by_model,
        split_prior_items,
    )

    models = args.model.split("+")
    check_models(models)
    priors = priors_by_model(args.prior, args.priors, models, args.simulator)
    stated = split_prior_items(args.prior, models, args.simulator)[1]
    check_simulator_request(
        args.simulator,
        models,
        stated,
        elastic_K=args.scm_elastic_K,
        damping_R=args.scm_damping_R,
        repair=args.scm_repair,
        contact=getattr(args, "scm_contact", None),
        seed=args.seed,
    )
    check_draws(args.draws, models, force=args.force)
    if not in_workers(models, getattr(args, "jobs", 1)):
        return _checked_sampled_written(args, models, priors, stated)

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


def _checked_sampled_written(
    args: argparse.Namespace, models: list[str], priors: dict[str, Any], stated: dict
) -> int:
    """:func:`run` from reading the campaign on."""
    from ..bayes.handout import preflight  # deferred: pandas
    from ..identification.reuse import reused_fits  # deferred: pandas

    campaign, provenance = prepared(args)
    args.soil = only_soil(campaign, args.soil)
    out = Path(args.out)
    _check_outputs(out, models, args)
    widths = contact_widths(args.contact_width, campaign, args.soil)
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
        options = SamplingOptions(
            args.seed, args.draws, args.soil, args.population, progress_enabled(args.progress)
        )
        results, caught, figures = sample_models(
            campaign, models, priors, options, jobs=getattr(args, "jobs", 1), figures=_figures
        )
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


def _check_outputs(out: Path, models: Sequence[str], args: argparse.Namespace) -> None:
    """Refuse before sampling, not after minutes of work, an output that may not be written
    (an existing file without --overwrite, a link); no folder is made yet."""
    names = ["posterior.nc", "draws.csv", "summary.csv", "posterior.json", "report.pdf"]
    names += [f"posterior_{m}.nc" for m in models[1:]]
    names += [f"{args.simulator}.csv", f"{args.simulator}.json"] if args.simulator else []
    for name in names:
        output_path(out, name, overwrite=args.overwrite, create=False)


def _figures(result: Any) -> Any:
    """One model's report figures, drawn in the worker that sampled it
    (:func:`soilstats.report.posterior_pdf.model_figures`; imported there, on use)."""
    from ..report.posterior_pdf import model_figures  # deferred: arviz

    return model_figures(result)


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.posterior ...``: the same as ``soilstats posterior ...``."""
    return run_subcommand("posterior", argv)
