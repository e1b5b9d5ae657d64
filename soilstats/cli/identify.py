"""Identify the soil parameters of a campaign per soil and condition, as the paper's Table 5.

For each soil, the sinkage tests are grouped by one test-log column (``--by``; by default the
first of velocity_m_s, preparation that varies) and each group is fitted with the paper's
weighted Levenberg–Marquardt.  Bekker needs two or more plate sizes in a group; where a group
has only one, the Bernstein model is used instead and the table says so.  Shear tests, where
present, are fitted with Mohr–Coulomb on their steady-state parts, grouped the same way.
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
    parser.add_argument("--soil", action="append", help="only this soil (repeatable)")
    parser.add_argument("--method", choices=("lm", "wong"), default="lm")
    parser.add_argument("--points-per-test", type=int, default=100)
    parser.add_argument("--verbose", action="store_true", help="print every fit's summary()")
    return parser


def _grouping(tests, requested):
    if requested:
        if requested not in tests.columns:
            raise CampaignError(
                f"--by {requested!r} is not a test-log column; columns: {list(tests.columns)}",
                file="tests.csv",
                column=requested,
            )
        return requested
    for column in _GROUPING_CANDIDATES:
        if column in tests.columns and tests[column].dropna().nunique() > 1:
            return column
    return None


def _label(value) -> str:
    if isinstance(value, float | np.floating):
        return f"{value:g}"
    return str(value)


def run(args: argparse.Namespace, out=sys.stdout) -> int:
    campaign = load_campaign(args.data)
    print(f"Campaign: {campaign.source}", file=out)
    tests = campaign.tests
    soils = args.soil or sorted(tests["soil"].astype(str).unique())
    for kind in ("sinkage", "shear"):
        kind_tests = tests[tests["kind"] == kind]
        if kind_tests.empty:
            continue
        by = _grouping(kind_tests, args.by)
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
