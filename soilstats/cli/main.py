"""``soilstats``: the one command-line front door (also ``python -m soilstats``).

Each subcommand lives in its own module of this package with ``configure(parser)`` (its
options; cheap, no heavy imports) and ``run(args) -> int`` (the work). The shared options and
the exit codes are those of :mod:`soilstats.cli.common`.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from .._version import __version__
from .common import guarded, resolve_campaign

# name -> (module of soilstats.cli, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "study": ("study", "run setup-effect studies (Sections 3-4) and write their reports"),
    "discover": ("discover", "find what the soil model gets wrong, name the cause, extend it"),
    "check": ("check", "screen the records for spikes, wrong units, seating offsets, failure"),
    "identify": ("identify", "identify soil parameters per soil and condition (Tables 5-6)"),
    "posterior": ("posterior", "sample parameter posteriors; joint draws for rover Monte Carlo"),
    "wheel": ("wheel", "predict measured wheel runs from plate tests: coverage, bias, what fails"),
    "simulate": ("simulate", "simulate a campaign from a specification, with its truth"),
    "import": ("import_campaign", "convert a lab's export into the campaign format (TOML map)"),
}

_DESCRIPTION = """\
Bevameter measurements in, soil parameters out, with honest uncertainty.

The method is that of M. Apfelbeck, S. Kuß, B. Rebele, B. Schäfer, "A systematic approach to
reliably characterize soils based on Bevameter testing", Journal of Terramechanics 48(5),
360-371, 2011. 'soilstats SUBCOMMAND --help' describes each subcommand; the options --data,
--out, --select, --seed, --progress and --json mean the same in all of them.

exit codes: 0 success, 2 bad input or usage, 1 internal error."""


def _version() -> str:
    return f"soilstats {__version__}"


def build_parser(prog: str = "soilstats") -> argparse.ArgumentParser:
    """The full parser, every subcommand configured (imports only the light CLI modules)."""
    parser = argparse.ArgumentParser(
        prog=prog, description=_DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=_version())
    subparsers = parser.add_subparsers(dest="command", metavar="SUBCOMMAND", required=True)
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        module = importlib.import_module(f".{module_name}", __package__)
        sub = subparsers.add_parser(
            name,
            help=help_text,
            description=module.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        sub.add_argument("--version", action="version", version=_version())
        module.configure(sub)
        sub.set_defaults(_run=module.run, _parser=sub)
    return parser


def main(argv: Sequence[str] | None = None, prog: str = "soilstats") -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``) and run the subcommand; return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(prog)
    try:
        args = parser.parse_args(argv)
        resolve_campaign(args, args._parser)
    except SystemExit as exit_:  # argparse: 0 for --help/--version, 2 for usage errors
        return int(exit_.code or 0)
    args.argv = argv
    return guarded(args._run, args)


def run_subcommand(name: str, argv: Sequence[str] | None = None) -> int:
    """``python -m soilstats.<name>``-style entry: ``soilstats NAME ARGV...``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return main([name, *argv])
