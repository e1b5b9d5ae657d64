"""The PDF report of a discovery, typeset: what the model gets wrong, the cause, the gain.

Of publishable length (issue #36: at most 12 pages on every bundled campaign). The main body
says the conclusion, shows the evidence in figures and short tables, and ends: page 1
answers (one short table of the findings, the combined models and what else the reader must
know); then the findings as a grid of figures (per finding its per-test deviations against
the cause and one measured curve per level with both models; titles state the effect and
the gain), the combined model per kind and soil with its parameters (value ± the test-level
σ, Eq. 4's in brackets), the red flags and data problems, and the methods. Every exhaustive
list goes to ONE appendix table in small print: the statistics of each finding, the
parameters of each finding's extension, every extension tried, the selection steps, the
caveats (each printed once), what the design could not detect, the screening, the columns,
the confounded candidates (aliases in one line each), and the notes. Everything the
discovery JSON holds is in the PDF. Reads a :class:`DiscoveryResult` only.
"""

from __future__ import annotations

import math
import re
import textwrap
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from .._text import plural
from ..discovery.candidates import candidate_values
from ..discovery.result import METHOD_NOTES, DiscoveryResult, Finding
from ..evidence import REAL_SE, RULE
from ..outputs.files import output_path
from ..outputs.provenance import Provenance
from .document import GRID_STYLE, Document, strong
from .front import data_origin, front_page
from .labels import column_label, natural_key, natural_sorted
from .methods import write_equations
from .parameters import EQ4_NOTE, fit_rows, fit_table

if TYPE_CHECKING:
    from ..discovery.crossval import Gain

__all__ = ["write_report"]

#: Findings per figure (two per row: deviations and curves side by side).
_PER_FIGURE = 6
#: Levels drawn in a finding's curve panel (spread over its sorted levels).
_CURVES = 4
#: Above this many distinct values a numeric cause is drawn on its own axis, with a trend.
_MAX_LEVELS = 12

_SIGMA_NOTE = (
    f"{EQ4_NOTE} In discovery the test-level σ is the bootstrap's linearised form, "
    "cluster-robust over tests and judged per parameter (docs/discover.md §4a): † where fewer "
    "than five tests inform the parameter or one test alone sets it — there the scatter "
    "between tests could not be measured; * where it exceeds Eq. 4's by more than 2× "
    "(TEST-SCATTER)."
)


def _shows_in(f) -> str:
    """The responses in physical words: level → stiffness (or shear strength), shape → n."""
    words = {
        "level": "stiffness" if f.kind == "sinkage" else "shear strength",
        "shape": "exponent n",
        "K": "shear modulus K",
    }
    return ", ".join(words.get(r, r) for r in f.responses)


def _gain_words(g) -> str:
    return (
        f"{g.relative:+.1%} in held-out error ({g.base:.4f} → {g.extended:.4f}, "
        f"{g.scheme} cross-validation, {g.folds} folds, {g.n_tests} tests; {g.text()})"
    )


def _schemes(f) -> list[tuple[str, Gain]]:
    """The held-out gains measured for a finding's extension: (scheme in words, Gain)."""
    out = [("tests held out", f.gain)]
    if f.gain_search is not None:
        out.append(("the whole search nested", f.gain_search))
    if f.gain_conditions is not None:
        out.append(("a whole condition held out", f.gain_conditions))
    return [(name, g) for name, g in out if g is not None and np.isfinite(g.relative)]


def _worst_scheme(f) -> tuple[str, Gain] | None:
    """The held-out scheme in which a kept extension does worst, where it is another than the
    one that kept it (tests held out, the cause fixed)."""
    schemes = _schemes(f)
    if f.extension is None or len(schemes) < 2:
        return None
    worst = min(schemes[1:], key=lambda s: s[1].relative)
    return worst if worst[1].relative < schemes[0][1].relative else None


def _gain_cell_page1(g) -> str:
    return f"{g.relative:+.1%}; {g.text()}"


def _all_groups_words(g) -> str:
    return (
        f"All extended groups together: {g.base:.4f} → {g.extended:.4f} "
        f"({g.relative:+.1%}, {g.n_tests} held-out tests)."
    )


def _group(record) -> str:
    return f"{record['kind']} / {record['soil']}"


# -- page 1 ---------------------------------------------------------------------------------


def _words_count(result) -> str:
    """How many kept extensions' gains are real, and how many weak (soilstats.evidence)."""
    words = [
        f.gain.verdict for f in result.findings if f.extension is not None and f.gain is not None
    ]
    real, weak = words.count("real"), words.count("weak")
    return f"{real} of them real (≥ {REAL_SE:g} standard errors)" + (
        f", {weak} kept on a weak gain (below {REAL_SE:g} standard errors)" if weak else ""
    )


def _conclusion(result, all_groups) -> list:
    """Page 1's conclusion, one paragraph (a list of runs) each: the causes found or the
    silence, where kept extensions fail out of sample, the combined model, the parameters
    that disagree, and everything else the reader should know."""
    out: list = _causes_paragraphs(result)
    combined = _combined_model_paragraph(result, all_groups)
    if combined is not None:
        out.append(combined)
    disagree = _disagreement_paragraph(result)
    if disagree is not None:
        out.append(disagree)
    also = _also_paragraph(result)
    if also is not None:
        out.append(also)
    return out


