"""The PDF report of a discovery, typeset: what the model gets wrong, the cause, the gain.

Page 1 answers in sentences (causes, kept extensions and their held-out gain, the combined
model, what the data cannot tell). Then: methods; one section per finding (its evidence, a
figure of the misfit per test and on the curves, the extended parameters ± σ, what else was
tried, caveats); the combined model per kind and soil; physical red flags; candidates lined
up with data-quality artefacts; what the design could not detect (power); the data-quality
screening; every column's role; confounded candidates; notes; provenance. Everything the
discovery JSON holds is in the PDF. Reads a :class:`DiscoveryResult` only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from .._text import plural
from ..discovery.candidates import candidate_values
from ..discovery.result import METHOD_NOTES
from .document import Document, strong
from .files import output_path
from .front import data_origin, front_page
from .labels import column_label, natural_key, natural_sorted
from .methods import write_equations
from .parameters import fit_table

__all__ = ["write_report"]

_RESPONSES = {
    "level": "level (ln of the test's pressure over the base model's)",
    "shape": "shape (the test's exponent n minus the base n)",
    "K": "K (ln of the test's shear modulus over the base K)",
}


def _shows_in(f) -> str:
    """The responses in physical words: level → stiffness (or shear strength), shape → n."""
    words = {
        "level": "the stiffness (pressure level)" if f.kind == "sinkage" else "the shear strength",
        "shape": "the exponent n",
        "K": "the shear modulus K",
    }
    return " and ".join(words.get(r, r) for r in f.responses)


def _gain_words(g) -> str:
    return (
        f"{g.relative:+.1%} in held-out error ({g.base:.4f} → {g.extended:.4f}, "
        f"{g.scheme} cross-validation, {g.folds} folds, {g.n_tests} tests)"
    )


def _all_groups_words(g) -> str:
    return (
        f"All extended groups together: {g.base:.4f} → {g.extended:.4f} "
        f"({g.relative:+.1%}, {g.n_tests} held-out tests)."
    )


def _conclusion(result, all_groups) -> list:
    out: list = []
    n_tests = result.tests_run
    if not result.findings:
        out.append(
            [
                strong("No cause found. "),
                f"No candidate passes its test at α = {result.alpha:g} (Holm over {n_tests} "
                "tests). Silence is not proof of no effect: the section on power gives the "
                f"smallest effect the design would have found for each of the {len(result.power)} "
                "candidates not found.",
            ]
        )
    for i, f in enumerate(result.findings, 1):
        conf = f" (confounded with {', '.join(f.confounded_with)})" if f.confounded_with else ""
        parts: list = [
            strong(f"[{i}] {f.kind} / {f.soil}: "),
            f"{_shows_in(f)} change{'' if len(f.responses) > 1 else 's'} with "
            f"{column_label(f.cause)}{conf}"
            f" (F = {f.statistic:.3g}, Holm-adjusted p = "
            f"{f.p_adjusted:.2g}, {f.n_tests} tests). ",
        ]
        if f.extension and f.gain is not None:
            parts.append(f"Kept extension: {f.extension}, gain {_gain_words(f.gain)}.")
        else:
            parts.append("No extension was kept (none gained on held-out tests and was plausible).")
        if f.caveats:
            parts.append(f" {len(f.caveats)} caveat(s) below.")
        out.append(parts)
    for m in result.models:
        if m.extensions and m.gain is not None:
            out.append(
                [
                    strong(f"Combined model, {m.kind} / {m.soil}: "),
                    " + ".join(m.extensions),
                    f", gain {_gain_words(m.gain)}.",
                ]
            )
    if all_groups is not None:
        out.append(_all_groups_words(all_groups))
    if result.artefacts:
        out.append(
            f"{len(result.artefacts)} significant candidate(s) line up with data-quality "
            "artefacts and are reported as data problems, never as causes."
        )
    q = result.quality or {}
    if q.get("tests"):
        out.append(
            f"Data quality: {len(q['tests'])} test(s) carry screening codes "
            f"({', '.join(f'{c} in {n}' for c, n in q['counts'].items())}); "
            f"{q['excluded_samples']} samples were left out of every fit."
        )
    if result.flags:
        out.append(f"{len(result.flags)} physical red flag(s) on the fits (section below).")
    return out


def _finding_figure(f) -> Figure | None:
    """Per-test deviations against the cause, and one test per level with both models."""
    g, rows = f.group, f.scope_rows
    if g is None or rows is None:
        return None
    fig = Figure(figsize=(6.5, 6.2), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, height_ratios=(1, 1.3))
    response = f.responses[0] if f.responses else "level"
    dev = g.tests[f"_dev_{response}"].to_numpy(float)[rows]
    values = candidate_values(g.tests, f.cause).to_numpy()[rows]
    labels = natural_sorted({str(v) for v in values})
    pos = {lv: i for i, lv in enumerate(labels)}
    xs = np.array([pos[str(v)] for v in values], float)
    jitter = np.random.default_rng(0).uniform(-0.15, 0.15, xs.size)  # display only
    ax1.scatter(xs + jitter, dev, s=12, alpha=0.7)
    for i in pos.values():
        m = dev[xs == i]
        if m.size:
            ax1.hlines(np.nanmean(m), i - 0.3, i + 0.3, color="k")
    ax1.axhline(0, color="0.6", lw=0.8)
    ax1.set_xticks(range(len(labels)), labels, fontsize=7, rotation=30 if len(labels) > 6 else 0)
    ax1.set_xlabel(column_label(f.cause))
    ax1.set_ylabel(f"deviation in {response}")
    if f.base_fitted is not None and f.fitted is not None:
        colours = [f"C{i}" for i in range(10)]
        for colour, lv in zip(colours, labels[:8], strict=False):
            pick = rows[[str(v) == lv for v in values]]
            if not pick.size:
                continue
            one = pick[:1]
            mask = g.samples_of(one)
            xk = "z" if g.kind == "sinkage" else "j"
            x = g.x[xk][mask]
            order = np.argsort(x)
            ax2.plot(x[order] * 1e3, g.y[mask][order] / 1e3, ".", ms=2, color=colour, label=f"{lv}")
            yb = f.base_fitted.extension.predict(f.base_fitted, g, one)
            ye = f.fitted.extension.predict(f.fitted, g, one)
            ax2.plot(x[order] * 1e3, yb[order] / 1e3, "--", color=colour, lw=0.9)
            ax2.plot(x[order] * 1e3, ye[order] / 1e3, "-", color=colour, lw=1.2)
        ax2.set_xlabel("sinkage z (mm)" if g.kind == "sinkage" else "shear displacement j (mm)")
        ax2.set_ylabel("pressure p (kPa)" if g.kind == "sinkage" else "shear stress τ (kPa)")
        ax2.legend(title=column_label(f.cause), fontsize=7, title_fontsize=7, ncol=2)
    else:
        ax2.text(0.5, 0.5, "no extended model could be fitted", ha="center")
        ax2.set_axis_off()
    return fig


def _finding_section(doc: Document, i: int, f) -> None:
    doc.heading(f"[{i}] {f.kind} / {f.soil}: {f.cause}", level=2)
    rows = [
        ("cause", f"{f.cause} ({column_label(f.cause)})"),
        ("confounded with", ", ".join(f.confounded_with) or "nothing"),
        ("shows in", "; ".join(_RESPONSES.get(r, r) for r in f.responses)),
        (
            "test",
            f"F = {f.statistic:.4g}, partial η² = {f.effect_size:.3f}, p = "
            f"{f.p_value:.3g}, Holm-adjusted p = {f.p_adjusted:.3g}, {f.n_tests} tests",
        ),
        ("extension kept", f.extension or "none"),
    ]
    if f.gain is not None:
        g = f.gain
        rows.append(
            (
                "gain (tests left out, cause fixed)",
                f"{_gain_words(g)}; paired difference "
                f"{g.difference:.3g} ± {g.stderr:.2g} ({g.z:.1f} SE); real: {g.real}",
            )
        )
    if f.gain_search is not None:
        g = f.gain_search
        rows.append(
            (
                "gain of the whole search",
                f"{g.relative:+.1%} when each fold re-selects the lead on its training tests "
                f"(chosen in {g.selected_folds} of {g.folds} folds; reported, not deciding)",
            )
        )
    if f.gain_conditions is not None:
        g = f.gain_conditions
        rows.append(("gain (conditions left out)", f"{_gain_words(g)}; real: {g.real}"))
    for key, value in f.information.items():
        rows.append((key.replace("_", " "), f"{value:.6g}" if isinstance(value, float) else value))
    doc.key_values(rows)
    fig = _finding_figure(f)
    if fig is not None:
        doc.figure(
            fig,
            f"{f.kind} / {f.soil}, cause {f.cause}. Top: each test's deviation in "
            f"{f.responses[0] if f.responses else 'level'} from the base model (black bars: "
            "level means) — the structure the base model leaves. Bottom: one test per level "
            "(at most eight): measured samples (dots), base model (dashed) and "
            f"{f.extension or 'extension'} (solid).",
        )
    fit_table(doc, f.fit, f"Parameters of {f.extension} ± σ (Eqs. 3–5).", f.test_level)
    if f.tried:
        tried = pd.DataFrame(
            [
                {
                    "extension": t.get("extension"),
                    "description": t.get("description", ""),
                    "gain": t.get("relative"),
                    "search": t.get("relative_search"),
                    "real": t.get("real"),
                    "physical": t.get("physical"),
                    "outcome": t.get("error")
                    or (
                        "kept" if t.get("extension") == f.extension else t.get("reason", "not kept")
                    ),
                }
                for t in f.tried
            ]
        )
        doc.table(
            tried,
            caption="Every extension tried for this cause: its gain with the cause fixed "
            "(deciding) and that of the whole search (each fold re-selecting the lead).",
            formats={"gain": "+.1%", "search": "+.1%"},
        )
    if f.caveats:
        doc.paragraph(strong("Caveats:"))
        doc.bullets(f.caveats)


def _record_table(doc: Document, records, columns, caption, labels=None) -> None:
    frame = pd.DataFrame([{c: r.get(c) for c in columns} for r in records])
    if not frame.empty:
        doc.table(frame, caption=caption, labels=labels, align_numbers=False)


def _record_section(doc: Document, title, records, columns, caption, *, empty, labels=None):
    """A section of records as a table, or the sentence ``empty`` when there are none."""
    doc.heading(title)
    if records:
        _record_table(doc, records, columns, caption, labels)
    else:
        doc.paragraph(empty)


def _model_section(doc: Document, result, all_groups) -> None:
    doc.heading("Combined model")
    if not result.models:
        doc.paragraph("No kept extension, so no combined model: the base models stand.")
        return
    doc.paragraph(
        "Forward selection over each finding's best plausible extension, on all tests of each "
        "kind and soil with one fold set for every step: an extension is added only on a real "
        "cross-validated gain over the model before it, and only if the combined fit is "
        "physically plausible and its parameters are determined."
    )
    for m in result.models:
        doc.heading(f"{m.kind} / {m.soil}", level=2)
        if not m.extensions:
            doc.paragraph("Base model: no extension adds a real gain on all tests.")
        else:
            doc.paragraph(
                " + ".join(m.extensions),
                f" (causes: {', '.join(m.causes)}); gain ",
                _gain_words(m.gain) if m.gain is not None else "not measured",
                ".",
            )
        fit_table(doc, m.fit, f"{m.kind} / {m.soil}: combined model parameters ± σ.", m.test_level)
        if m.caveats:
            doc.paragraph(strong("Caveats:"))
            doc.bullets(m.caveats)
        if m.steps:
            steps = pd.DataFrame(
                [
                    {
                        "extension": s["extension"],
                        "cause": s.get("cause"),
                        "added": s["added"],
                        "gain": s.get("relative"),
                        "reason": s["reason"],
                    }
                    for s in m.steps
                ]
            )
            doc.table(steps, caption="Selection steps, in order.", formats={"gain": "+.1%"})
    if all_groups is not None:
        doc.paragraph(_all_groups_words(all_groups))


def _power_section(doc: Document, result) -> None:
    doc.heading("What the design could not detect")
    if not result.power:
        doc.paragraph("Every candidate tested was either found or not testable (see the notes).")
        return
    first = result.power[0]
    doc.paragraph(
        "For each candidate tested and not found: the smallest effect the design would have "
        f"found with {first['power']:.0%} power at Holm's strictest level α/m = "
        f"{first['alpha_level']:.2g} (noncentral F), in physical units."
    )
    rows = [
        {
            "group": f"{p['kind']} / {p['soil']}",
            "candidate": p["candidate"],
            "role": p["role"],
            "tests": p["n_tests"],
            "response": r,
            "p": v.get("p_value"),
            "smallest detectable effect": v["statement"],
        }
        for p in result.power
        for r, v in p["responses"].items()
    ]
    doc.table(
        pd.DataFrame(rows),
        caption="Minimum detectable effects.",
        formats={"p": ".3g"},
        align_numbers=False,
    )


def _quality_section(doc: Document, result) -> None:
    q = result.quality
    doc.heading("Data quality")
    if not q:
        doc.paragraph("No screening record.")
        return
    if q["mode"] == "off":
        doc.paragraph("Screening was off: nothing was checked.")
        return
    counts = (
        ", ".join(f"{c} in {plural(n, 'test')}" for c, n in q["counts"].items()) or "no findings"
    )
    doc.paragraph(
        f"Screening in {q['mode']} mode (docs/quality.md: what each code means and what to "
        f"do): {counts}; {q['excluded_samples']} samples left out of every fit. These are data "
        "problems, never causes."
    )
    if q["tests"]:
        frame = pd.DataFrame(
            [
                {"kind": t["kind"], "test": t["test_id"], "codes": ", ".join(t["codes"])}
                for t in q["tests"]
            ]
        )
        frame = frame.iloc[
            sorted(range(len(frame)), key=lambda i: natural_key(frame["test"].iloc[i]))
        ]
        doc.table(frame, caption="Tests with screening codes.")


def _columns_section(doc: Document, result) -> None:
    doc.heading("Columns and their roles")
    doc.paragraph(
        "Every varying column of the log, classified as a design factor, covariate, time/order, "
        "outcome or bookkeeping (docs/discover.md). Outcomes — quantities the test's own result "
        "determines — never enter as causes."
    )
    _record_table(
        doc,
        result.columns,
        ("kind", "soil", "column", "role", "tested", "reason"),
        "Candidate columns per kind and soil.",
    )


def write_report(
    result,
    folder: Path,
    *,
    name: str = "discover.pdf",
    overwrite: bool = False,
) -> Path:
    """Write the typeset PDF report into ``folder`` (created if needed); returns its path.

    The last page and the PDF metadata carry the result's provenance; an existing file is
    an error unless ``overwrite``.
    """
    path = output_path(folder, name, overwrite=overwrite)
    doc = Document(
        "What the soil model gets wrong",
        subtitle="soilstats discover — model discovery after Apfelbeck et al. (2011)",
        provenance=result.provenance,
    )
    groups = natural_sorted({f"{c['kind']} / {c['soil']}" for c in result.columns})
    all_groups = result.all_groups_gain()  # page 1 and the model section share it
    front_page(
        doc,
        question=[
            "Where does the soil model (Bekker/Bernstein for sinkage, Janosi–Hanamoto for shear) "
            "miss the measured curves systematically, which recorded property of the tests "
            "explains the misfit, and how much does extending the model gain on tests it has "
            "not seen?"
        ],
        data=[
            data_origin(result.source),
            f"; groups analysed: {', '.join(groups) or 'none'}; "
            f"α = {result.alpha:g}, seed {result.seed}.",
        ],
        conclusion=_conclusion(result, all_groups),
    )
    doc.page_break()
    doc.heading("Methods")
    write_equations(
        doc, tuple(natural_sorted({c["kind"] for c in result.columns})) or ("sinkage", "shear")
    )
    doc.bullets(METHOD_NOTES)
    doc.heading("Findings")
    if not result.findings:
        doc.paragraph(result.no_finding_text())
    for i, f in enumerate(result.findings, 1):
        _finding_section(doc, i, f)
    if result.explained:
        doc.heading("Explained by a stronger finding", level=2)
        doc.bullets(
            f"{e['kind']} / {e['soil']}: {e['candidate']} (by {e['by']}; p after = "
            f"{e['p_after']:.3g})"
            for e in result.explained
        )
    _model_section(doc, result, all_groups)
    _record_section(
        doc,
        "Physical red flags",
        result.flags,
        ("kind", "soil", "scope", "code", "message"),
        "Red flags on the fits (docs/identification.md, health flags).",
        empty="No red flags.",
    )
    _record_section(
        doc,
        "Lined up with data-quality artefacts",
        result.artefacts,
        ("kind", "soil", "candidate", "p_adjusted", "reason"),
        "Significant candidates whose levels line up with artefact flags: data problems, "
        "not causes.",
        empty="No significant candidate lines up with data-quality artefacts.",
        labels={"p_adjusted": "p (Holm)"},
    )
    _power_section(doc, result)
    _quality_section(doc, result)
    _columns_section(doc, result)
    doc.heading("Confounded candidates")
    if result.confounded:
        doc.bullets(f"{c['kind']} / {c['soil']}: {c['text']}" for c in result.confounded)
    else:
        doc.paragraph("None: every pair of candidates can be told apart by this design.")
    doc.heading("Notes")
    doc.numbered(list(result.notes) or ["No further notes."])
    doc.provenance_section()
    doc.render(path)
    return path
