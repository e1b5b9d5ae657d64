"""The PDF report of ``soilstats identify``: parameters per soil and condition, and whether
each can be used.

Page 1 lists every identified parameter set with σ and fit quality, and says plainly which
fits carry health flags (and so must not be used as they are). Then the methods with the
paper's equations, one table per soil and kind (the paper's Tables 5 and 6), every health
flag with its message, every note and every condition that could not be identified.
Everything in identify.json is in the PDF.
"""

from __future__ import annotations

from pathlib import Path

from ..identification.table import format_value
from .document import Document, strong
from .files import output_path
from .front import data_origin, front_page
from .labels import natural_key, parameter_symbol
from .methods import write_equations
from .parameters import condition_table

__all__ = ["write_report"]


def _where(record: dict) -> str:
    parts = [record["soil"]]
    if record.get("series"):
        parts.append(f"series {record['series']}")
    parts.append(f"condition {record['condition']}" if record.get("condition") else "all tests")
    return ", ".join(parts)


def _parameter_sentence(record: dict) -> list:
    values = []
    for name, value in record["params"].items():
        unit = record["units"].get(name, "")
        values += [
            parameter_symbol(name),
            f" = {format_value(value, record['stderr'][name])}"
            + (f" {unit}" if unit and unit != "-" else ""),
            ", ",
        ]
    health = [h["code"] for h in record["health"]]
    verdict = (
        "no health flag."
        if not health
        else f"health flags {', '.join(health)} — not to be used as it is (see below)."
    )
    return [
        strong(f"{record['kind']} / {_where(record)} ({record['model']}): "),
        *values,
        f"ε = {record['epsilon']:.3f} over {record['tests']} tests; {verdict}",
    ]


def write_report(results, campaign, path: Path, *, provenance=None, overwrite: bool = False) -> int:
    """Write the typeset identification report of ``results`` (ConditionFits per kind).

    Returns the number of pages; an existing file is an error unless ``overwrite``.
    """
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    records = [f.to_dict() for r in results for f in r.fits]
    records.sort(key=lambda d: (d["kind"], natural_key(d["soil"]), natural_key(d["condition"])))
    doc = Document(
        "Soil parameters identified from Bevameter tests",
        subtitle="soilstats identify — weighted Levenberg–Marquardt after Apfelbeck et al. (2011)",
        provenance=provenance,
    )
    kinds = tuple(dict.fromkeys(d["kind"] for d in records))
    flagged = [d for d in records if d["health"]]
    conclusion: list = [_parameter_sentence(d) for d in records]
    conclusion.append(
        f"{len(records) - len(flagged)} of {len(records)} parameter sets carry no health flag"
        + ("." if not flagged else "; the others must not be used without reading their flags.")
    )
    front_page(
        doc,
        question=[
            "What are the soil parameters of each soil and test condition (Bekker k_c, k_φ, n or "
            "Bernstein k, n from plate sinkage; Mohr–Coulomb c, φ from shear), with what "
            "uncertainty, and can each set be trusted?"
        ],
        data=[
            data_origin(campaign.source),
            f": {len(campaign.tests)} tests; kinds identified: {', '.join(kinds)}.",
        ],
        conclusion=conclusion,
    )
    doc.page_break()
    doc.heading("Methods")
    write_equations(doc, kinds)
    doc.heading("Parameters per soil and condition")
    for (kind, soil), group in _groups(records).items():
        condition_table(
            doc,
            (
                {
                    "condition": d["condition"] or "all",
                    "model": d["model"],
                    **{k: d[k] for k in ("params", "stderr", "units", "epsilon", "tests")},
                    "converged": d["converged"],
                    "health": ", ".join(h["code"] for h in d["health"]) or "ok",
                }
                for d in group
            ),
            caption=f"{kind} / {soil}: value ± σ (Eqs. 3–5), fit quality ε (Eq. 2).",
        )
    doc.heading("Health flags and notes per fit")
    for d in records:
        doc.heading(f"{d['kind']} / {_where(d)} ({d['model']})", level=2)
        doc.paragraph(
            f"{d['method']}; {d['nobs']} samples of {d['tests']} tests; screening "
            f"{d.get('quality') or 'off'}; window {d.get('window') or 'none'}; converged: "
            f"{'yes' if d['converged'] else 'NO'}."
        )
        if d["health"]:
            doc.bullets([strong(f"{h['code']}: "), h["message"]] for h in d["health"])
        if d["notes"]:
            doc.numbered(d["notes"])
        if d.get("excluded"):
            doc.paragraph("Excluded tests: ", ", ".join(map(str, d["excluded"])), ".")
    failures = [f for r in results for f in r.failures]
    notes = [n for r in results for n in r.notes]
    if failures or notes:
        doc.heading("Conditions not identified and notes")
        doc.numbered([*failures, *notes])
    doc.provenance_section()
    return doc.render(path)


def _groups(records: list[dict]) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for d in records:
        out.setdefault((d["kind"], d["soil"]), []).append(d)
    return out
