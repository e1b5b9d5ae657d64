"""Simulate a Bevameter campaign from a SPEC file, with its truth written beside the data.

Writes tests.csv, sinkage.csv and/or shear.csv (the campaign format), truth.json (soils,
planted effects, scatter, noise), truth_tests.csv (every test's drawn parameters) and a
README.md saying the data are simulated, from which SPEC and seed.  The same SPEC and seed
give byte-identical files.  The SPEC format is documented in docs/simulator.md.

Regenerate the bundled campaign (from the repository root):

  soilstats simulate soilstats/data/simulated-paper/spec.toml \\
      --out soilstats/data/simulated-paper --seed 2026 --overwrite
"""

from __future__ import annotations

import argparse
import json
import sys

from .common import add_common_options, progress_enabled
from .main import run_subcommand


def configure(parser: argparse.ArgumentParser) -> None:
    """The simulate subcommand's options."""
    parser.add_argument("spec", metavar="SPEC", help="SPEC file (TOML, see docs/simulator.md)")
    add_common_options(
        parser,
        data=False,
        select=False,
        out="required",
        out_help="write the simulated campaign (and its truth) into DIR",
    )


def run(args: argparse.Namespace) -> int:
    """Simulate, save, and report what was written."""
    from ..simulation import simulate  # deferred: pandas

    sim = simulate(args.spec, seed=args.seed, progress=progress_enabled(args.progress))
    folder = sim.save(args.out, overwrite=args.overwrite)
    kinds = sim.campaign.tests["kind"].value_counts()
    counts = {"sinkage": int(kinds.get("sinkage", 0)), "shear": int(kinds.get("shear", 0))}
    if args.json:
        print(json.dumps({"out": str(folder), "seed": args.seed, "tests": counts}))
    else:
        print(
            f"wrote {len(sim.campaign.tests)} simulated tests ({counts['sinkage']} sinkage, "
            f"{counts['shear']} shear) to {folder}",
            file=sys.stdout,
        )
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.simulate ...``: the same as ``soilstats simulate ...``."""
    return run_subcommand("simulate", argv)
