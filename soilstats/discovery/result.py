"""The frozen result of a discovery: findings (strongest first), red flags, caveats."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .. import evidence
from .._text import plural
from ..outputs import Provenance, json_safe
from ..outputs.text import notes_block

if TYPE_CHECKING:
    from ..fitting.result import FitResult
    from .crossval import Gain
    from .data import Group
    from .extensions import Fitted
    from .testlevel import TestLevel

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


def parameter_table(fit: FitResult | None, level: TestLevel | None = None) -> dict | None:
    """``{name: {"value", "stderr", "unit", "stderr_eq4", "stderr_level"}}`` of a fit
    (JSON-ready), or None.

    ``stderr`` is the σ to quote (issue #36, :func:`~.testlevel.quoted_sigma`): the test-level
    σ where five tests or more inform the parameter (``stderr_level`` ``"tests"``), Eq. 4's
    otherwise (``"eq4"``); ``stderr_eq4`` is Eq. 4's. With ``level`` (a
    :class:`~.testlevel.TestLevel`) each entry also carries ``stderr_tests`` (the
    cluster-robust σ over tests, in the parameter's unit; null where the parameter rests on
    one test) and ``test_scatter`` (it exceeds Eq. 4's by more than 2×, judged on five or
    more tests)."""
    if fit is None:
        return None
    from .testlevel import quoted_sigma

    stderr, eq4, levels = quoted_sigma(fit, level)
    out = {
        name: {
            "value": json_safe(v),
            "stderr": json_safe(s),
            "unit": fit.units.get(name, ""),
            "stderr_eq4": json_safe(e),
            "stderr_level": lv,
        }
        for name, v, s, e, lv in zip(fit.param_names, fit.values, stderr, eq4, levels, strict=True)
    }
    if level is not None:
        for name, st, hit in zip(fit.param_names, level.stderr, level.flagged(), strict=True):
            out[name] |= {"stderr_tests": json_safe(st), "test_scatter": bool(hit)}
    return out


#: A combined model's parameter is flagged when it differs from the finding's own fit by more
#: than this many σ of the difference (σ_f and σ_c combined as if independent: both fits use
#: the same tests, so the real σ of the difference is smaller and the flag conservative).
DISAGREE_SIGMA = 2.0

#: What the ``+/-`` of discovery's parameter lines is (the console's legend, said once).
SIGMA_NOTE = (
    "Parameters: value +/- stderr, the test-level σ (cluster-robust over tests, the "
    "linearised form of identify's bootstrap) where five tests or more inform the parameter, "
    "with Eq. 4's σ (the paper's Eqs. 3–5) in brackets; † marks Eq. 4's σ where fewer inform "
    "it (or one test alone sets it): there the scatter between tests could not be measured; "
    "* the test-level σ exceeds Eq. 4's by more than 2× (TEST-SCATTER)."
)


def parameter_lines(
    fit: FitResult | None, indent: str = "    ", level: TestLevel | None = None
) -> list[str]:
    """A fit's parameters as aligned ``name = value +/- stderr unit [Eq. 4: σ]`` lines:
    ``stderr`` the test-level σ where five tests or more inform the parameter, with Eq. 4's
    in brackets (``*`` where it exceeds Eq. 4's by more than 2×: ``test-scatter``); else
    Eq. 4's, marked ``†`` with the reason the test scatter could not be measured
    (:data:`SIGMA_NOTE`)."""
    if fit is None:
        return []
    from .testlevel import eq4_reason, quoted_sigma

    stderr, eq4, levels = quoted_sigma(fit, level)
    flagged = np.zeros(len(levels), bool) if level is None else level.flagged()
    out = []
    for j, (name, v) in enumerate(zip(fit.param_names, fit.values, strict=True)):
        line = (
            f"{indent}{name:>34} = {v:>12.5g} +/- {stderr[j]:<10.3g} {fit.units.get(name, ''):<10}"
        )
        if levels[j] == "tests":
            line += f" [Eq. 4: {eq4[j]:.3g}]{' *' if flagged[j] else ''}"
        else:
            line += f" † Eq. 4's σ: {eq4_reason(level, j)}"
        out.append(line.rstrip())
    return out


@dataclass(frozen=True, eq=False)
class Finding:
    """One cause of misfit, the extension that models it and its out-of-sample gain.

    Attributes
    ----------
    kind, soil : str
    cause : str
        The candidate column or derived quantity (e.g. ``velocity_m_s``, ``aspect_ratio``).
    confounded_with : tuple of str
        Candidates whose effect this design cannot tell apart from the cause's.
    p_adjusted : float
        Holm-adjusted p-value of the cause's strongest response (family: every candidate ×
        response × group of the campaign).
    p_value : float
        The raw p-value of the same F-test.
    responses : tuple of str
        Per-test responses in which the cause showed (``level``, ``shape``, ``K``).
    statistic, effect_size : float
        F and partial η² of the strongest response.
    n_tests : int
        Tests in scope (the strata in which the cause varies).
    extension : str or None
        The extended model kept (None when no extension gives a real out-of-sample gain).
    fit : FitResult or None
        The kept extension fitted to all tests in scope: parameters ± Eq. 4's σ (Eq. 3); the
        σ printed and in JSON is the test-level one where five tests or more inform a
        parameter (:func:`~.testlevel.quoted_sigma`).
    test_level : TestLevel or None
        The test-level σ of ``fit`` (cluster-robust over tests, :mod:`.testlevel`); where it
        exceeds Eq. 4's by more than 2× a ``TEST-SCATTER`` caveat names the parameters.
    gain : Gain or None
        Cross-validated gain of the kept (or, if none is kept, the best tried) extension with
        the named cause held fixed (whole tests left out): the gain of this cause's extension,
        which decides whether it is kept.
    gain_search : Gain or None
        The same extension's gain when each fold repeats the choice of the lead on its
        training tests (:mod:`.nested`): the gain of the whole search (find a cause, then
        extend), reported beside ``gain``, never deciding; ``selected_folds`` says in how
        many folds the lead was chosen.
    gain_conditions : Gain or None
        Leave-one-condition-out gain, for extensions that can extrapolate to a new level.
    information : dict
        AIC/BIC of base and extended fits.
    tried : tuple of dict
        Every extension tried, with its gain or the reason it failed.
    caveats : tuple of str
    """

    kind: str
    soil: str
    cause: str
    confounded_with: tuple[str, ...]
    p_adjusted: float
    p_value: float
    responses: tuple[str, ...]
    statistic: float
    effect_size: float
    n_tests: int
    extension: str | None
    fit: FitResult | None = field(default=None, repr=False)
    base_fit: FitResult | None = field(default=None, repr=False)
    gain: Gain | None = None
    gain_search: Gain | None = None
    gain_conditions: Gain | None = None
    information: dict = field(default_factory=dict)
    tried: tuple[dict, ...] = ()
    caveats: tuple[str, ...] = ()
    scope_rows: np.ndarray | None = field(default=None, repr=False)
    group: Group | None = field(default=None, repr=False)
    fitted: Fitted | None = field(default=None, repr=False)
    base_fitted: Fitted | None = field(default=None, repr=False)
    #: Test-level σ of ``fit`` (:class:`~.testlevel.TestLevel`), None without a kept fit.
    test_level: TestLevel | None = field(default=None, repr=False)

    def to_dict(self) -> dict:
        """The JSON shape of issue #6, plus the supporting detail."""
        gain = json_safe(self.gain.to_dict()) if self.gain is not None else None
        out = {
            "kind": self.kind,
            "soil": self.soil,
            "cause": self.cause,
            "p_adjusted": json_safe(self.p_adjusted),
            "p_value": json_safe(self.p_value),
            "extension": self.extension,
            "gain": gain,
            "confounded_with": list(self.confounded_with),
            "responses": list(self.responses),
            "statistic": json_safe(self.statistic),
            "effect_size": json_safe(self.effect_size),
            "n_tests": self.n_tests,
            "parameters": None,
            "information": {k: json_safe(v) for k, v in self.information.items()},
            "tried": [json_safe(t) for t in self.tried],
            "caveats": list(self.caveats),
        }
        out["gain_search"] = (
            json_safe(self.gain_search.to_dict()) if self.gain_search is not None else None
        )
        if self.gain_conditions is not None:
            out["gain_conditions"] = json_safe(self.gain_conditions.to_dict())
        out["parameters"] = parameter_table(self.fit, self.test_level)
        return out

    def summary_lines(self) -> list[str]:
        conf = (
            f" (confounded with {', '.join(self.confounded_with)})" if self.confounded_with else ""
        )
        lines = [
            f"{self.kind} / {self.soil}: cause {self.cause}{conf}",
            f"  shows in {', '.join(self.responses)}: F = {self.statistic:.4g}, partial eta^2 = "
            f"{self.effect_size:.3f}, p = {self.p_value:.3g} "
            f"(Holm-adjusted {self.p_adjusted:.3g}), "
            f"{self.n_tests} tests in scope",
        ]
        if self.gain is not None:
            g = self.gain
            lines.append(
                f"  extension: {self.extension or 'none kept'}; {g.scheme} CV ({g.folds} folds, "
                f"cause fixed): base {g.base:.4f} -> extended {g.extended:.4f} (gain "
                f"{g.relative:+.1%}; paired difference base − extended, {g.text()})"
            )
            s = self.gain_search
            if s is not None:
                lines.append(
                    f"  whole search (the lead re-selected in each fold, chosen in "
                    f"{s.selected_folds} of {s.folds}): gain {s.relative:+.1%}"
                )
        else:
            lines.append("  extension: none (no extension could be cross-validated)")
        if self.gain_conditions is not None:
            g = self.gain_conditions
            lines.append(
                f"  leave-one-condition-out ({g.folds} conditions): base {g.base:.4f} -> "
                f"extended {g.extended:.4f} (gain {g.relative:+.1%}, {g.text()})"
            )
        lines += parameter_lines(self.fit, level=self.test_level)
        for t in self.tried:
            if t.get("error"):
                lines.append(f"  tried {t['extension']}: failed — {t['error']}")
            elif t["extension"] != self.extension:
                lines.append(
                    f"  tried {t['extension']}: gain {t['relative']:+.1%} ({_tried_text(t)})"
                )
        lines += [f"  caveat: {c}" for c in self.caveats]
        return lines

    def summary(self) -> str:
        """The finding in a few readable lines (as in :meth:`DiscoveryResult.summary`)."""
        return "\n".join(self.summary_lines())


