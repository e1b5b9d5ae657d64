"""The PDF report of a study, typeset: the answer on page 1, then how it was reached.

Order: question, data and conclusion (page 1); methods with the paper's equations; the
verdict of every soil and response; the pooled parameters per condition (value ± σ, ε,
health); the ANOVA/ANCOVA tables; pairs against the reference; the preparation criteria;
notes; figures with captions; provenance. Every row of the study's JSON is in the PDF.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from .._text import plural
from ..outputs.files import output_path
from ..outputs.provenance import Provenance
from ..study.result import CRITERIA_COLUMNS, StudyResult, best_method_name
from .document import Document, Markup, strong
from .front import data_origin, front_page
from .labels import column_label, natural_key, natural_sorted
from .methods import write_equations
from .parameters import EQ4_NOTE, condition_table
from .study_figures import make_figures

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..study.spec import StudySpec

__all__ = ["write_report"]

_VERDICT_WORDS = {
    "effect": "changes with",
    "no relevant effect": "does not change relevantly with",
    "no effect detected": "shows no detectable change with",
    "inconclusive": "is inconclusive about",
}


def _response_label(spec: StudySpec, name: str) -> str:
    for r in spec.responses:
        if r.name == name:
            return r.label
    return {"phi": "friction angle φ", "c": "cohesion c", "line": "Mohr–Coulomb line"}.get(
        name, column_label(name)
    )


def _responses_text(spec: StudySpec) -> str:
    return ", ".join(r.label for r in spec.responses) or "the Mohr–Coulomb line: c and φ"


def _margin_text(spec: StudySpec, name: str) -> str:
    for r in spec.responses:
        if r.name == name and r.margin is not None:
            if r.margin_kind == "relative":
                return f"±{r.margin * 100:g} %"
            return f"±{r.margin:g}"
    return ""


def _size_text(row: pd.Series, spec: StudySpec) -> str:
    """The largest difference between two levels in physical words."""
    d = row.get("largest_difference")
    if d is None or not isinstance(d, int | float) or not math.isfinite(d):
        return ""
    name = row["response"]
    if name.startswith("log10_"):
        size = f"by a factor {10 ** abs(d):.2f} ({(10 ** abs(d) - 1) * 100:.0f} %)"
    elif name == "phi":
        size = f"by {abs(d):.2f}°"
    elif name == "c":
        size = f"by {abs(d):.0f} Pa"
    else:
        size = f"by {abs(d):.3g}"
    pair = row.get("largest_pair")
    if isinstance(pair, str) and pair:
        size += f" between {column_label(spec.factor)} {pair.replace(' vs ', ' and ')}"
    return size


def _conclusion(result: StudyResult) -> list[list]:
    spec = result.spec
    out: list[list] = []
    eff = result.effects
    if eff.empty:
        out.append(["No effect could be tested (see the notes)."])
    for soil in natural_sorted(eff["soil"].unique()) if not eff.empty else []:
        rows = eff[eff["soil"] == soil]
        parts: list = [strong(f"{soil}: ")]
        for i, (_, r) in enumerate(rows.iterrows()):
            words = _VERDICT_WORDS.get(r["verdict"], r["verdict"])
            label = _response_label(spec, r["response"])
            size = _size_text(r, spec)
            margin = _margin_text(spec, r["response"])
            text = (
                f"the {label} {words} {column_label(spec.factor)}"
                + (f" — largest difference {size}" if size else "")
                + (f", relevance margin {margin}" if margin else "")
                + f" (F = {r['statistic']:.3g}, Holm-adjusted p = {r['p_adjusted']:.2g}, "
                f"{int(r['n_tests'])} tests)"
            )
            parts.append(("; " if i else "") + text)
        parts.append(".")
        out.append(parts)
    if result.best is not None:
        out.append(
            [
                strong("Best preparation method: "),
                _best_and_reason(result.best),
            ]
        )
    out.append(["The paper found (", spec.paper, "): ", " ".join(spec.paper_finding.split())])
    return out


def _best_and_reason(best: dict) -> str:
    """The best method and why, in words: none named is "none", never Python's None."""
    reason = str(best["reason"])
    name = best_method_name(best)
    return f"{name} — {reason}" if best.get("best") is None else f"{name}. {reason}"


