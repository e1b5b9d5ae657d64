"""The declarative SPEC of a simulated campaign: read a TOML file, check it, freeze it.

The format is documented, with a complete example, in ``docs/simulator.md``.  Every table of
the file is checked against the keys it may hold: a misspelled key, a wrong type or an unknown
choice raises :class:`SpecError` (a :class:`ValueError`) that names the key, the value seen and
the valid options.  Nothing in a SPEC is read with a silent default except where the
documentation states the default.
"""

from __future__ import annotations

import hashlib
import math
import os
import tomllib
from pathlib import Path
from typing import Any, TypeVar

from ..errors import refuse_unknown_keys
from . import records
from .artefacts import ARTEFACT_KINDS, check_artefact
from .effects import check_effect
from .records import (
    EFFECT_KINDS,
    KINDS,
    PARAMS,
    SHEAR_PARAMS,
    SINKAGE_PARAMS,
    Artefact,
    Effect,
    Noise,
    Preparation,
    Resolution,
    Scatter,
    Series,
    Soil,
    Spec,
    SpecError,
)
from .support import outside_support

# The SPEC's whole API from one import: its records and constants (their home is records.py)
# and the two readers.
__all__ = [*records.__all__, "load_spec", "parse_spec"]

_D = TypeVar("_D", Noise, Resolution, Scatter)  # the tables read by _dataclass_table


# --------------------------------------------------------------------------- checked access
def _fail(where: str, message: str) -> SpecError:
    return SpecError(f"SPEC {where}: {message}")


def _check_keys(table: dict, allowed: tuple[str, ...], where: str, extra_ok: bool = False) -> None:
    if not isinstance(table, dict):
        raise _fail(where, f"must be a table, got {type(table).__name__} {table!r}")
    if extra_ok:
        return

    def unknown_key(unknown: list[str]) -> SpecError:
        return _fail(
            f"{where}.{unknown[0]}",
            f"unknown key {unknown[0]!r}; valid keys are {list(allowed)} — check the spelling "
            "(docs/simulator.md lists every key)",
        )

    refuse_unknown_keys(table, allowed, unknown_key)


