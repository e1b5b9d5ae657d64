"""Statistics of setup-effect studies: does a setup variable change the identified parameters?

One tidy :class:`pandas.DataFrame` in (one row per test or per measured point), small tables
and frozen results out.  Every function checks its columns and raises
:class:`StatisticsInputError` (a :class:`ValueError`) with the column named; missing values
raise unless ``dropna=True``, and are then counted in the result.

============================  =============================================================
:func:`anova_oneway`          one-way ANOVA table, accurate to the data's last digit (NIST)
:func:`anova_twoway`          factor + blocking factor(s), type II sums of squares
:func:`anova_random_block`    the same with one random block (operators): factor against
                              the factor × block mean square
:func:`welch_random_block`    the same with one variance per factor level (unequal scatter)
:func:`ancova`                shear lines τ = c + σ·tanφ by group: do c, φ differ?
:func:`tukey_hsd`             which pairs of levels differ (simultaneous intervals)
:func:`tukey_lsmeans`         the same on least-squares means of a blocked model
:func:`effect_sizes`          η², partial η², ω², partial ω² of an ANOVA table
:func:`scatter_table`         between-repetition scatter per level (n, mean, sd, cv)
:func:`variance_test`         Brown–Forsythe / Levene test of equal scatter
:func:`welch_anova`           equal means without equal variances
:func:`verdicts`              Holm-adjusted verdicts across soils × responses at α
:func:`adjust_p_values`       adjusted p-values of one family (Holm unless stated)
============================  =============================================================

>>> import pandas as pd
>>> from soilstats.statistics import anova_oneway, effect_row, verdicts
>>> d = pd.DataFrame({"v": [10, 10, 10, 50, 50, 50], "n": [0.8, 0.9, 0.85, 1.1, 1.2, 1.15]})
>>> table = anova_oneway(d, "n", "v")
>>> bool(verdicts([effect_row("soil01", "n", "v", table)]).loc[0, "significant"])
True
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

# Each name loads its module on first use (PEP 562): statsmodels' formula and model APIs take
# most of a second to import, and discovery needs only the Holm verdicts of this package.
_LAZY = {
    "ConfoundingError": "._data",
    "StatisticsInputError": "._data",
    "AncovaResult": ".analysis_of_covariance",
    "ancova": ".analysis_of_covariance",
    "effect_sizes": ".effect_size",
    "anova_oneway": ".oneway",
    "anova_random_block": ".mixed",
    "shukla_variances": ".hetero",
    "welch_random_block": ".hetero",
    "tukey_hsd": ".posthoc",
    "tukey_lsmeans": ".posthoc",
    "TestResult": ".result",
    "anova_twoway": ".twoway",
    "scatter_table": ".variance",
    "variance_test": ".variance",
    "welch_anova": ".variance",
    "VERDICT_COLUMNS": ".verdict",
    "adjust_p_values": ".verdict",
    "effect_row": ".verdict",
    "verdicts": ".verdict",
}


if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from ._data import ConfoundingError, StatisticsInputError
    from .analysis_of_covariance import AncovaResult, ancova
    from .effect_size import effect_sizes
    from .hetero import shukla_variances, welch_random_block
    from .mixed import anova_random_block
    from .oneway import anova_oneway
    from .posthoc import tukey_hsd, tukey_lsmeans
    from .result import TestResult
    from .twoway import anova_twoway
    from .variance import scatter_table, variance_test, welch_anova
    from .verdict import VERDICT_COLUMNS, adjust_p_values, effect_row, verdicts


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())


__all__ = [
    "VERDICT_COLUMNS",
    "AncovaResult",
    "ConfoundingError",
    "StatisticsInputError",
    "TestResult",
    "adjust_p_values",
    "ancova",
    "anova_oneway",
    "anova_random_block",
    "anova_twoway",
    "effect_row",
    "effect_sizes",
    "scatter_table",
    "shukla_variances",
    "tukey_hsd",
    "tukey_lsmeans",
    "variance_test",
    "verdicts",
    "welch_anova",
    "welch_random_block",
]
