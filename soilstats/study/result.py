"""The result of one study: tables, verdicts, notes — frozen, with ``summary()``."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import pandas as pd

from .._html import facts_html, notes_html, result_html, table_html
from ..errors import warn_renamed
from ..identification.conditions import condition_label
from ..outputs import Provenance
from ..outputs.text import notes_block
from .outputs import to_json_dict

if TYPE_CHECKING:
    from .spec import StudySpec

__all__ = ["CRITERIA_COLUMNS", "StudyResult", "best_method_name"]

# The columns of the paper's Table 3 as the PDF prints them (the summary without the p-value).
CRITERIA_COLUMNS = [
    "soil",
    "method",
    "tests",
    "crit1",
    "crit2",
    "crit3",
    "score",
    "epsilon",
    "scatter_cv",
    "operator_p",
]


@dataclass(frozen=True)
class StudyResult:
    """Everything a study found, ready for the JSON, CSV and PDF outputs.

    Attributes
    ----------
    spec : StudySpec
    source : str
        The campaign read (folder or bundled name).
    date : str or None
        ISO time from ``SOURCE_DATE_EPOCH`` when set; None otherwise (outputs stay
        byte-identical between runs).
    soils : list of str
    effects : pandas.DataFrame
        One row per soil and response: ``soil, response, factor, statistic`` (F),
        ``p_value``, ``p_adjusted`` (Holm), ``significant``, ``effect_size`` (partial η²),
        ``test``, relevance columns and ``verdict``/``matters`` (see :mod:`.verdict`).
    anova : pandas.DataFrame
        The ANOVA tables (sinkage) or ANCOVA model comparisons (shear), tidy.
    pairs : pandas.DataFrame
        Tukey HSD pairs (sinkage studies; empty for shear).
    parameters : pandas.DataFrame
        Per-condition pooled identification (the paper's Tables 5–7): ``soil, condition,
        parameter, value, stderr, unit, epsilon, tests, flags, model``.
    lines : pandas.DataFrame
        Shear: per-level ANCOVA lines (c [Pa], φ [deg]).
    per_test : pandas.DataFrame
        The per-test responses analysed.
    criteria : pandas.DataFrame or None
        Preparation: the Table 3 criteria per soil and method.
    best : dict or None
        Preparation: ``{"best": method or None, "reason": ...}``.
    notes : tuple of str
        Caveats: confounding, tests left out, soils skipped, failed fits.
    runtime_s : float
        Wall time of the analysis (without the PDF) [s]; never written to files.
        Was ``seconds``, which still works (with a ``FutureWarning``) until 0.3.0.
    provenance : Provenance or None
        Version, input hash, command and seed, recorded in every output.
    defaults : dict of str to str
        What the result rests on that the user did not give: the spec's keys left at their
        defaults (``{"spec: z_window_m": "0.001"}``) and, from the CLI, its options
        (``{"--seed": "0"}``); the JSON's ``"defaults"`` and page 1 of the report.
    default_warnings : dict of str to str
        Those of the spec's defaults that move a verdict (``{"spec: z_ref_m": warning}``,
        :mod:`soilstats.study.defaults`): the JSON's ``"default_warnings"``, warnings on
        page 1 and in :meth:`summary`.
    """

    spec: StudySpec
    source: str
    date: str | None
    soils: list
    effects: pd.DataFrame
    anova: pd.DataFrame
    pairs: pd.DataFrame
    parameters: pd.DataFrame
    lines: pd.DataFrame
    per_test: pd.DataFrame
    criteria: pd.DataFrame | None = None
    best: dict | None = None
    notes: tuple[str, ...] = ()
    runtime_s: float = math.nan
    seed: int | None = None
    provenance: Provenance | None = None
    defaults: dict[str, str] = field(default_factory=dict)
    default_warnings: dict[str, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def seconds(self) -> float:
        """Renamed :attr:`runtime_s` (docs/conventions.md, "Renamed")."""
        warn_renamed("StudyResult.seconds", "StudyResult.runtime_s")
        return self.runtime_s

    def reference_pairs(self) -> pd.DataFrame:
        """Tukey pairs against the spec's reference level, as ``level − reference``."""
        ref = self.spec.reference
        if ref is None or self.pairs.empty:
            return pd.DataFrame()

        ref = condition_label(ref)
        rows = []
        for _, r in self.pairs.iterrows():
            if ref not in (r["group1"], r["group2"]):
                continue
            sign = 1.0 if r["group1"] == ref else -1.0
            lo, hi = sorted((sign * r["lower"], sign * r["upper"]))
            rows.append(
                dict(
                    soil=r["soil"],
                    response=r["response"],
                    level=r["group2"] if sign > 0 else r["group1"],
                    reference=ref,
                    difference=sign * r["meandiff"],
                    lower=lo,
                    upper=hi,
                    p_adj=r["p_adj"],
                    significant=bool(r["reject"]),
                )
            )
        out = pd.DataFrame(rows)
        if out.empty:
            return out
        margins = {r.name: r.margin_on_scale for r in self.spec.responses}
        out["relative_change"] = [
            10**d - 1 if resp.startswith("log10_") else math.nan
            for d, resp in zip(out["difference"], out["response"], strict=True)
        ]
        out["relevant"] = [
            bool(sig and (margins.get(resp) is None or abs(d) > margins[resp]))
            for sig, d, resp in zip(
                out["significant"], out["difference"], out["response"], strict=True
            )
        ]
        return out

    def to_dict(self) -> dict:
        """The study's JSON document (see :func:`soilstats.study.outputs.to_json_dict`)."""
        return to_json_dict(self)

    def summary(self) -> str:
        """The verdicts in a few lines, the criteria table (preparation), then numbered notes."""
        lines = [f"Study {self.name!r}: {self.spec.title}", f"Data: {self.source}"]
        if not self.effects.empty:
            for _, r in self.effects.iterrows():
                lines.append(
                    f"  {r['soil']:<14} {r['response']:<12} F = "
                    f"{r['statistic']:9.3g}  p = {r['p_value']:.3g}  "
                    f"p_Holm = {r['p_adjusted']:.3g}  -> {r['verdict']}"
                )
        if self.criteria is not None and not self.criteria.empty:
            lines.append("Criteria of Table 1 per method (as Table 3; Σ = sum of +1/−1):")
            table = self.criteria.assign(
                method=lambda d: d["method"].astype(str),
                epsilon=lambda d: d["epsilon"].map(lambda v: f"{v:.3f}"),
                scatter_cv=lambda d: d["scatter_cv"].map(lambda v: f"{v:.3f}"),
            )[[c for c in CRITERIA_COLUMNS if c != "operator_p"]]
            lines += ["  " + row for row in table.to_string(index=False).splitlines()]
        if self.best is not None:
            lines.append(
                f"Best preparation method: {best_method_name(self.best)} — {self.best['reason']}"
            )
        lines += [f"Warning: {text}" for text in self.default_warnings.values()]
        lines += notes_block(self.notes)
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        """The verdicts, the criteria (preparation) and the notes as tables, for notebooks."""
        verdicts = pd.DataFrame()
        if not self.effects.empty:
            keep = ["soil", "response", "statistic", "p_value", "p_adjusted", "verdict"]
            verdicts = self.effects[[c for c in keep if c in self.effects.columns]]
        parts = [facts_html({"data": self.source})]
        if not verdicts.empty:
            parts.append(table_html(verdicts, caption="Verdicts (F, raw and Holm p)"))
        if self.criteria is not None and not self.criteria.empty:
            parts.append(table_html(self.criteria, caption="Criteria of Table 1 per method"))
        if self.best is not None:
            parts.append(
                facts_html(
                    {"best preparation": f"{best_method_name(self.best)}: {self.best['reason']}"}
                )
            )
        if self.default_warnings:  # a default that moves a verdict (soilstats.study.defaults)
            parts.append(facts_html({"warning": " ".join(self.default_warnings.values())}))
        parts.append(notes_html(self.notes))
        return result_html(f"Study {self.name!r}: {self.spec.title}", *parts)


def best_method_name(best: Mapping | None) -> str:
    """The method a preparation study's ``best`` (``{"best": …, "reason": …}``) names, as
    printed: "none" where it names none (never Python's None)."""
    return "none" if not best or best.get("best") is None else str(best["best"])
