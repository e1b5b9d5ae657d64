"""Run setup-effect studies of the paper's Sections 3-4 and write their reports.

NAME is a shipped study (preparation, velocity, tool-shape, shear-ring, grousers,
grouser-height, shear-velocity), 'all' for every shipped study the campaign can answer (the
others are listed as "not applicable" with the reason), or the path of a study
specification (.toml; format in docs/studies.md: copy a shipped one from the 'studies' folder
of the repository and change it).

Each study selects its tests, fits every test on its own (Bernstein k, n per plate test;
steady-state shear stress per ring test), tests the factor per soil (ANOVA with blocking
factors and Tukey pairs, or ANCOVA of the Mohr-Coulomb lines), adjusts the p-values (Holm)
and states a verdict per soil and response; the preparation study also scores the methods
by the criteria of Table 1, as Table 3.

Writes into --out: NAME.pdf (report with figures), NAME.json (verdicts, parameter tables)
and NAME_*.csv tables, each with its provenance.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

from ..parallel import effective_jobs, one_blas_thread, parallel_map, warm_workers
from .common import (
    add_common_options,
    add_data_options,
    add_jobs_option,
    defaults_not_given,
    prepared,
    progress_enabled,
)
from .main import run_subcommand


def configure(parser: argparse.ArgumentParser) -> None:
    """The study subcommand's options."""
    parser.add_argument("name", metavar="NAME", help="study name, 'all', or a .toml path")
    add_common_options(parser, default_out="reports")
    add_data_options(parser, window=False)
    parser.add_argument("--no-pdf", action="store_true", help="write JSON and CSV only")
    add_jobs_option(parser, "the studies and the per-test fits they share")


def run(args: argparse.Namespace) -> int:
    """Run the studies; readable summaries (or one JSON object) on stdout."""
    from ..study import StudyDataError, available_studies, load_spec  # deferred: statsmodels
    from ..study.outputs import to_json_dict  # deferred: statsmodels
    from ..study.responses import PerTestCache  # deferred: statsmodels

    names = available_studies() if args.name == "all" else [args.name]
    specs = [load_spec(n) for n in names]  # every spec checked before any work
    parallel = effective_jobs(args.jobs) > 1 and len(specs) > 1
    if parallel:  # the workers start while the campaign loads
        modules = ("soilstats.study.runner", "soilstats.study.responses")
        warm_workers(args.jobs, modules + (() if args.no_pdf else ("soilstats.report.study_pdf",)))
    campaign, provenance = prepared(args)
    progress = progress_enabled(args.progress)
    cache = PerTestCache(campaign, progress=progress)
    out_dir = Path(args.out)
    log = sys.stderr if args.json else sys.stdout
    print(f"Campaign: {campaign.source}   output: {out_dir}/", file=log)
    if parallel:
        cache.fill(jobs=args.jobs)  # the per-test fits every study shares, across workers
        cache.progress = False
    tasks = [(spec, campaign, cache, args, provenance) for spec in specs]
    if parallel:
        outcomes = parallel_map(_run_one, tasks, jobs=args.jobs, progress=progress, desc="studies")
    else:  # one study after the other, each printed as soon as it is done
        outcomes = _one_after_another(tasks)
        if progress:
            from tqdm.auto import tqdm  # deferred: tqdm

            outcomes = tqdm(outcomes, total=len(tasks), desc="studies", unit="study")
    documents, timings, not_applicable = [], [], []
    for spec, (result, written, pages, runtime_s) in zip(specs, outcomes, strict=True):
        if isinstance(result, str):  # 'all': a study this campaign's design cannot answer
            not_applicable.append({"study": spec.name, "reason": result})
            continue
        timings.append((spec.name, runtime_s))
        documents.append(to_json_dict(result) | {"files": [str(p) for p in written]})
        if not args.json:
            print("\n" + result.summary())
        what = "JSON, CSV" + ("" if args.no_pdf else f", PDF ({pages} pages)")
        print(f"  -> {out_dir / spec.name}.*: {what};  {runtime_s:.1f} s", file=log)
    if len(timings) > 1:
        print(
            "\nTime per study: "
            + ", ".join(f"{n} {s:.1f} s" for n, s in timings)
            + f"; total {sum(s for _, s in timings):.1f} s",
            file=log,
        )
    reasons = "\n".join(  # a reason of several lines (one per response) stays indented
        f"  {n['study']}: not applicable: " + n["reason"].replace("\n", "\n    ")
        for n in not_applicable
    )
    if not documents:  # 'all' and no study applies: bad input, not an empty success
        raise StudyDataError(f"no study applies to the campaign {campaign.source}:\n{reasons}")
    if not_applicable:
        print(f"\nStudies this campaign cannot answer:\n{reasons}", file=log)
    if args.json:
        document = {"studies": documents, "not_applicable": not_applicable}
        print(json.dumps(document | {"provenance": provenance.to_dict()}, indent=2))
    return 0


def _one_after_another(tasks):
    """The studies in this process, BLAS on one thread as in workers (same bits for any N)."""
    for task in tasks:
        with one_blas_thread():
            yield _run_one(task)


def _run_one(task):
    """One study: run, write its JSON/CSV (and PDF); (result, files, pages, runtime_s).

    Under 'all', a study the campaign's design cannot answer (:class:`StudyDataError`: no
    tests of its kind, no factor column, one level per soil) gives its reason in place of
    the result; any other error (a bug, a failed fit) propagates and stops the command.
    """
    from ..report.study_pdf import write_report  # deferred: matplotlib
    from ..study import StudyDataError, run_study, write_outputs  # deferred: statsmodels

    spec, campaign, cache, args, provenance = task
    start = time.perf_counter()
    try:
        result = run_study(
            spec,
            campaign,
            cache=cache,
            progress=cache.progress,
            seed=args.seed,
            provenance=provenance,
        )
    except StudyDataError as err:
        if args.name != "all":
            raise
        return str(err), [], None, time.perf_counter() - start
    # What the result rests on unsaid: the command's options as well as the spec's keys.
    result = replace(result, defaults=defaults_not_given(args) | result.defaults)
    out_dir = Path(args.out)
    written = write_outputs(result, out_dir, overwrite=args.overwrite)
    pages = None
    if not args.no_pdf:
        pdf = out_dir / f"{spec.name}.pdf"
        pages = write_report(result, pdf, campaign=campaign, overwrite=args.overwrite)
        written.append(pdf)
    return result, written, pages, time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    """``python -m soilstats.study ...``: the same as ``soilstats study ...``."""
    return run_subcommand("study", argv)