def _campaign_design(result: StudyResult) -> str:
    """The design of the tests this study analysed, read from them (never the paper's): the
    soils, the factor's levels with their test counts in natural order, and the blocks."""
    spec, tests = result.spec, result.per_test
    factor = spec.factor
    counts = tests[factor].astype(str).value_counts() if factor in tests else None
    levels = (
        ", ".join(
            f"{lv} ({plural(int(counts[lv]), 'test')})" for lv in natural_sorted(counts.index)
        )
        if counts is not None
        else "not recorded"
    )
    soils = ", ".join(natural_sorted(result.soils))
    blocks = [
        f"{column_label(b)} ({plural(int(tests[b].nunique()), 'value')})"
        for b in spec.blocks
        if b in tests and tests[b].nunique() > 1
    ]
    return (
        f"This campaign: {plural(len(tests), 'test')} of {soils} analysed; "
        f"{column_label(factor)}: {levels}"
        + (
            f"; blocking columns that vary: {', '.join(blocks)} (the notes say where one "
            "cannot be separated from the factor)."
            if blocks
            else "; no blocking column varies."
        )
    )


def _methods(doc: Document, result: StudyResult) -> None:
    spec = result.spec
    doc.heading("Methods")
    doc.paragraph(_campaign_design(result))
    doc.paragraph(
        f"The paper's design, for comparison ({spec.paper}): ", " ".join(spec.description.split())
    )
    write_equations(doc, (spec.kind,))
    if spec.kind == "shear":
        doc.paragraph(
            "Statistics: one point per test (mean σ, steady-state τ). ANCOVA (statsmodels OLS) "
            "compares one line, parallel lines and separate lines per level: φ by the slope test, "
            "c by a Wald test of equal intercepts in the separate-lines model, the whole line by "
            f"common against separate lines. Verdicts: Holm-adjusted p < {spec.alpha:g}."
        )
        return
    margins = "; ".join(
        f"{r.label}: {_margin_text(spec, r.name)}" for r in spec.responses if r.margin is not None
    )
    doc.paragraph(
        "Statistics: per-test responses (the Bernstein fit of each test, Eq. 8, and the pressure "
        f"at z_ref = {spec.z_ref_m * 1e3:g} mm). Type II two-way ANOVA (statsmodels) of each "
        f"response by {column_label(spec.factor)} with the blocks "
        f"{', '.join(column_label(b) for b in spec.blocks) or 'none'} where they vary (one-way "
        "if confounded)"
        + (
            f", {', '.join(column_label(b) for b in spec.random_blocks)} taken as random (the "
            f"factor tested against its interaction with them)"
            if spec.random_blocks
            else ""
        )
        + ", Tukey–Kramer pairs on the least-squares means of the blocked model, Holm-adjusted "
        f"verdicts at α = {spec.alpha:g}. Relevance margins: {margins or 'none declared'}. "
        "Verdicts: effect (significant and beyond the margin), no relevant effect (all "
        "simultaneous intervals within the margin), inconclusive, no effect detected."
    )


def _effects_table(doc: Document, result: StudyResult) -> None:
    spec = result.spec
    eff = result.effects
    doc.heading("Verdicts")
    if eff.empty:
        doc.paragraph("No test of the factor could be made.")
        return
    cols = [
        c
        for c in (
            "soil",
            "response",
            "statistic",
            "p_value",
            "p_adjusted",
            "effect_size",
            "n_tests",
            "largest_difference",
            "largest_pair",
            "margin",
            "verdict",
        )
        if c in eff.columns
    ]
    table = eff[cols].copy()
    table["response"] = [_response_label(spec, r) for r in table["response"]]
    doc.table(
        table,
        caption=f"Effect of {column_label(spec.factor)} per soil and response (Holm family: "
        + ("the whole study" if spec.family is None else f"each {spec.family}")
        + "). Largest difference and margin on the response's scale (log₁₀ for pressures). "
        "p is that of the test named below the table; where operators are random it is the "
        "larger of the F's p and that of the Welch-type test with one variance per level "
        "(both must reject).",
        labels={
            "statistic": "F",
            "effect_size": "η² (partial)",
            "largest_difference": "largest difference",
            "largest_pair": "between",
            "margin": "margin",
        },
        formats={"p_value": ".3g", "p_adjusted": ".3g", "effect_size": ".3f"},
    )
    tests = sorted(
        {
            f"{t} (blocks: {b or 'none'})"
            for t, b in zip(
                eff["test"], eff.get("blocks", pd.Series([""] * len(eff))).fillna(""), strict=True
            )
        }
    )
    doc.note("Tests: ", "; ".join(tests), ".")


