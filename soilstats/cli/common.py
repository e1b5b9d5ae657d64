"""What every subcommand shares: the common options (the selection grammar:
:mod:`soilstats.campaign.selection`; running and exit codes: :mod:`.running`).

One option means one thing in every subcommand:

``--data CAMPAIGN``
    the campaign: a folder, or the name of a bundled campaign (default
    :data:`DEFAULT_CAMPAIGN`).
``--out DIR``
    the folder the command writes its files into (created if needed); an existing file is
    never replaced unless ``--overwrite`` is given.
``--select [KIND:]COLUMN=VALUE``
    keep only tests whose test-log COLUMN equals VALUE (repeatable; all must hold). VALUE is
    compared as the column's type: numbers as numbers, text as text. A ``sinkage:`` or
    ``shear:`` prefix applies the criterion to that kind of test only; the other kind's tests
    are kept.
``--seed N``
    the seed of every random step (default 0); recorded in every output.
``--progress {auto,on,off}``
    tqdm progress bars on stderr (auto: only when stderr is a terminal).
``--json``
    print one JSON object on stdout instead of the readable report (messages go to stderr).

Exit codes (:mod:`.running`): 0 success, 2 bad input or usage (the message says what and
where), 1 an internal error (a bug: the message asks for a report).

This module imports nothing heavy: ``soilstats --help`` must answer at once.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Sequence
from typing import Any

from ..data import bundled_names
from .running import EXIT_INPUT, EXIT_INTERNAL, EXIT_OK, guarded, prepared

__all__ = [
    "DEFAULT_CAMPAIGN",
    "EXIT_INPUT",
    "EXIT_INTERNAL",
    "EXIT_OK",
    "add_common_options",
    "add_data_options",
    "defaults_not_given",
    "guarded",
    "prepared",
    "progress_enabled",
]

#: The campaign a command uses when ``--data`` is not given: the bundled simulation of the
#: paper's full design (the only bundled campaign with every test series the studies need).
DEFAULT_CAMPAIGN = "simulated-paper"


def _bundled() -> str:
    return ", ".join(bundled_names())


def add_common_options(
    parser: argparse.ArgumentParser,
    *,
    data: bool = True,
    out: str | None = "optional",
    select: bool = True,
    default_out: str | None = None,
    out_help: str = "",
) -> None:
    """Add the shared options (see the module docstring) to one subcommand's parser.

    ``out`` is ``"optional"``, ``"required"`` or None (the command writes no files).
    """
    if data:
        parser.add_argument(
            "folder",
            nargs="?",
            default=None,
            metavar="CAMPAIGN",
            help="campaign folder or bundled name, as --data (either, not both)",
        )
        parser.add_argument(
            "--data",
            metavar="CAMPAIGN",
            default=None,
            help=f"campaign folder or bundled name ({_bundled()}); default {DEFAULT_CAMPAIGN}",
        )
    if out is not None:
        parser.add_argument(
            "--out",
            metavar="DIR",
            required=out == "required",
            default=default_out,
            help=(out_help or "write the output files into DIR (created if needed)")
            + (f"; default {default_out}/" if default_out else ""),
        )
        parser.add_argument(
            "--overwrite", action="store_true", help="replace output files that already exist"
        )
    if select:
        parser.add_argument(
            "--select",
            action="append",
            default=[],
            metavar="[KIND:]COLUMN=VALUE",
            help="only tests whose test-log COLUMN equals VALUE (repeatable, all must hold); "
            "a sinkage: or shear: prefix limits the criterion to that kind of test",
        )
    parser.add_argument(
        "--seed",
        type=_seed,
        default=0,
        help="seed of every random step, an integer >= 0 (default 0; recorded)",
    )
    parser.add_argument(
        "--progress",
        choices=("auto", "on", "off"),
        default="auto",
        help="tqdm progress bars on stderr (auto: only on a terminal)",
    )
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object on stdout instead of text"
    )


def resolve_campaign(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    """Set ``args.data`` from the positional CAMPAIGN or ``--data`` (default
    :data:`DEFAULT_CAMPAIGN`); both given is a usage error, not a silent choice."""
    if not hasattr(args, "data"):
        return
    folder = getattr(args, "folder", None)
    if folder is not None and args.data is not None and folder != args.data:
        parser.error(f"campaign given twice: {folder!r} and --data {args.data!r}; give one")
    args.data = folder or args.data or DEFAULT_CAMPAIGN


def add_jobs_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--jobs N``: worker processes over ``what`` (soilstats.parallel, joblib)."""
    parser.add_argument(
        "--jobs",
        type=JOBS,
        default=1,
        metavar="N",
        help=f"worker processes over {what} (joblib; -1: every core; default 1); the results "
        "are identical for any N",
    )


