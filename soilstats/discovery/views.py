"""The readable views of a discovery's result: the summary's sections (text) and the tables
of its notebook view (HTML). Each takes the parts of the result it shows."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import pandas as pd

from .._html import facts_html, notes_html, result_html, table_html
from .._text import plural
from .finding import Finding
from .testlevel import quoted_sigma

if TYPE_CHECKING:
    from .crossval import Gain

__all__ = [
    "column_lines",
    "discovery_html",
    "model_lines",
    "power_lines",
    "quality_lines",
    "section",
]


def section(width: int, title: str, texts: list[str], records: Sequence[dict]) -> list[str]:
    """A titled block of ``kind / soil: text`` lines (nothing when there are none)."""
    if not texts:
        return []
    body = [f"  {r['kind']} / {r['soil']}: {t}" for r, t in zip(records, texts, strict=True)]
    return ["-" * width, title, *body]


def model_lines(width: int, models: tuple, all_groups: Gain | None) -> list[str]:
    """The combined model per (kind, soil) and its gain over the base (``all_groups``: the
    gain of all extended groups together, or None)."""
    if not models:
        return []
    lines = ["-" * width, "Combined model (forward selection of the kept extensions):"]
    for m in models:
        lines.extend("  " + line for line in m.summary_lines())
    g = all_groups
    if g is not None:
        lines.append(
            f"  all extended groups together: {g.base:.4f} -> {g.extended:.4f} "
            f"({g.relative:+.1%}, {g.n_tests} held-out tests)"
        )
    return lines


def power_lines(width: int, power: tuple[dict, ...]) -> list[str]:
    """Candidates not found, with the smallest effect the design could have found."""
    if not power:
        return []
    level = power[0]["alpha_level"]
    lines = [
        "-" * width,
        f"Not found — the smallest effect each test would have found (power "
        f"{power[0]['power']:.0%} at Holm's strictest level alpha/m = {level:.2g}):",
    ]
    for p in power:
        parts = [f"{r}: {v['statement']}" for r, v in p["responses"].items()]
        lines.append(
            f"  {p['kind']} / {p['soil']}: {p['candidate']} ({p['role']}, "
            f"{p['n_tests']} tests) — " + "; ".join(parts)
        )
    return lines


def quality_lines(width: int, quality: dict | None) -> list[str]:
    """The screening the fits used: data problems, never causes."""
    q = quality
    if not q:
        return []
    lines = ["-" * width, f"Data quality ({q['mode']} mode; data problems, never causes):"]
    if q["mode"] == "off":
        return [*lines, "  screening was off: nothing was checked"]
    counts = (
        ", ".join(f"{c} in {plural(n, 'test')}" for c, n in q["counts"].items()) or "no findings"
    )
    lines.append(f"  {counts}; {q['excluded_samples']} samples left out of every fit")
    for t in q["tests"]:
        lines.append(f"  {t['kind']} {t['test_id']}: {', '.join(t['codes'])}")
    return lines


def column_lines(width: int, columns: tuple[dict, ...]) -> list[str]:
    """Candidates by role per (kind, soil); outcomes listed with why they never enter."""
    if not columns:
        return []
    lines = ["-" * width, "Columns and their roles (outcomes never enter as causes):"]
    groups: dict[tuple, list[dict]] = {}
    for c in columns:
        groups.setdefault((c["kind"], c["soil"]), []).append(c)
    for (kind, soil), cols in groups.items():
        for role in ("design", "covariate", "time/order"):
            names = [c["column"] for c in cols if c["role"] == role]
            if names:
                lines.append(f"  {kind} / {soil}: {role}: {', '.join(names)}")
        for c in cols:
            if c["role"] == "outcome":
                lines.append(f"  {kind} / {soil}: outcome {c['column']}: {c['reason']}")
    return lines


def _findings_frame(findings: tuple[Finding, ...]) -> pd.DataFrame:
    """The findings table of the HTML view, strongest first."""
    return pd.DataFrame(
        [
            {
                "#": i,
                "group": f"{f.kind} / {f.soil}",
                "cause": f.cause,
                "confounded with": ", ".join(f.confounded_with),
                "shows in": ", ".join(f.responses),
                "F": f"{f.statistic:.4g}",
                "p (Holm)": f"{f.p_adjusted:.3g}",
                "tests": f.n_tests,
                "extension": f.extension or "none",
                "gain": "" if f.gain is None else f"{f.gain.relative:+.1%}",
            }
            for i, f in enumerate(findings, 1)
        ]
    )


def _parameter_rows(models: tuple) -> list[dict]:
    """The combined models' parameters ± the σ the summary quotes, a row each."""
    rows = []
    for m in models:
        if m.fit is None:
            continue
        stderr, eq4, levels = quoted_sigma(m.fit, m.test_level)
        for j, name in enumerate(m.fit.param_names):
            rows.append(
                {
                    "group": f"{m.kind} / {m.soil}",
                    "parameter": name,
                    "value": f"{m.fit.values[j]:.6g}",
                    "stderr": f"{stderr[j]:.3g}",
                    "Eq. 4": f"{eq4[j]:.3g}",
                    "σ level": levels[j],
                    "unit": m.fit.units.get(name, ""),
                }
            )
    return rows


def _power_frame(power: tuple[dict, ...]) -> pd.DataFrame:
    """What was not found, with the smallest effect the design would have found."""
    return pd.DataFrame(
        [
            {
                "group": f"{p['kind']} / {p['soil']}",
                "candidate": p["candidate"],
                "role": p["role"],
                "tests": p["n_tests"],
                "smallest detectable effect": "; ".join(
                    f"{r}: {v['statement']}" for r, v in p["responses"].items()
                ),
            }
            for p in power
        ]
    )


def discovery_html(
    facts: dict,
    findings: tuple[Finding, ...],
    models: tuple,
    flags: tuple[dict, ...],
    power: tuple[dict, ...],
    notes: list[str],
) -> str:
    """The result as tables, for notebooks: the ``facts`` of the run, the findings, the
    combined models with their parameters (± the σ the summary quotes), the red flags, what
    was not found, and the caveats and ``notes``."""
    found = _findings_frame(findings)
    combined = pd.DataFrame(
        [
            {
                "group": f"{m.kind} / {m.soil}",
                "model": " + ".join(m.extensions) or "base model",
                "causes": ", ".join(m.causes),
                "gain": "" if m.gain is None else f"{m.gain.relative:+.1%}",
                "tests": m.n_tests,
            }
            for m in models
        ]
    )
    rows = _parameter_rows(models)
    red = pd.DataFrame(list(flags))
    missed = _power_frame(power)
    caveats = [f"[{i}] {c}" for i, f in enumerate(findings, 1) for c in f.caveats]
    caveats += [f"{m.kind} / {m.soil} model: {c}" for m in models for c in m.caveats]
    return result_html(
        "Discovery: what the soil model gets wrong",
        facts_html(facts),
        table_html(found, caption="Findings (strongest first)") if len(found) else "",
        table_html(combined, caption="Combined model per group") if len(combined) else "",
        table_html(
            pd.DataFrame(rows),
            caption="Combined-model parameters: stderr the test-level σ where five tests "
            "or more inform the parameter (σ level 'tests'), Eq. 4's otherwise",
        )
        if rows
        else "",
        table_html(red, caption="Physical red flags") if len(red) else "",
        table_html(missed, caption="Not found: the smallest effect the design would have found")
        if len(missed)
        else "",
        notes_html(caveats, "Caveats"),
        notes_html(notes),
    )
