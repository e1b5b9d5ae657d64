"""The small frozen result of one hypothesis test, shared by every test in this package."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..outputs.files import json_safe
from ..outputs.text import notes_block

__all__ = ["TestResult"]


@dataclass(frozen=True)
class TestResult:
    """One test: its statistic, p-value, degrees of freedom and effect size.

    Attributes
    ----------
    test : str
        What was tested, readable in a report (e.g. ``"Brown–Forsythe (Levene, median)"``).
    statistic : float
        The test statistic (an F value for every test in this package).
    p_value : float
        Its upper-tail probability under the null hypothesis.
    df_num, df_den : float
        Numerator and denominator degrees of freedom (``df_den`` is fractional for Welch).
    effect_size : float
        The effect size named by ``effect_size_name`` (NaN where none is defined).
    effect_size_name : str
        E.g. ``"eta_sq"`` or ``"partial_eta_sq"``.
    notes : tuple of str
        Caveats a reader of the verdict should see (numbered in :meth:`summary`).
    """

    __test__ = False  # not a pytest test class, despite the name

    test: str
    statistic: float
    p_value: float
    df_num: float
    df_den: float
    effect_size: float = math.nan
    effect_size_name: str = ""
    notes: tuple[str, ...] = field(default=())

    def summary(self) -> str:
        """A few readable lines: the test, F(df1, df2) = …, p, effect size, numbered notes."""
        lines = [
            self.test,
            f"  F({self.df_num:g}, {self.df_den:.4g}) = {self.statistic:.4g},"
            f"  p = {self.p_value:.4g}",
        ]
        if self.effect_size_name:
            lines.append(f"  {self.effect_size_name} = {self.effect_size:.3g}")
        lines += notes_block(self.notes)
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The JSON-ready content (NaN → None)."""

        return json_safe(
            {
                "test": self.test,
                "statistic": self.statistic,
                "p_value": self.p_value,
                "df_num": self.df_num,
                "df_den": self.df_den,
                "effect_size": self.effect_size,
                "effect_size_name": self.effect_size_name,
                "notes": self.notes,
            }
        )

    def __str__(self) -> str:
        return self.summary()
