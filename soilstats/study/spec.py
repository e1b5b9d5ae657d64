"""Study specifications: one TOML file per study, read and checked here.

A study asks whether one setup variable (the *factor*) changes the identified soil parameters
(the *responses*), beyond the test-to-test scatter.  Its specification names the factor, the
tests, the responses, the pooled model of the per-condition tables, the criteria and the
figures; the seven studies of the paper's Sections 3–4 are shipped in ``studies/`` and a user
adds one by writing a file.  Every key is documented in ``docs/studies.md``.

A malformed file raises :class:`SpecError` (a ``ValueError``) naming the file, the key, the
value seen and the valid options.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..campaign.window import FitWindow
from ..errors import SpecError, refuse_unknown_keys
from ..models import models_of_kind
from ..outputs.files import safe_stem

__all__ = [
    "STUDY_TYPES",
    "Criteria",
    "Response",
    "SpecError",
    "StudySpec",
    "available_studies",
    "find_spec",
    "load_spec",
    "studies_dir",
]

STUDY_TYPES = ("sinkage", "shear", "preparation")
# Per-test responses each study type can analyse (units in docs/studies.md).
RESPONSES = {
    "sinkage": ("log10_p_ref", "n", "log10_k"),
    "preparation": ("log10_p_ref", "n", "log10_k"),
    "shear": ("c", "phi", "line"),
}


def study_models(study_type: str) -> list[str]:
    """The pooled models a study of ``study_type`` may name, from the registry: every
    sinkage model for sinkage and preparation studies; for shear studies the shear models
    identified from the steady-state parts (Mohr–Coulomb: the c and φ of τ_ss against σ
    the studies compare)."""
    if study_type == "shear":
        return [m.name for m in models_of_kind("shear") if m.steady_state]
    return [m.name for m in models_of_kind("sinkage")]


FIGURES = ("curves", "relative", "mohr-coulomb", "epsilon", "responses")
_TOP_KEYS = {
    "name",
    "title",
    "type",
    "description",
    "paper",
    "factor",
    "blocks",
    "random_blocks",
    "alpha",
    "family",
    "reference",
    "z_ref_m",
    "z_window_m",
    "model",
    "fallback_model",
    "tests",
    "responses",
    "figures",
    "curves",
    "paper_finding",
    "criteria",
    "window",
}


@dataclass(frozen=True)
class Response:
    """A per-test response and its relevance margin.

    ``margin`` is the smallest change that matters to a rover team, in the response's unit
    (``margin_kind = "absolute"``) or as a relative change of the quantity whose log10 is the
    response (``"relative"``, e.g. 0.15 = ±15 % pressure).  ``None``: every significant
    effect is reported as one that matters.
    """

    name: str
    label: str
    margin: float | None = None
    margin_kind: str = "absolute"

    @property
    def margin_on_scale(self) -> float | None:
        """The margin in the response's own unit (log10 units for a relative margin)."""
        if self.margin is None:
            return None
        if self.margin_kind == "relative":
            return math.log10(1.0 + self.margin)
        return self.margin


@dataclass(frozen=True)
class Criteria:
    """The paper's Table 1 criteria of a preparation study (evaluated as Table 3)."""

    # criterion 1: applicability to a large testbed, from the methods' descriptions
    min_loosening_depth_cm: float
    #: Tools that scale to a large testbed, by role: the paper scales a hand shovel to dig
    #: and trickle (method 9, "+") but not to level (method 10, "−"; Table 3).
    scalable_loosening_tools: tuple[str, ...]
    scalable_levelling_tools: tuple[str, ...]
    time_consuming: tuple[str, ...]
    match_columns: tuple[str, ...]
    methods: dict[str, dict]
    # criterion 2: no operator effect, bounded between-repetition scatter
    max_scatter_cv: float
    operator_column: str
    # criterion 3: fit quality ε (Eq. 2) as close to one as the best method's
    epsilon_within_best: float


