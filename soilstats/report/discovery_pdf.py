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
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .._text import plural
from ..discovery.finding import Finding
from ..discovery.result import METHOD_NOTES, DiscoveryResult
from ..evidence import REAL_SE, RULE
from ..outputs.files import output_path
from ..outputs.provenance import Provenance
from .discovery_appendix import group_name, write_appendix
from .discovery_figures import findings_figure
from .document import Document, strong
from .front import data_origin, front_page
from .labels import natural_sorted
from .methods import write_equations
from .parameters import EQ4_NOTE, fit_table

if TYPE_CHECKING:

    from ..discovery.crossval import Gain
    from ..discovery.selection import CombinedModel

__all__ = ["write_report"]

#: Findings per figure (one per row: deviations and curves side by side, 8 pt text).
_PER_FIGURE = 4

_SIGMA_NOTE = (
    f"{EQ4_NOTE} In discovery the test-level σ is the bootstrap's linearised form, "
    "cluster-robust over tests and judged per parameter (docs/discover.md §4a): † where fewer "
    "than five tests inform the parameter or one test alone sets it — there the scatter "
    "between tests could not be measured; * where it exceeds Eq. 4's by more than 2× "
    "(TEST-SCATTER)."
)


def _shows_in(f: Finding) -> str:
    """The responses in physical words: level → stiffness (or shear strength), shape → n."""
    words = {
        "level": "stiffness" if f.kind == "sinkage" else "shear strength",
        "shape": "exponent n",
        "K": "shear modulus K",
    }
    return ", ".join(words.get(r, r) for r in f.responses)


def _gain_words(g: Gain) -> str:
    return (
        f"{g.relative:+.1%} in held-out error ({g.base:.4f} → {g.extended:.4f}, "
        f"{g.scheme} cross-validation, {g.folds} folds, {g.n_tests} tests; {g.text()})"
    )


def _schemes(f: Finding) -> list[tuple[str, Gain]]:
    """The held-out gains measured for a finding's extension: (scheme in words, Gain)."""
    out = [("tests held out", f.gain)]
    if f.gain_search is not None:
        out.append(("the whole search nested", f.gain_search))
    if f.gain_conditions is not None:
        out.append(("a whole condition held out", f.gain_conditions))
    return [(name, g) for name, g in out if g is not None and np.isfinite(g.relative)]


def _worst_scheme(f: Finding) -> tuple[str, Gain] | None:
    """The held-out scheme in which a kept extension does worst, where it is another than the
    one that kept it (tests held out, the cause fixed)."""
    schemes = _schemes(f)
    if f.extension is None or len(schemes) < 2:
        return None
    worst = min(schemes[1:], key=lambda s: s[1].relative)
    return worst if worst[1].relative < schemes[0][1].relative else None


def _gain_cell_page1(g: Gain) -> str:
    return f"{g.relative:+.1%}; {g.text()}"


def _all_groups_words(g: Gain) -> str:
    return (
        f"All extended groups together: {g.base:.4f} → {g.extended:.4f} "
        f"({g.relative:+.1%}, {g.n_tests} held-out tests)."
    )


# -- page 1 ---------------------------------------------------------------------------------


def _words_count(result: DiscoveryResult) -> str:
    """How many kept extensions' gains are real, and how many weak (soilstats.evidence)."""
    words = [
        f.gain.verdict for f in result.findings if f.extension is not None and f.gain is not None
    ]
    real, weak = words.count("real"), words.count("weak")
    return f"{real} of them real (≥ {REAL_SE:g} standard errors)" + (
        f", {weak} kept on a weak gain (below {REAL_SE:g} standard errors)" if weak else ""
    )


def _conclusion(result: DiscoveryResult, all_groups: Gain | None) -> list:
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


def _causes_paragraphs(result: DiscoveryResult) -> list:
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


def _combined_model_paragraph(result: DiscoveryResult, all_groups: Gain | None) -> list | None:
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


def _disagreement_paragraph(result: DiscoveryResult) -> list | None:
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


def _also_paragraph(result: DiscoveryResult) -> list | None:
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


def _findings_table(doc: Document, result: DiscoveryResult) -> None:
    rows = [
        {
            "#": f"[{i}]",
            "group": group_name({"kind": f.kind, "soil": f.soil}),
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


def _worst_cell(f: Finding) -> str:
    worst = _worst_scheme(f)
    if worst is None:
        return "–" if f.extension is None else "no other scheme measured"
    name, g = worst
    return f"{name}: {_gain_cell_page1(g)}"


def _failures_out_of_sample(result: DiscoveryResult) -> list[str]:
    """Sentences for page 1: kept extensions that predict worse, or gain nothing real, in
    another held-out scheme than the one that kept them."""
    out = []
    for f in result.findings:
        worst = _worst_scheme(f)
        if worst is None or worst[1].verdict == "real":
            continue
        name, g = worst
        assert f.gain is not None  # the other schemes are measured after this one
        out.append(
            f"{group_name({'kind': f.kind, 'soil': f.soil})} {f.extension}: {f.gain.relative:+.1%} "
            f"with tests held out but {g.relative:+.1%} with {name} ({g.verdict})"
        )
    return out


# -- the findings' figures ------------------------------------------------------------------


def _findings_section(doc: Document, result: DiscoveryResult) -> None:
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
                doc.figure(findings_figure(chunk), f"{which}, drawn as in the figure before.")
                continue
            doc.figure(
                findings_figure(chunk),
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


def _model_section(doc: Document, result: DiscoveryResult, all_groups: Gain | None) -> None:
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


def _model_table(doc: Document, m: CombinedModel) -> None:
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


def _problems_section(doc: Document, result: DiscoveryResult) -> None:
    doc.heading("Red flags and data quality")
    if result.flags:
        doc.table(
            pd.DataFrame(
                [
                    {"group": group_name(f), **{k: f[k] for k in ("scope", "code", "message")}}
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
                        "group": group_name(a),
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
    write_appendix(doc, result)
    doc.provenance_section(new_page=False)
    return doc.render(path)
