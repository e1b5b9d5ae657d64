"""Identify the soil parameters of a campaign per soil and condition, as the paper's Table 5.

For each soil, the sinkage tests are grouped by one test-log column (``--by``; by default the
first of velocity_m_s, preparation that varies) and each group is fitted with the paper's
weighted Levenberg–Marquardt.  Bekker needs two or more plate sizes in a group; where a group
has only one, the Bernstein model is used instead and the table says so.  Shear tests, where
present, are fitted with Mohr–Coulomb on their steady-state parts, grouped by ``--shear-by``
(default: the first of tool, r_inner_m that varies).

Campaigns with a ``series`` column (the bundled simulated-paper campaign) hold several test
series that share soils and velocities; by default the sinkage table uses the ``velocity``
series and the shear table the ``shear-ring`` series, as the paper's Tables 5 and 6.  Use
``--series NAME`` or ``--select COLUMN=VALUE`` (repeatable) to choose others.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ..campaign import bundled_campaigns, load_campaign
from ..errors import CampaignError, ConvergenceError, IdentifiabilityError
from ..identification import fit_shear, fit_sinkage
from ..identification.table import format_parameter_table

DEFAULT_DATA = "cullinan-sand"
_GROUPING_CANDIDATES = ("velocity_m_s", "preparation")
_SHEAR_GROUPING_CANDIDATES = ("tool", "r_inner_m")
_DEFAULT_SERIES = {"sinkage": "velocity", "shear": "shear-ring"}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m soilstats.identify",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--data",
        default=DEFAULT_DATA,
        help=f"campaign folder or bundled name ({', '.join(bundled_campaigns())}); "
        f"default {DEFAULT_DATA}",
    )
    parser.add_argument(
        "--model",
        choices=("auto", "bekker", "bernstein", "reece"),
        default="auto",
        help="sinkage model (auto: Bekker where 2+ plate sizes)",
    )
    parser.add_argument(
        "--by",
        default=None,
        help="test-log column that defines the conditions (default: "
        "velocity_m_s, else preparation, whichever varies)",
    )
    parser.add_argument(
        "--shear-by",
        default=None,
        help="test-log column defining shear conditions (default: tool, else "
        "r_inner_m, whichever varies)",
    )
    parser.add_argument(
        "--series",
        default=None,
        help="only tests of this series (campaigns with a 'series' column; "
        "default: velocity for sinkage, shear-ring for shear)",
    )
    parser.add_argument(
        "--select",
        action="append",
        default=[],
        metavar="COLUMN=VALUE",
        help="only tests whose COLUMN equals VALUE (repeatable)",
    )
    parser.add_argument("--soil", action="append", help="only this soil (repeatable)")
    parser.add_argument("--method", choices=("lm", "wong"), default="lm")
    parser.add_argument("--points-per-test", type=int, default=100)
    parser.add_argument("--verbose", action="store_true", help="print every fit's summary()")
    return parser


def _grouping(tests, requested, candidates=_GROUPING_CANDIDATES):
    if requested:
        if requested not in tests.columns:
            raise CampaignError(
                f"--by {requested!r} is not a test-log column; columns: {list(tests.columns)}",
                file="tests.csv",
                column=requested,
            )
        return requested
    for column in candidates:
        if column in tests.columns and tests[column].dropna().nunique() > 1:
            return column
    return None


def _label(value) -> str:
    if isinstance(value, float | np.floating):
        return f"{value:g}"
    return str(value)


def _parse_select(items: list[str]) -> dict[str, str]:
    selection = {}
    for item in items:
        column, sep, value = item.partition("=")
        if not sep or not column:
            raise ValueError(f"--select takes COLUMN=VALUE, got {item!r}")
        selection[column] = value
    return selection


def _apply_filters(campaign, kind: str, args) -> object:
    """The campaign restricted to --select and the series to tabulate for ``kind``."""
    selection = _parse_select(args.select)
    chosen = campaign
    for column, text in selection.items():
        if column not in chosen.tests.columns:
            raise CampaignError(
                f"--select: no column {column!r}; columns: {list(chosen.tests.columns)}",
                file="tests.csv",
                column=column,
            )
        values = chosen.tests[column]
        # Compare as the column's own type: numbers as numbers, text as text.
        numeric = np.issubdtype(values.dtype, np.number)
        chosen = chosen.select(**{column: float(text) if numeric else text})
    tests = chosen.tests
    if "series" in tests.columns and "series" not in selection:
        series = args.series or _DEFAULT_SERIES[kind]
        present = set(tests.loc[tests["kind"] == kind, "series"].dropna().astype(str))
        if series in present:
            chosen = chosen.select(
                series=lambda col, s=series: (col.astype(str) == s) | (chosen.tests["kind"] != kind)
            )
        elif args.series:
            raise CampaignError(
                f"--series {series!r} has no {kind} tests; series present: {sorted(present)}",
                file="tests.csv",
                column="series",
            )
    return chosen


def run(args: argparse.Namespace, out=sys.stdout) -> int:
    full = load_campaign(args.data)
    print(f"Campaign: {full.source}", file=out)
    soils = args.soil or sorted(full.tests["soil"].astype(str).unique())
    for kind in ("sinkage", "shear"):
        if not (full.tests["kind"] == kind).any():
            continue
        campaign = _apply_filters(full, kind, args)
        tests = campaign.tests
        kind_tests = tests[tests["kind"] == kind]
        if kind_tests.empty:
            continue
        by = (
            _grouping(kind_tests, args.by)
            if kind == "sinkage"
            else _grouping(kind_tests, args.shear_by, _SHEAR_GROUPING_CANDIDATES)
        )
        if "series" in kind_tests.columns and kind_tests["series"].nunique() == 1:
            print(f"\n[{kind}: series {kind_tests['series'].iloc[0]!r}]", file=out)
        for soil in soils:
            sub = kind_tests[kind_tests["soil"].astype(str) == soil]
            if sub.empty:
                continue
            values = sorted(sub[by].dropna().unique()) if by else [None]
            fits, failures = {}, []
            model_used = set()
            for value in values:
                selection = {"soil": soil}
                if by:
                    selection[by] = value
                label = _label(value) if by else "all"
                try:
                    if kind == "sinkage":
                        model = args.model
                        if model == "auto":
                            group = sub if not by else sub[sub[by] == value]
                            model = "bekker" if group["b_m"].nunique() > 1 else "bernstein"
                        fit = fit_sinkage(
                            campaign,
                            model,
                            method=args.method,
                            points_per_test=args.points_per_test,
                            **selection,
                        )
                        model_used.add(model)
                    else:
                        fit = fit_shear(campaign, "mohr-coulomb", **selection)
                        model_used.add("mohr-coulomb")
                except (ConvergenceError, IdentifiabilityError, CampaignError) as err:
                    failures.append(f"{label}: {err}")
                    continue
                fits[label] = fit
                if args.verbose:
                    print(fit.summary(), file=out)
            title = (
                f"\n{kind} · {soil} · {', '.join(sorted(model_used))} · conditions by "
                f"{by or '(all tests)'}"
            )
            if fits:
                print(format_parameter_table(fits, title=title), file=out)
            for failure in failures:
                print(f"  ! not identified — {failure}", file=out)
            if kind == "sinkage" and "bernstein" in model_used and args.model == "auto":
                print(
                    "  note: one plate size per condition, so Bekker's kc and kphi cannot be "
                    "separated (Section 2.1 needs two or more); Bernstein k, n shown.",
                    file=out,
                )
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return run(args)
    except (CampaignError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