@dataclass(frozen=True)
class StudySpec:
    """A validated study specification (see ``docs/studies.md`` for every key)."""

    name: str
    title: str
    type: str
    description: str
    paper: str
    factor: str
    blocks: tuple[str, ...]
    alpha: float
    family: str | None
    #: Blocks whose levels are a random sample (operators): the factor is tested against the
    #: factor × block mean square (:func:`soilstats.statistics.anova_random_block`).
    random_blocks: tuple[str, ...]
    reference: str | float | None  # a level of the factor as the TOML writes it, or None
    z_ref_m: float
    z_window_m: float
    model: str
    fallback_model: str | None
    where: dict
    where_present: dict
    responses: tuple[Response, ...]
    figures: tuple[str, ...]
    curves_where: dict
    paper_finding: str
    criteria: Criteria | None
    window: FitWindow | None = None  # sinkage/pressure window of every fit (empty: none)
    path: Path | None = field(default=None, compare=False)

    @property
    def kind(self) -> str:
        """The kind of test the study reads: ``"sinkage"`` or ``"shear"``."""
        return "shear" if self.type == "shear" else "sinkage"


def studies_dir() -> Path:
    """Folder of the shipped specifications.

    Installed: ``soilstats/studies/`` (mapped from the repository's ``studies/`` at build
    time, see ``setup.py``); in a source checkout: ``studies/`` beside the package.
    """
    package = Path(__file__).resolve().parent.parent  # soilstats/
    for candidate in (package / "studies", package.parent / "studies"):
        if candidate.is_dir() and any(candidate.glob("*.toml")):
            return candidate
    raise SpecError(
        f"no study specifications found in {package / 'studies'} or {package.parent / 'studies'}; "
        "reinstall soilstats (the wheel ships them) or pass the path of a .toml file"
    )


def available_studies() -> list[str]:
    """Names of the shipped studies, in the paper's order where known."""
    names = sorted(p.stem for p in studies_dir().glob("*.toml"))
    order = [
        "preparation",
        "velocity",
        "tool-shape",
        "shear-ring",
        "grousers",
        "grouser-height",
        "shear-velocity",
    ]
    return [n for n in order if n in names] + [n for n in names if n not in order]


def find_spec(name: str) -> Path:
    """The file of a shipped study ``name``, or ``name`` itself if it is a path to a file."""
    path = Path(name)
    if path.suffix == ".toml" or path.is_file():
        if not path.is_file():
            raise SpecError(f"study specification file {str(path)!r} does not exist")
        return path
    candidate = studies_dir() / f"{name}.toml"
    if not candidate.is_file():
        raise SpecError(
            f"unknown study {name!r}; choose one of {[*available_studies(), 'all']} or give the "
            "path of a study specification (.toml)"
        )
    return candidate


def _fail(path: str | os.PathLike[str], key: str, message: str) -> SpecError:
    return SpecError(f"study specification {str(path)!r}, key {key!r}: {message}")


def _get(
    raw: dict,
    key: str,
    kinds: type | tuple[type, ...],
    path: str | os.PathLike[str],
    default: Any = ...,
    options: Iterable[object] | None = None,
) -> Any:
    if key not in raw:
        if default is ...:
            raise _fail(path, key, "is required")
        return default
    value = raw[key]
    if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in _tuple(kinds)):
        raise _fail(path, key, f"value {value!r} must be {_names(kinds)}")
    if options is not None and value not in options:
        raise _fail(path, key, f"value {value!r} is not one of {list(options)}")
    return value


def _tuple(kinds):
    return kinds if isinstance(kinds, tuple) else (kinds,)


def _names(kinds: type | tuple[type, ...]) -> str:
    return " or ".join(k.__name__ for k in _tuple(kinds))


def _check_keys(raw: dict, allowed: set, path: str | os.PathLike[str], where: str) -> None:
    refuse_unknown_keys(
        raw,
        allowed,
        lambda unknown: _fail(
            path,
            f"{where}{min(unknown)}",
            f"unknown key; valid keys here are {sorted(allowed)} (a misspelled key must not be "
            "silently ignored)",
        ),
    )


