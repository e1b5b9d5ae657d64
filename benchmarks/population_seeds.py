"""Does a population posterior give one answer whatever the seed?  One line per seed.

    python benchmarks/population_seeds.py grc1-oravec2009 GRC-1 bekker --seeds 0-7
    python benchmarks/population_seeds.py simulated-paper soil01 janosi --seeds 0,1

For each seed: converged or not (R-hat ≤ 1.01, bulk/tail ESS ≥ 400), the posterior medians of
the soil-level parameters and the scatter, the share of new-preparation draws that are not
finite, and the wall time.  An improper posterior shows as seeds that disagree, run off to
overflowing moduli or fail convergence (docs/posterior.md, "Why log-flat").  One run on this
machine; not a unit test.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import soilstats
from soilstats.bayes import sample_population
from soilstats.data import bundled_path


def _seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = (int(v) for v in text.split("-"))
        return list(range(lo, hi + 1))
    return [int(v) for v in text.split(",")]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("campaign", nargs="?", help="bundled campaign name or a campaign folder")
    p.add_argument("soil", nargs="?")
    p.add_argument("model", nargs="?", choices=("bekker", "bernstein", "janosi"))
    p.add_argument("--seeds", default="0-3", help="0-7 or 0,3,5")
    p.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    args = p.parse_args(argv)
    if args.smoke:  # GRC-1's 51 mm plate, one seed
        args.campaign, args.soil, args.model, args.seeds = (
            "grc1-oravec2009",
            "GRC-1",
            "bernstein",
            "0",
        )
    elif args.model is None:
        p.error("campaign, soil and model are required")
    campaign = soilstats.load_campaign(bundled_path(args.campaign) or args.campaign)
    for seed in _seeds(args.seeds):
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # ArviZ's NaN warnings on a run that ran off
            result = sample_population(campaign, args.model, seed=seed, soil=args.soil)
        post = result.idata.posterior
        shown = [v for v in post.data_vars if v.startswith(("mu_", "sd_", "corr_"))]
        medians = "  ".join(f"{v}={float(np.nanmedian(post[v])):.4g}" for v in shown)
        new = result.draws().to_numpy()
        nonfinite = float(np.mean(~np.all(np.isfinite(new), axis=1)))
        print(
            f"seed {seed}: {'converged' if result.converged else 'NOT converged'}  {medians}  "
            f"non-finite new draws {nonfinite:.1%}  {time.perf_counter() - t0:.1f} s",
            flush=True,
        )


if __name__ == "__main__":
    main()
