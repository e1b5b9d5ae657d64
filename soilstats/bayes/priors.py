"""Priors of the posterior models: physics by default, overridable per parameter.

A prior here is a (possibly truncated, possibly improper) density on one parameter in the
parameter's own unit (φ in degrees).  The defaults are each model's record's
(``Model.priors``, :mod:`soilstats.models`); those of the paper's models only encode what
physics forbids:

======================  ===============================  =====================================
model                   parameter                         default prior
======================  ===============================  =====================================
bekker (Eq. 7)          kc [N/m^(n+1)]                    flat on ℝ, with kc/b + kφ > 0 for
                                                          every plate size b of the data
                        kφ [N/m^(n+2)]                    flat on (0, ∞)
                        n [-]                             flat on (0, ∞)
bernstein (Eq. 8)       k [N/m^(n+2)], n [-]              flat on (0, ∞)
reece                   k1 [Pa]                           flat on ℝ, with k1 + k2·b > 0
                        k2 [Pa/m], n [-]                  flat on (0, ∞)
mohr-coulomb (Eq. 15)   c [Pa]                            flat on [0, ∞)
                        φ [deg]                           flat on (0, 90)
janosi (Eq. 13)         c [Pa], φ [deg]                   as Mohr–Coulomb
                        K [m]                             flat on (0, ∞)
======================  ===============================  =====================================

These are the pooled model's priors.  The population model (:mod:`soilstats.bayes.population_model`)
keeps their support and, by default, makes them flat in the logarithm of the measured scales
(plate moduli, k, τ_max, K): flat in a modulus makes its posterior improper.

kc may be negative: the paper's Table 5 reports kc < 0 for all three soils, which only says
that pressure grows less than linearly in 1/b; what physics demands is a positive pressure,
kc/b + kφ > 0, on every plate used.  The noise scale σ_w of the weighted residuals has the
Jeffreys prior 1/σ_w (see :mod:`soilstats.bayes.likelihood`).
"""

from __future__ import annotations

import difflib
import os
import tomllib
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from .._ascii import ascii_float, non_ascii_note
from ..errors import InputError, ModelError
from ..models import MODELS, Model, get_model, model_names
from ..models.priors import FLAT, Normal, Prior, Uniform

__all__ = [
    "DEFAULT_PRIORS",
    "Normal",
    "Prior",
    "Uniform",
    "parse_prior",
    "priors_from_items",
    "priors_from_toml",
    "resolve_priors",
]


class _DefaultPriors(Mapping):
    """``{model name: {parameter: Prior}}``: the default priors of every registered model,
    read from its record (``Model.priors``) when asked, so a registered model has its own."""

    def __getitem__(self, name: str) -> dict[str, Prior]:
        if name not in MODELS:
            raise KeyError(name)
        return dict(MODELS[name].priors)

    def __iter__(self):
        return iter(list(MODELS))

    def __len__(self) -> int:
        return len(MODELS)


DEFAULT_PRIORS: Mapping[str, dict[str, Prior]] = _DefaultPriors()


def resolve_priors(
    model: str | Model, param_names: tuple[str, ...], priors: Mapping[str, object] | None
) -> tuple[Prior, ...]:
    """The prior of each parameter: the default, replaced where ``priors`` names one.

    Parameters
    ----------
    model : str or Model
        The model (a registered name, or the record itself), whose ``priors`` are the
        defaults; a parameter without one is flat on ℝ.
    param_names : tuple of str
        The model's parameter names, in order.
    priors : mapping, optional
        ``{name: Prior}`` or ``{name: (lower, upper)}`` (a flat prior on that interval);
        ``{name: None}`` means flat on ℝ.

    Raises
    ------
    ValueError
        For a name that is not a parameter of the model, or a value of the wrong type.
    """
    spec = get_model(model)
    model_name = spec.name
    chosen = dict(spec.priors)
    for name in param_names:
        chosen.setdefault(name, FLAT)
    for name, value in (priors or {}).items():
        if name not in param_names:
            raise ModelError(
                f"prior given for {name!r}, which is not a parameter of {model_name!r}; "
                f"its parameters are {list(param_names)}"
            )
        if value is None:
            chosen[name] = FLAT
        elif isinstance(value, Prior):
            chosen[name] = value
        elif isinstance(value, tuple) and len(value) == 2:
            lo, hi = (float(v) for v in value)
            if not lo < hi:
                raise InputError(f"prior interval for {name!r} must have lower < upper: {value}")
            chosen[name] = Uniform(lo, hi)
        else:
            raise InputError(
                f"prior for {name!r} must be a soilstats.bayes.Prior, a (lower, upper) tuple "
                f"or None (flat on the real line), got {value!r}"
            )
    return tuple(chosen[name] for name in param_names)