def _tried_text(tried: dict) -> str:
    """A tried extension's gain in the words of :mod:`soilstats.evidence` (an older record
    without the difference and its SE: its word alone)."""
    if "difference" in tried and "stderr" in tried:
        return evidence.describe(tried["difference"], tried["stderr"], tried.get("relative"))
    return "real" if tried.get("real") else "not real"


def _section(width: int, title: str, texts: list[str], records) -> list[str]:
    """A titled block of ``kind / soil: text`` lines (nothing when there are none)."""
    if not texts:
        return []
    body = [f"  {r['kind']} / {r['soil']}: {t}" for r, t in zip(records, texts, strict=True)]
    return ["-" * width, title, *body]


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
        from .crossval import campaign_gain

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
        from ..models import models_of_kind
        from .testlevel import quoted_sigma

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
        from .crossval import campaign_gain

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
        lines.extend(self._model_lines(width))
        lines += _section(
            width,
            f"Combined-model parameters that disagree with a finding's own fit "
            f"(> {DISAGREE_SIGMA:g} σ):",
            self.disagreement_lines(),
            self.disagreements(),
        )
        lines += _section(
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
        lines += _section(
            width,
            "Significant, but lined up with data-quality artefacts (not causes):",
            [
                f"{a['candidate']} (Holm p = {a['p_adjusted']:.3g}): {a['reason']}"
                for a in self.artefacts
            ],
            self.artefacts,
        )
        lines.extend(self._power_lines(width))
        lines.extend(self._quality_lines(width))
        lines.extend(self._column_lines(width))
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

    def _model_lines(self, width: int) -> list[str]:
        """The combined model per (kind, soil) and its gain over the base."""
        if not self.models:
            return []
        lines = ["-" * width, "Combined model (forward selection of the kept extensions):"]
        for m in self.models:
            lines.extend("  " + line for line in m.summary_lines())
        g = self.all_groups_gain()
        if g is not None:
            lines.append(
                f"  all extended groups together: {g.base:.4f} -> {g.extended:.4f} "
                f"({g.relative:+.1%}, {g.n_tests} held-out tests)"
            )
        return lines

    def _power_lines(self, width: int) -> list[str]:
        """Candidates not found, with the smallest effect the design could have found."""
        if not self.power:
            return []
        level = self.power[0]["alpha_level"]
        lines = [
            "-" * width,
            f"Not found — the smallest effect each test would have found (power "
            f"{self.power[0]['power']:.0%} at Holm's strictest level alpha/m = {level:.2g}):",
        ]
        for p in self.power:
            parts = [f"{r}: {v['statement']}" for r, v in p["responses"].items()]
            lines.append(
                f"  {p['kind']} / {p['soil']}: {p['candidate']} ({p['role']}, "
                f"{p['n_tests']} tests) — " + "; ".join(parts)
            )
        return lines

    def _quality_lines(self, width: int) -> list[str]:
        """The screening the fits used: data problems, never causes."""
        q = self.quality
        if not q:
            return []
        lines = ["-" * width, f"Data quality ({q['mode']} mode; data problems, never causes):"]
        if q["mode"] == "off":
            return [*lines, "  screening was off: nothing was checked"]
        counts = (
            ", ".join(f"{c} in {plural(n, 'test')}" for c, n in q["counts"].items())
            or "no findings"
        )
        lines.append(f"  {counts}; {q['excluded_samples']} samples left out of every fit")
        for t in q["tests"]:
            lines.append(f"  {t['kind']} {t['test_id']}: {', '.join(t['codes'])}")
        return lines

    def _column_lines(self, width: int) -> list[str]:
        """Candidates by role per (kind, soil); outcomes listed with why they never enter."""
        if not self.columns:
            return []
        lines = ["-" * width, "Columns and their roles (outcomes never enter as causes):"]
        groups: dict[tuple, list[dict]] = {}
        for c in self.columns:
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

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        """The summary as tables, for notebooks: the findings, the combined models with
        their parameters (± the σ the summary quotes), the red flags, what was not found,
        and the caveats and notes."""
        from .._html import facts_html, notes_html, result_html, table_html
        from .testlevel import quoted_sigma

        facts = {
            "campaign": self.source,
            "alpha": f"{self.alpha} (Holm over {self.tests_run} tests)",
            "seed": self.seed,
        }
        if not self.findings:
            facts["findings"] = self.no_finding_text()
        findings = pd.DataFrame(
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
                for i, f in enumerate(self.findings, 1)
            ]
        )
        models = pd.DataFrame(
            [
                {
                    "group": f"{m.kind} / {m.soil}",
                    "model": " + ".join(m.extensions) or "base model",
                    "causes": ", ".join(m.causes),
                    "gain": "" if m.gain is None else f"{m.gain.relative:+.1%}",
                    "tests": m.n_tests,
                }
                for m in self.models
            ]
        )
        rows = []
        for m in self.models:
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
        flags = pd.DataFrame(list(self.flags))
        power = pd.DataFrame(
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
                for p in self.power
            ]
        )
        caveats = [f"[{i}] {c}" for i, f in enumerate(self.findings, 1) for c in f.caveats]
        caveats += [f"{m.kind} / {m.soil} model: {c}" for m in self.models for c in m.caveats]
        return result_html(
            "Discovery: what the soil model gets wrong",
            facts_html(facts),
            table_html(findings, caption="Findings (strongest first)") if len(findings) else "",
            table_html(models, caption="Combined model per group") if len(models) else "",
            table_html(
                pd.DataFrame(rows),
                caption="Combined-model parameters: stderr the test-level σ where five tests "
                "or more inform the parameter (σ level 'tests'), Eq. 4's otherwise",
            )
            if rows
            else "",
            table_html(flags, caption="Physical red flags") if len(flags) else "",
            table_html(power, caption="Not found: the smallest effect the design would have found")
            if len(power)
            else "",
            notes_html(caveats, "Caveats"),
            notes_html([*METHOD_NOTES, *self.notes]),
        )
