"""Running a subcommand: the campaign it analyses (:func:`prepared`) and its exit codes
(:func:`guarded`): 0 success, 2 bad input or usage (the message says what and where), 1 an
internal error (a bug: the message asks for a report).

Moved out of :mod:`.common` (issue #45: every module of cli/ within 300 lines); this module
imports nothing heavy either: ``soilstats --help`` must answer at once.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, TextIO, cast

import numpy as np

from .._text import plural
from ..errors import SoilstatsError, SoilstatsWarning
from ..outputs import Provenance
from ..outputs.outset import output_set

if TYPE_CHECKING:
    from ..campaign import Campaign
    from ..outputs import Provenance

__all__ = ["EXIT_INPUT", "EXIT_INTERNAL", "EXIT_OK", "check_out", "guarded", "prepared"]

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT = 0, 1, 2


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
    from ..campaign import load_campaign  # deferred: pandas
    from ..campaign.selection import apply_selection  # deferred: pandas
    from ..campaign.window import FitWindow  # deferred: pandas
    from ..quality import screen  # deferred: pandas

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


def check_out(folder: str | None) -> None:
    """Fail before any work if ``--out`` names an existing file (it must be a folder)."""
    if folder is not None and os.path.exists(folder) and not os.path.isdir(folder):
        raise NotADirectoryError(20, "not a folder", folder)


def guarded(run: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """Run a subcommand, mapping failures to exit codes and one-line messages.

    Bad input of any kind (a campaign or spec that breaks a rule, a missing or unreadable
    path, a directory where a file belongs, a refused overwrite) is exit 2 with the message;
    anything else is a bug: exit 1, with the traceback for the report.
    """

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


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """soilstats' own warnings as one line for the user, ``warning: <message>``: their text
    names the file, column and test; the library line that raised them is no help. Other
    warnings (numpy, scipy) keep Python's format, which says where they came from."""
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
