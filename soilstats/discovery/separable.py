"""Whether an extended model's terms can be told apart from its base on the tests it is
fitted on — judged on the test-level design, before any fit (:mod:`.extensions`).

Linearised at θ = 0, a factor exp(θ·F) moves ln k (or c, tan φ, K) by F·dθ and an offset
moves n by F·dθ, so a model's parameters are determined only if the per-test columns they
move are linearly independent:

* sinkage: [1, F_n] for the exponent, [1, F_k] for the stiffness; and Eq. 7's kc/b + kφ
  adds 1/b beside them.  A stiffness factor per level of a column whose levels each hold
  one plate width (``tool``, ``velocity_m_s × b_m``) gives every plate a stiffness of its
  own, leaving kc/b + kφ one number to set with two parameters: such a model keeps Eq. 8's
  one k instead (its fit used to walk off to kc → −∞ and fail as rank-deficient);
* shear: a test's plateau τ_max = c·e^(θ_c·F) + σ·tan φ·e^(θ_t·F) moves with 1, σ, F_c and
  σ·F_t (factors on c and tan φ per level of a column whose levels each hold one normal
  stress cannot be told apart, as c and tan φ cannot from tests at one σ, Eq. 12), and
  ln K with 1 and F_K.

Terms redundant among themselves (a combination whose one column's levels determine the
other's; a trend in a column constant on the tests) raise :class:`IdentifiabilityError`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ..errors import IdentifiabilityError

if TYPE_CHECKING:
    from .data import Group

__all__ = ["FeatureMatrix", "TermLike", "check_shear_terms", "sinkage_keeps_bekker"]


class FeatureMatrix(Protocol):
    """What the checks read of a term's features (:class:`.extensions.Features`)."""

    def matrix(self, group: Group, state: dict) -> np.ndarray: ...


class TermLike(Protocol):
    """What the checks read of a covariate term, :class:`.extensions.Term` (that module
    imports this one: an import back would close a loop, tests/test_layers.py)."""

    @property
    def features(self) -> FeatureMatrix: ...

    @property
    def targets(self) -> tuple[str, ...]: ...


def _columns(
    terms: Sequence[TermLike],
    states: Sequence[dict],
    group: Group,
    rows: np.ndarray,
    targets: tuple[str, ...],
) -> list[np.ndarray]:
    """Per-test feature columns (on the tests ``rows``) of every term moving one of
    ``targets``."""
    return [
        col
        for t, st in zip(terms, states, strict=True)
        if set(t.targets) & set(targets)
        for col in t.features.matrix(group, st)[rows].T
    ]


def _independent(columns: Sequence[np.ndarray]) -> bool:
    """Whether test-level design columns are linearly independent.

    Each column is scaled to unit length first (features, 1 and 1/b [1/m] differ in scale
    by orders of magnitude); a column that is zero on these tests (a trend in a column that
    is constant on them) makes the design dependent."""
    a = np.column_stack(columns)
    norm = np.linalg.norm(a, axis=0)
    a = a / np.where(norm > 0, norm, 1.0)
    return bool(np.all(norm > 0) and np.linalg.matrix_rank(a) == a.shape[1])


def _not_separable(name: str, rows: np.ndarray, parts: str) -> IdentifiabilityError:
    return IdentifiabilityError(
        f"{name}: {parts} are not determined on these {len(rows)} tests (the design is "
        "rank-deficient before any fit: one column's levels determine another's, or a trend's "
        "column is constant on them or aliased with such levels)"
    )


def _test_column(group: Group, column: str, rows: np.ndarray) -> np.ndarray:
    return group.tests[column].to_numpy(float)[rows]


def sinkage_keeps_bekker(
    name: str,
    bekker: bool,
    terms: Sequence[TermLike],
    states: Sequence[dict],
    group: Group,
    rows: np.ndarray,
) -> bool:
    """Whether Eq. 7's kc/b + kφ can stay beside ``terms`` on the tests ``rows`` (else
    Eq. 8's one k takes its place; ``bekker``: what the model asks for).  Raises
    :class:`IdentifiabilityError` when the terms themselves are redundant."""
    one = np.ones(len(rows))
    k_cols = _columns(terms, states, group, rows, ("k",))
    n_cols = _columns(terms, states, group, rows, ("n",))
    if n_cols and not _independent([one, *n_cols]):
        raise _not_separable(name, rows, "the exponent's offsets beside the base n")
    if k_cols and not _independent([one, *k_cols]):
        raise _not_separable(name, rows, "the stiffness factors beside the base k")
    if not (bekker and k_cols):
        return bekker
    return _independent([one, 1.0 / _test_column(group, "b_m", rows), *k_cols])


def check_shear_terms(
    name: str,
    terms: Sequence[TermLike],
    states: Sequence[dict],
    group: Group,
    rows: np.ndarray,
) -> None:
    """Raise :class:`IdentifiabilityError` when the shear ``terms`` are redundant on the
    tests ``rows`` (σ: each test's mean normal stress, ``sigma_mean_Pa``)."""
    one = np.ones(len(rows))
    sigma = _test_column(group, "sigma_mean_Pa", rows)
    c_cols = _columns(terms, states, group, rows, ("c",))
    t_cols = _columns(terms, states, group, rows, ("tan_phi",))
    k_cols = _columns(terms, states, group, rows, ("K",))
    if (c_cols or t_cols) and not _independent(
        [one, sigma, *c_cols, *(sigma * col for col in t_cols)]
    ):
        raise _not_separable(name, rows, "the factors on c and tan φ beside the base c, φ")
    if k_cols and not _independent([one, *k_cols]):
        raise _not_separable(name, rows, "the factors on K beside the base K")