def _parameter_tables(doc: Document, result: StudyResult) -> None:
    params = result.parameters
    doc.heading("Identified parameters per condition")
    if params.empty:
        doc.paragraph("No pooled identification (the study needs per-test responses only).")
        return
    doc.paragraph(
        f"Pooled weighted least-squares identification per soil and condition (Eq. 9): {EQ4_NOTE} "
        "Fit quality ε (Eq. 2), and the fit's health codes (docs/identification.md, health "
        "flags: what each means and what to do)."
    )
    factor = column_label(result.spec.factor)
    for soil in natural_sorted(params["soil"].unique()):
        g = params[params["soil"] == soil]
        conditions = []
        for cond, gc in g.groupby("condition", sort=False):
            gc = gc.set_index("parameter")
            first = gc.iloc[0]
            conditions.append(
                {
                    "condition": cond,
                    "model": ", ".join(sorted(set(gc["model"]))),
                    "params": gc["value"].to_dict(),
                    "stderr": gc["stderr"].to_dict(),
                    "stderr_eq4": gc["stderr_eq4"].to_dict() if "stderr_eq4" in gc else None,
                    "stderr_level": first.get("stderr_level"),
                    "units": gc["unit"].to_dict(),
                    "epsilon": first["epsilon"],
                    "tests": first["tests"],
                    "health": first["flags"] or "ok",
                }
            )
        condition_table(
            doc, conditions, caption=f"{soil}: parameters per {factor}.", condition_label=factor
        )


def _anova_tables(doc: Document, result: StudyResult) -> None:
    spec = result.spec
    doc.heading("ANCOVA model comparisons" if spec.kind == "shear" else "ANOVA tables")
    if result.anova.empty:
        doc.paragraph("None.")
    else:
        table = result.anova.drop(columns=[c for c in ("test",) if c in result.anova.columns])
        if "response" in table.columns:
            table["response"] = [_response_label(spec, r) for r in table["response"]]
        if "term" in table.columns:
            table["term"] = [column_label(t) if t != "Residual" else t for t in table["term"]]
        doc.table(
            table,
            caption="Analysis-of-variance tables behind the verdicts. A row '… (one variance "
            "per level)' holds the Welch-type statistic A and its bootstrap p; with it, the "
            "larger of its p and the F's above it decides.",
            labels={
                "PR(>F)": "p",
                "sum_sq": "sum of squares",
                "mean_sq": "mean square",
                "df_resid": "residual df",
                "ssr": "residual SS",
                "df_diff": "Δdf",
                "ss_diff": "ΔSS",
            },
            formats={"PR(>F)": ".3g"},
        )
    if not result.lines.empty:
        doc.table(
            result.lines,
            caption="Mohr–Coulomb line per level (separate-lines model, Eq. 15): intercept c "
            "(Pa), slope tan φ, friction angle φ (°), each with its standard error.",
            labels={
                "intercept": "c (Pa)",
                "intercept_stderr": "σ c (Pa)",
                "slope": "tan φ",
                "slope_stderr": "σ tan φ",
                "phi_deg": "φ (°)",
                "phi_stderr_deg": "σ φ (°)",
                "n": "tests",
            },
        )


