"""Exceptions and warnings of soilstats.

Every error raised for bad user input is a :class:`ValueError` subclass, so callers that
already catch ``ValueError`` keep working; every warning derives from
:class:`SoilstatsWarning`, so one filter silences (or escalates) them all.
"""

from __future__ import annotations

__all__ = [
    "CampaignError",
    "ConvergenceError",
    "ConvergenceWarning",
    "IdentifiabilityError",
    "SoilstatsError",
    "SoilstatsWarning",
]


class SoilstatsError(Exception):
    """Base class of every error soilstats raises on purpose (bad input, failed fits)."""


class SoilstatsWarning(UserWarning):
    """Base class of every warning soilstats emits."""


class ConvergenceWarning(SoilstatsWarning):
    """A fit or sampler finished, but a health check failed (see the result's flags)."""


class CampaignError(SoilstatsError, ValueError):
    """A campaign breaks a rule of the campaign format.

    The message names the file, the column, the test and the row (1-based data row, the
    header not counted) wherever they exist; the same facts are kept as attributes.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        column: str | None = None,
        test_id: str | None = None,
        row: int | None = None,
    ) -> None:
        self.file = file
        self.column = column
        self.test_id = test_id
        self.row = row
        where = []
        if file is not None:
            where.append(f"file {file!r}")
        if column is not None:
            where.append(f"column {column!r}")
        if test_id is not None:
            where.append(f"test {test_id!r}")
        if row is not None:
            where.append(f"row {row}")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class IdentifiabilityError(SoilstatsError, ValueError):
    """The data cannot determine the model's parameters (e.g. Bekker with one plate size)."""


class ConvergenceError(SoilstatsError, RuntimeError):
    """An optimiser did not reach a trustworthy minimum.

    ``result`` holds the last iterate (a :class:`soilstats.fitting.FitResult` with
    ``converged=False``) for inspection; it must not be used as an estimate.
    """

    def __init__(self, message: str, result: object | None = None) -> None:
        super().__init__(message)
        self.result = result
