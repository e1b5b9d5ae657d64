"""Discover what the soil model gets wrong in a campaign: the cause, the extension, the gain.

Fits the base model (Bekker/Bernstein for sinkage, Janosi-Hanamoto for shear), tests every
test-log column and derived quantity for structure in what the model leaves (Holm-controlled
across all candidates), extends the model for the leading causes and measures the gain by
cross-validation over whole tests. Prints a readable summary, or with --json one JSON object
{"findings": [...], "flags": [...], ..., "provenance": {...}}; with --out, discover.json and
the PDF report discover.pdf in that folder. --jobs N spreads the per-test fits and the
cross-validation fits over N worker processes, with identical results.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..outputs import write_json
from .common import (
    ALPHA,
    add_common_options,
    add_data_options,
    add_jobs_option,
    defaults_not_given,
    prepared,
    progress_enabled,
)
from .main import run_subcommand


def configure(parser: argparse.ArgumentParser) -> None:
    """The discover subcommand's options."""
    add_common_options(parser, out_help="write discover.json and discover.pdf into DIR")
    add_data_options(parser)
    parser.add_argument(
        "--alpha",
        type=ALPHA,
        default=0.05,
        help="family-wise error rate in (0, 0.5] (default 0.05)",
    )
    add_jobs_option(parser, "the per-test fits and the cross-validation fits")


def run(args: argparse.Namespace) -> int:
    """Run discovery; print the summary (or JSON) and write the files asked for."""
    from ..discovery import discover  # deferred: statsmodels

    campaign, provenance = prepared(args)
    result = discover(
        campaign,
        alpha=args.alpha,
        seed=args.seed,
        progress=progress_enabled(args.progress),
        provenance=provenance,
        jobs=args.jobs,
    )
    if args.out:
        from ..report.discovery_pdf import write_report  # deferred: matplotlib

        folder = Path(args.out)

        defaults = defaults_not_given(args)
        document = {"defaults": defaults} | {
            k: v for k, v in result.to_dict().items() if k != "provenance"
        }
        json_path, pdf_path = folder / "discover.json", folder / "discover.pdf"
        # the path written is the staging folder's: the user is told where the set lands
        write_json(json_path, document, provenance, overwrite=args.overwrite)
        write_report(result, pdf_path, overwrite=args.overwrite, defaults=defaults)
        print(f"wrote {json_path} and {pdf_path}", file=sys.stderr)
    print(result.to_json() if args.json else result.summary())
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.discover ...``: the same as ``soilstats discover ...``."""
    return run_subcommand("discover", argv)
