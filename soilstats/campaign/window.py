"""Fitting windows: the sinkage and pressure range a fit may use, global or per test group.

Where a test runs past bearing failure, or tests stop at one load so that small plates reach
far higher pressures than large ones, the window decides the answer (on GRC-1 it moves n
from 0.5 to 1.1). A window is therefore stated, applied before Section 2.1's equal-sinkage
thinning (so the thinning spans the window), counted per test, and shown in every summary.

A :class:`FitWindow` holds rules: a global one (no column) and any number that apply to the
tests whose test-log ``column`` equals ``value`` (e.g. ``radius_m = 0.038``); a matching
rule's limits replace the global ones.  Command lines write a rule as ``LIMIT`` or
``COLUMN=VALUE:LIMIT`` (``--z-max radius_m=0.038:0.0034``); ``test_id`` is a column too, so
``--z-max test_id=method5-test1:0.01077`` windows one test (as ``soilstats check`` proposes
for a single failed test).

:meth:`Campaign.windowed <soilstats.campaign.Campaign.windowed>` applies a window; the
campaign it returns records the :class:`AppliedWindow` (its per-test counts) in ``window``.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, TypeVar

import numpy as np
import pandas as pd

from ..errors import RENAMED_GO_IN, CampaignError, InputError
from .matching import match_values

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["AppliedWindow", "FitWindow", "WindowRule", "windowed"]


@dataclass(frozen=True)
class WindowRule:
    """Limits for the tests whose ``column`` equals ``value`` (``column`` None: every test)."""

    z_max: float | None = None  # [m]
    p_max: float | None = None  # [Pa]
    column: str | None = None
    value: str | float | None = None  # None: every test (``column`` None)

    def describe(self) -> str:
        limits = [f"z <= {self.z_max:g} m" if self.z_max is not None else ""]
        limits.append(f"p <= {self.p_max:g} Pa" if self.p_max is not None else "")
        where = "all tests" if self.column is None else f"{self.column} = {self.value}"
        return f"{where}: {', '.join(x for x in limits if x)}"


@dataclass(frozen=True)
class FitWindow:
    """The sinkage/pressure window of a fit (see the module docstring)."""

    rules: tuple[WindowRule, ...] = ()

    @classmethod
    def of(cls, z_max: float | None = None, p_max: float | None = None) -> FitWindow:
        """A global window: z <= ``z_max`` [m] and p <= ``p_max`` [Pa] for every test."""
        return cls((WindowRule(_positive(z_max, "z_max"), _positive(p_max, "p_max")),))

    @classmethod
    def parse(cls, z_max: Iterable[object] = (), p_max: Iterable[object] = ()) -> FitWindow:
        """From command-line items ``LIMIT`` or ``COLUMN=VALUE:LIMIT`` (z in m, p in Pa)."""
        rules: dict[tuple, dict] = {}
        for name, items in (("z_max", z_max), ("p_max", p_max)):
            for item in items or ():
                where, colon, limit = str(item).rpartition(":")
                key: tuple = (None, None)
                if colon:
                    column, eq, value = where.partition("=")
                    if not eq or not column:
                        raise InputError(
                            f"--{name.replace('_', '-')} takes LIMIT or COLUMN=VALUE:LIMIT "
                            f"(e.g. radius_m=0.038:0.0034), got {item!r}"
                        )
                    key = (column.strip(), value.strip())
                try:
                    number = float(limit)
                except ValueError:
                    raise InputError(
                        f"--{name.replace('_', '-')} {item!r}: the limit {limit!r} is not a number"
                    ) from None
                rules.setdefault(key, {})[name] = _positive(number, name)
        return cls(
            tuple(WindowRule(column=c, value=v, **limits) for (c, v), limits in rules.items())
        )

    def __bool__(self) -> bool:
        return any(r.z_max is not None or r.p_max is not None for r in self.rules)

    def limits(self, tests: pd.DataFrame, file: str = "tests.csv") -> pd.DataFrame:
        """``test_id``, ``z_max``, ``p_max`` per test (NaN: no limit); a column rule whose
        value matches a test replaces the global rule's limits.  ``file``: the test log's
        name, for messages."""
        out = pd.DataFrame({"test_id": tests["test_id"].astype(str).to_numpy()})
        out["z_max"] = np.nan
        out["p_max"] = np.nan
        ordered = sorted(self.rules, key=lambda r: r.column is not None)
        for rule in ordered:
            if rule.column is None:
                hit = np.ones(len(tests), bool)
            else:
                if rule.column not in tests.columns:
                    raise CampaignError(
                        f"window rule {rule.describe()!r}: no such column; the test log has "
                        f"{list(tests.columns)}",
                        file=file,
                        column=rule.column,
                    )
                value = rule.value
                if value is not None and pd.api.types.is_numeric_dtype(tests[rule.column]):
                    value = float(value)
                hit = match_values(tests[rule.column], value, rule.column)
            for name in ("z_max", "p_max"):
                if getattr(rule, name) is not None:
                    out.loc[hit, name] = getattr(rule, name)
        return out

    def apply(
        self, tests: pd.DataFrame, sinkage: pd.DataFrame, file: str = "tests.csv"
    ) -> tuple[pd.DataFrame, AppliedWindow]:
        """The samples of ``sinkage`` inside this window (z <= z_max and p <= p_max of their
        test), and the window as applied: its per-test counts and the rows it left out.

        ``tests`` is the test log (its sinkage tests are windowed), ``file`` its name for
        messages. :meth:`Campaign.windowed <soilstats.campaign.Campaign.windowed>` applies a
        window to a campaign.
        """
        limits = self.limits(tests[tests["kind"] == "sinkage"], file)
        per_sample = limits.set_index("test_id").reindex(sinkage["test_id"].astype(str))
        z_max = per_sample["z_max"].to_numpy(float)
        p_max = per_sample["p_max"].to_numpy(float)
        z, p = sinkage["z_m"].to_numpy(float), sinkage["pressure_Pa"].to_numpy(float)
        outside = (~np.isnan(z_max) & (z > z_max)) | (~np.isnan(p_max) & (p > p_max))
        counts = pd.Series(outside).groupby(sinkage["test_id"].astype(str).to_numpy()).sum()
        limits["outside"] = limits["test_id"].map(counts).fillna(0).astype(int)
        cut = np.sort(sinkage.index.to_numpy()[outside].astype(np.int64) + 1)
        return sinkage[~outside], AppliedWindow(self, limits, cut)

    def describe(self) -> str:
        """One line: every rule, or 'none'."""
        return "; ".join(r.describe() for r in self.rules if r.z_max or r.p_max) or "none"

    def to_dict(self) -> list[dict]:
        return [
            {"column": r.column, "value": r.value, "z_max_m": r.z_max, "p_max_Pa": r.p_max}
            for r in self.rules
        ]


def _positive(value: float | None, name: str) -> float | None:
    if value is None:
        return None
    value = float(value)
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{name} must be a positive number, got {value!r}")
    return value


@dataclass(frozen=True)
class AppliedWindow:
    """A window and what it left out, per test (``test_id``, ``z_max``, ``p_max``,
    ``outside``: samples beyond the limits), and the 1-based data rows of the sample file it
    left out (``rows``, sorted): a screening flag whose rows all lie there is cut off."""

    window: FitWindow
    per_test: pd.DataFrame
    rows: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64), repr=False)

    def cuts(self, rows: ArrayLike) -> bool:
        """Whether the window left out every one of these 1-based sample-file rows."""
        rows = np.asarray(rows, dtype=np.int64)
        return bool(rows.size) and bool(np.isin(rows, self.rows, assume_unique=False).all())

    def to_dict(self) -> dict:
        outside = self.per_test[self.per_test["outside"] > 0]
        return {
            "rules": self.window.to_dict(),
            "outside": {
                str(t): int(n) for t, n in zip(outside["test_id"], outside["outside"], strict=True)
            },
        }


_Windowed = TypeVar("_Windowed", covariant=True)


class _Windowable(Protocol[_Windowed]):
    """What has a :meth:`~soilstats.campaign.Campaign.windowed` method: a campaign."""

    def windowed(self, window: FitWindow | None, /) -> _Windowed: ...


def windowed(campaign: _Windowable[_Windowed], window: FitWindow | None) -> _Windowed:
    """Deprecated (removed in soilstats 0.3.0): ``campaign.windowed(window)``
    (:meth:`soilstats.campaign.Campaign.windowed`), which this calls."""
    warnings.warn(
        "soilstats.campaign.window.windowed(campaign, window) is deprecated and will be "
        f"removed in soilstats {RENAMED_GO_IN}; use campaign.windowed(window)",
        FutureWarning,
        stacklevel=2,
    )
    return campaign.windowed(window)
