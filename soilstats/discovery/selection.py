"""One extended model per (kind, soil) that carries every real cause: forward selection.

Each finding's extension was measured alone against the base model, with every other effect
left in the noise.  A lab wants the one model that carries them all, and what it gains.
Forward selection builds it on all tests of the group, by the same cross-validation (whole
tests held out, :mod:`.crossval`, one set of folds for every step):

1. start from the base model (Eq. 7/8 or Eq. 13);
2. add, of the extensions the findings kept, the one whose addition gives the largest gain
   over the current model that passes the keep rule (mean paired difference > ``Z_KEEP`` SE,
   :mod:`.crossval`; called real only at 2 SE, :mod:`soilstats.evidence`)
   **and** leaves the combined fit physically plausible (:mod:`.plausibility`) and
   determined (it converges, no rank deficiency: an interaction's cells already carry its
   main effect, say);
3. repeat until no remaining extension passes the keep rule; report the final model's
   parameters ± σ (Eq. 3) fitted to all tests and its gain over the base model.

Extensions combine by :func:`.library.combine`; Reece's model replaces Eq. 7 and does not
combine with another extension (the step says so).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np

from .. import evidence
from ..outputs import json_safe
from .crossval import FoldFits, GroupFolds, compare
from .extensions import Extension
from .library import base_model, combine
from .plausibility import implausible
from .result import parameter_lines, parameter_table
from .testlevel import scatter_caveat, test_level
from .work import FIT_ERRORS, FitTask, Wave

if TYPE_CHECKING:
    from ..fitting.result import FitResult
    from .crossval import Gain
    from .data import Group
    from .extensions import Fitted
    from .testlevel import TestLevel
    from .work import Process

__all__ = [
    "CombinedModel",
    "PreparedSelection",
    "prepare_selection",
    "selection_steps",
]


@dataclass(frozen=True, eq=False)
class CombinedModel:
    """The extended model of one (kind, soil) built by forward selection.

    Attributes
    ----------
    kind, soil : str
    extensions : tuple of str
        The extensions selected, in the order they were added (empty: none adds a real gain
        on all tests; the base model stands).
    causes : tuple of str
        The finding (cause) each selected extension came from, in the same order.
    fit : FitResult or None
        The combined model fitted to all tests of the group: parameters ± Eq. 4's σ (Eq. 3);
        printed and in JSON with the test-level σ (:func:`~.testlevel.quoted_sigma`).
    test_level : TestLevel or None
        Test-level σ of ``fit`` (cluster-robust over tests, :mod:`.testlevel`).
    caveats : tuple of str
        A ``TEST-SCATTER`` caveat where the test-level σ exceeds Eq. 4's by more than 2×.
    gain : Gain or None
        Cross-validated gain of the combined model over the base model (same folds).
    steps : tuple of dict
        Every step: the extension tried, its cause, its gain over the model before it, and
        whether it was added or why not.
    n_tests : int
        Tests the model was fitted to (every usable test of the group).
    """

    kind: str
    soil: str
    extensions: tuple[str, ...]
    causes: tuple[str, ...]
    fit: FitResult | None = field(default=None, repr=False)
    gain: Gain | None = None
    steps: tuple[dict, ...] = ()
    n_tests: int = 0
    fitted: Fitted | None = field(default=None, repr=False)
    #: Test-level σ of ``fit`` (:class:`~.testlevel.TestLevel`; cluster-robust over tests).
    test_level: TestLevel | None = field(default=None, repr=False)
    #: ``TEST-SCATTER`` and the like: what the reader of the parameters must know.
    caveats: tuple[str, ...] = ()
    #: Per-test held-out errors (base, combined), for a campaign-wide gain.
    held_out: tuple | None = field(default=None, repr=False)

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "soil": self.soil,
            "extensions": list(self.extensions),
            "causes": list(self.causes),
            "gain": None if self.gain is None else json_safe(self.gain.to_dict()),
            "parameters": parameter_table(self.fit, self.test_level),
            "steps": [json_safe(s) for s in self.steps],
            "n_tests": self.n_tests,
            "caveats": list(self.caveats),
        }

    def summary(self) -> str:
        """The combined model in a few readable lines: extensions, gain, parameters ± σ."""
        return "\n".join(self.summary_lines())

    def summary_lines(self) -> list[str]:
        head = f"{self.kind} / {self.soil}: "
        if not self.extensions:
            return [head + "base model (no extension gains enough to be kept on all tests)"]
        g = self.gain
        assert g is not None  # an extended model has its gain (selection_steps)
        lines = [
            head + " + ".join(self.extensions) + f"  (causes: {', '.join(self.causes)})",
            f"  gain over the base model, {self.n_tests} tests, {g.scheme} CV ({g.folds} folds): "
            f"{g.base:.4f} -> {g.extended:.4f} ({g.relative:+.1%}, paired difference "
            f"base − extended, {g.text()})",
        ]
        lines += parameter_lines(self.fit, level=self.test_level)
        lines += [f"  caveat: {c}" for c in self.caveats]
        for st in self.steps:
            if st["added"]:
                continue
            gain = f"gain {st['relative']:+.1%}; " if st.get("relative") is not None else ""
            lines.append(f"  not added: {st['extension']} ({gain}{st['reason']})")
        return lines


def _failure(exc: Exception) -> str:
    """Why a combination could not be fitted, in one short clause."""
    text = str(exc)
    if "rank-deficient" in text or "not determined" in text:
        return (
            "adds nothing the model does not already carry (the combined fit is "
            "rank-deficient: its parameters are not determined)"
        )
    return f"the combined fit fails: {text[:240]}"


@dataclass(frozen=True, eq=False)
class PreparedSelection:
    """What forward selection starts from: the candidates, the tests, the base model fitted
    to all of them, and the folds (drawn)."""

    kept: list
    rows: np.ndarray
    base_full: Fitted
    folds: np.ndarray


def prepare_selection(
    group: Group,
    kept: Iterable[tuple[str, Extension]],
    folds: GroupFolds,
    base: Fitted | None = None,
) -> PreparedSelection | None:
    """Forward selection up to its first fit: ``kept`` reduced to one ``(cause,
    Extension)`` per extension (the strongest finding names it), the base model fitted to
    all tests if ``base`` is None, on the group's ``folds`` (those its findings were
    measured on, :class:`.crossval.GroupFolds`).  None when ``kept`` is empty."""
    first: dict[str, tuple] = {}
    for cause, ext in kept:  # one extension kept by several findings: the strongest names it
        first.setdefault(ext.name, (cause, ext))
    kept = list(first.values())
    if not kept:
        return None
    rows = folds.rows
    base_full = base if base is not None else base_model(group, rows).fit(group, rows)
    return PreparedSelection(kept, rows, base_full, folds.folds)


def selection_steps(group: Group, prepared: PreparedSelection) -> Process[CombinedModel]:
    """Process (:mod:`.work`) of forward selection after :func:`prepare_selection`: the
    base model's fold fits, then one wave per step with every candidate's fold fits and its
    fit on all tests.  Returns the :class:`CombinedModel`."""
    rows, base_full, folds = prepared.rows, prepared.base_full, prepared.folds
    base_plan = FoldFits(rows, base_full.extension, folds, scheme="tests", chain="base")
    starts, e_base = base_plan.collect((yield Wave(group, base_plan.tasks)))
    e_current = e_base
    chosen: list[tuple[str, Extension]] = []
    steps: list[dict] = []
    remaining = list(prepared.kept)
    current = None  # (Extension, Fitted, errors) of the model so far
    while remaining:
        options, failed = [], []
        # Every candidate of this step: its fold fits and its fit on all tests, one wave.
        planned, tasks = [], []
        for i, (cause, ext) in enumerate(remaining):  # chain i: the folds, then all tests
            model = combine([e for _, e in chosen] + [ext])
            plan: FoldFits | None = None
            if model is not None:
                plan = FoldFits(rows, model, folds, scheme="tests", starts=starts, chain=i)
                tasks += [*plan.tasks, FitTask(model, rows, base_full, chain=i)]
            planned.append((cause, ext, model, plan))
        outcomes = iter((yield Wave(group, tasks, probe=True)))
        for cause, ext, model, plan in planned:
            step = {"extension": ext.name, "cause": cause, "added": False}
            if model is None or plan is None:
                failed.append({**step, "reason": "does not combine with " + chosen[0][1].name})
                continue
            folds_out = [next(outcomes) for _ in plan.tasks]
            full = next(outcomes)
            try:
                errors = plan.collect(folds_out)[1]
                full.raise_error()
                fitted = cast("Fitted", full.fitted)  # a fit on all tests: a Fitted
            except FIT_ERRORS as exc:
                failed.append({**step, "reason": _failure(exc)})
                continue
            gain = compare(e_current, errors, scheme="tests", folds=folds)
            reasons = implausible(fitted, base_full, group, rows)
            step.update(relative=gain.relative, gain=gain.to_dict())
            if reasons:
                step["reason"] = "physically implausible: " + "; ".join(reasons)
            elif not gain.kept:
                step["reason"] = f"too little gain over the model before it ({gain.text()})"
            good = not reasons and bool(gain.kept)
            options.append((good, gain.relative, cause, ext, step, fitted, errors, model))
        steps += failed  # a model that fails or does not combine now will not later
        goods = [o for o in options if o[0]]
        if not goods:
            steps += [o[4] for o in options]
            break
        _, _, cause, ext, step, fitted, errors, model = max(goods, key=lambda o: o[1])
        steps.append(
            {**step, "added": True, "reason": "plausible, gain " + _described(step["gain"])}
        )
        chosen.append((cause, ext))
        current = (model, fitted, errors)
        e_current = errors
        remaining = [(o[2], o[3]) for o in options if o[3].name != ext.name]
    if current is None:
        return CombinedModel(group.kind, group.soil, (), (), steps=tuple(steps), n_tests=rows.size)
    level = test_level(current[1], group, rows)
    scatter = scatter_caveat(current[1].result, level)
    return CombinedModel(
        kind=group.kind,
        soil=group.soil,
        extensions=tuple(e.name for _, e in chosen),
        causes=tuple(c for c, _ in chosen),
        fit=current[1].result,
        gain=compare(e_base, current[2], scheme="tests", folds=folds),
        steps=tuple(steps),
        n_tests=int(rows.size),
        fitted=current[1],
        test_level=level,
        caveats=() if scatter is None else (scatter,),
        held_out=(e_base, current[2]),
    )


def _described(gain: dict) -> str:
    """A step's gain (its ``to_dict``) in the words of :mod:`soilstats.evidence`."""
    return evidence.describe(gain["difference"], gain["stderr"], gain["relative"])
