"""One finding of a discovery (a cause of misfit, its extension and its out-of-sample gain)
and the parameter table and lines every discovery view quotes a fit's parameters by."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .. import evidence
from ..outputs import json_safe
from .testlevel import eq4_reason, quoted_sigma

if TYPE_CHECKING:
    from ..fitting.result import FitResult
    from .crossval import Gain
    from .data import Group
    from .extensions import Fitted
    from .testlevel import TestLevel

__all__ = ["SIGMA_NOTE", "Finding", "parameter_lines", "parameter_table"]


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