def _number(value: Any, where: str, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _fail(where, f"must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise _fail(where, f"must be > 0, got {value!r}")
    if nonneg and value < 0:
        raise _fail(where, f"must be ≥ 0, got {value!r}")
    return float(value)


def _int(value: Any, where: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise _fail(where, f"must be an integer ≥ {minimum}, got {value!r}")
    return value


def _text(value: Any, where: str, choices: tuple[str, ...] | None = None) -> str:
    if not isinstance(value, str | int) or isinstance(value, bool):
        raise _fail(where, f"must be text, got {value!r}")
    value = str(value)
    if choices is not None and value not in choices:
        raise _fail(where, f"{value!r} is not a valid option; choose one of {list(choices)}")
    return value


def _list(value: Any, where: str) -> list:
    out = value if isinstance(value, list) else [value]
    if not out:
        raise _fail(where, "must not be empty")
    return out


def _numbers(value: Any, where: str, **kw: bool) -> tuple[float, ...]:
    return tuple(_number(v, f"{where}[{i}]", **kw) for i, v in enumerate(_list(value, where)))


def _scalar_cell(value: Any, where: str) -> str | float:
    """A value that can stand in a test-log cell: text or a finite number."""
    if isinstance(value, str):
        return value
    return _number(value, where)


# --------------------------------------------------------------------------- parsing
def _dataclass_table(cls: type[_D], table: Any, where: str, base: _D | None = None) -> _D:
    defaults = base if base is not None else cls()
    names = tuple(defaults.__dataclass_fields__)
    if table is None:
        return defaults
    _check_keys(table, names, where)
    values = {k: getattr(defaults, k) for k in names}
    for k, v in table.items():
        values[k] = _number(v, f"{where}.{k}", nonneg=True)
    return cls(**values)


def _params(table: dict, where: str, allowed: tuple[str, ...] = PARAMS) -> dict[str, float]:
    out = {}
    for k, v in table.items():
        _text(k, where, allowed)
        out[k] = _number(v, f"{where}.{k}")
    if "K" in out and out["K"] <= 0:
        raise _fail(f"{where}.K", f"the shear deformation modulus K must be > 0 m, got {out['K']}")

    bad = outside_support(out)
    if bad:
        raise _fail(
            f"{where}.{bad[0].split(' ')[0]}",
            f"outside the models' support: {'; '.join(bad)} (docs/simulator.md)",
        )
    return out


def _soil(name: str, table: Any) -> Soil:
    where = f"[soils.{name}]"
    _check_keys(table, (*PARAMS, "conditions"), where)
    params = _params({k: v for k, v in table.items() if k != "conditions"}, where)
    conds = []
    for i, cond in enumerate(table.get("conditions", [])):
        cw = f"{where}.conditions[{i}]"
        _check_keys(cond, (*PARAMS, "where"), cw)
        if "where" not in cond or not isinstance(cond["where"], dict) or not cond["where"]:
            raise _fail(
                f"{cw}.where",
                "must be a non-empty table of test-log column = value, "
                "e.g. where = { velocity_m_s = 4.8e-4 }",
            )
        match = {k: _scalar_cell(v, f"{cw}.where.{k}") for k, v in cond["where"].items()}
        conds.append((match, _params({k: v for k, v in cond.items() if k != "where"}, cw)))
    return Soil(name, params, tuple(conds))


_PREP_RESERVED = ("scatter", "operator_cv")
#: Log columns the design itself writes: a preparation may not set them.
_DESIGN_COLUMNS = ("test_id", "kind", "soil", "preparation", "repetition", "series")


def _preparation(name: str, table: Any, scatter: Scatter) -> Preparation:
    where = f"[preparations.{name}]"
    _check_keys(table, (), where, extra_ok=True)
    own = _dataclass_table(Scatter, table.get("scatter"), f"{where}.scatter", base=scatter)
    op = _number(table.get("operator_cv", 0.0), f"{where}.operator_cv", nonneg=True)
    cols = {k: _scalar_cell(v, f"{where}.{k}") for k, v in table.items() if k not in _PREP_RESERVED}
    taken = [k for k in cols if k in _DESIGN_COLUMNS]
    if taken:
        raise _fail(
            f"{where}.{taken[0]}",
            f"{taken[0]!r} is a column the design writes ({list(_DESIGN_COLUMNS)}); "
            "a preparation's keys add test-log columns of their own",
        )
    return Preparation(name, own, op, cols)


_PLATE_KEYS = ("shape", "radius_m", "width_m", "length_m", "aspect", "area_m2")
_RING_KEYS = ("r_inner_m", "r_outer_m")
_SERIES_COMMON = (
    "name",
    "kind",
    "soils",
    "preparations",
    "operators",
    "repetitions",
    "points",
    "covariates",
)
_SERIES_KEYS = {
    "sinkage": (*_SERIES_COMMON, "plates", "velocity_m_s", "sinkage_m", "start_m"),
    "shear": (
        *_SERIES_COMMON,
        "rings",
        "grousers",
        "grouser_height_m",
        "omega_rpm",
        "normal_pressure_Pa",
        "shear_deformation_m",
    ),
}


def _plate(p: Any, where: str) -> dict[str, str | float]:
    _check_keys(p, (), where, extra_ok=True)
    shape = _text(p.get("shape"), f"{where}.shape", ("circle", "rectangle"))
    out: dict[str, str | float] = {"shape": shape}
    if shape == "circle":
        if "radius_m" in p:
            out["radius_m"] = _number(p["radius_m"], f"{where}.radius_m", positive=True)
        elif "area_m2" in p:
            out["radius_m"] = math.sqrt(
                _number(p["area_m2"], f"{where}.area_m2", positive=True) / math.pi
            )
        else:
            raise _fail(where, "a circle needs radius_m (or area_m2)")
    elif "aspect" in p:
        ratio = _number(p["aspect"], f"{where}.aspect", positive=True)
        area = _number(p.get("area_m2"), f"{where}.area_m2", positive=True)
        if ratio < 1:
            raise _fail(f"{where}.aspect", f"is length/width and must be ≥ 1, got {ratio}")
        width = math.sqrt(area / ratio)
        out["width_m"] = width
        out["length_m"] = ratio * width
    else:
        if "width_m" not in p or "length_m" not in p:
            raise _fail(where, "a rectangle needs width_m and length_m, or aspect and area_m2")
        out["width_m"] = _number(p["width_m"], f"{where}.width_m", positive=True)
        out["length_m"] = _number(p["length_m"], f"{where}.length_m", positive=True)
    for k, v in p.items():  # extra keys (e.g. tool = "tool02") become test-log columns
        if k not in _PLATE_KEYS:
            out[k] = _scalar_cell(v, f"{where}.{k}")
    return out


def _ring(r: Any, where: str) -> dict[str, str | float]:
    _check_keys(r, (), where, extra_ok=True)
    for k in _RING_KEYS:
        if k not in r:
            raise _fail(where, f"a ring needs {list(_RING_KEYS)}; {k!r} is missing")
    ri = _number(r["r_inner_m"], f"{where}.r_inner_m", nonneg=True)
    ro = _number(r["r_outer_m"], f"{where}.r_outer_m", positive=True)
    if ro <= ri:
        raise _fail(where, f"r_outer_m ({ro}) must exceed r_inner_m ({ri})")
    out: dict[str, str | float] = {"r_inner_m": ri, "r_outer_m": ro}
    for k, v in r.items():
        if k not in _RING_KEYS:
            out[k] = _scalar_cell(v, f"{where}.{k}")
    return out


def _operators(
    t: Any, where: str, name: str, prep_names: tuple[str, ...], preps: dict
) -> tuple[str, ...]:
    """A series' operators; a preparation's ``operator`` column must name one of them (its
    columns must not rewrite what the design sets)."""
    operators = tuple(
        _text(o, f"{where}.operators")
        for o in _list(t.get("operators", ["op1"]), f"{where}.operators")
    )
    for p in prep_names:
        own = preps[p].columns
        if "operator" in own and str(own["operator"]) not in operators:
            raise _fail(
                f"[preparations.{p}].operator",
                f"{own['operator']!r} is not an operator of series {name!r} "
                f"(operators: {list(operators)}); list it in [[series]].operators",
            )
    return operators


def _series(i: int, t: Any, soils: dict, preps: dict) -> Series:
    where = f"[[series]][{i}]"
    _check_keys(t, (), where, extra_ok=True)
    kind = _text(t.get("kind"), f"{where}.kind", KINDS)
    _check_keys(t, _SERIES_KEYS[kind], f"{where} (kind {kind!r})")
    name = _text(t.get("name", f"series{i + 1}"), f"{where}.name")
    need = SINKAGE_PARAMS if kind == "sinkage" else SHEAR_PARAMS
    soil_names = tuple(
        _text(s, f"{where}.soils", tuple(soils)) for s in _list(t.get("soils"), f"{where}.soils")
    )
    for s in soil_names:
        missing = [p for p in need if p not in soils[s].params]
        if missing:
            raise _fail(
                f"[soils.{s}]",
                f"series {name!r} of kind {kind!r} needs {list(need)}; missing {missing}",
            )
    prep_names = tuple(
        _text(p, f"{where}.preparations", tuple(preps))
        for p in _list(t.get("preparations", list(preps)[:1]), f"{where}.preparations")
    )
    operators = _operators(t, where, name, prep_names, preps)
    common: dict[str, Any] = dict(
        name=name,
        kind=kind,
        soils=soil_names,
        preparations=prep_names,
        operators=operators,
        repetitions=_int(t.get("repetitions", 1), f"{where}.repetitions"),
        points=_int(t.get("points", 120), f"{where}.points", minimum=10),
        covariates={
            k: tuple(
                _scalar_cell(v, f"{where}.covariates.{k}")
                for v in _list(vals, f"{where}.covariates.{k}")
            )
            for k, vals in (t.get("covariates") or {}).items()
        },
    )
    if kind == "sinkage":
        plates = tuple(
            _plate(p, f"{where}.plates[{j}]")
            for j, p in enumerate(_list(t.get("plates"), f"{where}.plates"))
        )
        return Series(
            geometries=plates,
            velocity_m_s=_numbers(
                t.get("velocity_m_s", 4.8e-3), f"{where}.velocity_m_s", positive=True
            ),
            sinkage_m=_number(t.get("sinkage_m", 0.03), f"{where}.sinkage_m", positive=True),
            start_m=_number(t.get("start_m", -5e-4), f"{where}.start_m"),
            **common,
        )
    rings = tuple(
        _ring(r, f"{where}.rings[{j}]")
        for j, r in enumerate(_list(t.get("rings"), f"{where}.rings"))
    )
    return Series(
        geometries=rings,
        grousers=tuple(
            _int(g, f"{where}.grousers", 0)
            for g in _list(t.get("grousers", 12), f"{where}.grousers")
        ),
        grouser_height_m=_numbers(
            t.get("grouser_height_m", 0.005), f"{where}.grouser_height_m", nonneg=True
        ),
        omega_rpm=_numbers(t.get("omega_rpm", 0.1), f"{where}.omega_rpm", positive=True),
        normal_pressure_Pa=_numbers(
            t.get("normal_pressure_Pa"), f"{where}.normal_pressure_Pa", positive=True
        ),
        shear_deformation_m=_number(
            t.get("shear_deformation_m", 0.1), f"{where}.shear_deformation_m", positive=True
        ),
        **common,
    )


def _limited(
    i: int, t: Any, soils: dict, series_names: tuple[str, ...], table: str
) -> tuple[str, dict[str, Any], tuple[str, ...], tuple[str, ...]]:
    """(kind, options, soils, series) of an ``[[effects]]`` or ``[[artefacts]]`` entry: a
    kind of its table, limited to some soils and series, its options checked by the module
    that owns the kind's physics."""
    kinds, check = {
        "effects": (EFFECT_KINDS, check_effect),
        "artefacts": (tuple(ARTEFACT_KINDS), check_artefact),
    }[table]
    where = f"[[{table}]][{i}]"
    _check_keys(t, (), where, extra_ok=True)
    kind = _text(t.get("kind"), f"{where}.kind", kinds)
    e_soils = tuple(
        _text(s, f"{where}.soils", tuple(soils))
        for s in (_list(t["soils"], f"{where}.soils") if "soils" in t else [])
    )
    e_series = tuple(
        _text(s, f"{where}.series", series_names)
        for s in (_list(t["series"], f"{where}.series") if "series" in t else [])
    )
    options = {k: v for k, v in t.items() if k not in ("kind", "soils", "series")}
    return kind, check(kind, options, where), e_soils, e_series


def _effect(i: int, t: Any, soils: dict, series_names: tuple[str, ...]) -> Effect:
    return Effect(*_limited(i, t, soils, series_names, "effects"))


def _artefact(i: int, t: Any, soils: dict, series_names: tuple[str, ...]) -> Artefact:
    return Artefact(*_limited(i, t, soils, series_names, "artefacts"))


_TOP = (
    "name",
    "artefacts",
    "description",
    "soils",
    "preparations",
    "series",
    "effects",
    "noise",
    "resolution",
    "scatter",
)


def parse_spec(data: dict[str, Any], *, source: str = "<memory>", sha256: str = "") -> Spec:
    """Check a SPEC given as the dict that :func:`tomllib.loads` returns.

    Raises
    ------
    SpecError
        Naming the offending key, the value and the valid options.
    """
    _check_keys(data, _TOP, "top level")
    for key in ("soils", "series"):
        if key not in data:
            raise _fail(
                f"top level.{key}",
                f"the required table {key!r} is missing; a SPEC "
                f"needs {['soils', 'series']} (see docs/simulator.md)",
            )
    scatter = _dataclass_table(Scatter, data.get("scatter"), "[scatter]")
    soils_t = data["soils"]
    _check_keys(soils_t, (), "[soils]", extra_ok=True)
    soils = {str(k): _soil(str(k), v) for k, v in soils_t.items()}
    preps_t = data.get("preparations") or {"default": {}}
    _check_keys(preps_t, (), "[preparations]", extra_ok=True)
    preps = {str(k): _preparation(str(k), v, scatter) for k, v in preps_t.items()}
    series = tuple(
        _series(i, t, soils, preps) for i, t in enumerate(_list(data["series"], "[[series]]"))
    )
    names = [s.name for s in series]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise _fail("[[series]].name", f"series names must be unique; repeated: {dup}")
    effects = tuple(
        _effect(i, t, soils, tuple(names)) for i, t in enumerate(data.get("effects", []))
    )
    artefacts = tuple(
        _artefact(i, t, soils, tuple(names))
        for i, t in enumerate(
            _list(data["artefacts"], "[[artefacts]]") if "artefacts" in data else []
        )
    )
    return Spec(
        name=_text(data.get("name", "simulated"), "top level.name"),
        description=_text(data.get("description", ""), "top level.description"),
        soils=soils,
        preparations=preps,
        series=series,
        effects=effects,
        artefacts=artefacts,
        noise=_dataclass_table(Noise, data.get("noise"), "[noise]"),
        resolution=_dataclass_table(Resolution, data.get("resolution"), "[resolution]"),
        scatter=scatter,
        raw=data,
        source=source,
        sha256=sha256,
    )


def load_spec(path: str | os.PathLike[str]) -> Spec:
    """Read and check a SPEC file (TOML, see ``docs/simulator.md``).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.toml`` file.

    Returns
    -------
    Spec
        With ``source`` the file name and ``sha256`` its content hash (both go into the
        simulated campaign's README, so that it names exactly what it came from).
    """
    path = Path(path)
    try:
        blob = path.read_bytes()
    except OSError as exc:
        raise SpecError(f"cannot read SPEC file {str(path)!r}: {exc}") from exc
    try:
        data = tomllib.loads(blob.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SpecError(f"SPEC file {path.name!r} is not valid TOML: {exc}") from exc
    return parse_spec(data, source=path.name, sha256=hashlib.sha256(blob).hexdigest())
