"""Run setup-effect studies of the paper's Sections 3-4 and write their reports.

NAME is a shipped study (preparation, velocity, tool-shape, shear-ring, grousers,
grouser-height, shear-velocity), 'all' for every shipped study, or the path of a study
specification (.toml; format in docs/studies.md — copy a shipped one from the 'studies'
folder of the repository and change it).

Each study selects its tests, fits every test on its own (Bernstein k, n per plate test;
steady-state shear stress per ring test), tests the factor per soil (ANOVA with blocking
factors and Tukey pairs, or ANCOVA of the Mohr-Coulomb lines), adjusts the p-values (Holm)
and states a verdict per soil and response; the preparation study also scores the methods
by the criteria of Table 1, as Table 3.

Writes into --out: NAME.pdf (report with figures), NAME.json (verdicts, parameter tables)
and NAME_*.csv tables.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..campaign import bundled_campaigns, load_campaign
from ..errors import CampaignError

DEFAULT_DATA = "simulated-paper"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m soilstats.study",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("name", metavar="NAME", help="study name, 'all', or a .toml path")
    parser.add_argument(
        "--data",
        default=DEFAULT_DATA,
        help=f"campaign folder or bundled name ({', '.join(bundled_campaigns())}); "
        f"default {DEFAULT_DATA}",
    )
    parser.add_argument("--out", default="reports", help="output folder (default reports/)")
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        help="seed for any random step (recorded in the outputs; the shipped studies draw "
        "no random numbers)",
    )
    parser.add_argument("--no-pdf", action="store_true", help="JSON and CSV only")
    parser.add_argument(
        "--progress",
        choices=("auto", "on", "off"),
        default="auto",
        help="tqdm progress bars on stderr (auto: when it is a terminal)",
    )
    return parser


def run(args: argparse.Namespace, out=sys.stdout) -> int:
    from ..study import available_studies, load_spec, run_study, write_outputs, write_report
    from ..study.responses import PerTestCache

    names = available_studies() if args.name == "all" else [args.name]
    specs = [load_spec(n) for n in names]  # every spec checked before any work
    campaign = load_campaign(args.data)
    progress = args.progress == "on" or (args.progress == "auto" and sys.stderr.isatty())
    cache = PerTestCache(campaign, progress=progress)
    out_dir = Path(args.out)
    print(f"Campaign: {campaign.source}   output: {out_dir}/", file=out)
    if progress:
        from tqdm.auto import tqdm

        specs_iter = tqdm(specs, desc="studies", unit="study")
    else:
        specs_iter = specs
    timings = []
    for spec in specs_iter:
        start = time.perf_counter()
        result = run_study(spec, campaign, cache=cache, progress=progress, seed=args.seed)
        write_outputs(result, out_dir)
        pages = 0 if args.no_pdf else write_report(result, campaign, out_dir / f"{spec.name}.pdf")
        seconds = time.perf_counter() - start
        timings.append((spec.name, seconds))
        print("\n" + result.summary(), file=out)
        print(
            f"  -> {out_dir / spec.name}.json, .pdf ({pages} pages), CSV;  {seconds:.1f} s",
            file=out,
        )
    if len(timings) > 1:
        print(
            "\nTime per study: "
            + ", ".join(f"{n} {s:.1f} s" for n, s in timings)
            + f"; total {sum(s for _, s in timings):.1f} s",
            file=out,
        )
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return run(args)
    except (CampaignError, ValueError) as err:  # SpecError, StudyDataError are ValueErrors
        print(f"error: {err}", file=sys.stderr)
        return 2
