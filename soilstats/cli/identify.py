"""Soil parameters per soil and test condition, as the paper's Tables 5 and 6.

Fits the pressure-sinkage law (Bekker where a condition has two or more plate sizes,
Bernstein otherwise; --model to choose) and the shear law (Janosi-Hanamoto, with
Mohr-Coulomb) to the pooled tests of each soil and condition, and prints each parameter with
its standard deviation, the fit quality and any health flag.

A condition is one value of a test-log column: --by for sinkage (default: the first of
velocity_m_s, preparation that varies), --shear-by for shear (default: tool, else
r_inner_m). A campaign's series are never pooled: each is tabulated on its own, and
--series NAME keeps one. --out DIR also writes identify.json, identify.csv and a PDF report.

Example:  soilstats identify --data cullinan-sand --by preparation --out reports/
"""

# Developer note: the work is soilstats.identification.conditions.plan_conditions for each
# kind, then fit_planned for both at once (one queue of conditions for --jobs); this module
# parses options and prints.

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import CampaignError
from ..outputs import json_safe, write_csv, write_json
from ..parallel import warm_workers
from .common import (
    add_common_options,
    add_data_options,
    add_jobs_option,
    defaults_not_given,
    number_in,
    prepared,
    progress_enabled,
)
from .main import run_subcommand

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..identification.conditions import ConditionPlan
    from ..outputs.provenance import Provenance


def configure(parser: argparse.ArgumentParser) -> None:
    """The identify subcommand's options."""
    add_common_options(
        parser,
        out_help="also write identify.json, identify.csv (every fit) and identify.pdf into DIR",
    )
    add_data_options(parser)
    model = parser.add_argument(
        "--model", default="auto", help="sinkage model (auto: Bekker where 2+ plate sizes)"
    )
    model.choices = _SinkageModels()  # after add_argument, which would format them now
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
        help="only tests of this series (campaigns with a 'series' column; default: "
        "every series, each tabulated on its own)",
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
        type=number_in(int, 3, 1_000_000),
        default=100,
        help="samples per test after equal-sinkage thinning, 3 to 1e6 (Section 2.1; default 100)",
    )
    parser.add_argument(
        "--test-resamples",
        type=number_in(int, 0, 100_000),
        default=200,
        help="resamples of the cluster bootstrap over tests behind stderr_tests, 0 to 1e5 (0: off; "
        "default 200, seeded by --seed)",
    )
    parser.add_argument("--verbose", action="store_true", help="print every fit's summary()")
    add_jobs_option(parser, "the soils and conditions")


class _SinkageModels:
    """``--model``'s choices: ``auto`` and the registered sinkage models, read from the
    registry when first needed (it imports numpy; building the parser must stay cheap)."""

    def _names(self) -> tuple[str, ...]:
        from ..models import model_names  # deferred: pandas

        return ("auto", *model_names("sinkage"))

    def __iter__(self):
        return iter(self._names())

    def __contains__(self, name: object) -> bool:
        return name in self._names()


def _check_series(campaign: Campaign, series: str | None) -> None:
    if series is None:
        return
    tests = campaign.tests
    present = set(tests["series"].dropna().astype(str)) if "series" in tests.columns else set()
    if series not in present:
        raise CampaignError(
            f"--series {series!r}: no such series; series present: {sorted(present)}",
            file=campaign.file_name("tests"),
            column="series",
        )


def run(args: argparse.Namespace) -> int:
    """Fit every soil and condition; print Table-5-style tables or one JSON object."""
    from ..identification.conditions import fit_planned, plan_conditions  # deferred: pandas

    warm_workers(args.jobs, ("soilstats.identification.conditions",))  # while loading
    campaign, provenance = prepared(args)
    soils_present = sorted(campaign.tests["soil"].astype(str).unique())
    unknown = sorted(set(args.soil or ()) - set(soils_present))
    if unknown:
        raise CampaignError(
            f"--soil {', '.join(unknown)}: no such soil; soils present: {soils_present}",
            file=campaign.file_name("tests"),
            column="soil",
        )
    _check_series(campaign, args.series)
    if args.series is not None:
        campaign = campaign.select(series=args.series)
    out = sys.stderr if args.json else sys.stdout
    print(f"Campaign: {campaign.source}", file=out)
    # Both kinds are planned first and fitted as one queue of conditions (with --jobs, no
    # worker waits for the sinkage conditions to finish before the shear ones start).
    # (kind, plan or None when the campaign has no tests of the kind)
    plans: list[tuple[str, ConditionPlan | None]] = []
    for kind, by in (("sinkage", args.by), ("shear", args.shear_by)):
        if not (campaign.tests["kind"] == kind).any():
            plans.append((kind, None))
            continue
        options = {"test_resamples": args.test_resamples, "seed": args.seed}
        if kind == "sinkage":
            options |= {"method": args.method, "points_per_test": args.points_per_test}
        model = args.model if kind == "sinkage" else "mohr-coulomb"
        plans.append(
            (kind, plan_conditions(campaign, kind, by=by, model=model, soils=args.soil, **options))
        )
    fitted = iter(
        fit_planned(
            [plan for _, plan in plans if plan is not None],
            jobs=args.jobs,
            progress=progress_enabled(args.progress),
        )
    )
    results = []
    for kind, plan in plans:
        if plan is None:
            if args.series is not None:
                print(f"\n[{kind}: no tests of series {args.series!r}]", file=out)
            continue
        result = next(fitted)
        print("\n" + result.summary(), file=out)
        if args.verbose:
            for condition in result.fits:
                print(condition.fit.summary(), file=out)
        results.append(result)
    records = [f.to_dict() for r in results for f in r.fits]
    if not records:
        raise CampaignError(
            "no condition could be identified in the selected tests (see the messages above)",
            file=campaign.file_name("tests"),
        )

    defaults = defaults_not_given(args)
    document: dict[str, Any] = {"defaults": defaults, "fits": records}
    if args.out:
        _write(args, document, results, campaign, provenance)
    if args.json:
        document |= {"provenance": provenance.to_dict()}
        print(json.dumps(json_safe(document), indent=2, ensure_ascii=False))
    return 0


def _write(
    args: argparse.Namespace,
    document: dict[str, Any],
    results: list[Any],
    campaign: Campaign,
    provenance: Provenance,
) -> None:
    """identify.json, identify.csv (every fit) and identify.pdf into --out."""
    import pandas as pd  # deferred: pandas

    from ..report.identify_pdf import write_report  # deferred: matplotlib

    folder = Path(args.out)
    write_json(folder / "identify.json", document, provenance, overwrite=args.overwrite)
    table = pd.concat([r.table() for r in results], ignore_index=True)
    write_csv(folder / "identify.csv", table, provenance, overwrite=args.overwrite)
    write_report(
        results,
        folder / "identify.pdf",
        campaign=campaign,
        provenance=provenance,
        overwrite=args.overwrite,
        defaults=document["defaults"],
    )
    print(f"wrote {folder / 'identify.json'}, identify.csv and identify.pdf", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.cli.identify ...``: the same as ``soilstats identify ...``."""
    return run_subcommand("identify", argv)
