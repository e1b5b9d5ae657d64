"""What every subcommand shares: the common options, the selection grammar, exit codes.

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

Exit codes: 0 success, 2 bad input or usage (the message says what and where), 1 an internal
error (a bug: the message asks for a report).

This module imports nothing heavy: ``soilstats --help`` must answer at once.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import traceback
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TextIO, cast

from .._text import plural
from ..errors import InputError
from ..kinds import TEST_KINDS

if TYPE_CHECKING:
    from ..campaign import Campaign
    from ..outputs import Provenance

__all__ = [
    "DEFAULT_CAMPAIGN",
    "EXIT_INPUT",
    "EXIT_INTERNAL",
    "EXIT_OK",
    "Criterion",
    "add_common_options",
    "add_data_options",
    "apply_selection",
    "defaults_not_given",
    "guarded",
    "parse_selection",
    "prepared",
    "progress_enabled",
]

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT = 0, 1, 2

#: The campaign a command uses when ``--data`` is not given: the bundled simulation of the
#: paper's full design (the only bundled campaign with every test series the studies need).
DEFAULT_CAMPAIGN = "simulated-paper"


def _bundled() -> str:
    from ..data import bundled_names

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

    def parse(text: str):
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


def prepared(args: argparse.Namespace, *, out: TextIO | None = None) -> tuple[Campaign, Provenance]:
    """The campaign a command analyses and the provenance of its outputs.

    The campaign is loaded, screened (``--quality``), windowed (``--z-max``/``--p-max``)
    and selected (``--select``), in that order, so that screening rows are the file's rows.
    One line on stderr (or ``out``) says what screening found in the tests selected.

    The provenance hashes the records as the command received them — loaded, after
    ``--select`` — not as screening and the window left them: those are the command's own
    processing, recorded by its command line.  So every command on the same data and
    selection names the same ``campaign_sha256``, that of ``soilstats check``.
    """
    from ..campaign import load_campaign
    from ..campaign.window import FitWindow
    from ..outputs import Provenance
    from ..quality import screen

    loaded = load_campaign(args.data)
    provenance = Provenance.of(
        apply_selection(loaded, args.select), argv=args.argv, seed=getattr(args, "seed", None)
    )
    report = screen(loaded, getattr(args, "quality", "clean"))
    window = FitWindow.parse(getattr(args, "z_max", ()), getattr(args, "p_max", ()))
    screened = cast("Campaign", report.campaign)  # screen's report carries the campaign
    campaign = apply_selection(screened.windowed(window), args.select)
    if report.mode != "off":
        # Screening runs on the whole file (its rows are the file's rows), but the line
        # counts the tests the command uses: a failed test outside --select is no concern.
        used = report.for_tests(campaign.tests["test_id"])
        counts = used.counts
        excluded = len(used.excluded)
        scope = f", selection: {len(used.tests)} of {plural(len(report.tests), 'test')}"
        print(
            f"Data quality ({report.mode}{scope if args.select else ''}): "
            + (", ".join(f"{c} in {plural(n, 'test')}" for c, n in counts.items()) or "no findings")
            + (f"; {excluded} samples left out" if excluded else "")
            + " (details: soilstats check)",
            file=out or sys.stderr,
        )
    return campaign, provenance


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
    given = {token.split("=", 1)[0] for token in getattr(args, "argv", []) or []}
    out: dict[str, str] = {}
    for action in parser._actions:  # argparse keeps no public list of a parser's options
        if not action.option_strings or action.dest in _NOT_ANALYSIS:
            continue
        if given & set(action.option_strings):
            continue
        value = getattr(args, action.dest, None)
        if value is None or value is False or value == []:
            continue
        out[max(action.option_strings, key=len)] = (
            " ".join(map(str, value)) if isinstance(value, list | tuple) else str(value)
        )
    return out


def check_out(folder: str | None) -> None:
    """Fail before any work if ``--out`` names an existing file (it must be a folder)."""
    if folder is not None and os.path.exists(folder) and not os.path.isdir(folder):
        raise NotADirectoryError(20, "not a folder", folder)


def progress_enabled(choice: str) -> bool:
    """``--progress`` as a bool: on, off, or (auto) whether stderr is a terminal."""
    return {"on": True, "off": False}.get(choice, sys.stderr.isatty())


@dataclass(frozen=True)
class Criterion:
    """One ``--select [KIND:]COLUMN=VALUE`` item."""

    column: str
    text: str
    kind: str | None = None  # None: every test; "sinkage"/"shear": tests of that kind only

    def __str__(self) -> str:
        prefix = f"{self.kind}:" if self.kind else ""
        return f"{prefix}{self.column}={self.text}"


def parse_selection(items: Sequence[str]) -> list[Criterion]:
    """Parse ``--select`` items; a ``ValueError`` names the malformed one."""
    out = []
    for item in items:
        kind = None
        prefix, colon, rest = item.partition(":")
        if colon and prefix in TEST_KINDS:
            kind, item = prefix, rest
        column, sep, text = item.partition("=")
        if not sep or not column:
            raise InputError(
                f"--select takes [KIND:]COLUMN=VALUE (e.g. soil=soil01 or "
                f"sinkage:velocity_m_s=0.01), got {item!r}"
            )
        out.append(Criterion(column.strip(), text.strip(), kind))
    return out


def apply_selection(campaign: Campaign, items: Sequence[str] | Sequence[Criterion]) -> Campaign:
    """The campaign restricted to the ``--select`` criteria (all must hold).

    Each value is compared as its column's type: a numeric column takes a number (an error
    otherwise), a text column the text as given. A criterion with a kind applies only to
    that kind's tests. Unknown columns and criteria that keep nothing raise the campaign's
    own :class:`~soilstats.errors.CampaignError`.
    """
    import numpy as np
    import pandas as pd

    from ..campaign.matching import match_values
    from ..errors import CampaignError

    criteria = [c if isinstance(c, Criterion) else parse_selection([c])[0] for c in items]
    if not criteria:
        return campaign
    tests = campaign.tests
    masks, own, scopes = [], [], []
    for crit in criteria:
        if crit.column not in tests.columns:
            raise CampaignError(
                f"--select {crit}: no such column; the test log has {list(tests.columns)}",
                file=campaign.file_name("tests"),
                column=crit.column,
            )
        value: object = crit.text
        if pd.api.types.is_numeric_dtype(tests[crit.column]):
            try:
                value = float(crit.text)
            except ValueError:
                raise CampaignError(
                    f"--select {crit}: {crit.column!r} is a numeric column; give a number",
                    file=campaign.file_name("tests"),
                    column=crit.column,
                ) from None
        # The tests a criterion speaks about: all, or those of its kind (the others pass).
        scope = np.ones(len(tests), bool) if crit.kind is None else (tests["kind"] == crit.kind)
        scope = np.asarray(scope, dtype=bool)
        hit = match_values(tests[crit.column], value, crit.column)
        scopes.append(scope)
        own.append(hit & scope)
        masks.append(hit | ~scope)
    keep = np.logical_and.reduce(masks)
    if not keep.any():
        raise _kept_nothing(campaign, criteria, masks, own, scopes)
    return campaign.select(test_id=list(tests["test_id"][keep]))


def _kept_nothing(campaign, criteria, masks, own, scopes) -> Exception:
    """The error of a selection that keeps no test: the criteria that match nothing with the
    values present in their column (as ``Campaign.select`` says), or, when each matches some
    tests, every criterion with the values its column has among the tests meeting the others.
    """
    import numpy as np

    from ..campaign.matching import values_present
    from ..errors import CampaignError

    tests = campaign.tests

    def among(crit, rows) -> str:
        where = f" of the {crit.kind} tests" if crit.kind else ""
        return f"{crit.column}{where} has {values_present(tests.loc[rows, crit.column])}"

    empty = [i for i, hit in enumerate(own) if not hit.any()]
    if empty:
        why = "; ".join(
            f"{criteria[i]} matched none (values present: "
            f"{values_present(tests.loc[scopes[i], criteria[i].column])})"
            for i in empty
        )
    else:
        others = [
            np.logical_and.reduce([m for j, m in enumerate(masks) if j != i] or [scopes[i]])
            & scopes[i]
            for i in range(len(criteria))
        ]
        why = (
            f"each of {', '.join(map(str, criteria))} matches some tests, but no test meets "
            "all; among the tests meeting the other criteria, "
            + "; ".join(among(c, rows) for c, rows in zip(criteria, others, strict=True))
        )
    return CampaignError(
        f"--select kept no test: {why} — change the criteria",
        file=campaign.file_name("tests"),
        column=criteria[empty[0] if empty else 0].column,
    )


def guarded(run: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """Run a subcommand, mapping failures to exit codes and one-line messages.

    Bad input of any kind (a campaign or spec that breaks a rule, a missing or unreadable
    path, a directory where a file belongs, a refused overwrite) is exit 2 with the message;
    anything else is a bug: exit 1, with the traceback for the report.
    """
    import numpy as np

    from ..errors import SoilstatsError

    try:
        check_out(getattr(args, "out", None))
        # numpy's floating-point and runtime warnings never reach the user: the library
        # checks its numbers itself and says what is wrong in its own words (a
        # ConvergenceWarning, a health flag, an error naming the file and test).
        with warnings.catch_warnings(), np.errstate(all="ignore"):  # both restored afterwards
            warnings.showwarning = _show_warning
            warnings.filterwarnings("ignore", category=RuntimeWarning)
            out = getattr(args, "out", None)
            if out is None:
                return run(args)
            from ..outputs.outset import output_set

            # The whole run is one output set: locked, staged, swapped in at the end.
            command = " ".join(["soilstats", *map(str, getattr(args, "argv", []))])
            overwrite = bool(getattr(args, "overwrite", False))
            with output_set(out, command=command, overwrite=overwrite):
                return run(args)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (SoilstatsError, ValueError, OSError) as err:
        print(f"error: {_describe(err)}", file=sys.stderr)
        return EXIT_INPUT
    except Exception:
        traceback.print_exc()
        print(
            "internal error: this is a bug in soilstats; please report it with the command "
            "and the traceback above",
            file=sys.stderr,
        )
        return EXIT_INTERNAL


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """soilstats' own warnings as one line for the user, ``warning: <message>``: their text
    names the file, column and test; the library line that raised them is no help. Other
    warnings (numpy, scipy) keep Python's format, which says where they came from."""
    from ..errors import SoilstatsWarning

    stream = sys.stderr if file is None else file
    if issubclass(category, SoilstatsWarning):
        stream.write(f"warning: {message}\n")
    else:
        stream.write(warnings.formatwarning(message, category, filename, lineno, line))


def _describe(err: BaseException) -> str:
    if isinstance(err, OSError) and err.filename is not None:
        what = {
            FileNotFoundError: "no such file or folder",
            PermissionError: "permission denied",
            IsADirectoryError: "is a folder, a file was expected",
            NotADirectoryError: "is not a folder",
            FileExistsError: "exists already (give --overwrite to replace it)",
        }.get(type(err), err.strerror or type(err).__name__)
        return f"{os.fsdecode(err.filename)!s}: {what}"
    return str(err)
