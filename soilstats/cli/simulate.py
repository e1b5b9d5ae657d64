"""Simulate a Bevameter campaign from a SPEC file, with its truth written beside the data.

Writes tests.csv, sinkage.csv and/or shear.csv (the campaign format), truth.json (soils,
planted effects, scatter, noise), truth_tests.csv (every test's drawn parameters) and a
README.md saying the data are simulated, from which SPEC and seed.  The same SPEC and seed
give byte-identical files.  The SPEC format is documented in docs/simulator.md.

Regenerate the bundled campaign (from the repository root):

  python -m soilstats.simulate soilstats/data/simulated-paper/spec.toml \\
      soilstats/data/simulated-paper --seed 2026 --overwrite
"""

from __future__ import annotations

import argparse
import sys

from ..errors import CampaignError
from ..simulation import SpecError, simulate


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m soilstats.simulate",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("spec", metavar="SPEC", help="SPEC file (TOML, see docs/simulator.md)")
    parser.add_argument("out", metavar="OUT", help="output folder (created if needed)")
    parser.add_argument(
        "--seed",
        type=int,
        required=True,
        help="seed of numpy.random.default_rng (the only source of randomness)",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace campaign and truth files already in OUT"
    )
    parser.add_argument(
        "--progress",
        choices=("auto", "on", "off"),
        default="auto",
        help="tqdm progress bar on stderr (auto: only on a terminal)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    progress = {"on": True, "off": False, "auto": sys.stderr.isatty()}[args.progress]
    try:
        sim = simulate(args.spec, seed=args.seed, progress=progress)
        folder = sim.save(args.out, overwrite=args.overwrite)
    except (SpecError, CampaignError, FileExistsError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    kinds = sim.campaign.tests["kind"].value_counts()
    print(
        f"wrote {len(sim.campaign.tests)} simulated tests ({int(kinds.get('sinkage', 0))} "
        f"sinkage, {int(kinds.get('shear', 0))} shear) to {folder}"
    )
    return 0