def _causes_paragraphs(result) -> list:
    """No cause found (and what the silence does not prove), or the causes found with the
    extensions kept, then where a kept extension fails out of sample."""
    out: list = []
    n_tests = result.tests_run
    if not result.findings:
        out.append(
            [
                strong("No cause found. "),
                f"No candidate passes its test at α = {result.alpha:g} (Holm over {n_tests} "
                "tests). Silence is not proof of no effect: the appendix gives the smallest "
                f"effect the design would have found for each of the {len(result.power)} "
                "candidates not found.",
            ]
        )
    else:
        kept = sum(f.extension is not None and f.gain is not None for f in result.findings)
        groups = len({(f.kind, f.soil) for f in result.findings})
        out.append(
            [
                strong(
                    f"{plural(len(result.findings), 'cause')} of misfit in "
                    f"{plural(groups, 'group')}: "
                ),
                f"each passes its F-test at α = {result.alpha:g} (Holm over {n_tests} tests); "
                f"{kept} keep an extension that predicts held-out tests better (Table 1; "
                "the evidence in the figures of the next pages), "
                f"{_words_count(result)}.",
            ]
        )
        failures = _failures_out_of_sample(result)
        if failures:
            out.append(
                [
                    strong("Where a kept extension fails out of sample: "),
                    "; ".join(failures)
                    + ". An extension that does not carry to an unseen condition describes the "
                    "conditions measured, not new ones.",
                ]
            )
    return out


def _combined_model_paragraph(result, all_groups) -> list | None:
    """The extensions of each group's combined model with their held-out gain, and all
    extended groups together (None: no group's model is extended)."""
    extended = [m for m in result.models if m.extensions and m.gain is not None]
    if not extended:
        return None
    parts: list = [strong("Combined model: ")]
    parts.append(
        "; ".join(
            f"{m.kind} / {m.soil}: {' + '.join(m.extensions)} "
            f"({m.gain.relative:+.1%} in held-out error, {m.gain.n_tests} tests; "
            f"{m.gain.text()})"
            for m in extended
        )
        + ". "
    )
    if all_groups is not None:
        parts.append(_all_groups_words(all_groups))
    return parts


def _disagreement_paragraph(result) -> list | None:
    """The parameters that disagree between a finding's fit and the combined model (None:
    none do)."""
    disagree = [
        f"{d['kind']} / {d['soil']}: {line}"
        for d, line in zip(result.disagreements(), result.disagreement_lines(), strict=True)
    ]
    if not disagree:
        return None
    return [
        strong("Parameters that disagree between the finding and the combined model: "),
        "; ".join(disagree) + ".",
    ]


def _also_paragraph(result) -> list | None:
    """ "Also": the caveats, physical red flags, artefacts, screening codes and untested
    groups, counted (None: there are none)."""
    said = []
    caveats = sum(len(f.caveats) for f in result.findings)
    if caveats:
        said.append(f"{plural(caveats, 'caveat')} on the findings (appendix)")
    if result.flags:
        said.append(f"{len(result.flags)} physical red flag(s) on the fits")
    if result.artefacts:
        said.append(
            f"{len(result.artefacts)} significant candidate(s) line up with data-quality "
            "artefacts: data problems, never causes"
        )
    q = result.quality or {}
    if q.get("tests"):
        said.append(
            f"{len(q['tests'])} test(s) carry screening codes "
            f"({', '.join(f'{c} in {n}' for c, n in q['counts'].items())}); "
            f"{q['excluded_samples']} samples were left out of every fit"
        )
    if result.untested:
        said.append(f"{plural(len(result.untested), 'group')} could not be tested (notes)")
    if not said:
        return None
    return [strong("Also: "), "; ".join(said) + "."]


def _findings_table(doc: Document, result) -> None:
    rows = [
        {
            "#": f"[{i}]",
            "group": _group({"kind": f.kind, "soil": f.soil}),
            "cause": f.cause
            + (f" (confounded with {', '.join(f.confounded_with)})" if f.confounded_with else ""),
            "shows in": _shows_in(f),
            "Holm p": f.p_adjusted,
            "tests": f.n_tests,
            "extension kept": f.extension or "none",
            "held-out gain (tests)": _gain_cell_page1(f.gain)
            if f.extension and f.gain is not None
            else "–",
            "worst held-out scheme": _worst_cell(f),
        }
        for i, f in enumerate(result.findings, 1)
    ]
    doc.table(
        pd.DataFrame(rows),
        caption="The causes found, strongest first: where the per-test responses change with "
        "the cause, and the extension kept with its gain in held-out error: tests left out "
        "with the cause fixed (what decides keeping), and beside it the worst other scheme "
        "measured (a whole condition left out, or the whole search nested). Gain: relative "
        f"change of the RMS error; then the paired difference ± its standard error; {RULE}.",
        formats={"Holm p": ".2g", "tests": ".0f"},
        align_numbers=False,
        widths=["auto", "auto", "1.2fr", "1fr", "auto", "auto", "1fr", "1.3fr", "1.3fr"],
    )


