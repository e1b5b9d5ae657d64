"""Posterior draws of a soil's parameters for rover Monte Carlo (issue #5).

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

import pandas as pd

from ..bayes import SIMULATOR_FORMATS, joint_draws, sample_population, sample_posterior
from ..bayes.data import SINKAGE_MODELS
from ..bayes.plots import write_report
from ..campaign import load_campaign
from ..errors import CampaignError, ConvergenceWarning


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m soilstats.posterior",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("campaign", help="campaign folder or bundled campaign name")
    p.add_argument("--soil", required=True, help="soil name (the soil column of tests.csv)")
    p.add_argument("--model", required=True, help="model, or sinkage+shear (bekker+janosi)")
    p.add_argument(
        "--select",
        action="append",
        default=[],
        metavar="[KIND:]COLUMN=VALUE",
        help="only tests whose test-log COLUMN equals VALUE (repeatable); a KIND: prefix "
        "(sinkage: or shear:) limits it to that kind's tests, e.g. --select "
        "sinkage:series=velocity --select sinkage:velocity_m_s=0.0048 --select "
        "shear:series=shear-ring",
    )
    p.add_argument(
        "--population",
        action="store_true",
        help="population model: draws for a NEW preparation (sinkage models)",
    )
    p.add_argument("--draws", type=int, default=None, help="kept draws (default per model)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument(
        "--simulator",
        choices=sorted(SIMULATOR_FORMATS),
        help="also write the draws as this simulator's parameter sets",
    )
    p.add_argument("--progress", action="store_true", help="show progress bars")
    return p


def _selected(campaign, items: list[str], model: str):
    """The campaign for ``model`` with the ``--select [KIND:]COLUMN=VALUE`` items applied.

    Values compare as the column's type (numbers as numbers).  An item with a KIND: prefix
    is used only for that kind's model; tests of the other kind are always kept.
    """
    kind = "sinkage" if model in SINKAGE_MODELS else "shear"
    other = (campaign.tests["kind"] != kind).to_numpy()
    out = {}
    for item in items:
        prefix, colon, rest = item.partition(":")
        if colon and prefix in ("sinkage", "shear") and "=" not in prefix:
            if prefix != kind:
                continue
            item = rest
        column, sep, text = item.partition("=")
        if not sep or not column:
            raise ValueError(f"--select takes [KIND:]COLUMN=VALUE, got {item!r}")
        if column not in campaign.tests.columns:
            raise ValueError(
                f"--select: no column {column!r}; columns: {list(campaign.tests.columns)}"
            )
        numeric = pd.api.types.is_numeric_dtype(campaign.tests[column])
        value = float(text) if numeric else text
        out[column] = lambda col, v=value: (col == v).to_numpy() | other
    return campaign.select(**out) if out else campaign


def _run(campaign, model, args):
    kw = {"seed": args.seed, "progress": args.progress, "soil": args.soil}
    campaign = _selected(campaign, args.select, model)
    if args.draws is not None:
        kw["draws"] = args.draws
    if args.population and model in ("bekker", "bernstein"):
        return sample_population(campaign, model, **kw)
    return sample_posterior(campaign, model, **kw)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    models = args.model.split("+")
    try:
        campaign = load_campaign(
            args.campaign if Path(args.campaign).exists() is False else Path(args.campaign)
        )
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            results = [_run(campaign, m, args) for m in models]
    except (CampaignError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    for i, res in enumerate(results):
        name = "posterior.nc" if i == 0 else f"posterior_{res.model_name}.nc"
        res.idata.to_netcdf(str(args.out / name))
    n = min(len(r.draws()) for r in results)
    if len(results) == 2:
        draws = joint_draws(results[0], results[1], n, seed=args.seed)
    else:
        draws = results[0].draws()
    draws.to_csv(args.out / "draws.csv", index=False, float_format="%.10g")
    table = pd.concat([r.diagnostics.assign(model=r.model_name, kind=r.kind) for r in results])
    table.index.name = "quantity"
    table.to_csv(args.out / "summary.csv")
    write_report(results, args.out / "report.pdf")
    if args.simulator:
        from ..bayes import simulator_parameters

        try:
            sim = simulator_parameters(draws, args.simulator)
        except ValueError as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        sim.to_csv(args.out / f"{args.simulator}.csv", index=False, float_format="%.10g")
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
    if any(not r.converged for r in results):
        print("WARNING: NOT CONVERGED — see summary.csv and the notes above", file=sys.stderr)
        return 1
    return 0