def parse_prior(text: str) -> Prior:
    """A prior from its text form (command lines and TOML files).

    ``LO:HI`` is flat on (LO, HI) (``inf``/``-inf`` allowed); ``normal:MU:SD`` is a normal
    prior, ``normal:MU:SD:LO:HI`` the same truncated to (LO, HI). Values in the parameter's
    own unit (SI, φ in degrees).
    """
    parts = [p.strip() for p in str(text).split(":")]
    try:
        if parts[0].lower() == "normal" and len(parts) in (3, 5):
            mu, sd, *bounds = (ascii_float(p) for p in parts[1:])
            lo, hi = bounds or (-np.inf, np.inf)
            return Normal(lower=lo, upper=hi, mu=mu, sd=sd)
        if len(parts) == 2:
            lo, hi = ascii_float(parts[0]), ascii_float(parts[1])
            if lo < hi:
                return Uniform(lo, hi)
    except ValueError:
        pass
    raise InputError(
        f"cannot read the prior {text!r}: write LO:HI (flat), normal:MU:SD or "
        f"normal:MU:SD:LO:HI, e.g. 0.2:2 or normal:1.0:0.3:0:inf{non_ascii_note(text)}"
    )


def priors_from_items(items: Iterable[str] | None) -> dict[str, Prior]:
    """``["n=0.2:2", "kc=normal:0:5e4"]`` -> ``{"n": Prior, "kc": Prior}`` (``--prior``)."""
    out: dict[str, Prior] = {}
    for item in items or ():
        name, eq, spec = str(item).partition("=")
        if not eq or not name.strip():
            raise InputError(f"--prior takes NAME=SPEC (e.g. n=0.2:2), got {item!r}")
        out[name.strip()] = parse_prior(spec)
    return out


def _read_priors_toml(path: os.PathLike[str] | str) -> dict:
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise InputError(f"cannot read the priors file {str(path)!r}: {err}") from None


def check_priors_file(path: str | os.PathLike[str]) -> None:
    """Refuse a priors file with a table naming no registered model (``[bekkr]``): its priors
    would otherwise be ignored silently. Tables for other registered models are allowed (one
    file may serve several runs)."""

    known = list(model_names())
    stray = sorted(set(_read_priors_toml(path)) - set(known))
    if stray:
        near = {s: difflib.get_close_matches(s, known, n=1) for s in stray}
        hint = "; ".join(f"[{s}] → [{m[0]}]?" for s, m in near.items() if m)
        raise InputError(
            f"{path}: tables {stray} name no model (models: {sorted(known)})"
            + (f"; did you mean {hint}" if hint else "")
        )


def priors_from_toml(path: str | os.PathLike[str], model_name: str) -> dict[str, Prior]:
    """The ``[MODEL]`` table of a TOML file: ``NAME = "SPEC"`` (as :func:`parse_prior`).

    A file may hold tables for several models (``[bekker]``, ``[janosi]``); a model without a
    table keeps its defaults. Unknown parameter names are refused by :func:`resolve_priors`.
    """
    path = Path(path)
    section = _read_priors_toml(path).get(model_name, {})
    if not isinstance(section, dict):
        raise InputError(f'{path}: [{model_name}] must be a table of NAME = "SPEC" entries')
    try:
        return {name: parse_prior(spec) for name, spec in section.items()}
    except ValueError as err:
        raise InputError(f"{path}, [{model_name}]: {err}") from None
