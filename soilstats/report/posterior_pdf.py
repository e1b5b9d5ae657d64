"""The PDF report of a posterior, typeset: can these draws feed a rover Monte Carlo?

Page 1: the question, the data, and the answer — the posterior mean ± sd and interval of
each physical parameter in its unit, convergence, the physical-support check, every warning
and the health flags of the least-squares fit the sampler started from. Then the methods
(the paper's equations, the likelihood, the sampler), the full diagnostics table, and per
model the start fit's flags and the trace, pair and posterior-predictive figures
(:mod:`.posterior_figures`, physical units). Everything in ``posterior.json`` is in the PDF.
"""

from __future__ import annotations

from pathlib import Path

from ..bayes.result import PosteriorResult
from ..identification.table import format_value
from ..models import get_model
from .document import Document, strong
from .files import output_path
from .front import data_origin, front_page
from .labels import parameter_symbol
from .methods import write_equations
from .posterior_figures import pair_figure, predictive_figure, trace_figure
from .provenance import Provenance

__all__ = ["write_report"]


def _estimates(res: PosteriorResult, prob: float, handed_out=None) -> list:
    table = res.summary_table(prob, handed_out)
    lo, hi = table.columns[2], table.columns[3]
    parts: list = []
    for name in res.param_names:
        row = table.loc[name]
        unit = res.units.get(name, "")
        unit = "" if unit in ("", "-") else f" {unit}"
        parts += [
            parameter_symbol(name),
            f" = {format_value(row['mean'], row['sd'])}{unit} "
            f"({prob:.0%} interval {row[lo]:.4g} to {row[hi]:.4g}); ",
        ]
    return parts


def _conclusion(results, record: dict, prob: float, handed_out=None) -> list:
    out: list = []
    for res in results:
        status = (
            "converged (R-hat and effective sample sizes pass)"
            if res.converged
            else "NOT CONVERGED: " + "; ".join(res.problems)
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
    if record:
        support = record.get("support") or {}
        if record.get("forced"):
            out.append(
                [
                    strong("FORCED: "),
                    "these draws failed a check and were written only because --force was "
                    "given: " + "; ".join(record.get("failures", [])),
                ]
            )
        elif record.get("failures"):
            out.append([strong("Not fit for use: "), "; ".join(record["failures"])])
        else:
            out.append(
                f"The draws pass every check: {record.get('draws_written')} joint draws written "
                "for a rover Monte Carlo (draws.csv), correlations kept."
            )
        if support:
            lo, hi = (support.get("contact_widths_m") or [float("nan")] * 2)[:2]
            out.append(
                f"Physical support at contact widths {lo:g}–{hi:g} m: {support['outside']} of "
                f"{support['draws']} draws outside ({support['share_outside']:.1%}, at most "
                f"{support['max_share']:.0%} allowed) — "
                + ("passed." if support["passed"] else "FAILED.")
            )
        for w in [*record.get("warnings", []), *record.get("pooling_warnings", [])]:
            out.append([strong("Warning: "), w])
    return out


def _diagnostics_table(doc: Document, res: PosteriorResult, prob: float, handed_out) -> None:
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


def write_report(
    results: list[PosteriorResult],
    path: str | Path,
    *,
    record: dict | None = None,
    provenance: Provenance | None = None,
    prob: float = 0.9,
    overwrite: bool = True,
    handed_out=None,
) -> int:
    """Write the typeset posterior report for ``results`` to ``path``; return its pages.

    ``record`` is the content of ``posterior.json`` (checks, warnings, priors); everything
    in it is printed. ``provenance`` goes into the PDF metadata and onto the last page.
    ``handed_out``: the draws written (as :meth:`PosteriorResult.summary_table`).
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
        if res.problems:
            doc.paragraph(strong("Convergence problems:"))
            doc.bullets(res.problems)
        if res.notes:
            doc.paragraph(strong("Notes:"))
            doc.numbered(res.notes)
        for make in (trace_figure, pair_figure, predictive_figure):
            fig, caption = make(res)
            doc.figure(fig, caption)
    if record.get("support"):
        doc.heading("Physical support of the draws")
        support = record["support"]
        doc.key_values((str(k).replace("_", " "), v) for k, v in support.items())
    if record.get("failures"):
        doc.heading("Failed checks")
        doc.numbered(record["failures"])
    doc.provenance_section()
    return doc.render(path)