def _responses(raw: dict, study_type: str, path: str | os.PathLike[str]) -> tuple[Response, ...]:
    items = _get(raw, "responses", list, path)
    if not items:
        raise _fail(path, "responses", "needs at least one response")
    out = []
    for i, item in enumerate(items):
        if isinstance(item, str):
            item = {"name": item}
        if not isinstance(item, dict):
            raise _fail(path, f"responses[{i}]", f"value {item!r} must be a name or a table")
        _check_keys(item, {"name", "label", "margin", "margin_kind"}, path, f"responses[{i}].")
        name = _get(item, "name", str, path, options=RESPONSES[study_type])
        margin = _get(item, "margin", (int, float), path, default=None)
        if margin is not None and not margin > 0:
            raise _fail(path, f"responses[{i}].margin", f"value {margin!r} must be > 0")
        kind = _get(
            item, "margin_kind", str, path, default="absolute", options=("absolute", "relative")
        )
        out.append(Response(name, _get(item, "label", str, path, default=name), margin, kind))
    return tuple(out)


def _criteria(raw: dict, path: str | os.PathLike[str]) -> Criteria:
    crit = _get(raw, "criteria", dict, path)
    _check_keys(
        crit, {"applicability", "repeatability", "fit_quality", "methods"}, path, "criteria."
    )
    c1 = _get(crit, "applicability", dict, path)
    _check_keys(
        c1,
        {
            "min_loosening_depth_cm",
            "scalable_tools",
            "scalable_loosening_tools",
            "scalable_levelling_tools",
            "time_consuming",
            "match_columns",
        },
        path,
        "criteria.applicability.",
    )
    c2 = _get(crit, "repeatability", dict, path)
    _check_keys(c2, {"max_scatter_cv", "operator_column"}, path, "criteria.repeatability.")
    c3 = _get(crit, "fit_quality", dict, path)
    _check_keys(c3, {"epsilon_within_best"}, path, "criteria.fit_quality.")
    methods = _get(crit, "methods", dict, path)
    for label, description in methods.items():
        if not isinstance(description, dict):
            raise _fail(path, f"criteria.methods.{label}", "must be a table of the method")
        _check_keys(
            description,
            {
                "loosening_tool",
                "levelling_tool",
                "loosening_pattern",
                "loosening_movement",
                "loosening_depth_cm",
            },
            path,
            f"criteria.methods.{label}.",
        )
    # scalable_tools: one list for both roles (as before the roles were told apart).
    both = _get(c1, "scalable_tools", list, path, default=None)
    if both is None and not {"scalable_loosening_tools", "scalable_levelling_tools"} <= set(c1):
        raise _fail(
            path,
            "criteria.applicability",
            "needs scalable_loosening_tools and scalable_levelling_tools (or scalable_tools "
            "for both)",
        )
    return Criteria(
        min_loosening_depth_cm=float(_get(c1, "min_loosening_depth_cm", (int, float), path)),
        scalable_loosening_tools=tuple(
            _get(c1, "scalable_loosening_tools", list, path, default=both)
        ),
        scalable_levelling_tools=tuple(
            _get(c1, "scalable_levelling_tools", list, path, default=both)
        ),
        time_consuming=tuple(_get(c1, "time_consuming", list, path, default=[])),
        match_columns=tuple(_get(c1, "match_columns", list, path, default=[])),
        methods={str(k): dict(v) for k, v in methods.items()},
        max_scatter_cv=float(_get(c2, "max_scatter_cv", (int, float), path)),
        operator_column=_get(c2, "operator_column", str, path, default="operator"),
        epsilon_within_best=float(_get(c3, "epsilon_within_best", (int, float), path)),
    )


def _window(raw, path):
    """``[window]``: ``z_max`` [m] / ``p_max`` [Pa], a number or a list of
    ``"COLUMN=VALUE:LIMIT"`` items (as the CLI's --z-max/--p-max)."""
    table = _get(raw, "window", dict, path, default={})
    _check_keys(table, {"z_max", "p_max"}, path, "window.")
    items = {}
    for key in ("z_max", "p_max"):
        value = table.get(key, [])
        items[key] = [value] if isinstance(value, (int, float, str)) else list(value)
    try:
        return FitWindow.parse(items["z_max"], items["p_max"])
    except ValueError as err:
        raise _fail(path, "window", str(err)) from None


