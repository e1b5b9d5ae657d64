"""Which extended models discovery tries for a cause, the base model of a group of tests,
and extensions combined into one model (the models themselves:
:mod:`soilstats.discovery.extensions`).

For a cause the library proposes the physical extensions its name suggests first
(``velocity``, ``softening``, ``reece``, ``side-walls``: the paper's Sections 3–4), then
the generic ones — ``levels`` for a categorical covariate, ``linear`` for a numeric one
(see :mod:`soilstats.discovery.extensions`).
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pandas as pd

from .candidates import MISSING, WITHIN, candidate_values

if TYPE_CHECKING:
    from .data import Group

from ..identification.conditions import model_for
from .extensions import (
    Extension,
    Features,
    ModelExtension,
    ReeceExtension,
    ShearExtension,
    SinkageExtension,
    Term,
    shear_inputs_a,
)

__all__ = ["base_model", "bekker_refused", "combine", "library"]


def base_model(group: Group, rows: np.ndarray) -> Extension:
    """The paper's base model for these tests: Bekker (Eq. 7) where ``identify`` would fit
    it (two or more plate sizes at least 1.5× apart, :func:`bekker_refused`), else
    Bernstein (Eq. 8); Janosi–Hanamoto (Eq. 13) for shear — or the group's own registered
    model (``Group.model``, from ``discover(model=...)``)."""
    own = getattr(group, "model", None)
    if own is not None and own.kind == group.kind:
        return ModelExtension(
            f"{own.name} (base)",
            False,
            f"{own.equation.split(':')[0]}, one {', '.join(own.param_names)}",
            model=own,
        )
    if group.kind == "shear":
        return ShearExtension("janosi (base)", False, "Eq. 13, one c, φ, K for all tests")
    if bekker_refused(group, rows) is None:
        return SinkageExtension("bekker (base)", False, "Eq. 7, one kc, kφ, n", bekker=True)
    return SinkageExtension("bernstein (base)", False, "Eq. 8, one k, n", bekker=False)


def bekker_refused(group: Group, rows: np.ndarray) -> str | None:
    """Why Bekker (Eq. 7) cannot be the base of these sinkage tests, in ``identify``'s words,
    or None when it can: ``identify`` decides (:func:`soilstats.identification.conditions
    .model_for`: one plate size, or plate sizes closer than ``MIN_SIZE_RATIO`` = 1.5×, leave
    kc and kφ apart undetermined), and discovery follows — until issue #35 it fitted Bekker
    to any two sizes, and plates of 20 and 22.5 mm gave kc–kφ collinearity red flags where
    ``identify`` refused the design."""
    tests = group.tests.iloc[np.asarray(rows, int)]
    model, why = model_for("sinkage", "auto", None, tests)
    return None if model == "bekker" else why


_SIZE = {"b_m", "area_m2", "tool"}
_ASPECT = {"aspect_ratio", "shape"}
_RING = {"grouser_height_m", "r_inner_m", "r_outer_m", "ring_area_m2"}


def library(
    group: Group,
    rows: np.ndarray,
    cause: str,
    related: Iterable[str],
    *,
    numeric: bool,
    responses: Collection[str],
    log_scale: bool = True,
) -> list[Extension]:
    """Extensions to try for ``cause`` (and the candidates confounded with it), physical first.

    Parameters
    ----------
    group, rows
        The tests in scope.
    cause : str
        The leading candidate.
    related : sequence of str
        Candidates confounded with it (their physics is tried too: with ``tool`` aliased with
        ``b_m``, Reece is a candidate explanation).
    numeric : bool
        Whether ``cause`` holds numbers (linear trend) or labels (per-level factors).
    responses : set of str
        Per-test responses in which the cause showed: ``level``, ``shape`` (sinkage),
        ``level``, ``K`` (shear) — they decide which parameters the generic extension frees.
    log_scale : bool
        Whether a ``linear`` trend in ``cause`` may enter on ln x, as diagnosis tested it
        (:func:`~.candidates.trend_on_log`: not for a time/order column).
    """
    names = {cause, *related}
    tests = group.tests.iloc[np.asarray(rows, int)]
    base = base_model(group, rows)
    trend = cause.split(WITHIN)[0] if WITHIN in cause else None
    if trend is not None and trend in tests and cause in tests:
        # A drift inside one block: a trend of its own in each block, on the parameters
        # whose response showed it (the generic extension's targets).
        return [_within_extension(group, base, cause, trend, responses)]
    if isinstance(base, ModelExtension):
        return _own_library(base, group, tests, cause, names, numeric, responses, log_scale)
    asked = _Asked(cause, names, numeric, responses, log_scale)
    if group.kind == "sinkage":
        assert isinstance(base, SinkageExtension)  # base_model's for sinkage tests
        return _sinkage_library(base, tests, asked)
    return _shear_library(shear_inputs_a(group, rows), asked)


@dataclass(frozen=True)
class _Asked:
    """What :func:`library` is asked for: the ``cause``, the ``names`` whose physics is tried
    (it and the candidates confounded with it), whether it is ``numeric``, the
    ``responses`` it showed in and whether a linear trend may enter on ln x
    (``log_scale``)."""

    cause: str
    names: set[str]
    numeric: bool
    responses: Collection[str]
    log_scale: bool


def _sinkage_library(base: SinkageExtension, tests: pd.DataFrame, asked: _Asked) -> list[Extension]:
    """The paper's sinkage extensions for ``cause`` (Bekker/Bernstein's base ``base``): the
    velocity law, softening of narrow plates, Reece and the per-size Bernstein law where
    their columns are among the ``names``, then the generic one."""
    out: list[Extension] = []
    bekker = base.bekker
    v = tests["velocity_m_s"].to_numpy(float) if "velocity_m_s" in tests else np.array([])
    if "velocity_m_s" in asked.names and v.size and np.all(v > 0) and np.unique(v).size >= 2:
        out.append(
            SinkageExtension(
                "velocity",
                True,
                "k·(v/v_ref)^a and n + m·ln(v/v_ref) (Section 3.1.2)",
                bekker=bekker,
                terms=(Term(Features("velocity_m_s", "velocity"), ("k", "n")),),
            )
        )
    aspect = tests["aspect_ratio"].to_numpy(float)
    if asked.names & (_ASPECT | _SIZE) and np.any(aspect >= 1.5) and np.any(aspect < 1.5):
        out.append(
            SinkageExtension(
                "softening",
                True,
                "narrow plates soften beyond a critical sinkage z_c (Section 3.1.3, Fig. 9)",
                bekker=bekker,
                soften=True,
            )
        )
    if asked.names & _SIZE and bekker:
        out.append(ReeceExtension("reece", True, "Reece p = (k1 + k2·b)(z/b)^n"))
    if asked.names & _SIZE:
        # The plate size's own curve: Bernstein k and n per size (each plate its own
        # power law) — what a size effect on the exponent asks for, and always positive.
        out.append(
            SinkageExtension(
                f"k and n per {asked.cause}",
                False,
                f"Bernstein k and n per level of {asked.cause} (Eq. 8 per plate size)",
                bekker=False,
                terms=(Term(Features(asked.cause, "levels"), ("k", "n")),),
            )
        )
    stiffness = "level" in asked.responses or not asked.responses
    exponent = "shape" in asked.responses or not asked.responses
    how = "linear" if asked.numeric else "levels"
    if (
        asked.names & _SIZE
        and not asked.numeric
        and stiffness
        and exponent
        and _fixes_width(tests, asked.cause)
    ):
        # k and n per level of a column that fixes the plate width is what the generic
        # extension becomes (separable.sinkage_keeps_bekker): the same model, fitted once.
        return out
    out.append(
        _generic(
            SinkageExtension, asked.cause, how, stiffness, exponent, asked.log_scale, bekker=bekker
        )
    )
    return out


def _shear_library(a: np.ndarray, asked: _Asked) -> list[Extension]:
    """The shear extensions for ``cause``: the ring's side walls where the ring or tool is
    among the ``names`` and the rings differ, then the generic one."""
    out: list[Extension] = []
    if asked.names & (_RING | {"tool"}) and np.unique(np.round(a, 9)).size >= 2:
        out.append(
            ShearExtension(
                "side-walls",
                True,
                "torque on the ring's side walls (Eq. 12 extended): c·(1+a), tan φ·(1+a·K0)",
                side_walls=True,
            )
        )
    targets = (("c", "tan_phi") if "level" in asked.responses or not asked.responses else ()) + (
        ("K",) if "K" in asked.responses else ()
    )
    how = "linear" if asked.numeric else "levels"
    out.append(
        ShearExtension(
            f"{asked.cause} ({how})",
            False,
            f"{', '.join(targets)} depend on {asked.cause} ({how})",
            terms=(Term(Features(asked.cause, how, log_scale=asked.log_scale), targets),),
        )
    )
    return out


def _own_library(
    base: ModelExtension,
    group: Group,
    tests: pd.DataFrame,
    cause: str,
    names: Collection[str],
    numeric: bool,
    responses: Collection[str],
    log_scale: bool,
) -> list[Extension]:
    """A registered model's extensions: the velocity law (k·(v/v_ref)^a and an offset of n)
    where the velocity is a cause, then the generic one (the responses' parameters depend on
    the cause).  Softening, Reece and the per-size Bernstein law are the paper's
    Bekker/Bernstein's."""
    model, out = base.model, list[Extension]()
    n_free = model.exponent is not None
    v = tests["velocity_m_s"].to_numpy(float) if "velocity_m_s" in tests else np.array([])
    if "velocity_m_s" in names and v.size and np.all(v > 0) and np.unique(v).size >= 2:
        targets = ("k", "n") if n_free else ("k",)
        out.append(
            ModelExtension(
                "velocity",
                True,
                "stiffness·(v/v_ref)^a" + (" and n + m·ln(v/v_ref)" if n_free else ""),
                model=model,
                terms=(Term(Features("velocity_m_s", "velocity"), targets),),
            )
        )
    stiffness = "level" in responses or not responses
    exponent = n_free and ("shape" in responses or not responses)
    if not (stiffness or exponent):
        stiffness = True  # a shape effect on a model without an exponent: its level moves
    how = "linear" if numeric else "levels"
    out.append(_generic(ModelExtension, cause, how, stiffness, exponent, log_scale, model=model))
    return out


