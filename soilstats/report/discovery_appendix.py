"""The discovery report's appendix (statistics, parameters, what was tried, steps, caveats,
power, quality, columns, confounded conditions, notes): the exhaustive lists, each in full
(moved out of :mod:`.discovery_pdf`, issue #45)."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .._text import plural
from ..discovery.result import DiscoveryResult
from .document import Document
from .labels import natural_key, natural_sorted
from .parameters import fit_rows

if TYPE_CHECKING:
    from ..discovery.crossval import Gain


def _small_table(doc: Document, frame: pd.DataFrame, caption: str, widths: Any, **kw: Any) -> None:
    doc.table(frame, caption=caption, small=True, align_numbers=False, widths=widths, **kw)


def _gain_cell(g: Gain | None, name: str) -> str:
    if g is None:
        return ""
    if g.selected_folds is not None and name == "whole search":
        return f"{name}: {g.relative:+.1%} (lead chosen in {g.selected_folds} of {g.folds} folds)"
    return (
        f"{name}: {g.relative:+.1%} ({g.base:.4f} → {g.extended:.4f}; paired difference "
        f"{g.text()}; {g.scheme} CV, "
        f"{g.folds} folds, {g.n_tests} tests)"
    )


def _statistics_appendix(doc: Document, result: DiscoveryResult) -> None:
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


def _same_fit(a: Any, b: Any) -> bool:
    """Whether two fits are one: the same parameters at the same values (a finding whose
    extension alone makes its group's combined model, fitted to the same tests)."""
    if a is None or b is None or tuple(a.param_names) != tuple(b.param_names):
        return False
    return bool(np.allclose(a.values, b.values, rtol=1e-12, atol=0, equal_nan=True))


def _parameters_appendix(doc: Document, result: DiscoveryResult) -> None:
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


def _tried_appendix(doc: Document, result: DiscoveryResult) -> None:
    said: set = set()

    def described(t: Mapping[str, Any]) -> str:
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


def _steps_appendix(doc: Document, result: DiscoveryResult) -> None:
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


def _caveats_appendix(doc: Document, result: DiscoveryResult) -> None:
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


def _power_rows_shown(power: Sequence[dict]) -> tuple[list[dict], list[dict]]:
    """(records listed in the PDF, records left to the JSON): all of them up to
    :data:`POWER_ROWS`, else the main effects (the interactions' records stay in the JSON)."""
    if len(power) <= POWER_ROWS:
        return list(power), []
    main = [p for p in power if " × " not in str(p["candidate"])]
    return main, [p for p in power if " × " in str(p["candidate"])]


def _power_appendix(doc: Document, result: DiscoveryResult) -> None:
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
            "group": group_name(p),
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


def _quality_appendix(doc: Document, result: DiscoveryResult) -> None:
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


def _columns_appendix(doc: Document, result: DiscoveryResult) -> None:
    """Every column by role: one row per role and reason, the columns of each group in it
    (a reason is said once, not once per column)."""
    if not result.columns:
        return
    order = ("design", "covariate", "time/order", "outcome", "bookkeeping")
    rows: dict[tuple, dict[str, list[str]]] = {}
    for c in result.columns:
        key = (c["role"], "yes" if c.get("tested") else "no", c["reason"])
        rows.setdefault(key, {}).setdefault(group_name(c), []).append(c["column"])
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


def _confounded_appendix(doc: Document, result: DiscoveryResult) -> None:
    if not result.confounded:
        doc.paragraph(
            "Confounded candidates: none — every pair of candidates can be told apart by this "
            "design."
        )
        return
    by_group: dict[str, list[dict]] = {}
    for c in result.confounded:
        by_group.setdefault(group_name(c), []).append(c)
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


def _notes_appendix(doc: Document, result: DiscoveryResult) -> None:
    untested = [f"{u['kind']} / {u['soil']}: {u['reason']}" for u in result.untested]
    doc.numbered([*untested, *result.notes] or ["No further notes."], small=True)


def group_name(record: Mapping[str, Any]) -> str:
    """A group's name: ``"kind / soil"``."""
    return f"{record['kind']} / {record['soil']}"


def write_appendix(doc: Document, result: DiscoveryResult) -> None:
    """The appendices and the notes, in the report's order: the findings in full (when
    there are findings), then what was not found and why."""
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
