"""Full-size calibration of the posteriors (the figures quoted in docs/posterior.md).

The suite (tests/test_posterior_calibration.py) runs small seeded versions of the same two
checks; this script runs them at a size where the binomial error is well inside the bands:

* pooled model, model-matched noise: coverage of the truth by 90 % equal-tailed credible
  intervals over many simulated Bekker and Bernstein campaigns (target 90 ± 4 %);
* population model: coverage of held-out repetitions' true curves by the 90 % predictive band
  of a new preparation (target 90 ± 5 %), and by the band implied by the paper's pooled σ.

    python benchmarks/calibrate_posterior.py [--sets 200] [--population-sets 20] [--seed 0]

Prints the rates with their binomial standard errors (~5–10 min on 2 cores at the defaults).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from posterior_calibration import pooled_coverage, population_coverage


def _line(label, cov, seconds) -> str:
    se = (cov.rate * (1 - cov.rate) / cov.trials) ** 0.5
    return (
        f"{label:<48} {cov.rate:7.1%} ± {se:5.1%}  ({cov.hits}/{cov.trials}; "
        f"not converged: {cov.not_converged}; {seconds:.0f} s)"
    )


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sets", type=int, default=200, help="pooled campaigns per model")
    p.add_argument("--population-sets", type=int, default=20, help="population campaigns")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    args = p.parse_args(argv)
    if args.smoke:
        args.sets, args.population_sets = 2, 1
    print("Coverage of 90 % intervals (rate ± binomial se of independent trials)")
    total_hits = total = 0
    for model in ("bekker", "bernstein"):
        t0 = time.perf_counter()
        cov = pooled_coverage(args.sets, model=model, seed=args.seed)
        total_hits, total = total_hits + cov.hits, total + cov.trials
        print(_line(f"pooled {model}: truth in 90 % ETI", cov, time.perf_counter() - t0))
    print(f"{'pooled, both models':<48} {total_hits / total:7.1%}  (target 90 ± 4 %)")
    t0 = time.perf_counter()
    pop, ls = population_coverage(args.population_sets, train=4, held_out=10, seed=args.seed)
    dt = time.perf_counter() - t0
    print(_line("population predictive band: held-out curves", pop, dt))
    print(_line("paper's pooled sigma (Eq. 4) band: same curves", ls, 0))
    print(
        "(held-out trials are (curve, sinkage) points; points of one curve are correlated, so "
        "the se above understates the population figures' uncertainty)"
    )


if __name__ == "__main__":
    main()
