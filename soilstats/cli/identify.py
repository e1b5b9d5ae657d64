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
import json
import sys
from pathlib import Path

from .common import add_common_options, apply_selection, parse_selection

_GROUPING_CANDIDATES = ("velocity_m_s", "preparation")
_SHEAR_GROUPING_CANDIDATES = ("tool", "r_inner_m")
_DEFAULT_SERIES = {"sinkage": "velocity", "shear": "shear-ring"}


def configure(parser: argparse.ArgumentParser) -> None:
    """The identify subcommand's options."""
    add_common_options(
        parser, out_help="also write identify.json and identify.csv (every fit) into DIR"
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
    parser.add_argument("--soil", action="append", help="only this soil (repeatable)")
    parser.add_argument(
        "--method",
        choices=("lm", "wong"),
        default="lm",
        help="lm: the paper's weighted Levenberg-Marquardt; wong: Wong's log-log method",
    )
    parser.add_argument(
        "--points-per-test",
        type=int,
        default=100,
        help="samples per test after equal-sinkage thinning (Section 2.1; default 100)",
    )
    parser.add_argument("--verbose", action="store_true", help="print every fit's summary()")


def _grouping(tests, requested, candidates=_GROUPING_CANDIDATES):
    from ..errors import CampaignError

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
    import numpy as np

    if isinstance(value, float | np.floating):
        return f"{value:g}"
    return str(value)


def _series_filter(campaign, kind: str, args):
    """The campaign restricted to the series to tabulate for ``kind``, or None to skip ``kind``.

    Only campaigns with a ``series`` column have series. ``--series`` names one for every
    kind that has it (a kind without it is skipped); without it, each kind's default series
    is used where present. ``--select series=...`` takes precedence over both.
    """
    tests = campaign.tests
    if "series" not in tests.columns or any(
        c.column == "series" for c in parse_selection(args.select)
    ):
        return campaign
    series = args.series or _DEFAULT_SERIES[kind]
    present = set(tests.loc[tests["kind"] == kind, "series"].dropna().astype(str))
    if series in present:
        keep = (tests["series"].astype(str) == series) | (tests["kind"] != kind)
        return campaign.select(test_id=list(tests["test_id"][keep]))
    return None if args.series else campaign


def _check_series(campaign, args) -> None:
    from ..errors import CampaignError

    tests = campaign.tests
    if args.series is None:
        return
    present = set(tests["series"].dropna().astype(str)) if "series" in tests.columns else set()
    if args.series not in present:
        raise CampaignError(
            f"--series {args.series!r}: no such series; series present: {sorted(present)}",
            file="tests.csv",
            column="series",
        )


def _fit_soil(campaign, kind: str, soil: str, by, sub, args):
    """Fit every condition of one soil; return ({model: {label: fit}}, failures)."""
    from ..errors import ConvergenceError, IdentifiabilityError
    from ..identification import fit_shear, fit_sinkage

    values = sorted(sub[by].dropna().unique()) if by else [None]
    fits: dict[str, dict] = {}
    failures = []
    for value in values:
        selection = {"soil": soil} | ({by: value} if by else {})
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
            else:
                model = "mohr-coulomb"
                fit = fit_shear(campaign, model, **selection)
        except (ConvergenceError, IdentifiabilityError) as err:
            failures.append(f"{label}: {err}")
            continue
        fits.setdefault(model, {})[label] = fit
    return fits, failures


def _record(kind, soil, by, label, model, fit) -> dict:
    return {
        "kind": kind,
        "soil": soil,
        "condition": {"column": by, "value": label} if by else None,
        "model": model,
        "params": dict(fit.params),
        "stderr": dict(fit.stderr),
        "units": dict(fit.units),
        "epsilon": fit.epsilon,
        "health": [{"code": f.code, "message": f.message} for f in fit.flags],
        "converged": fit.converged,
        "nobs": fit.nobs,
        "tests": None if fit.tests is None else len(fit.tests),
        "notes": list(fit.notes),
    }


def run(args: argparse.Namespace) -> int:
    """Fit every soil and condition; print Table-5-style tables or one JSON object."""
    from ..campaign import load_campaign
    from ..errors import CampaignError
    from ..identification.table import format_parameter_table, parameter_table
    from ..report import Provenance, json_safe, write_csv, write_json

    full = apply_selection(load_campaign(args.data), args.select)
    soils_present = sorted(full.tests["soil"].astype(str).unique())
    unknown = sorted(set(args.soil or ()) - set(soils_present))
    if unknown:
        raise CampaignError(
            f"--soil {', '.join(unknown)}: no such soil; soils present: {soils_present}",
            file="tests.csv",
            column="soil",
        )
    soils = args.soil or soils_present
    _check_series(full, args)
    out = sys.stderr if args.json else sys.stdout
    print(f"Campaign: {full.source}", file=out)
    records, tables = [], []
    for kind in ("sinkage", "shear"):
        if not (full.tests["kind"] == kind).any():
            continue
        campaign = _series_filter(full, kind, args)
        if campaign is None:
            print(f"\n[{kind}: no tests of series {args.series!r}]", file=out)
            continue
        kind_tests = campaign.tests[campaign.tests["kind"] == kind]
        if kind == "sinkage":
            by = _grouping(kind_tests, args.by)
        else:
            by = _grouping(kind_tests, args.shear_by, _SHEAR_GROUPING_CANDIDATES)
        if "series" in kind_tests.columns and kind_tests["series"].nunique() == 1:
            print(f"\n[{kind}: series {kind_tests['series'].iloc[0]!r}]", file=out)
        for soil in soils:
            sub = kind_tests[kind_tests["soil"].astype(str) == soil]
            if sub.empty:
                continue
            by_model, failures = _fit_soil(campaign, kind, soil, by, sub, args)
            for model, fits in by_model.items():
                title = f"\n{kind} · {soil} · {model} · conditions by {by or '(all tests)'}"
                print(format_parameter_table(fits, title=title), file=out)
                for label, fit in fits.items():
                    if args.verbose:
                        print(fit.summary(), file=out)
                    records.append(_record(kind, soil, by, label, model, fit))
                tables.append(parameter_table(fits).assign(kind=kind, soil=soil, model=model))
            for failure in failures:
                print(f"  ! not identified: {failure}", file=out)
            if kind == "sinkage" and "bernstein" in by_model and args.model == "auto":
                print(
                    "  note: one plate size per condition, so Bekker's kc and kphi cannot be "
                    "separated (Section 2.1 needs two or more); Bernstein k, n shown.",
                    file=out,
                )
    if not records:
        raise CampaignError(
            "no condition could be identified in the selected tests (see the messages above)",
            file="tests.csv",
        )
    provenance = Provenance.of(full, argv=args.argv, seed=args.seed)
    document = {"fits": records}
    if args.out:
        import pandas as pd

        folder = Path(args.out)
        write_json(folder / "identify.json", document, provenance, overwrite=args.overwrite)
        write_csv(
            folder / "identify.csv",
            pd.concat(tables, ignore_index=True),
            provenance,
            overwrite=args.overwrite,
        )
        print(f"wrote {folder / 'identify.json'} and identify.csv", file=sys.stderr)
    if args.json:
        document |= {"provenance": provenance.to_dict()}
        print(json.dumps(json_safe(document), indent=2, ensure_ascii=False))
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.identify ...``: the same as ``soilstats identify ...``."""
    from .main import run_subcommand

    return run_subcommand("identify", argv)
