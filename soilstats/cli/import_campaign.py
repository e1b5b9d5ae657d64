"""Convert a lab's own export into a campaign folder, with columns and units mapped.

MAPPING is a small TOML file that names the lab's CSV files (relative to the TOML file), maps
their columns onto the campaign format's columns with each column's unit (mm, kN, N*mm,
deg, ...) and may set constant test-log values; the format is documented in
docs/importing.md. The result is checked exactly like any campaign (and for implausible
units) before anything is written; --out receives tests.csv, sinkage.csv and/or shear.csv.
"""

from __future__ import annotations

import argparse
import json

from ..kinds import TEST_KINDS
from .common import add_common_options


def configure(parser: argparse.ArgumentParser) -> None:
    """The import subcommand's options."""
    parser.add_argument("mapping", metavar="MAPPING", help="the TOML mapping file")
    add_common_options(
        parser,
        data=False,
        select=False,
        out="required",
        out_help="write the converted campaign into DIR",
    )


def run(args: argparse.Namespace) -> int:
    """Import, validate, save; report what was written."""
    from ..campaign import import_campaign

    campaign = import_campaign(args.mapping)
    folder = campaign.save(args.out, overwrite=args.overwrite)
    kinds = campaign.tests["kind"].value_counts()
    counts = {k: int(kinds.get(k, 0)) for k in TEST_KINDS}
    if args.json:
        print(json.dumps({"out": str(folder), "tests": counts}))
    else:
        print(campaign.summary())
        print(f"\nwrote {len(campaign.tests)} tests to {folder}")
    return 0