def _worst_cell(f) -> str:
    worst = _worst_scheme(f)
    if worst is None:
        return "–" if f.extension is None else "no other scheme measured"
    name, g = worst
    return f"{name}: {_gain_cell_page1(g)}"


def _failures_out_of_sample(result) -> list[str]:
    """Sentences for page 1: kept extensions that predict worse, or gain nothing real, in
    another held-out scheme than the one that kept them."""
    out = []
    for f in result.findings:
        worst = _worst_scheme(f)
        if worst is None or worst[1].verdict == "real":
            continue
        name, g = worst
        out.append(
            f"{_group({'kind': f.kind, 'soil': f.soil})} {f.extension}: {f.gain.relative:+.1%} "
            f"with tests held out but {g.relative:+.1%} with {name} ({g.verdict})"
        )
    return out


# -- the findings' figures ------------------------------------------------------------------


def _numeric(labels: list[str]) -> list[float] | None:
    try:
        return [float(v) for v in labels]
    except ValueError:
        return None


def _response_words(f, response: str) -> str:
    if response == "level":
        return "pressure" if f.kind == "sinkage" else "shear strength"
    return {"shape": "n", "K": "K"}.get(response, response)


def _change(f, response: str, delta: float) -> str:
    """A change of the per-test response in physical words: a factor on the log responses
    (level, K), a difference in n (shape)."""
    if response == "shape":
        return f"{_response_words(f, response)} {delta:+.2g}"
    return f"{_response_words(f, response)} ×{math.exp(delta):.2g}"


def _short(text: str, n: int = 14) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"


def _deviation_panel(ax, f) -> str:
    """Each test's deviation against the cause (means per level, or a trend on a numeric
    cause of many values); returns the effect in words, for the title."""
    g, rows = f.group, f.scope_rows
    response = f.responses[0] if f.responses else "level"
    dev = g.tests[f"_dev_{response}"].to_numpy(float)[rows]
    values = candidate_values(g.tests, f.cause).to_numpy()[rows]
    labels = natural_sorted({str(v) for v in values})
    numbers = _numeric(labels)
    if numbers is not None and len(labels) > _MAX_LEVELS:
        x = values.astype(float)
        ax.scatter(x, dev, s=4, alpha=0.6)
        ok = np.isfinite(x) & np.isfinite(dev)
        slope, icept = np.polyfit(x[ok], dev[ok], 1)
        span = np.array([x[ok].min(), x[ok].max()])
        ax.plot(span, icept + slope * span, color="k", lw=0.9)
        effect = f"{_change(f, response, slope * (span[1] - span[0]))} over its range"
    else:
        xs = np.array([labels.index(str(v)) for v in values], float)
        jitter = np.random.default_rng(0).uniform(-0.15, 0.15, xs.size)  # display only
        ax.scatter(xs + jitter, dev, s=4, alpha=0.6)
        means = np.array(
            [np.nanmean(dev[xs == k]) if (xs == k).any() else np.nan for k in range(len(labels))]
        )
        for k, m in enumerate(means):
            if np.isfinite(m):
                ax.hlines(m, k - 0.3, k + 0.3, color="k", lw=1.1)
        many = len(labels) > 4 or sum(map(len, labels)) > 24
        ax.set_xticks(
            range(len(labels)),
            [_short(lv, 10) for lv in labels],
            rotation=40 if many else 0,
            ha="right" if many else "center",
            rotation_mode="anchor",
        )
        if numbers is not None and len(labels) > 1:
            effect = (
                f"{_change(f, response, means[-1] - means[0])} from {labels[0]} to {labels[-1]}"
            )
        else:
            spread = float(np.nanmax(means) - np.nanmin(means))
            effect = f"{_change(f, response, spread)} between its {len(labels)} levels"
    ax.axhline(0, color="0.6", lw=0.6)
    ax.set_xlabel(_short(column_label(f.cause), 44))
    ax.set_ylabel(f"deviation in {response}")
    return effect