def _pairs_and_criteria(doc: Document, result: StudyResult) -> None:
    spec = result.spec
    pairs = result.reference_pairs()
    if not pairs.empty:
        table = pairs.drop(columns=["reference"]).copy()
        table["response"] = [_response_label(spec, r) for r in table["response"]]
        doc.table(
            table,
            caption=f"Each level against the reference {pairs['reference'].iloc[0]} (Tukey HSD, "
            "simultaneous 95 % intervals, on the block-adjusted response).",
            labels={"relative_change": "relative change", "p_adj": "p (Tukey)"},
            formats={"p_adj": ".3g", "relative_change": "+.1%"},
        )
    if result.criteria is not None and not result.criteria.empty:
        doc.heading("Criteria of the preparation methods (Table 1)")
        crit = result.criteria.copy()
        crit = crit.iloc[
            sorted(
                range(len(crit)),
                key=lambda i: (
                    natural_key(crit["soil"].iloc[i]),
                    natural_key(crit["method"].iloc[i]),
                ),
            )
        ]
        doc.table(
            crit[CRITERIA_COLUMNS],
            caption="Criteria per method as the paper's Table 3 (+1 met, −1 not met; Σ the "
            "sum), with the mean per-test fit quality ε (criterion 3) and the test-to-test "
            "scatter.",
            labels={
                "crit1": "crit. 1",
                "crit2": "crit. 2",
                "crit3": "crit. 3",
                "score": "Σ",
                "epsilon": Markup("$epsilon$"),
                "scatter_cv": "scatter CV",
                "operator_p": "operator p",
            },
            formats={"epsilon": ".3f", "scatter_cv": ".3f", "operator_p": ".3g"},
        )
        doc.paragraph("Reasons per soil and method:")
        doc.bullets(
            [
                strong(f"{r['soil']}, method {r['method']}: "),
                f"[1] {r['crit1_reason']} [2] {r['crit2_reason']} [3] {r['crit3_reason']}",
            ]
            for _, r in crit.iterrows()
        )
        if result.best is not None:
            doc.paragraph(
                strong("Best method: "),
                _best_and_reason(result.best),
                ". Ranking: " if result.best.get("ranking") else "",
                ", ".join(map(str, result.best.get("ranking") or [])),
            )


def write_report(
    result: StudyResult,
    path: str | Path,
    *,
    campaign: Campaign,
    provenance: Provenance | None = None,
    overwrite: bool = False,
) -> int:
    """Write the typeset PDF report of ``result`` (a study of ``campaign``) to ``path``;
    return the number of pages.

    The last page and the PDF metadata carry ``provenance`` (default: the result's); an
    existing file is an error unless ``overwrite`` (the signature of every report writer:
    docs/conventions.md).
    """
    spec = result.spec
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    provenance = provenance or result.provenance or Provenance.of(campaign, seed=result.seed)
    doc = Document(
        spec.title,
        subtitle=f"soilstats study {spec.name} — after Apfelbeck et al. (2011), {spec.paper}",
        provenance=provenance,
    )
    n_tests = len(result.per_test)
    front_page(
        doc,
        question=[
            f"Does the {column_label(spec.factor)} change the identified soil behaviour "
            f"({_responses_text(spec)})"
            f" of {', '.join(natural_sorted(result.soils))}?"
        ],
        data=[
            data_origin(result.source),
            f": {n_tests} {spec.kind} tests of {len(result.soils)} soil(s)",
            f", recorded {result.date}" if result.date else "",
            ". Levels of the factor: ",
            ", ".join(map(str, natural_sorted(result.per_test[spec.factor].dropna().unique())))
            if spec.factor in result.per_test.columns
            else "–",
            ".",
        ],
        conclusion=_conclusion(result),
        defaults=getattr(result, "defaults", None),
        default_warnings=getattr(result, "default_warnings", None),
    )
    if result.notes:
        doc.heading("Notes", level=2)
        doc.numbered(result.notes)
    doc.page_break()
    _methods(doc, result)
    _effects_table(doc, result)
    _parameter_tables(doc, result)
    _anova_tables(doc, result)
    _pairs_and_criteria(doc, result)
    figures = make_figures(result, campaign)
    if figures:
        doc.heading("Figures")
        for _name, fig, caption in figures:
            doc.figure(fig, caption)
    doc.provenance_section()
    return doc.render(path)