def _random_blocks(
    raw: dict,
    blocks: tuple[str, ...],
    criteria: Criteria | None,
    path: str | os.PathLike[str],
) -> tuple[str, ...]:
    """``random_blocks``: at most one of ``blocks``.  Default: the preparation criteria's
    ``operator_column`` when it is a block (the people of Table 1's criterion 2 are a sample
    of those who will prepare the bin), none otherwise."""
    if "random_blocks" in raw:
        chosen = tuple(_get(raw, "random_blocks", list, path))
    elif criteria is not None and criteria.operator_column in blocks:
        chosen = (criteria.operator_column,)
    else:
        chosen = ()
    for block in chosen:
        if block not in blocks:
            raise _fail(
                path, "random_blocks", f"value {block!r} is not one of blocks {list(blocks)}"
            )
    if len(chosen) > 1:
        raise _fail(
            path,
            "random_blocks",
            f"value {list(chosen)}: at most one random block is supported (the factor is "
            "tested against its interaction with it)",
        )
    return chosen


def load_spec(source: str | Path) -> StudySpec:
    """Read and validate a study specification (a shipped name or a .toml path)."""
    path = find_spec(str(source))
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise SpecError(f"study specification {str(path)!r} is not valid TOML: {err}") from None
    _check_keys(raw, _TOP_KEYS, path, "")
    study_type = _get(raw, "type", str, path, options=STUDY_TYPES)
    tests = _get(raw, "tests", dict, path, default={})
    _check_keys(tests, {"where", "where_present"}, path, "tests.")
    curves = _get(raw, "curves", dict, path, default={})
    _check_keys(curves, {"where"}, path, "curves.")
    alpha = float(_get(raw, "alpha", (int, float), path, default=0.05))
    if not 0 < alpha < 1:
        raise _fail(path, "alpha", f"value {alpha!r} must lie in (0, 1), e.g. 0.05")
    figures = tuple(_get(raw, "figures", list, path, default=[]))
    for fig in figures:
        if fig not in FIGURES:
            raise _fail(path, "figures", f"value {fig!r} is not one of {list(FIGURES)}")
    z_ref = float(_get(raw, "z_ref_m", (int, float), path, default=0.025))
    if not z_ref > 0:
        raise _fail(path, "z_ref_m", f"value {z_ref!r} must be > 0 (a sinkage in m)")
    name = _get(raw, "name", str, path, default=path.stem)
    blocks = tuple(_get(raw, "blocks", list, path, default=[]))
    criteria = _criteria(raw, path) if study_type == "preparation" else None
    try:
        safe_stem(name)  # the outputs are named after it: never a path
    except ValueError as err:
        raise _fail(path, "name", str(err)) from None
    return StudySpec(
        name=name,
        title=_get(raw, "title", str, path, default=path.stem),
        type=study_type,
        description=_get(raw, "description", str, path, default="").strip(),
        paper=_get(raw, "paper", str, path, default=""),
        factor=_get(raw, "factor", str, path),
        blocks=blocks,
        alpha=alpha,
        family=_get(raw, "family", str, path, default=None),
        random_blocks=_random_blocks(raw, blocks, criteria, path),
        reference=raw.get("reference"),
        z_ref_m=z_ref,
        z_window_m=float(_get(raw, "z_window_m", (int, float), path, default=0.001)),
        model=_get(raw, "model", str, path, options=study_models(study_type)),
        fallback_model=_get(
            raw, "fallback_model", str, path, default=None, options=study_models(study_type)
        ),
        where=dict(_get(tests, "where", dict, path, default={})),
        where_present=dict(_get(tests, "where_present", dict, path, default={})),
        responses=_responses(raw, study_type, path),
        figures=figures,
        curves_where=dict(_get(curves, "where", dict, path, default={})),
        window=_window(raw, path),
        paper_finding=_get(raw, "paper_finding", str, path, default="").strip(),
        criteria=criteria,
        path=path,
    )