def _within_extension(
    group: Group,
    base: Extension,
    cause: str,
    trend: str,
    responses: Collection[str],
) -> Extension:
    """The extension of a drift inside blocks: per block its own linear trend in the
    time/order column ``trend`` (features centred within each block), on the parameters of
    the responses that showed it."""
    features = Features(trend, "block-linear", log_scale=False, by=cause)
    description = f"{{}} drift linearly in {trend}, at a rate of their own in each block"
    if group.kind == "shear":
        targets = (("c", "tan_phi") if "level" in responses or not responses else ()) + (
            ("K",) if "K" in responses else ()
        )
        return ShearExtension(
            f"{cause} (linear per block)",
            False,
            description.format(", ".join(targets)),
            terms=(Term(features, targets),),
        )
    stiffness = "level" in responses or not responses
    exponent = "shape" in responses or not responses
    targets = ("k",) * stiffness + ("n",) * exponent
    if isinstance(base, ModelExtension):
        form: dict = dict(model=base.model)
    else:  # a sinkage group's base (shear returned above)
        form = dict(bekker=cast(SinkageExtension, base).bekker)
    kind = ModelExtension if isinstance(base, ModelExtension) else SinkageExtension
    return kind(
        f"{cause} (linear per block)",
        False,
        description.format(" and ".join(targets)),
        terms=(Term(features, targets),),
        **form,
    )


