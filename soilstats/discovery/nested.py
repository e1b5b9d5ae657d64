"""A finding's data-driven choices, repeated inside each cross-validation fold: the gain of
the whole search.

Two gains are measured for each extension (:func:`.leads._try_extensions`).  The one that
decides what is kept holds the named cause fixed — the Holm-controlled test established it
on all tests, and the question is what its extension gains on tests left out.  The one of
this module measures the whole search (find the cause, then extend) as a lab would repeat
it on fewer tests; it is reported beside the other, as what it is, and decides nothing
(before issue #35 it decided, and threw away extensions of causes the test had
established: a +14 % bin in 30 tests, named at Holm p = 0.027, "chosen in 2 of 5 folds",
−10.8 %, nothing kept).

Diagnosis chooses, from F-tests on *all* tests, that a lead is significant at all and in
which per-test responses it shows (``level``, ``shape``; ``level``, ``K``); the generic
extension frees the parameters of those responses (:func:`.library.library`).  Measured
on folds of the same tests, the gain of the chosen extension is optimistic: the held-out
tests helped choose it (a null factor kept at p < 0.01 in 16–24 tests gained a median
+18 % in the review's toy).  So each fold repeats the choice on its training tests alone
(:func:`fold_choices`): the base model fitted without the fold, the responses measured
against it (:func:`.diagnose.training_responses`), the lead's F-test within the same
strata (:func:`.diagnose.retest`), each response at the level Holm applied to it on all
tests (:func:`.diagnose._holm_levels`).  A fold where the lead shows in no response
predicts its held-out tests with the base model, as discovery would have done had it seen
only the training tests; otherwise the fold's extension frees the parameters of the
responses the fold chose (:func:`fold_extensions`).

Not repeated (docs/discover.md, "Known gaps"): the Holm family over the other candidates
(the level of each response is kept as it was on all tests), which candidate of a
confounded group leads, which extension of the library is kept, the leave-one-condition-out
gain (:func:`.leads._condition_gain`), forward selection (:mod:`.selection`), and the
reference depth of the ``level`` response (half the median depth reached, taken over all
tests of the group, held-out ones included).  And
the gain is still reported only for leads that were significant on all tests: conditional
on that, the held-out tests share some of the chance pattern that made the lead
significant (docs/discover.md, "Gain").
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .diagnose import RESPONSES, retest, training_responses
from .library import library

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from .data import Group
    from .extensions import Extension, FitStart

__all__ = ["fold_choices", "fold_extensions"]


def fold_choices(
    group: Group,
    lead_table: pd.DataFrame,
    scope: ArrayLike,
    folds: ArrayLike,
    starts: Mapping[int, FitStart],
) -> dict[int, tuple]:
    """The responses in which the lead is significant on each fold's training tests.

    Parameters
    ----------
    group
        The (kind, soil) group, with its diagnosis columns.
    lead_table : DataFrame
        The diagnosis rows of the lead, one per response (significant or not), with
        ``holm_level``; the first significant one carries the strata (``blocks``).
    scope : array of int
        The tests in scope (rows of the group), those the folds split.
    folds : array of int
        Fold of each test in scope (:func:`.crossval.make_folds`).
    starts : dict
        The base model's fit without each fold (fold → ``Start`` or ``Fitted``).

    Returns
    -------
    dict
        fold → tuple of responses (in :data:`.diagnose.RESPONSES` order); empty when the
        lead is significant in none on that fold's training tests.
    """
    scope, folds = np.asarray(scope, int), np.asarray(folds)
    level = dict(zip(lead_table["response"], lead_table["holm_level"], strict=True))
    top = lead_table[lead_table["significant"]].sort_values(["p_adjusted", "p_value"]).iloc[0]
    out = {}
    for fold in np.unique(folds):
        table = training_responses(group, starts[int(fold)], scope[folds != fold])
        p = retest(group, table, top)
        out[int(fold)] = tuple(
            r
            for r in RESPONSES[group.kind]
            if np.isfinite(p.get(r, np.nan)) and p[r] < level.get(r, np.nan)
        )
    return out


def fold_extensions(
    ext: Extension,
    choices: dict[int, tuple],
    **library_args: Any,  # library.library's keywords but responses, of their own types
) -> dict[int, Extension | None]:
    """fold → the extension ``ext`` as the fold's choice makes it, or None (the fold predicts
    with the base model: the lead is not significant on its training tests).

    ``library_args`` are those :func:`.library.library` built ``ext`` with, but for
    ``responses``: the fold's extension is the one of the same name in the library built
    with the fold's responses (a physical extension does not depend on them; the generic
    one frees the parameters of the fold's responses only)."""
    out: dict = {}
    built: dict = {}
    for fold, chosen in choices.items():
        if not chosen:
            out[fold] = None
            continue
        if chosen not in built:
            built[chosen] = {e.name: e for e in library(**library_args, responses=set(chosen))}
        out[fold] = built[chosen].get(ext.name, ext)
    return out
