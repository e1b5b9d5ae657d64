"""Convert a lab's own export into a campaign folder, with columns and units mapped.

MAPPING is a small TOML file that names the lab's CSV files (relative to the TOML file), maps
their columns onto the campaign format's columns with each column's unit (mm, kN, N*mm,
deg, ...) and may set constant test-log values; the format is documented in
docs/importing.md. The result is checked exactly like any campaign (and for implausible
units) before anything is written; a reversed sign or a unit slip the mapping does not state
is refused. --out receives tests.csv, sinkage.csv and/or shear.csv, and import.json: the
source files with their SHA-256, the mapping and the soilstats version.
"""

from __future__ import annotations

import argparse
import json

from ..kinds import TEST_KINDS
from ..outputs.files import output_path, write_atomic
from .common import add_common_options


def configure(parser: argparse.ArgumentParser) -> None:
    """The import subcommand's options."""
    parser.add_argument("mapping", metavar="MAPPING", help="the TOML mapping file")
    parser.add_argument(
        "--skip-rows",
        type=int,
        default=None,
        metavar="N",
        help="lines above the header line of the record files (sinkage, shear), overriding "
        "the mapping's skip_rows for a one-off file",
    )
    add_common_options(
        parser,
        data=False,
        select=False,
        out="required",
        out_help="write the converted campaign into DIR",
    )


def run(args: argparse.Namespace) -> int:
    """Import, validate, save; report what was written."""
    from ..campaign.importing import import_campaign_record  # deferred: pandas

    campaign, record = import_campaign_record(args.mapping, skip_rows=args.skip_rows)
    folder = campaign.save(args.out, overwrite=args.overwrite)
    # What was imported from where, beside the campaign (load_campaign ignores it).
    target = output_path(folder, "import.json", overwrite=True)
    write_atomic(target, json.dumps(record.to_dict(), indent=2, sort_keys=True) + "\n")
    kinds = campaign.tests["kind"].value_counts()
    counts = {k: int(kinds.get(k, 0)) for k in TEST_KINDS}
    if args.json:
        print(json.dumps({"out": str(folder), "tests": counts}))
    else:
        print(campaign.summary())
        print(f"\nwrote {len(campaign.tests)} tests to {folder}")
    return 0
