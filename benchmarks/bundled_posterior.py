"""Convergence and time of the posteriors on the bundled campaigns, at the default settings.

For every soil and model the data has (simulated-paper soil01/soil02/soil08 and the real
cullinan-sand; all series of a soil pooled, as ``--soil`` alone does), runs
``sample_posterior`` and, for Bekker, Bernstein and Janosi, ``sample_population``, and prints
the worst R-hat, the smallest bulk and tail ESS over the checked quantities and the wall time.

    python benchmarks/bundled_posterior.py [--seeds 0 1 2]
"""

from __future__ import annotations

import argparse
import time
import warnings

import soilstats
from soilstats.bayes import sample_population, sample_posterior
from soilstats.bayes.population import POPULATION_MODELS
from soilstats.errors import ConvergenceWarning

CASES = [
    ("simulated-paper", soil, model)
    for soil in ("soil01", "soil02", "soil08")
    for model in ("bekker", "bernstein", "janosi", "mohr-coulomb")
    if not (soil == "soil08" and model in ("janosi", "mohr-coulomb"))  # no shear tests
] + [("cullinan-sand", "cullinan-sand", "bernstein")]  # one plate size: no Bekker


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    args = p.parse_args(argv)
    cases = CASES[-1:] if args.smoke else CASES  # smoke: Cullinan sand's Bernstein only
    campaigns = {name: soilstats.load_campaign(name) for name in {c[0] for c in cases}}
    print(
        f"{'campaign':16} {'soil':14} {'model':13} {'kind':10} {'seed':>4} {'seconds':>8}"
        f" {'max R-hat':>9} {'min ESS bulk':>12} {'min ESS tail':>12}  converged"
    )
    for seed in args.seeds:
        for name, soil, model in cases:
            kinds = ("pooled", "population") if model in POPULATION_MODELS else ("pooled",)
            for kind in kinds:
                fn = sample_posterior if kind == "pooled" else sample_population
                t0 = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", ConvergenceWarning)
                    post = fn(campaigns[name], model, soil=soil, seed=seed)
                seconds = time.perf_counter() - t0
                d = post.diagnostics
                print(
                    f"{name:16} {soil:14} {model:13} {kind:10} {seed:>4} {seconds:>8.1f}"
                    f" {d['r_hat'].max():>9.4f} {d['ess_bulk'].min():>12.0f}"
                    f" {d['ess_tail'].min():>12.0f}  {post.converged}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
