"""Screen a campaign's records for data-quality problems (codes explained in docs/quality.md).

Every test is run through the screening rules (spikes, implausible units, pre-contact
segments, a displacement zeroed after contact, load-capped tests, bearing failure, copied
records, a force zero drifting with test order, non-monotone sinkage, saturation). The report
lists each finding with its test, code and file rows, what the default cleaning leaves out
of fits, and the sinkage windows that bearing failure proposes. Units are judged here, not
at loading, so a campaign in the wrong unit is reported rather than refused.

Example:  soilstats check --data grc1-oravec2009 --out reports/
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..outputs import Provenance, json_safe, write_json
from .common import add_common_options, defaults_not_given
from .main import run_subcommand


def configure(parser: argparse.ArgumentParser) -> None:
    """The check subcommand's options."""
    add_common_options(
        parser, select=False, out_help="also write check.json and check.pdf into DIR"
    )
    parser.add_argument(
        "--quality",
        choices=("flag", "clean"),
        default="clean",
        help="clean (default): say which samples the analyses leave out; flag: report only",
    )


def run(args: argparse.Namespace) -> int:
    """Screen the campaign and print the findings (or one JSON object)."""
    from ..campaign import load_campaign  # deferred: pandas
    from ..quality import screen  # deferred: pandas

    campaign = load_campaign(args.data, check_units=False)
    report = screen(campaign, args.quality)
    provenance = Provenance.of(campaign, argv=args.argv, seed=args.seed)
    defaults = defaults_not_given(args)
    document = {"defaults": defaults} | report.to_dict()
    if args.out:
        from ..report.check_pdf import write_report  # deferred: pandas

        folder = Path(args.out)
        write_json(folder / "check.json", document, provenance, overwrite=args.overwrite)
        write_report(
            report,
            folder / "check.pdf",
            campaign=campaign,
            provenance=provenance,
            overwrite=args.overwrite,
            defaults=defaults,
        )
        print(f"wrote {folder / 'check.json'} and check.pdf", file=sys.stderr)
    if args.json:
        document |= {"provenance": provenance.to_dict()}
        print(json.dumps(json_safe(document), indent=2, ensure_ascii=False))
    else:
        print(f"Campaign: {campaign.source}")
        print(report.summary())
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.check ...``: the same as ``soilstats check ...``."""
    return run_subcommand("check", argv)