def _curve_panel(ax, f) -> str:
    """One test per level (at most four, spread over the levels): measured samples, base
    model (dashed), extension (solid); returns the gain in words, for the title."""
    g, rows = f.group, f.scope_rows
    name = f.extension or "no extension kept"
    gain = (
        f"held-out error {f.gain.base:.3f} → {f.gain.extended:.3f} ({f.gain.relative:+.0%})"
        if f.gain is not None
        else "no held-out gain measured"
    )
    if f.base_fitted is None or f.fitted is None:
        ax.text(
            0.5,
            0.5,
            "no extended model\ncould be fitted",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
        ax.set_axis_off()
        return f"{name}: {gain}"
    values = candidate_values(g.tests, f.cause).to_numpy()[rows]
    labels = natural_sorted({str(v) for v in values})
    if len(labels) > _CURVES:
        labels = [labels[k] for k in np.linspace(0, len(labels) - 1, _CURVES).round().astype(int)]
    xk = "z" if g.kind == "sinkage" else "j"
    for k, lv in enumerate(labels):
        pick = rows[[str(v) == lv for v in values]]
        if not pick.size:
            continue
        one, colour = pick[:1], f"C{k}"
        mask = g.samples_of(one)
        x = g.x[xk][mask]
        order = np.argsort(x)
        ax.plot(x[order] * 1e3, g.y[mask][order] / 1e3, ".", ms=1.5, color=colour, label=_short(lv))
        yb = f.base_fitted.extension.predict(f.base_fitted, g, one)
        ye = f.fitted.extension.predict(f.fitted, g, one)
        ax.plot(x[order] * 1e3, yb[order] / 1e3, "--", color=colour, lw=0.8)
        ax.plot(x[order] * 1e3, ye[order] / 1e3, "-", color=colour, lw=1.1)
    ax.set_xlabel("sinkage z (mm)" if g.kind == "sinkage" else "shear displacement j (mm)")
    ax.set_ylabel("p (kPa)" if g.kind == "sinkage" else "τ (kPa)")
    ax.legend(ncol=2, frameon=False, handletextpad=0.2, columnspacing=0.6, markerscale=3)
    return f"{name}: {gain}"


def _findings_figure(numbered: list[tuple[int, Finding]]) -> Figure:
    """A grid of findings, two per row: each its deviation and curve panels under a title
    that states the effect and the gain."""
    import matplotlib as mpl

    per_row = 2 if len(numbered) > 1 else 1
    rows = math.ceil(len(numbered) / per_row)
    with mpl.rc_context(GRID_STYLE):
        fig = Figure(figsize=(6.5, 2.3 * rows + (0.5 if rows == 1 else 0)), layout="constrained")
        grid: Any = fig.subfigures(rows, per_row, wspace=0.03, hspace=0.02)  # one or an array
        subs = np.atleast_1d(grid).ravel()
        for k, sub in enumerate(subs):
            if k >= len(numbered):
                continue
            i, f = numbered[k]
            ax1, ax2 = sub.subplots(1, 2)
            effect = _deviation_panel(ax1, f)
            gain = _curve_panel(ax2, f)
            head = f"[{i}] {f.kind} / {f.soil}, {_short(f.cause, 30)}: {effect}"
            title = "\n".join(textwrap.wrap(head, 50) + textwrap.wrap(gain, 50))
            sub.suptitle(title, x=0.02, ha="left")
        fig.canvas.draw()  # lay out under the style's fonts before the rc context ends
    return fig


def _findings_section(doc: Document, result) -> None:
    doc.heading("Findings")
    if not result.findings:
        doc.paragraph(result.no_finding_text())
    drawn = [(i, f) for i, f in enumerate(result.findings, 1) if f.group is not None]
    drawn = [(i, f) for i, f in drawn if f.scope_rows is not None]
    if drawn:
        for k in range(math.ceil(len(drawn) / _PER_FIGURE)):
            chunk = drawn[k * _PER_FIGURE : (k + 1) * _PER_FIGURE]
            which = (
                f"Finding {chunk[0][0]}"
                if len(chunk) == 1
                else f"Findings {chunk[0][0]}–{chunk[-1][0]}"
            )
            if k:
                doc.figure(_findings_figure(chunk), f"{which}, drawn as in the figure before.")
                continue
            doc.figure(
                _findings_figure(chunk),
                f"{which}: each title states the effect (from the level means: a factor on "
                "pressure, strength or K, a difference in n) and the held-out error of the base "
                "model and of the extension (tests left out, the cause fixed). Left: each test's "
                "deviation from the base model in the response named on the axis, against the "
                "cause (black bars: level means; a line: the trend of a numeric cause of many "
                "values). Right: one test per level (at most four, spread over the levels): "
                "measured samples (dots), base model (dashed), extension (solid).",
            )
    if result.explained:
        doc.paragraph(
            strong("Explained by a stronger finding: "),
            "; ".join(
                f"{e['kind']} / {e['soil']}: {e['candidate']} (by {e['by']}; p after = "
                f"{e['p_after']:.3g})"
                for e in result.explained
            )
            + ".",
        )


# -- combined model, red flags --------------------------------------------------------------


def _model_section(doc: Document, result, all_groups) -> None:
    doc.heading("Combined model")
    if not result.models:
        doc.paragraph("No kept extension, so no combined model: the base models stand.")
        return
    doc.paragraph(
        "Forward selection over each finding's best plausible extension, on all tests of each "
        "kind and soil with one fold set for every step (steps: appendix): an extension is "
        "added only on a cross-validated gain over the model before it of at least 1 standard "
        "error (the keep rule; 'real' is said only at 2), and only if the "
        "combined fit is physically plausible and its parameters are determined."
    )
    doc.note(f"In the parameter tables: {_SIGMA_NOTE}")
    with doc.columns(2):
        for m in result.models:
            _model_table(doc, m)
    if all_groups is not None:
        doc.paragraph(_all_groups_words(all_groups))


def _model_table(doc: Document, m) -> None:
    """One combined model: its parameters, the caption naming its extensions and gain."""
    if not m.extensions:
        doc.paragraph(
            strong(f"{m.kind} / {m.soil}: "),
            "base model: no extension gains enough to be kept on all tests.",
        )
        return
    gain = _gain_words(m.gain) if m.gain is not None else "not measured"
    caption = (
        f"{m.kind} / {m.soil}: {' + '.join(m.extensions)} (causes: {', '.join(m.causes)}); "
        f"gain {gain}."
    )
    if m.fit is None:
        doc.paragraph(caption)
    fit_table(doc, m.fit, caption, m.test_level, units="name", widths=["1fr", "auto"])


def _problems_section(doc: Document, result) -> None:
    doc.heading("Red flags and data quality")
    if result.flags:
        doc.table(
            pd.DataFrame(
                [
                    {"group": _group(f), **{k: f[k] for k in ("scope", "code", "message")}}
                    for f in result.flags
                ]
            ),
            caption="Physical red flags on the fits (docs/identification.md, health flags): "
            "not findings.",
            align_numbers=False,
            widths=["auto", "auto", "auto", "1fr"],
        )
    else:
        doc.paragraph("No red flags on the fits.")
    if result.artefacts:
        doc.table(
            pd.DataFrame(
                [
                    {
                        "group": _group(a),
                        "candidate": a["candidate"],
                        "p (Holm)": a["p_adjusted"],
                        "reason": a["reason"],
                    }
                    for a in result.artefacts
                ]
            ),
            caption="Significant candidates whose levels line up with artefact flags: data "
            "problems, not causes.",
            formats={"p (Holm)": ".3g"},
            align_numbers=False,
            widths=["auto", "auto", "auto", "1fr"],
        )
    else:
        doc.paragraph("No significant candidate lines up with data-quality artefacts.")
    q = result.quality
    if not q:
        doc.paragraph("Data quality: no screening record.")
    elif q["mode"] == "off":
        doc.paragraph("Data quality: screening was off, nothing was checked.")
    else:
        counts = (
            ", ".join(f"{c} in {plural(n, 'test')}" for c, n in q["counts"].items())
            or "no findings"
        )
        doc.paragraph(
            f"Data quality: screening in {q['mode']} mode (docs/quality.md: what each code "
            f"means and what to do): {counts}; {q['excluded_samples']} samples left out of "
            "every fit (the tests: appendix). These are data problems, never causes."
        )


# -- appendix -------------------------------------------------------------------------------


def _small_table(doc: Document, frame: pd.DataFrame, caption: str, widths, **kw) -> None:
    doc.table(frame, caption=caption, small=True, align_numbers=False, widths=widths, **kw)


def _gain_cell(g, name: str) -> str:
    if g is None:
        return ""
    if g.selected_folds is not None and name == "whole search":
        return f"{name}: {g.relative:+.1%} (lead chosen in {g.selected_folds} of {g.folds} folds)"
    return (
        f"{name}: {g.relative:+.1%} ({g.base:.4f} → {g.extended:.4f}; paired difference "
        f"{g.text()}; {g.scheme} CV, "
        f"{g.folds} folds, {g.n_tests} tests)"
    )


def _statistics_appendix(doc: Document, result) -> None:
    rows = []
    for i, f in enumerate(result.findings, 1):
        gains = [
            _gain_cell(f.gain, "cause fixed"),
            _gain_cell(f.gain_search, "whole search"),
            _gain_cell(f.gain_conditions, "conditions left out"),
        ]
        rows.append(
            {
                "#": f"[{i}]",
                "test": f"F = {f.statistic:.4g}, partial η² = {f.effect_size:.3f}, p = "
                f"{f.p_value:.3g}, Holm p = {f.p_adjusted:.3g}; shows in "
                + ", ".join(f.responses)
                + f"; {_information(f.information)}",
                "gain in held-out error": "; ".join(g for g in gains if g) or "–",
            }
        )
    _small_table(
        doc,
        pd.DataFrame(rows),
        "Each finding's test (responses as defined in the methods) and gains: the gain with the "
        "cause fixed (tests left out) decides "
        "what is kept; that of the whole search (each fold re-selecting the lead) and with "
        "whole conditions left out are reported beside it; AIC/BIC treat samples as "
        "independent.",
        ["auto", "30%", "1fr"],
    )


def _information(info: dict) -> str:
    """AIC and BIC of the base and the extended fit: ``AIC a → b; BIC c → d``."""
    parts, keys = [], list(info)
    for name in ("aic", "bic"):
        base, ext = f"{name}_base", f"{name}_extended"
        if base in info and ext in info:
            parts.append(f"{name.upper()} {info[base]:.6g} → {info[ext]:.6g}")
            keys = [k for k in keys if k not in (base, ext)]
    parts += [
        f"{k.replace('_', ' ')} {info[k]:.6g}" if isinstance(info[k], float) else f"{k} {info[k]}"
        for k in keys
    ]
    return "; ".join(parts) or "–"


def _same_fit(a, b) -> bool:
    """Whether two fits are one: the same parameters at the same values (a finding whose
    extension alone makes its group's combined model, fitted to the same tests)."""
    if a is None or b is None or tuple(a.param_names) != tuple(b.param_names):
        return False
    return bool(np.allclose(a.values, b.values, rtol=1e-12, atol=0, equal_nan=True))


def _parameters_appendix(doc: Document, result) -> None:
    rows = []
    for i, f in enumerate(result.findings, 1):
        same = [m for m in result.models if _same_fit(f.fit, m.fit)]
        if same:
            m = same[0]
            rows.append(
                {
                    "finding": f"[{i}] {f.extension}",
                    "parameter": f"the combined model of {m.kind} / {m.soil} (its table above)",
                    "value ± σ": "",
                }
            )
            continue
        rows += [
            {"finding": f"[{i}] {f.extension}", **r}
            for r in fit_rows(f.fit, f.test_level, units="name")
        ]
    if rows:
        with doc.columns(2):
            _small_table(
                doc,
                pd.DataFrame(rows),
                "Parameters of each finding's extension, fitted to the tests in its scope "
                "(value ± σ as in the combined model's tables); a fit that is its group's "
                "combined model is printed there.",
                ["1fr", "auto"],
                sections="finding",
            )


def _tried_appendix(doc: Document, result) -> None:
    said: set = set()

    def described(t) -> str:
        """An extension's description the first time it is tried, then a pointer to it."""
        text = t.get("description", "")
        key = (t.get("extension"), text)
        if key in said and text:
            return "as above"
        said.add(key)
        return text

    rows = [
        {
            "finding": f"[{i}]",
            "extension": t.get("extension"),
            "description": described(t),
            "gain": t.get("relative"),
            "search": t.get("relative_search"),
            "evidence": t.get("verdict", "real" if t.get("real") else "none"),
            "physical": t.get("physical"),
            "outcome": t.get("error")
            or ("kept" if t.get("extension") == f.extension else t.get("reason", "not kept")),
        }
        for i, f in enumerate(result.findings, 1)
        for t in f.tried
    ]
    if rows:
        _small_table(
            doc,
            pd.DataFrame(rows),
            "Every extension tried per finding: its gain with the cause fixed (deciding) and "
            "that of the whole search (each fold re-selecting the lead); an extension tried "
            "again is described where it first appears.",
            ["auto", "20%", "1fr", "auto", "auto", "auto", "auto", "20%"],
            formats={"gain": "+.1%", "search": "+.1%"},
        )


def _steps_appendix(doc: Document, result) -> None:
    rows = [
        {
            "group": f"{m.kind} / {m.soil}",
            "extension": s["extension"],
            "cause": s.get("cause"),
            "added": s["added"],
            "gain": s.get("relative"),
            "reason": s["reason"],
        }
        for m in result.models
        for s in m.steps
    ]
    if rows:
        _small_table(
            doc,
            pd.DataFrame(rows),
            "The combined models' selection steps, in order per group; gain over the model "
            "before the step.",
            ["auto", "22%", "auto", "auto", "auto", "1fr"],
            formats={"gain": "+.1%"},
        )


def _common_start(texts: list[str]) -> str:
    first = min(texts)
    last = max(texts)
    k = next((k for k, (a, b) in enumerate(zip(first, last, strict=False)) if a != b), None)
    return first if k is None else first[:k]


def _shared_text(texts: list[str]) -> tuple[str, str]:
    """The beginning (up to a ": ") and the end (from a ". ") that all ``texts`` share."""
    head = _common_start(texts)
    head = head[: head.rfind(": ") + 2] if ": " in head else ""
    tail = _common_start([t[::-1] for t in texts])[::-1]
    tail = tail[tail.find(". ") :] if ". " in tail else ""
    if any(len(head) + len(tail) > len(t) for t in texts):
        return head, ""
    return head, tail


def _caveats_appendix(doc: Document, result) -> None:
    """Every caveat once, with what it is on; caveats of one code (``TEST-SCATTER: …``)
    that share their wording print it once, in the row before them, and their own part."""
    owners: dict[str, list[str]] = {}
    for i, f in enumerate(result.findings, 1):
        for c in f.caveats:
            owners.setdefault(c, []).append(f"[{i}]")
    for m in result.models:
        for c in m.caveats:
            owners.setdefault(c, []).append(f"model {m.kind} / {m.soil}")
    if not owners:
        return
    codes: dict[str, list[str]] = {}
    for c in owners:
        found = re.match(r"([A-Z][A-Z-]+): ", c)
        codes.setdefault(found.group(1) if found else c, []).append(c)
    rows = []
    for code, texts in codes.items():
        head, tail = _shared_text(texts) if len(texts) > 1 else ("", "")
        if len(head) + len(tail) <= len(code) + 2:
            rows += [{"of": ", ".join(dict.fromkeys(owners[c])), "caveat": c} for c in texts]
            continue
        rows.append(
            {
                "of": f"{len(texts)} caveats",
                "caveat": f"{code} caveats all read “{head}…{tail}”, … as in the rows below:",
            }
        )
        rows += [
            {
                "of": ", ".join(dict.fromkeys(owners[c])),
                "caveat": f"{code}: …{c[len(head) : len(c) - len(tail)]}…",
            }
            for c in texts
        ]
    _small_table(
        doc,
        pd.DataFrame(rows),
        "The caveats of the findings ([number]) and of the combined models, each printed "
        "once (the wording several share, once before them).",
        ["auto", "1fr"],
    )


#: Most candidates-not-found listed in the PDF; beyond, the interactions go to the JSON only.
POWER_ROWS = 30


def _power_rows_shown(power: list[dict]) -> tuple[list[dict], list[dict]]:
    """(records listed in the PDF, records left to the JSON): all of them up to
    :data:`POWER_ROWS`, else the main effects (the interactions' records stay in the JSON)."""
    if len(power) <= POWER_ROWS:
        return list(power), []
    main = [p for p in power if " × " not in str(p["candidate"])]
    return main, [p for p in power if " × " in str(p["candidate"])]


def _power_appendix(doc: Document, result) -> None:
    if not result.power:
        doc.paragraph("Every candidate tested was either found or not testable (see the notes).")
        return
    first = result.power[0]
    shown, left = _power_rows_shown(result.power)
    if left:
        doc.paragraph(
            f"{len(result.power)} candidates were tested and not found. The "
            f"{len(shown)} main effects are below; the smallest detectable effect of the other "
            f"{plural(len(left), 'candidate')} (two-way interactions) is in the JSON "
            '("power"), one record each: listed here they would need small type.'
        )
    slots = max(len(p["responses"]) for p in shown)
    labels = {
        f"r{j}": " / ".join(
            dict.fromkeys(list(p["responses"])[j] for p in shown if len(p["responses"]) > j)
        )
        + " (raw p)"
        for j in range(slots)
    }
    rows = []
    for p in shown:
        row: dict[str, Any] = {
            "group": _group(p),
            "candidate": f"{p['candidate']} ({p['role']}, {p['n_tests']} tests)",
        }
        items = list(p["responses"].values())
        for j in range(slots):
            v = items[j] if j < len(items) else None
            row[f"r{j}"] = (
                None
                if v is None
                else v["statement"]
                + (f" (p {v['p_value']:.2g})" if v.get("p_value") is not None else "")
            )
        rows.append(row)
    _small_table(
        doc,
        pd.DataFrame(rows),
        "What the design could not detect: for each candidate tested and not found, the "
        f"smallest effect it would have found with {first['power']:.0%} power at Holm's "
        f"strictest level α/m = {first['alpha_level']:.2g} (noncentral F), in physical units, "
        "per response, with the test's raw p.",
        ["17%", *(["1fr"] * slots)],
        labels=labels,
        sections="group",
    )


def _quality_appendix(doc: Document, result) -> None:
    q = result.quality
    if not q or not q.get("tests"):
        return
    groups: dict[tuple, list[str]] = {}
    for t in q["tests"]:
        groups.setdefault((t["kind"], ", ".join(t["codes"])), []).append(t["test_id"])
    rows = [
        {"kind": kind, "codes": codes, "tests": ", ".join(sorted(ids, key=natural_key))}
        for (kind, codes), ids in sorted(groups.items())
    ]
    _small_table(
        doc,
        pd.DataFrame(rows),
        "The tests with screening codes, by their codes (docs/quality.md).",
        ["auto", "30%", "1fr"],
    )


def _columns_appendix(doc: Document, result) -> None:
    """Every column by role: one row per role and reason, the columns of each group in it
    (a reason is said once, not once per column)."""
    if not result.columns:
        return
    order = ("design", "covariate", "time/order", "outcome", "bookkeeping")
    rows: dict[tuple, dict[str, list[str]]] = {}
    for c in result.columns:
        key = (c["role"], "yes" if c.get("tested") else "no", c["reason"])
        rows.setdefault(key, {}).setdefault(_group(c), []).append(c["column"])
    ranked = sorted(rows, key=lambda k: (order.index(k[0]) if k[0] in order else len(order), k))
    frame = pd.DataFrame(
        [
            {
                "role": role,
                "tested": tested,
                "reason": reason,
                "columns": "; ".join(
                    f"{g}: {', '.join(rows[(role, tested, reason)][g])}"
                    for g in natural_sorted(rows[(role, tested, reason)])
                ),
            }
            for role, tested, reason in ranked
        ]
    )
    _small_table(
        doc,
        frame,
        "Every varying column of the log by its role (docs/discover.md): a design factor, "
        "covariate, time/order, outcome or bookkeeping, with the columns of each group. "
        "Outcomes — quantities the test's own result determines — never enter as causes.",
        ["auto", "auto", "25%", "1fr"],
    )


def _merged(records: list[dict]) -> list[str]:
    """The confounded pairs of one group in as few sentences as they allow: aliased columns
    in one class each, the columns one column determines in one sentence. A relation whose
    text is not the standard one is printed as it is; one that stands alone keeps its own
    text (the merged sentence of one pair is that text)."""

    def alias(a, b):
        return f"{a} and {b} are aliased (the same partition of the tests)"

    def nest(a, b):
        return f"{a} determines {b} (each {a} has one {b})"

    classes: list[list[str]] = []
    nested: dict[str, list[str]] = {}
    out: list[str] = []
    for r in records:
        cols = r.get("columns") or []
        if r.get("relation") == "aliased" and len(cols) == 2 and r["text"] == alias(*cols):
            hit = [c for c in classes if cols[0] in c or cols[1] in c]
            merged = [x for c in hit for x in c] + list(cols)
            classes = [c for c in classes if c not in hit] + [list(dict.fromkeys(merged))]
        elif r.get("relation") == "nested" and len(cols) == 2 and r["text"] == nest(*cols):
            nested.setdefault(cols[0], []).append(cols[1])
        else:
            out.append(r["text"])
    for c in classes:
        if len(c) == 2:
            out.append(alias(*c))
        else:
            out.append(
                f"{', '.join(c[:-1])} and {c[-1]} are aliased (the same partition of the tests)"
            )
    for a, bs in nested.items():
        if len(bs) == 1:
            out.append(nest(a, bs[0]))
        else:
            out.append(f"{a} determines {', '.join(bs)} (each {a} has one of each)")
    return out


def _confounded_appendix(doc: Document, result) -> None:
    if not result.confounded:
        doc.paragraph(
            "Confounded candidates: none — every pair of candidates can be told apart by this "
            "design."
        )
        return
    by_group: dict[str, list[dict]] = {}
    for c in result.confounded:
        by_group.setdefault(_group(c), []).append(c)
    rows = [
        {"group": g, "cannot be told apart": text}
        for g, records in by_group.items()
        for text in _merged(records)
    ]
    left = ""
    if sum(len(r["cannot be told apart"]) for r in rows) > CONFOUNDED_CHARS:
        # Where the list would need small type: the main effects' confounding here, that of
        # interactions (implied by the design, "A × B determines …") in the JSON only.
        kept = [r for r in rows if "×" not in r["cannot be told apart"].split(" determines")[0]]
        left = (
            f" {plural(len(rows) - len(kept), 'further line')} on interactions that the design "
            "determines (an interaction of two factors fixing the others' interactions) "
            'are in the JSON ("confounded") only: here they would need small type.'
        )
        rows = kept or rows[:1]
    _small_table(
        doc,
        pd.DataFrame(rows),
        f"Confounded candidates: the {plural(len(result.confounded), 'pair')} of columns "
        "(and their interactions) whose effects this design cannot separate, the pairs that "
        "share a column said together." + left,
        ["1fr"],
        sections="group",
    )


#: Most characters of the confounded-candidates table before the interactions' lines go to
#: the JSON only (about a page at 8 pt).
CONFOUNDED_CHARS = 6000


def _notes_appendix(doc: Document, result) -> None:
    untested = [f"{u['kind']} / {u['soil']}: {u['reason']}" for u in result.untested]
    doc.numbered([*untested, *result.notes] or ["No further notes."], small=True)


def write_report(
    result: DiscoveryResult,
    path: str | Path,
    *,
    provenance: Provenance | None = None,
    overwrite: bool = False,
    defaults: Mapping[str, str] | None = None,
) -> int:
    """Write the typeset PDF report of ``result`` to ``path`` (its folder created if
    needed); return the number of pages.

    The last page and the PDF metadata carry ``provenance`` (default: the result's); an
    existing file is an error unless ``overwrite`` (the signature of every report writer:
    docs/conventions.md).
    """
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    doc = Document(
        "What the soil model gets wrong",
        subtitle="soilstats discover — model discovery after Apfelbeck et al. (2011)",
        provenance=provenance or result.provenance,
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
        defaults=defaults,
    )
    if result.findings:
        _findings_table(doc, result)
    doc.page_break()
    _findings_section(doc, result)
    _model_section(doc, result, all_groups)
    _problems_section(doc, result)
    doc.heading("Methods")
    kinds = tuple(natural_sorted({c["kind"] for c in result.columns})) or ("sinkage", "shear")
    write_equations(doc, kinds, columns=2)
    doc.paragraph(strong("How discovery reaches its findings:"))
    doc.numbered(METHOD_NOTES, small=True)
    doc.heading("Appendix: the findings in full")
    if result.findings:
        _statistics_appendix(doc, result)
        _parameters_appendix(doc, result)
        _tried_appendix(doc, result)
    _steps_appendix(doc, result)
    _caveats_appendix(doc, result)
    doc.heading("Appendix: what was not found, and why")
    _power_appendix(doc, result)
    _confounded_appendix(doc, result)
    _columns_appendix(doc, result)
    _quality_appendix(doc, result)
    doc.heading("Notes")
    _notes_appendix(doc, result)
    doc.provenance_section(new_page=False)
    return doc.render(path)