def add_data_options(parser: argparse.ArgumentParser, *, window: bool = True) -> None:
    """``--quality`` (data screening) and, for sinkage fits, the window ``--z-max``/``--p-max``."""
    parser.add_argument(
        "--quality",
        choices=("off", "flag", "clean"),
        default="clean",
        help="data screening (soilstats check): clean (default) leaves spikes and pre-contact "
        "samples out of every fit; flag only reports; off checks nothing",
    )
    if not window:
        return
    parser.add_argument(
        "--z-max",
        action="append",
        default=[],
        metavar="[COLUMN=VALUE:]LIMIT",
        help="fit sinkage only up to LIMIT m, for every test or those whose test-log COLUMN "
        "equals VALUE (repeatable, e.g. --z-max radius_m=0.038:0.0034)",
    )
    parser.add_argument(
        "--p-max",
        action="append",
        default=[],
        metavar="[COLUMN=VALUE:]LIMIT",
        help="fit sinkage only up to pressure LIMIT Pa (as --z-max)",
    )


def number_in(
    kind: type, low: float, high: float, *, low_open: bool = False, high_open: bool = False
) -> Callable[[str], Any]:
    """An argparse ``type``: a finite ``kind`` (int or float) in [low, high] (``low_open``,
    ``high_open``: that end excluded).  ``nan``, ``inf`` and out-of-range numbers are usage
    errors (exit 2) naming the range, never passed on to fail later (``--alpha nan``)."""
    lo, hi = ("(" if low_open else "["), (")" if high_open else "]")
    what = "a whole number" if kind is int else "a finite number"

    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except (TypeError, ValueError):
            value = None
        inside = (
            value is not None
            and math.isfinite(value)
            and (low < value if low_open else low <= value)
            and (value < high if high_open else value <= high)
        )
        if not inside:
            raise argparse.ArgumentTypeError(
                f"must be {what} in {lo}{low:g}, {high:g}{hi}, got {text!r}"
            )
        return value

    parse.__name__ = kind.__name__  # argparse names the type in its messages
    return parse


#: ``--alpha``: a family-wise error rate.
ALPHA = number_in(float, 0.0, 0.5, low_open=True)
#: ``--jobs``: -1 every core, −2 all but one, …, at most 1024 workers.
JOBS = number_in(int, -1024, 1024)


def _seed(text: str) -> int:
    """``--seed``: numpy's generators take non-negative integers only."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}")
    return value


#: Options that change what is computed, never listed as defaults: where output goes, how
#: it is shown, how fast it runs.
_NOT_ANALYSIS = {
    "help",
    "version",
    "out",
    "overwrite",
    "progress",
    "json",
    "jobs",
    "verbose",
    "select",
    "data",
    "campaign",
    "argv",
}


def defaults_not_given(args: argparse.Namespace) -> dict[str, str]:
    """``{"--option": "value"}`` for every analysis option the user left at its default
    (the JSON's ``"defaults"``, page 1 of the report): what the result rests on without the
    user having said so. Output, display and speed options are left out."""
    parser = getattr(args, "_parser", None)
    if parser is None:
        return {}
    tokens = [str(t) for t in getattr(args, "argv", []) or [] if str(t).startswith("-")]
    out: dict[str, str] = {}
    for action in parser._actions:  # argparse keeps no public list of a parser's options
        if not action.option_strings or action.dest in _NOT_ANALYSIS:
            continue
        if any(_names(token, action.option_strings) for token in tokens):
            continue
        value = getattr(args, action.dest, None)
        if value is None or value is False or value == []:
            continue
        out[max(action.option_strings, key=len)] = (
            " ".join(map(str, value)) if isinstance(value, list | tuple) else str(value)
        )
    return out


def _names(token: str, options: Sequence[str]) -> bool:
    """Whether a command-line ``token`` gives one of ``options``: whole (``--seed``,
    ``--seed=3``), abbreviated as argparse allows (``--see 3``) or short with its value
    attached (``-s3``)."""
    if token.startswith("--"):
        name = token.split("=", 1)[0]
        if name == "--":  # the end of the options, not one of them
            return False
        return any(o.startswith("--") and o.startswith(name) for o in options)
    return any(len(o) == 2 and token[:2] == o for o in options)


def progress_enabled(choice: str) -> bool:
    """``--progress`` as a bool: on, off, or (auto) whether stderr is a terminal."""
    return {"on": True, "off": False}.get(choice, sys.stderr.isatty())
