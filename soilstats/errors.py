"""Exceptions and warnings of soilstats.

Every error raised for bad user input is a :class:`ValueError` subclass, so callers that
already catch ``ValueError`` keep working; every warning derives from
:class:`SoilstatsWarning`, so one filter silences (or escalates) them all.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Collection, Iterable

from ._text import shown

__all__ = [
    "CampaignError",
    "ConfoundingError",
    "ConvergenceError",
    "ConvergenceWarning",
    "DefaultWarning",
    "IdentifiabilityError",
    "InputError",
    "ModelError",
    "RenamedWarning",
    "SoilstatsError",
    "SoilstatsWarning",
    "SpecError",
    "StatisticsInputError",
    "StudyDataError",
    "located",
    "refuse_unknown_keys",
    "warn_renamed",
]


class SoilstatsError(Exception):
    """Base class of every error soilstats raises on purpose (bad input, failed fits)."""


class SoilstatsWarning(UserWarning):
    """Base class of every warning soilstats emits."""


class ConvergenceWarning(SoilstatsWarning):
    """A fit or sampler finished, but a health check failed (see the result's flags)."""


class DefaultWarning(SoilstatsWarning):
    """A default the user did not give moves a verdict: tried at its documented alternative,
    the verdict changes (docs/conventions.md, "Defaults that move a verdict")."""


class RenamedWarning(SoilstatsWarning, FutureWarning):
    """An old name of something soilstats renamed (docs/conventions.md, "Renamed"): it still
    works, with this warning naming the new one, until the release :data:`RENAMED_GO_IN`."""


#: The release in which the old names of docs/conventions.md's "Renamed" table stop working.
RENAMED_GO_IN = "0.3.0"


def warn_renamed(old: str, new: str, *, stacklevel: int = 3) -> None:
    """Warn (:class:`RenamedWarning`, a ``FutureWarning``) that ``old`` is now ``new``;
    ``stacklevel`` 3 points at the caller of the property or function that calls this."""
    warnings.warn(
        f"{old} is renamed {new}; the old name goes in soilstats {RENAMED_GO_IN}",
        RenamedWarning,
        stacklevel=stacklevel,
    )


class CampaignError(SoilstatsError, ValueError):
    """A campaign breaks a rule of the campaign format.

    The message names the file, the column, the test and the row (1-based data row, the
    header not counted) wherever they exist; the same facts are kept as attributes. A column
    name or test id of hostile length is cut short in the message (the attribute keeps it
    whole), so the message stays one readable line.
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
        super().__init__(located(message, file=file, column=column, test=test_id, row=row))


def located(
    message: str,
    *,
    file: str | None = None,
    column: str | None = None,
    row: int | None = None,
    **unit: str | None,
) -> str:
    """``message`` prefixed by where it applies: ``file 'x.csv', column 'z_m', test 't1', row
    4: …`` (the parts given, in that order; ``unit`` is one keyword naming the unit, e.g.
    ``test=`` or ``run=``, whose value is cut short when it is of hostile length)."""
    where = []
    if file is not None:
        where.append(f"file {file!r}")
    if column is not None:
        where.append(f"column {shown(column)}")
    where += [f"{kind} {shown(value)}" for kind, value in unit.items() if value is not None]
    if row is not None:
        where.append(f"row {row}")
    prefix = ", ".join(where)
    return f"{prefix}: {message}" if prefix else message


def refuse_unknown_keys(
    table: Iterable[str], allowed: Collection[str], error: Callable[..., Exception]
) -> None:
    """Raise ``error(unknown)`` when ``table`` (a TOML table) holds keys outside ``allowed``.

    The one rule of every TOML file soilstats reads (a SPEC, a study specification, an import
    mapping, a wheels file): a misspelled key is refused, never ignored, as ignoring it would
    leave in force the default it meant to change.  ``unknown`` lists the offending keys in
    the table's order; each format words its own message (the key, what it allows, where its
    documentation is).
    """
    unknown = [key for key in table if key not in allowed]
    if unknown:
        raise error(unknown)


class InputError(SoilstatsError, ValueError):
    """An argument of a soilstats function or command holds a value it does not take (an
    option outside its choices, a number out of range, a malformed item, a table without the
    columns it needs); the message names the argument, the value given and what would do.

    The general bad-input error, for what none of the more specific errors below describes.
    """


class IdentifiabilityError(SoilstatsError, ValueError):
    """The data cannot determine the model's parameters (e.g. Bekker with one plate size)."""


class ModelError(SoilstatsError, ValueError):
    """A soil model name that is not registered, or a model asked for where its kind does not
    fit (a shear model for sinkage tests); the message lists the models that would."""


class ConvergenceError(SoilstatsError, RuntimeError):
    """An optimiser did not reach a trustworthy minimum, or a sampler a converged posterior.

    ``result`` holds the last iterate (a :class:`soilstats.fitting.FitResult` with
    ``converged=False``) or the unconverged :class:`soilstats.bayes.PosteriorResult`, for
    inspection; it must not be used as an estimate.
    """

    def __init__(self, message: str, result: object | None = None) -> None:
        super().__init__(message)
        self.result = result


class SpecError(SoilstatsError, ValueError):
    """A specification file (a study spec or a simulation SPEC) breaks a rule.

    The message names the file, the key, the value and the valid options.
    """


class StudyDataError(SoilstatsError, ValueError):
    """The campaign lacks what a study needs (the message says what, and what was found)."""


class StatisticsInputError(SoilstatsError, ValueError):
    """The data cannot be analysed as asked (missing column, too few levels, non-finite values).

    Attributes
    ----------
    column : str or None
        The offending column, where there is one.
    """

    def __init__(self, message: str, *, column: str | None = None) -> None:
        self.column = column
        super().__init__(f"column {column!r}: {message}" if column is not None else message)


class ConfoundingError(StatisticsInputError):
    """A factor's effect cannot be separated from a blocking factor's (rank-deficient design).

    Attributes
    ----------
    factor, block : str
        The tested factor and the blocking factor(s) it is confounded with.
    df_lost : int
        How many of the factor's degrees of freedom the blocks absorb.
    """

    def __init__(self, message: str, *, factor: str, block: str, df_lost: int) -> None:
        self.factor = factor
        self.block = block
        self.df_lost = df_lost
        super().__init__(message, column=factor)
