"""The PDF report of ``soilstats check``: which records are fit to identify soil from.

Page 1: the question, the data, and the answer (how many tests carry which screening code,
what the analyses leave out). Then every code found with what it is, why it matters and what
to do (from :mod:`soilstats.quality.codes`, the one home of that documentation), and every
flag of every test with its message. Everything in check.json is in the PDF.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from .._text import plural
from ..outputs.files import output_path
from ..quality.codes import CODES
from .document import Document, strong
from .front import data_origin, front_page
from .labels import natural_key

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..outputs.provenance import Provenance
    from ..quality.report import QualityReport

__all__ = ["write_report"]


def _conclusion(doc_dict: dict, n_tests: int) -> list:
    tests = doc_dict["tests"]
    flagged = [t for t in tests if t["flags"]]
    if doc_dict["mode"] == "off":
        return ["Screening was off: nothing was checked."]
    if not flagged:
        return [[strong("Clean. "), f"None of the {n_tests} tests carries a screening code."]]
    out: list = [
        [
            strong(f"{len(flagged)} of {n_tests} tests carry screening codes: "),
            "; ".join(f"{code} in {plural(n, 'test')}" for code, n in doc_dict["counts"].items()),
            ".",
        ]
    ]
    left_out = doc_dict["excluded_samples"]
    out.append(
        f"{left_out} samples are left out of every fit ({doc_dict['mode']} mode: the samples "
        "of spikes, bursts, pre-contact travel, holds, unload-reload branches, steps, "
        "releases and copied records; every other code flags the fits that use the test)."
        if doc_dict["mode"] == "clean"
        else "Flag mode: nothing is left out; the codes become health flags of the fits."
    )
    for code in doc_dict["counts"]:
        q = CODES.get(code)
        if q is not None:
            out.append([strong(f"{code}: "), q.action])
    return out


def write_report(
    report: QualityReport,
    path: str | Path,
    *,
    campaign: Campaign,
    provenance: Provenance | None = None,
    overwrite: bool = False,
) -> int:
    """Write the typeset screening report of ``report`` (a QualityReport) of ``campaign``
    to ``path``.

    Returns the number of pages; an existing file is an error unless ``overwrite`` (the
    signature of every report writer: docs/conventions.md).
    """
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    record = report.to_dict()
    n_tests = len(campaign.tests)
    doc = Document(
        "Data quality of a Bevameter campaign",
        subtitle="soilstats check — screening before identification",
        provenance=provenance,
    )
    front_page(
        doc,
        question=[
            "Are the measured records fit to identify soil parameters from? Which tests carry "
            "sensor spikes, seating offsets, load-terminated stops, bearing failure, drift or "
            "other artefacts, and what do the analyses leave out?"
        ],
        data=[data_origin(campaign.source), f": {n_tests} tests in the log."],
        conclusion=_conclusion(record, n_tests),
    )
    doc.page_break()
    _codes(doc, record)
    _flags(doc, record)
    if report.phases:
        _phases(doc, report)
    if record.get("proposed_windows"):
        _windows(doc, record)
    doc.paragraph(
        "Every screening rule, its thresholds and its measured detection and false-flag "
        "rates: soilstats' docs/quality.md (`soilstats check --json` lists the codes found "
        "here with what to do)."
    )
    doc.provenance_section()
    return doc.render(path)


def _codes(doc: Document, record: dict) -> None:
    """Every code found: what it is, why it matters and what to do."""
    doc.heading("Codes found")
    if not record["counts"]:
        doc.paragraph("No code was found.")
    for code, count in record["counts"].items():
        q = CODES.get(code)
        doc.heading(f"{code} ({plural(count, 'test')})", level=2)
        if q is None:
            doc.paragraph("No documentation for this code.")
            continue
        doc.key_values([("what", q.what), ("why it matters", q.why), ("what to do", q.action)])


def _flags(doc: Document, record: dict) -> None:
    """Every flag of every test, one table row each (tests in natural order)."""
    doc.heading("Every flag of every test")
    rows = [
        {
            "kind": t["kind"],
            "test": t["test_id"],
            "code": fl["code"],
            "samples": "whole test" if not fl.get("rows") else f"{len(fl['rows'])} rows",
            "left out": fl.get("excluded", False),
            "message": fl["message"],
        }
        for t in sorted(record["tests"], key=lambda t: natural_key(t["test_id"]))
        for fl in t["flags"]
    ]
    if rows:
        doc.table(
            pd.DataFrame(rows),
            caption="Screening flags per test (rows: samples concerned).",
            align_numbers=False,
        )
    else:
        doc.paragraph("No test carries a flag.")


def _phases(doc: Document, report: QualityReport) -> None:
    """The phases of each sinkage record (only contact and loading are fitted)."""
    doc.heading("Phases of each record")
    table = report.phase_table()
    plain = len(report.phases) - len(table)
    doc.paragraph(
        "Each sinkage record cut into its phases from z and force alone (docs/quality.md, "
        "Phases of a record): only contact and loading are fitted; holds, unload-reload "
        "branches, steps and the release are left out in clean mode; failure is cut by "
        "the proposed window. "
        + (
            f"The other {plural(plain, 'test')} hold approach, contact and loading only."
            if len(table)
            else f"All {plural(plain, 'test')} hold approach, contact and loading only."
        )
    )
    if len(table):
        doc.table(
            table.rename(columns={"test_id": "test"}),
            caption="Phases per test, each with the data rows of its first and last "
            "sample in the sample file.",
            align_numbers=False,
        )


def _windows(doc: Document, record: dict) -> None:
    """The proposed fitting windows, as ``--z-max`` items."""
    doc.heading("Proposed fitting windows")
    doc.paragraph(
        "Where most tests of a plate (soil and plate size b) failed, one sinkage window "
        "for all of them: the smallest onset. Otherwise a window for each failed test "
        "only, at its onset: the plate's other tests keep their depth. Set them with "
        "soilstats identify --z-max ITEM (repeatable):"
    )
    windows = pd.DataFrame(record["proposed_windows"])
    windows["test_id"] = windows["test_id"].fillna("all")
    doc.table(
        windows[["soil", "b_m", "test_id", "tests", "plate_tests", "z_max_m", "z_max_item"]],
        caption="Proposed windows: z_max (m) is the failure onset, the last sinkage the "
        "early law describes; the --z-max item states it rounded up to 4 digits.",
        labels={
            "b_m": "plate width b (m)",
            "test_id": "for test",
            "tests": "failed",
            "plate_tests": "tests of plate",
            "z_max_m": "z_max (m)",
            "z_max_item": "--z-max",
        },
        align_numbers=False,
    )
