"""Posterior draws of a soil's parameters for rover Monte Carlo.

Writes to --out: posterior.nc (ArviZ netCDF; one group set per model, see below),
draws.csv (one row per joint draw, one column per parameter, SI units, phi in degrees),
summary.csv (mean, sd, 90 % HDI, MCSE, ESS, R-hat), report.pdf (trace, pair and
posterior-predictive plots) and, with --simulator, the draws as a simulator's parameter sets.

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

from .common import add_common_options, add_data_options, prepared_campaign, progress_enabled

#: Simulators whose parameter sets --simulator writes (soilstats.bayes.SIMULATOR_FORMATS; a
#: test keeps the two in step, the bayes package being too heavy to import for --help).
SIMULATORS = ("chrono-scm",)


def configure(parser: argparse.ArgumentParser) -> None:
    """The posterior subcommand's options."""
    add_common_options(
        parser,
        out="required",
        out_help="write posterior.nc, draws.csv, summary.csv and report.pdf into DIR",
    )
    add_data_options(parser)
    parser.add_argument("--soil", required=True, help="soil name (the soil column of tests.csv)")
    parser.add_argument(
        "--model", required=True, help="model, or sinkage+shear (e.g. bekker+janosi)"
    )
    parser.add_argument(
        "--population",
        action="store_true",
        help="population model: draws for a NEW preparation (sinkage models)",
    )
    parser.add_argument("--draws", type=int, default=None, help="kept draws (default per model)")
    parser.add_argument(
        "--simulator",
        choices=SIMULATORS,
        help="also write the draws as this simulator's parameter sets",
    )


def _run(campaign, model, args):
    from ..bayes import sample_population, sample_posterior

    kw = {"seed": args.seed, "progress": progress_enabled(args.progress), "soil": args.soil}
    if args.draws is not None:
        kw["draws"] = args.draws
    if args.population and model in ("bekker", "bernstein"):
        return sample_population(campaign, model, **kw)
    return sample_posterior(campaign, model, **kw)


def run(args: argparse.Namespace) -> int:
    """Sample, write the files, print the summaries; exit 1 when not converged."""
    import json

    import pandas as pd

    from ..bayes import joint_draws
    from ..errors import ConvergenceWarning
    from ..report import Provenance, json_safe, output_path, write_csv
    from ..report.posterior_pdf import write_report

    models = args.model.split("+")
    campaign = prepared_campaign(args)
    provenance = Provenance.of(campaign, argv=args.argv, seed=args.seed)
    out = Path(args.out)
    names = ["posterior.nc", "draws.csv", "summary.csv", "report.pdf"]
    names += [f"posterior_{m}.nc" for m in models[1:]]
    names += [f"{args.simulator}.csv"] if args.simulator else []
    for name in names:  # refuse before sampling, not after minutes of work
        output_path(out, name, overwrite=args.overwrite)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        results = [_run(campaign, m, args) for m in models]
    for i, res in enumerate(results):
        name = "posterior.nc" if i == 0 else f"posterior_{res.model_name}.nc"
        # netCDF attributes take no None: the provenance travels as one JSON string.
        res.idata.posterior.attrs["soilstats_provenance"] = json.dumps(provenance.to_dict())
        res.idata.to_netcdf(str(output_path(out, name, overwrite=True)))
    n = min(len(r.draws()) for r in results)
    draws = (
        joint_draws(results[0], results[1], n, seed=args.seed)
        if len(results) == 2
        else results[0].draws()
    )
    write_csv(out / "draws.csv", draws, provenance, overwrite=True, float_format="%.10g")
    table = pd.concat([r.diagnostics.assign(model=r.model_name, kind=r.kind) for r in results])
    table.index.name = "quantity"
    write_csv(out / "summary.csv", table.reset_index(), provenance, overwrite=True)
    write_report(results, out / "report.pdf", provenance=provenance)
    if args.simulator:
        from ..bayes import simulator_parameters

        sim = simulator_parameters(draws, args.simulator)
        write_csv(
            out / f"{args.simulator}.csv", sim, provenance, overwrite=True, float_format="%.10g"
        )
    converged = all(r.converged for r in results)
    if args.json:
        print(
            json.dumps(
                json_safe(
                    {
                        "out": str(out),
                        "converged": converged,
                        "summary": table.reset_index().to_dict("records"),
                        "warnings": [str(w.message) for w in caught],
                        "provenance": provenance.to_dict(),
                    }
                ),
                indent=2,
            )
        )
    else:
        for res in results:
            print(res.summary())
    if args.population and any(m not in ("bekker", "bernstein") for m in models):
        print(
            "note: the population model covers sinkage models only; the shear block is the "
            "pooled posterior",
            file=sys.stderr,
        )
    for w in caught:
        print(f"WARNING: {w.message}", file=sys.stderr)
    if not converged:
        print("WARNING: NOT CONVERGED — see summary.csv and the notes above", file=sys.stderr)
        return 1
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.posterior ...``: the same as ``soilstats posterior ...``."""
    from .main import run_subcommand

    return run_subcommand("posterior", argv)
