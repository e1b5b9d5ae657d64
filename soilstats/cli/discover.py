"""Discover what the soil model gets wrong in a campaign: the cause, the extension, the gain.

Fits the base model (Bekker/Bernstein for sinkage, Janosi–Hanamoto for shear), tests every
test-log column and derived quantity for structure in what the model leaves (Holm-controlled
across all candidates), extends the model for the leading causes and measures the gain by
cross-validation over whole tests.  Prints a readable summary, or with --json one JSON object
{"findings": [...], "flags": [...], ...}; with --out a PDF report in that folder.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..campaign import bundled_campaigns
from ..errors import CampaignError


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m soilstats.discover",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "campaign",
        metavar="CAMPAIGN_DIR",
        help=f"campaign folder or bundled name ({', '.join(bundled_campaigns())})",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object to stdout")
    parser.add_argument("--out", metavar="DIR", help="write the PDF report discover.pdf here")
    parser.add_argument("--alpha", type=float, default=0.05, help="family-wise error rate")
    parser.add_argument("--seed", type=int, default=0, help="seed of the cross-validation folds")
    parser.add_argument(
        "--progress",
        choices=("auto", "on", "off"),
        default="auto",
        help="tqdm progress bars on stderr (auto: only on a terminal)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from ..discovery import discover

    progress = {"on": True, "off": False, "auto": sys.stderr.isatty()}[args.progress]
    try:
        result = discover(args.campaign, alpha=args.alpha, seed=args.seed, progress=progress)
    except (CampaignError, ValueError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.out:
        from ..discovery.report import write_report

        path = write_report(result, Path(args.out))
        print(f"wrote {path}", file=sys.stderr)
    if args.json:
        print(result.to_json())
    else:
        print(result.summary())
    return 0
