"""The PDF report of a posterior, typeset: can these draws feed a rover Monte Carlo?

Page 1: the question, the data, and the answer — the posterior mean ± sd and interval of
each physical parameter in its unit, convergence, the physical-support check, every warning
and the health flags of the least-squares fit the sampler started from, and with a simulator
export its constraint check (broken, repaired), the columns from user priors or a mapping,
and where Bekker's modulus turns negative. "The draws pass every check" is said only when
every one of these passed; otherwise page 1 says which did not. Then the methods
(the paper's equations, the likelihood, the sampler), the full diagnostics table, and per
model the start fit's flags and the trace, pair and posterior-predictive figures
(:mod:`.posterior_figures`, physical units). Everything in ``posterior.json`` is in the PDF.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..bayes.result import PosteriorResult
from ..bayes.support import widths_text
from ..identification.table import format_value
from ..models import get_model
from ..outputs.files import output_path
from ..outputs.provenance import Provenance
from .document import Document, figure_svg, strong
from .front import data_origin, front_page
from .labels import parameter_symbol
from .methods import write_equations
from .posterior_figures import pair_figure, trace_figure
from .posterior_predictive import predictive_figure

__all__ = ["write_report"]


def _estimates(
    res: PosteriorResult, prob: float, handed_out: pd.DataFrame | None = None
) -> list:
    table = res.summary_table(prob, handed_out)
    lo, hi = table.columns[2], table.columns[3]
    parts: list = []
    for name in res.param_names:
        row = table.loc[name]
        unit = res.units.get(name, "")
        unit = "" if unit in ("", "-") else f" {unit}"
        if row[lo] > 0 and row[hi] > DECADES * row[lo]:
            # Spanning decades: mean ± sd says nothing there (a review: "(0.0 ± 1.4)e13");
            # the median and the interval on the log scale do.
            median = float(np.sqrt(row[lo] * row[hi])) if "median" not in row else row["median"]
            parts += [
                parameter_symbol(name),
                f" spans {np.log10(row[hi] / row[lo]):.1f} decades: log10 of it "
                f"{np.log10(row[lo]):.2f} to {np.log10(row[hi]):.2f} ({prob:.0%} interval, "
                f"{row[lo]:.2g} to {row[hi]:.2g}{unit}; geometric middle {median:.2g}); ",
            ]
            continue
        parts += [
            parameter_symbol(name),
            f" = {format_value(row['mean'], row['sd'])}{unit} "  # type: ignore[arg-type]  # pandas-stubs: .loc[name] may be a frame (one row per parameter)
            f"({prob:.0%} interval {row[lo]:.4g} to {row[hi]:.4g}); ",
        ]
    return parts


#: An interval whose ends are more than this factor apart is shown on the log scale.
DECADES = 100.0


def _caveats(results: Sequence[PosteriorResult], record: dict) -> list[str]:
    """What keeps "the draws pass every check" from being true, though nothing was refused:
    flagged start fits, warnings, repaired simulator constraints."""
    out = []
    flagged = [r.model_name for r in results if r.least_squares_health()]
    if flagged:
        out.append(f"the least-squares start of {', '.join(flagged)} is flagged")
    said = len(record.get("warnings", [])) + len(record.get("pooling_warnings", []))
    if said:
        out.append(f"{said} warning{'s' if said > 1 else ''}")
    failed = [
        f"the band check of {name} fails ({', '.join(check['failures'])})"
        for name, check in (record.get("band_check") or {}).items()
        if check.get("failures")
    ]
    out += failed
    repaired = ((record.get("simulator") or {}).get("constraints") or {}).get("repaired", 0)
    if repaired:
        out.append(f"SCM's elastic_K > Bekker_Kphi repaired in {repaired} parameter sets")
    return out


def _verdict(results: Sequence[PosteriorResult], record: dict) -> list:
    """The one sentence on whether the draws can be used; "pass every check" only when
    every check passed (support, convergence, the start fits' health, warnings, and the
    simulator's constraints unrepaired)."""
    written = record.get("draws_written")
    if record.get("forced"):
        return [
            strong("FORCED: "),
            "these draws failed a check and were written only because --force was given: "
            + "; ".join(record.get("failures", [])),
        ]
    if record.get("failures"):
        return [strong("Not fit for use: "), "; ".join(record["failures"])]
    caveats = _caveats(results, record)
    if not caveats:
        return [
            f"The draws pass every check: {written} joint draws written for a rover Monte "
            "Carlo (draws.csv), correlations kept."
        ]
    stops = "convergence, physical support" + (
        ", the simulator's constraints" if record.get("simulator") else ""
    )
    return [
        strong("Not every check passed: "),
        f"{written} joint draws written (draws.csv), correlations kept; they pass the checks "
        f"that stop the output ({stops}), but {'; '.join(caveats)} (below).",
    ]


def _simulator_lines(record: dict) -> list:
    """Page 1 on the simulator export: its constraint check (broken, repaired) and its notes
    (the columns that come from user priors or a mapping rather than from tests, where the
    modulus turns negative)."""
    sim = record.get("simulator")
    if not sim:
        return []
    check = sim.get("constraints") or {}
    broken = {k: v for k, v in (check.get("broken") or {}).items() if v}
    rows = check.get("rows", sim.get("draws"))
    name = sim.get("simulator", "simulator")
    if not broken:
        status = f"all {rows} parameter sets meet SCM's constraints (Chrono's source, below)."
    else:
        parts = [f"{label}: broken in {count} of {rows} sets" for label, count in broken.items()]
        if check.get("repaired"):
            parts.append(
                f"elastic_K repaired to {check.get('repair_multiple'):g} x Bekker_Kphi in "
                f"{check['repaired']} sets (column elastic_K_repaired = 1), as --scm-repair "
                "asked; Chrono would otherwise have raised it to Bekker_Kphi silently"
            )
        verdict = "PASSED after repair" if check.get("passed") else "FAILED"
        status = f"SCM's constraints {verdict}: " + "; ".join(parts) + "."
    out: list = [[strong(f"Simulator export ({name}.csv): "), status]]
    for note in sim.get("notes", []):  # the mapping, the user priors, a negative modulus
        out.append([strong("Simulator note: "), note])
    return out


def _conclusion(
    results: Sequence[PosteriorResult],
    record: dict,
    prob: float,
    handed_out: pd.DataFrame | None = None,
) -> list:
    out: list = []
    for res in results:
        status = (
            "converged (R-hat and effective sample sizes pass)"
            if res.converged
            else "NOT CONVERGED: " + "; ".join(f.message for f in res.flags)
        )
        out.append(
            [
                strong(f"{res.model_name} ({res.kind}): "),
                *_estimates(res, prob, handed_out),
                f"{status}.",
            ]
        )
        codes = sorted({f["code"] for f in res.least_squares_health()})
        if codes:
            out.append(
                [
                    strong("Start fit flagged: "),
                    f"the {res.model_name} least-squares fit these draws start from carries "
                    f"{', '.join(codes)}; the posterior inherits its data and model problems "
                    f"(messages under {res.model_name}, Health of the start fit).",
                ]
            )
    if not record:
        return out
    out.append(_verdict(results, record))
    for name, check in (record.get("band_check") or {}).items():
        fails = ", band check FAILS" if check.get("failures") else ""
        out.append([strong(f"{name}{fails}: "), check["sentence"]])
    out += _simulator_lines(record)
    width = record.get("negative_modulus_below_m")
    if width is not None and not record.get("simulator"):  # the simulator's note says it
        out.append(
            [
                strong("Negative modulus: "),
                f"kc < 0 in some draws: Bekker's modulus kc/b + kphi turns negative for contact "
                f"widths below {width:.3g} m (99 % of draws); do not use the draws for narrower "
                "contacts.",
            ]
        )
    support = record.get("support") or {}
    if support:
        lo, hi = (support.get("contact_widths_m") or [float("nan")] * 2)[:2]
        out.append(
            f"Physical support at {widths_text(lo, hi)}: {support['outside']} of "
            f"{support['draws']} draws outside ({support['share_outside']:.1%}, at most "
            f"{support['max_share']:.0%} allowed) — "
            + ("passed." if support["passed"] else "FAILED.")
        )
    said = set((record.get("default_warnings") or {}).values())  # already under Data
    for w in [*record.get("warnings", []), *record.get("pooling_warnings", [])]:
        if w not in said:
            out.append([strong("Warning: "), w])
    return out


def _simulator_section(doc: Document, sim: dict) -> None:
    """Every column's unit and source, SCM's constraints as read in Chrono's source with the
    sets that broke each, the stated inputs and the notes (all of the export's record)."""
    doc.heading(f"Simulator export: {sim.get('simulator')}")
    doc.paragraph(
        f"{sim.get('draws')} parameter sets, one per draw handed out, for {sim.get('call')}. "
        "Where each column comes from:"
    )
    columns = sim.get("columns") or {}
    doc.table(
        pd.DataFrame(
            [(c, columns.get(c, ""), src) for c, src in (sim.get("sources") or {}).items()],
            columns=["column", "unit", "source"],
        ),
        caption="Columns of the export in SetSoilParameters' order, their units and sources.",
    )
    check = sim.get("constraints") or {}
    rules = check.get("constraints") or {}
    doc.table(
        pd.DataFrame(
            [
                (
                    label,
                    (check.get("broken") or {}).get(label, 0),
                    rule["chrono"],
                    rule["otherwise"],
                )
                for label, rule in rules.items()
            ],
            columns=["constraint", "sets breaking it", "where in Chrono", "what Chrono does"],
        ),
        caption=f"SCM's constraints, read from {check.get('chrono_source')}; "
        f"{check.get('repaired', 0)} sets repaired (elastic_K = "
        f"{check.get('repair_multiple') or '-'} x Bekker_Kphi), check "
        + ("passed." if check.get("passed") else "FAILED."),
    )
    stated = sim.get("stated_inputs") or {}
    doc.key_values(
        (name, f"{v['value']:g} {v['unit']} ({v['source']})") for name, v in stated.items()
    )
    if sim.get("notes"):
        doc.numbered(sim["notes"])


def _diagnostics_table(
    doc: Document, res: PosteriorResult, prob: float, handed_out: pd.DataFrame | None
) -> None:
    table = res.summary_table(prob, handed_out).reset_index(names="quantity")
    over = (
        f"; mean, sd and interval of {', '.join(res.param_names)} over the draws handed out "
        "(draws.csv, inside the physical support)"
        if handed_out is not None
        else ""
    )
    doc.table(
        table,
        caption=f"{res.model_name}: posterior mean, sd, {prob:.0%} equal-tailed interval, "
        "Monte Carlo standard error, bulk and tail effective sample size and R-hat of every "
        f"sampled quantity (SI units as in the campaign format){over}.",
        labels={
            "mcse_mean": "MCSE",
            "ess_bulk": "ESS bulk",
            "ess_tail": "ESS tail",
            "r_hat": "R-hat",
        },
    )


def model_figures(result: PosteriorResult) -> list[tuple[bytes, str]]:
    """The report's figures of one posterior — trace, pair plot, predictive check — as SVG
    with their captions (:func:`~soilstats.report.document.figure_svg`): what
    :func:`write_report` embeds, drawable apart from it (``soilstats posterior --jobs``
    draws each model's in the worker that sampled it)."""
    out = []
    for make in (trace_figure, pair_figure, predictive_figure):
        fig, caption = make(result)
        out.append((figure_svg(fig), caption))
    return out


def write_report(
    results: list[PosteriorResult],
    path: str | Path,
    *,
    provenance: Provenance | None = None,
    overwrite: bool = False,
    record: dict | None = None,
    prob: float = 0.9,
    handed_out: pd.DataFrame | None = None,
    figures: Mapping[str, Sequence[tuple[bytes, str]]] | None = None,
) -> int:
    """Write the typeset posterior report for ``results`` to ``path``; return its pages.

    An existing file is an error unless ``overwrite`` (the signature of every report writer:
    docs/conventions.md).

    ``record`` is the content of ``posterior.json`` (checks, warnings, priors); everything
    in it is printed. ``provenance`` goes into the PDF metadata and onto the last page.
    ``handed_out``: the draws written (as :meth:`PosteriorResult.summary_table`).
    ``figures``: each model's figures as :func:`model_figures` drew them (in a worker
    process, say); a model without an entry is drawn here.
    """
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    record = record or {}
    soil = record.get("soil", "")
    doc = Document(
        f"Posterior of the soil parameters{f' of {soil}' if soil else ''}",
        subtitle="soilstats posterior — emcee sampling, ArviZ diagnostics, after "
        "Apfelbeck et al. (2011)",
        provenance=provenance,
    )
    source = provenance.campaign if provenance is not None else ""
    kinds = tuple(dict.fromkeys(get_model(r.model_name).kind for r in results))
    front_page(
        doc,
        question=[
            "What values of the soil parameters ("
            + ", ".join(r.model_name for r in results)
            + ") are consistent with the measured tests, with what joint uncertainty, and can "
            "the draws feed a rover Monte Carlo?"
        ],
        data=[
            data_origin(source) if source else "data passed in memory",
            f"; soil {soil}" if soil else "",
            f"; selection {', '.join(record['selection'])}" if record.get("selection") else "",
            ".",
        ],
        conclusion=_conclusion(results, record, prob, handed_out),
        defaults=record.get("defaults"),
        default_warnings=record.get("default_warnings"),
    )
    doc.page_break()
    doc.heading("Methods")
    write_equations(doc, kinds)
    doc.paragraph(
        "The likelihood is the paper's weighted least-squares criterion (Eq. 9) read as a "
        "Gaussian with an unknown weighted noise scale; emcee's affine-invariant ensemble "
        "samples it; ArviZ computes R-hat and the effective sample sizes. The draws are "
        "checked for convergence and physical support before anything is written."
    )
    if record.get("priors"):
        doc.paragraph(strong("Priors:"))
        doc.bullets(f"{model}: {prior}" for model, prior in record["priors"].items())
    for res in results:
        _model_section(doc, res, prob, handed_out, (figures or {}).get(res.model_name))
    if record.get("simulator"):
        _simulator_section(doc, record["simulator"])
    if record.get("support"):
        doc.heading("Physical support of the draws")
        doc.key_values(_support_rows(record["support"]))
    if record.get("failures"):
        doc.heading("Failed checks")
        doc.numbered(record["failures"])
    doc.provenance_section()
    return doc.render(path)


def _model_section(
    doc: Document,
    res: PosteriorResult,
    prob: float,
    handed_out: pd.DataFrame | None,
    drawn: Sequence[tuple[bytes, str]] | None,
) -> None:
    """One model's section: sampler, diagnostics, health, flags, notes and its figures
    (``drawn`` as :func:`model_figures` drew them elsewhere, else drawn here)."""
    doc.heading(f"{res.model_name} ({res.kind})")
    s = res.sampler
    doc.paragraph(
        f"Sampler: emcee, {s.get('walkers')} walkers, {s.get('steps')} steps, burn-in "
        f"{s.get('burn')}, thin {s.get('thin')}, {s.get('kept')} draws kept; "
        f"autocorrelation time {s.get('tau_max', float('nan')):.3g} steps; acceptance "
        f"{s.get('acceptance', float('nan')):.2f}."
    )
    _diagnostics_table(doc, res, prob, handed_out)
    health = res.least_squares_health()
    if health:
        doc.paragraph(strong("Health of the start fit (the least-squares fit sampled from):"))
        doc.bullets([strong(f"{h['code']}: "), h["message"]] for h in health)
    if res.flags:
        doc.paragraph(strong("Failed convergence checks:"))
        doc.bullets([strong(f"{f.code}: "), f.message] for f in res.flags)
    if res.notes:
        doc.paragraph(strong("Notes:"))
        doc.numbered(res.notes)
    for svg, caption in drawn if drawn is not None else model_figures(res):
        doc.svg_figure(svg, caption)


def _support_rows(support: dict) -> list[tuple[str, str]]:
    """The physical-support check as label/value rows in words: one row per reason a draw
    can fall outside (never a printed mapping)."""
    rows: list[tuple[str, str]] = []
    for key, value in support.items():
        label = str(key).replace("_", " ")
        if isinstance(value, dict):
            rows += [(f"{label}: {k}", _support_value(v)) for k, v in value.items()]
        elif isinstance(value, list | tuple):
            rows.append((label, " – ".join(_support_value(v) for v in value)))
        else:
            rows.append((label, _support_value(value)))
    return rows


def _support_value(value: object) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:g}"
    return "" if value is None else str(value)
