"""The PDF report of a study: title, methods, tables, verdicts, figures (matplotlib PdfPages).

Text pages are monospace so that tables line up on paper; figures come from
:mod:`.figures`.  Page order: title page, methods, parameter tables (value ± σ, ε),
ANOVA/ANCOVA tables, verdicts (with criteria and notes), then the figures.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.backends.backend_pdf import PdfPages

from ..identification.table import format_value
from ..study.result import CRITERIA_COLUMNS
from .files import output_path
from .pages import A4, frame_lines, provenance_page, text_pages, wrap_paragraphs
from .provenance import Provenance
from .study_figures import make_figures

__all__ = ["write_report"]


_EQUATIONS = {
    "sinkage": [
        "p = F / A                                  (Eq. 6)  measured pressure",
        "p = (kc/b + kphi) z^n                      (Eq. 7)  Bekker, pooled per condition",
        "p = k z^n                                  (Eq. 8)  Bernstein, per test and pooled",
        "min 1/2 || w (p_m - p(X, theta)) ||^2      (Eq. 9)  w = 1/max(p) per test",
        "eps = 1 - sqrt(sum e^2/(N-2)) / (sum|y|/N) (Eq. 2)  fit quality",
        "stderr = sqrt(diag Cov), Cov = s^2 (J'J)^-1 (Eqs. 3-5)",
    ],
    "shear": [
        "tau = 3 T / (2 pi (ro^3 - ri^3))           (Eq. 12) shear stress",
        "j = (ro + ri)/2 * alpha                    (Eq. 14) shear deformation",
        "tau = (c + sigma tan phi)(1 - exp(-j/K))   (Eq. 13) per-test curve",
        "tau = c + sigma tan phi                    (Eq. 15) steady state, Mohr-Coulomb",
        "stderr(c), stderr(phi) by linear least squares (paper ref. [9])",
    ],
}


def _parameter_lines(result) -> list[str]:
    params = result.parameters
    if params.empty:
        return ["(no pooled identification)"]
    lines = []
    for soil, g in params.groupby("soil", sort=False):
        conds = list(dict.fromkeys(g["condition"]))
        lines.append(
            f"{soil}   model: {', '.join(sorted(set(g['model'])))}   "
            f"conditions by {result.spec.factor}"
        )
        for chunk in [conds[i : i + 5] for i in range(0, len(conds), 5)]:
            rows = [["parameter", *chunk]]
            for name, gp in g.groupby("parameter", sort=False):
                unit = gp["unit"].iloc[0]
                vals = gp.set_index("condition")
                rows.append(
                    [
                        f"{name} [{unit}]",
                        *(format_value(vals.loc[c, "value"], vals.loc[c, "stderr"]) for c in chunk),
                    ]
                )
            first = g.drop_duplicates("condition").set_index("condition")
            rows.append(["epsilon (Eq. 2)", *(f"{first.loc[c, 'epsilon']:.3f}" for c in chunk)])
            rows.append(["tests", *(f"{first.loc[c, 'tests']:.0f}" for c in chunk)])
            rows.append(["health", *((first.loc[c, "flags"] or "ok")[:22] for c in chunk)])
            widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
            for r in rows:
                lines.append("  ".join(cell.ljust(w) for cell, w in zip(r, widths, strict=True)))
            lines.append("")
    return lines


def _verdict_lines(result) -> list[str]:
    spec = result.spec
    lines = []
    eff = result.effects
    if not eff.empty:
        lines.append(
            f"alpha = {spec.alpha:g}; p-values Holm-adjusted "
            + (
                f"across all {len(eff)} tests of the study"
                if spec.family is None
                else f"within each {spec.family}"
            )
        )
        for _, r in eff.iterrows():
            margin = ""
            if pd.notna(r.get("margin")):
                margin = f"  largest diff {r['largest_difference']:.3g} (margin {r['margin']:.3g})"
            lines.append(
                f"  {r['soil']:<14}{r['response']:<13}F = {r['statistic']:<9.4g}"
                f"p = {r['p_value']:<10.3g}p_Holm = {r['p_adjusted']:<10.3g}"
                f"-> {r['verdict'].upper()}{margin}"
            )
        lines.append("")
    pairs = result.reference_pairs()
    if not pairs.empty:
        lines.append(
            f"Each level against the reference {pairs['reference'].iloc[0]} "
            "(Tukey HSD, simultaneous intervals):"
        )
        lines += frame_lines(pairs.drop(columns=["reference"]))
        lines.append("")
    if result.criteria is not None:
        crit = result.criteria
        lines.append("Criteria of Table 1 per method (as the paper's Table 3):")
        lines += frame_lines(crit[CRITERIA_COLUMNS])
        lines.append("")
        lines.append(f"Best method: {result.best.get('best')}")
        lines += wrap_paragraphs(result.best["reason"])
        lines.append("Reasons:")
        for _, r in crit.iterrows():
            lines += textwrap.wrap(
                f"{r['soil']} method {r['method']}: [1] {r['crit1_reason']} [2] "
                f"{r['crit2_reason']} [3] {r['crit3_reason']}",
                110,
                subsequent_indent="    ",
            )
        lines.append("")
    if result.notes:
        lines.append("Notes:")
        for i, note in enumerate(result.notes, 1):
            lines += textwrap.wrap(f"[{i}] {note}", 110, subsequent_indent="    ")
    return lines


def _methods_lines(result) -> list[str]:
    spec = result.spec
    lines = wrap_paragraphs(spec.description)
    lines.append("Equations used:")
    lines += ["  " + e for e in _EQUATIONS[spec.kind]]
    lines.append("")
    if spec.kind == "shear":
        stats = (
            "Statistics: one point per test (mean sigma, steady-state tau). ANCOVA "
            "(statsmodels OLS) compares one line, parallel lines and separate lines per level: "
            "phi by the slope test, c by a Wald test of equal intercepts in the separate-lines "
            "model, the whole line by common vs separate lines. Verdicts: Holm-adjusted "
            f"p < {spec.alpha:g}."
        )
    else:
        margins = (
            "; ".join(
                f"{r.name}: ±{r.margin:g}{' relative' if r.margin_kind == 'relative' else ''}"
                for r in spec.responses
                if r.margin is not None
            )
            or "none declared"
        )
        stats = (
            "Statistics: per-test responses (Bernstein fit of each test; pressure at "
            f"z_ref = {spec.z_ref_m * 1e3:g} mm). Type II two-way ANOVA (statsmodels) of each "
            f"response by {spec.factor} with blocks {', '.join(spec.blocks) or 'none'} where they "
            "vary (one-way if confounded), Tukey HSD pairs on the block-adjusted response, "
            f"Holm-adjusted verdicts at alpha = {spec.alpha:g}. Relevance margins: {margins}. "
            "Verdicts: effect (significant and beyond the margin), no relevant effect (all "
            "simultaneous intervals within the margin), inconclusive, no effect detected."
        )
    lines += wrap_paragraphs(stats)
    return lines


def write_report(result, campaign, path: Path, *, overwrite: bool = False) -> int:
    """Write the PDF report of ``result`` to ``path``; return the number of pages.

    The last page and the PDF metadata carry the result's provenance; an existing file is
    an error unless ``overwrite``.
    """
    spec = result.spec
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    provenance = result.provenance or Provenance.of(campaign, seed=result.seed)
    pages = 0
    with PdfPages(path, metadata=provenance.pdf_metadata(spec.title)) as pdf:
        fig = plt.figure(figsize=A4)
        fig.text(0.5, 0.80, spec.title, ha="center", fontsize=15, weight="bold", wrap=True)
        info = [
            f"soilstats study '{spec.name}'",
            f"Paper: {spec.paper}",
            f"Data source: {result.source}",
            f"Factor: {spec.factor}    soils: {', '.join(result.soils)}",
            f"Seed: {result.seed}",
        ]
        if result.date is not None:
            info.append(f"Date: {result.date}")
        fig.text(0.5, 0.70, "\n".join(info), ha="center", va="top", fontsize=10)
        summary = (
            [f"{r['soil']} / {r['response']}: {r['verdict']}" for _, r in result.effects.iterrows()]
            if not result.effects.empty
            else []
        )
        if result.best is not None:
            summary.append(f"best preparation method: {result.best.get('best')}")
        text = "\n".join(
            [
                *wrap_paragraphs("The paper found: " + spec.paper_finding, 90),
                "Verdicts here:",
                *summary,
            ]
        )
        fig.text(0.08, 0.52, text, va="top", fontsize=9, family="monospace")
        pdf.savefig(fig)
        plt.close(fig)
        pages += 1
        pages += text_pages(pdf, "Methods", _methods_lines(result))
        pages += text_pages(
            pdf,
            "Identified parameters per condition (value ± σ, Eqs. 3-5)",
            _parameter_lines(result),
        )
        title = "ANCOVA model comparisons" if spec.kind == "shear" else "ANOVA tables"
        tables = frame_lines(result.anova) if not result.anova.empty else ["(none)"]
        if not result.lines.empty:
            tables += ["", "Lines per level (separate-lines model):"]
            tables += frame_lines(result.lines)
        pages += text_pages(pdf, title, tables)
        pages += text_pages(pdf, "Verdicts", _verdict_lines(result))
        for _name, fig in make_figures(result, campaign):
            pdf.savefig(fig)
            plt.close(fig)
            pages += 1
        pages += provenance_page(pdf, provenance)
    return pages
