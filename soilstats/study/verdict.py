"""A study's verdicts: Holm-adjusted significance, then relevance against the spec's margin.

Categories (column ``verdict``; ``matters`` is True only for the first):

* ``effect`` — significant after Holm adjustment and the largest pairwise difference exceeds
  the margin (or no margin is declared);
* ``no relevant effect`` — every simultaneous pairwise interval lies within ±margin: any
  difference is smaller than what the spec says matters (it may still be *detectable*);
* ``inconclusive`` — significant, below the margin, but its interval reaches beyond it;
* ``no effect detected`` — not significant (absence of evidence, not evidence of absence,
  unless the intervals also lie within the margin, which is then ``no relevant effect``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..statistics import verdicts

__all__ = ["classify"]


def classify(effect_rows: list[dict], *, alpha: float, family: str | None) -> pd.DataFrame:
    """Verdict table of a study from its effect rows (see the module docstring)."""
    if not effect_rows:
        return pd.DataFrame()
    table = verdicts(effect_rows, alpha=alpha, family=family)
    margin = table.get("margin", pd.Series(np.nan, index=table.index)).astype(float)
    largest = table.get("largest_difference", pd.Series(np.nan, index=table.index)).astype(float)
    bound = table.get("difference_bound", pd.Series(np.nan, index=table.index)).astype(float)
    has_margin = margin.notna()
    equivalent = has_margin & (bound < margin)
    beyond = ~has_margin | (largest > margin)
    sig = table["significant"].astype(bool)
    verdict = np.where(
        equivalent,
        "no relevant effect",
        np.where(sig & beyond, "effect", np.where(sig, "inconclusive", "no effect detected")),
    )
    table["verdict"] = verdict
    table["matters"] = table["verdict"] == "effect"
    return table
