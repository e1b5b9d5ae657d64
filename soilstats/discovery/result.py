"""The frozen result of a discovery: findings (strongest first), red flags, caveats."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..models import models_of_kind
from ..outputs import Provenance, json_safe
from ..outputs.text import notes_block
from . import views
from .crossval import campaign_gain
from .finding import SIGMA_NOTE, Finding, parameter_lines, parameter_table
from .testlevel import quoted_sigma

if TYPE_CHECKING:
    from .crossval import Gain

__all__ = [
    "METHOD_NOTES",
    "SIGMA_NOTE",
    "DiscoveryResult",
    "Finding",
    "parameter_lines",
    "parameter_table",
]

#: How discovery reaches its findings, in four sentences (the summary's and the PDF's notes).
METHOD_NOTES = (
    "Per-test responses: level = ln of the test's own pressure (shear: plateau stress) over "
    "the base model's; shape = its n minus the base n; K = ln K over the base K.",
    "Each candidate is tested within strata of the other design candidates not confounded with "
    "it (F-test); Holm's method controls the chance of any false cause.",
    "Gain: cross-validation leaving out whole tests; each finding's extension is measured "
    "against the base model alone with the named cause fixed (kept when the paired difference "
    "exceeds 1 SE), the whole search's gain (each fold re-selecting the lead) beside it; the "
    "combined model by forward selection on all tests of its kind and soil, on the same folds.",
    "AIC/BIC treat samples as independent; samples of one test are not, so they overstate the "
    "evidence — the cross-validated gain decides.",
)


#: A combined model's parameter is flagged when it differs from the finding's own fit by more
#: than this many σ of the difference (σ_f and σ_c combined as if independent: both fits use
#: the same tests, so the real σ of the difference is smaller and the flag conservative).
DISAGREE_SIGMA = 2.0


@dataclass(frozen=True, eq=False)
class DiscoveryResult:
    """What the soil model gets wrong in a campaign, and what extending it gains.

    Attributes
    ----------
    findings : tuple of Finding
        Strongest first (smallest adjusted p, then largest F).
    flags : tuple of dict
        Physical red flags (``kind, soil, scope, code, message``); not findings.
    tests : pandas.DataFrame
        Every candidate × response × group significance test (raw and Holm-adjusted p).
    confounded : tuple of dict
        Aliased and nested candidate pairs per group.
    explained : tuple of dict
        Significant candidates whose structure vanished once a stronger finding's extension
        was fitted (e.g. the plate-size pattern left by a velocity effect).
    notes : tuple of str
        What was excluded or could not be tested, and why.
    columns : tuple of dict
        Every varying column per (kind, soil): ``role`` (design, covariate, time/order,
        outcome, bookkeeping), the ``reason`` and whether it was ``tested``; outcomes never are.
    models : tuple of CombinedModel
        Per (kind, soil) with a kept extension, the one model carrying every real cause
        (forward selection, :mod:`.selection`), its parameters ± σ and its gain.
    artefacts : tuple of dict
        Significant candidates that line up with data-quality artefacts (each level with its
        own flags): reported as data problems, never as causes.
    power : tuple of dict
        Per candidate tested and not found: the smallest effect the design would have found
        (80 % power at Holm's strictest level, :mod:`.power`).
    untested : tuple of dict
        Per (kind, soil) in which no candidate cause could be tested (one test, no varying
        set-up column): ``kind``, ``soil``, ``n_tests``, ``reason``.  "No finding" there
        says nothing about the model.
    quality : dict or None
        The data-quality screening the fits used (:mod:`soilstats.quality`): data problems,
        never causes.
    alpha, seed, runtime_s, source
    """

    findings: tuple[Finding, ...]
    flags: tuple[dict, ...]
    tests: pd.DataFrame = field(repr=False)
    confounded: tuple[dict, ...] = ()
    explained: tuple[dict, ...] = ()
    notes: tuple[str, ...] = ()
    columns: tuple[dict, ...] = ()
    models: tuple = ()
    artefacts: tuple[dict, ...] = ()
    power: tuple[dict, ...] = ()
    untested: tuple[dict, ...] = ()
    quality: dict | None = None
    alpha: float = 0.05
    seed: int = 0
    runtime_s: float = float("nan")
    source: str = ""
    provenance: Provenance | None = field(default=None, repr=False)

    def model(self) -> dict:
        """The combined model of the campaign: ``{"extensions", "causes", "gain", "groups"}``
        — every selected extension and its cause as ``"kind / soil: name"``, the gain over the
        base models on all held-out tests of the extended groups together, and per (kind,
        soil) the model with its parameters ± σ and its selection steps."""
        extended = [m for m in self.models if m.extensions]
        gain = campaign_gain(extended)
        return {
            "extensions": [f"{m.kind} / {m.soil}: {e}" for m in extended for e in m.extensions],
            "causes": [f"{m.kind} / {m.soil}: {c}" for m in extended for c in m.causes],
            "gain": None if gain is None else json_safe(gain.to_dict()),
            "groups": [m.to_dict() for m in self.models],
        }

    def disagreements(self) -> list[dict]:
        """Parameters of a combined model that differ from the same parameter of a finding's
        own fit by more than their σ allow: |Δ| > :data:`DISAGREE_SIGMA`·√(σ_f² + σ_c²).

        Only an extension's own parameters (K0, a velocity factor …) are compared, where the
        combined model carries that finding's extension; the base law's (kc, kφ, n; c, φ, K)
        change meaning with every extension added. Each record says why it differs.
        """
        base_names = {
            n for kind in ("sinkage", "shear") for m in models_of_kind(kind) for n in m.param_names
        }
        out = []
        for m in self.models:
            if m.fit is None or not m.extensions:
                continue
            c_sigma = dict(
                zip(m.fit.param_names, quoted_sigma(m.fit, m.test_level)[0], strict=True)
            )
            c_value = dict(zip(m.fit.param_names, m.fit.values, strict=True))
            for i, f in enumerate(self.findings, 1):
                if (f.kind, f.soil) != (m.kind, m.soil) or f.fit is None:
                    continue
                if f.extension not in m.extensions:
                    continue
                f_sigma = quoted_sigma(f.fit, f.test_level)[0]
                for name, v, sf in zip(f.fit.param_names, f.fit.values, f_sigma, strict=True):
                    if name in base_names or name not in c_value:
                        continue
                    vc, sc = float(c_value[name]), float(c_sigma[name])
                    allowed = DISAGREE_SIGMA * float(np.hypot(sf, sc))
                    if not abs(vc - v) > allowed:
                        continue
                    others = [e for e in m.extensions if e != f.extension]
                    out.append(
                        {
                            "kind": m.kind,
                            "soil": m.soil,
                            "parameter": name,
                            "finding": i,
                            "extension": f.extension,
                            "finding_value": float(v),
                            "finding_stderr": float(sf),
                            "combined_value": vc,
                            "combined_stderr": sc,
                            "sigmas": float(abs(vc - v) / np.hypot(sf, sc)),
                            "explanation": (
                                f"the combined model also carries {', '.join(others)}, which "
                                f"takes up part of what {name} describes alone (the "
                                "extensions overlap), and is fitted to every test of the "
                                "group, not the finding's scope: the finding's value describes "
                                "the cause alone, the combined one is for prediction with all "
                                "extensions in"
                                if others
                                else "the combined model is fitted to every test of the "
                                "group, the finding to its scope only: the cause does not "
                                "act alike on all tests"
                            ),
                        }
                    )
        return out

    def disagreement_lines(self) -> list[str]:
        """One sentence per :meth:`disagreements` record (after its ``kind / soil: ``)."""
        return [
            f"{d['parameter']} = {d['combined_value']:.3g} ± "
            f"{d['combined_stderr']:.2g} in the combined model against "
            f"{d['finding_value']:.3g} ± {d['finding_stderr']:.2g} in finding [{d['finding']}] "
            f"({d['extension']}), {d['sigmas']:.1f} σ apart: {d['explanation']}"
            for d in self.disagreements()
        ]

    def all_groups_gain(self) -> Gain | None:
        """The combined models' gain on the held-out tests of all extended groups together,
        or None unless two or more groups are extended (one group's gain is its own)."""
        extended = [m for m in self.models if m.extensions]
        return campaign_gain(extended) if len(extended) > 1 else None

    def no_finding_text(self) -> str:
        """What an empty ``findings`` means: nothing passed, or nothing could be tested."""
        if self.tests_run == 0:
            return (
                "No finding, because NO CANDIDATE CAUSE COULD BE TESTED: this says nothing "
                "about whether the model is right."
            )
        if self.untested:
            return "No finding: no candidate cause passes the test (some groups untested)."
        return "No finding: no candidate cause passes the test."

    @property
    def tests_run(self) -> int:
        """Distinct hypotheses with a p-value (the m of Holm's method: aliased candidates,
        one test under several names, count once)."""
        if not len(self.tests):
            return 0
        tested = self.tests[self.tests["p_value"].notna()]
        if "hypothesis" in tested:
            return int(tested["hypothesis"].nunique())
        return len(tested)

    def to_dict(self) -> dict:
        """JSON-ready content (no run time: outputs are byte-identical between runs)."""
        return {
            "model": self.model(),
            "disagreements": self.disagreements(),
            "findings": [f.to_dict() for f in self.findings],
            "flags": list(self.flags),
            "confounded": list(self.confounded),
            "explained": list(self.explained),
            "columns": list(self.columns),
            "artefacts": list(self.artefacts),
            "power": list(self.power),
            "untested": list(self.untested),
            "quality": self.quality,
            "notes": list(self.notes),
            "alpha": self.alpha,
            "seed": self.seed,
            "source": self.source,
            "provenance": None if self.provenance is None else self.provenance.to_dict(),
        }

    def to_json(self, **kwargs: Any) -> str:  # json.dumps's keywords, of their own types
        """One JSON object: ``{"findings": [...], "flags": [...], ..., "provenance": {...}}``."""
        return json.dumps(json_safe(self.to_dict()), **{"indent": 2, **kwargs})

    def summary(self) -> str:
        width = 100
        lines = [
            " discovery: what the soil model gets wrong ".center(width, "="),
            f"campaign: {self.source}   alpha = {self.alpha} (Holm over "
            f"{self.tests_run} tests)   "
            f"seed = {self.seed}   runtime {self.runtime_s:.1f} s",
            "-" * width,
        ]
        if not self.findings:
            lines.append(self.no_finding_text())
        lines += [f"  ! {u['kind']} / {u['soil']}: {u['reason']}" for u in self.untested]
        for i, f in enumerate(self.findings, 1):
            first, *rest = f.summary_lines()
            lines.append(f"[{i}] {first}")
            lines.extend(rest)
        lines.extend(views.model_lines(width, self.models, self.all_groups_gain()))
        lines += views.section(
            width,
            f"Combined-model parameters that disagree with a finding's own fit "
            f"(> {DISAGREE_SIGMA:g} σ):",
            self.disagreement_lines(),
            self.disagreements(),
        )
        lines += views.section(
            width,
            "Significant at first, explained by a stronger finding's extension:",
            [
                f"{e['candidate']} (by {e['by']}; p after = {e['p_after']:.3g})"
                for e in self.explained
            ],
            self.explained,
        )
        lines.append("-" * width)
        lines.append(f"Physical red flags ({len(self.flags)}):" if self.flags else "No red flags.")
        for fl in self.flags:
            lines.append(
                f"  ! {fl['kind']} / {fl['soil']} [{fl['scope']}] {fl['code']}: {fl['message']}"
            )
        lines += views.section(
            width,
            "Significant, but lined up with data-quality artefacts (not causes):",
            [
                f"{a['candidate']} (Holm p = {a['p_adjusted']:.3g}): {a['reason']}"
                for a in self.artefacts
            ],
            self.artefacts,
        )
        lines.extend(views.power_lines(width, self.power))
        lines.extend(views.quality_lines(width, self.quality))
        lines.extend(views.column_lines(width, self.columns))
        if self.confounded:
            lines.append("-" * width)
            lines.append("Confounded candidates (effects this design cannot separate):")
            for c in self.confounded:
                lines.append(f"  {c['kind']} / {c['soil']}: {c['text']}")
        lines.append("-" * width)
        fits = [*self.findings, *self.models]
        sigma = [SIGMA_NOTE] if any(f.fit is not None for f in fits) else []
        lines.extend(notes_block([*METHOD_NOTES, *sigma, *self.notes]))
        lines.append("=" * width)
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        """The summary as tables, for notebooks: the findings, the combined models with
        their parameters (± the σ the summary quotes), the red flags, what was not found,
        and the caveats and notes."""
        facts = {
            "campaign": self.source,
            "alpha": f"{self.alpha} (Holm over {self.tests_run} tests)",
            "seed": self.seed,
        }
        if not self.findings:
            facts["findings"] = self.no_finding_text()
        return views.discovery_html(
            facts,
            self.findings,
            self.models,
            self.flags,
            self.power,
            [*METHOD_NOTES, *self.notes],
        )