def _generic(
    kind: type[SinkageExtension] | type[ModelExtension],
    cause: str,
    how: str,
    stiffness: bool,
    exponent: bool,
    log_scale: bool,
    **form: Any,
) -> Extension:
    """The generic sinkage extension of ``kind``: the stiffness and/or the exponent depend on
    ``cause`` (``how``: per level, or a linear trend)."""
    return kind(
        f"{cause} ({how})",
        False,
        f"{'k' if stiffness else ''}{' and ' if stiffness and exponent else ''}"
        f"{'n' if exponent else ''} depend on {cause} ({how})",
        terms=(
            Term(
                Features(cause, how, log_scale=log_scale),
                ("k",) * stiffness + ("n",) * exponent,
            ),
        ),
        **form,
    )


def _fixes_width(tests: pd.DataFrame, column: str) -> bool:
    """Whether each level of ``column`` holds one plate width b among ``tests``."""
    levels = candidate_values(tests, column).astype(object).fillna(MISSING)
    widths = np.round(tests["b_m"].to_numpy(float), 9)
    return bool(pd.Series(widths).groupby(levels.to_numpy()).nunique().max() == 1)


def combine(extensions: Iterable[Extension]) -> Extension | None:
    """One model that carries the effects of every extension given (of one kind), or None
    when one of them cannot be combined: Reece replaces Eq. 7 rather than extending it.

    Terms on the same column merge their targets; softening and side walls switch on when
    any part has them; the base is Bekker only if every part keeps Bekker (a per-plate-size
    Bernstein term makes kc/b + kφ redundant).
    """
    extensions = list(extensions)
    if len(extensions) == 1:
        return extensions[0]
    if not extensions or any(
        not isinstance(e, SinkageExtension | ShearExtension | ModelExtension) for e in extensions
    ):
        return None
    # Past this check every part is one of the three, and all are of one kind (the models of
    # one group): a cast, for the attributes read below.
    parts = cast("list[SinkageExtension | ShearExtension | ModelExtension]", extensions)
    if any(isinstance(e, ModelExtension) for e in parts) and not all(
        isinstance(e, ModelExtension) and e.model == cast(ModelExtension, parts[0]).model
        for e in parts
    ):
        return None
    merged: dict[Features, tuple[str, ...]] = {}  # Features is frozen: its fields are the key
    for e in parts:
        for t in e.terms:
            merged[t.features] = tuple(dict.fromkeys((*merged.get(t.features, ()), *t.targets)))
    terms = tuple(Term(features, targets) for features, targets in merged.items())
    name = " + ".join(e.name for e in extensions)
    description = "; ".join(e.description for e in extensions)
    physical = all(e.physical for e in extensions)
    first = parts[0]
    if isinstance(first, ModelExtension):
        return ModelExtension(name, physical, description, model=first.model, terms=terms)
    if isinstance(first, SinkageExtension):
        sinkage = cast("list[SinkageExtension]", parts)  # one kind: all sinkage
        return SinkageExtension(
            name,
            physical,
            description,
            bekker=all(e.bekker for e in sinkage),
            terms=terms,
            soften=any(e.soften for e in sinkage),
        )
    shear = cast("list[ShearExtension]", parts)  # one kind: all shear
    return ShearExtension(
        name, physical, description, terms=terms, side_walls=any(e.side_walls for e in shear)
    )
