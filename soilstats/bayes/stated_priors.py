"""User-stated priors for parameters that no test measured (c, φ, K without a shear test).

soilstats never invents a parameter: one that is neither in the draws nor given here is not
used, and what needs it is not predicted (:func:`soilstats.wheel.predict_wheel`).  A prior is
a tuple, in the parameter's documented unit (c Pa, φ deg, K m, kc N/m^(n+1), kφ and k
N/m^(n+2), k1 Pa, k2 Pa/m, n -):

* ``("normal", mean, sd)``
* ``("truncnormal", mean, sd, low, high)`` — normal restricted to [low, high], sampled by a
  tail-stable inverse CDF (right even for a window 40 sd into either tail)
* ``("uniform", low, high)``
* ``("lognormal", median, sigma_log)`` — ln x ~ Normal(ln median, sigma_log)

Draws come from one seeded :class:`numpy.random.Generator`, one parameter after another in
sorted name order, so the same seed gives the same draws.  A draw outside the parameter's
physical support (c ≥ 0, 0 < φ < 90°, K > 0, n > 0) is an error naming the prior, never
silently clipped.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np
from scipy.stats import truncnorm

from .._ascii import ascii_float, non_ascii_note
from ..errors import InputError

__all__ = ["SUPPORT", "describe_prior", "parse_stated_prior", "sample_priors", "stated_priors_of"]

#: Physical support of the parameters: (low, high, whether low itself is allowed).
SUPPORT: dict[str, tuple[float, float, bool]] = {
    "c": (0.0, np.inf, True),
    "phi": (0.0, 90.0, False),
    "K": (0.0, np.inf, False),
    "n": (0.0, np.inf, False),
    "kphi": (0.0, np.inf, True),
    "k": (0.0, np.inf, False),
    "k2": (0.0, np.inf, True),
}

_ARITY = {"normal": 2, "truncnormal": 4, "uniform": 2, "lognormal": 2}


def describe_prior(spec: Sequence[str | float]) -> str:
    """``normal(30, 3)`` for ``("normal", 30, 3)``."""
    return f"{spec[0]}({', '.join(f'{float(v):g}' for v in spec[1:])})"


_STATED_FORMS = (
    "uniform:LO:HI (or LO:HI), normal:MU:SD, normal:MU:SD:LO:HI (truncated), "
    "lognormal:MEDIAN:SIGMA_LOG"
)


def parse_stated_prior(text: str) -> tuple:
    """A user prior's text form -> the tuple of this module.

    ``uniform:LO:HI`` (or ``LO:HI``), ``normal:MU:SD``, ``normal:MU:SD:LO:HI`` (truncated:
    ``truncnormal``), ``lognormal:MEDIAN:SIGMA_LOG`` (ln x ~ Normal(ln MEDIAN, SIGMA_LOG)), in
    the parameter's unit (c Pa, φ deg, K m). The numbers are checked by
    :func:`sample_priors` when drawn.
    """
    parts = [p.strip() for p in str(text).split(":")]
    kind = parts[0].lower()
    try:
        if kind == "normal" and len(parts) == 5:
            kind = "truncnormal"
        if kind in ("uniform", "normal", "lognormal", "truncnormal"):
            return (kind, *(ascii_float(p) for p in parts[1:]))
        if len(parts) == 2:
            return ("uniform", ascii_float(parts[0]), ascii_float(parts[1]))
    except ValueError:
        pass
    raise InputError(
        f"cannot read the prior {text!r}: write {_STATED_FORMS}, e.g. normal:30:3"
        f"{non_ascii_note(text)}"
    )


def _check(name: str, spec: object) -> tuple[str, tuple[float, ...]]:
    if not isinstance(spec, tuple | list) or not spec or spec[0] not in _ARITY:
        raise InputError(
            f"prior for {name!r} must be a tuple (kind, *args) with kind one of "
            f"{sorted(_ARITY)}, got {spec!r}"
        )
    kind, args = spec[0], tuple(float(v) for v in spec[1:])
    if len(args) != _ARITY[kind]:
        raise InputError(f"prior {kind!r} for {name!r} takes {_ARITY[kind]} numbers, got {spec!r}")
    if not all(np.isfinite(args)):
        raise InputError(f"prior for {name!r} has a non-finite number: {spec!r}")
    checks = {
        "normal": lambda: args[1] > 0,
        "truncnormal": lambda: args[1] > 0 and args[2] < args[3],
        "uniform": lambda: args[0] < args[1],
        "lognormal": lambda: args[0] > 0 and args[1] > 0,
    }
    if not checks[kind]():
        raise InputError(f"prior for {name!r} is degenerate or inverted: {spec!r}")
    return kind, args


def _draw(kind: str, args: tuple[float, ...], size: int, rng: np.random.Generator) -> np.ndarray:
    if kind == "normal":
        return rng.normal(args[0], args[1], size)
    if kind == "uniform":
        return rng.uniform(args[0], args[1], size)
    if kind == "lognormal":
        return args[0] * np.exp(args[1] * rng.standard_normal(size))
    mean, sd, low, high = args
    # Inverse CDF through scipy's truncnorm, which works in log space in the tails: inverting
    # ndtr directly saturates there (a window 50 sd above the mean gave every draw == high).
    a, b = (low - mean) / sd, (high - mean) / sd
    x = mean + sd * truncnorm.ppf(rng.random(size), a, b)
    if not np.all(np.isfinite(x)):  # a window beyond what double precision can resolve
        raise InputError(
            f"the prior truncnormal({mean:g}, {sd:g}, {low:g}, {high:g}) cannot be sampled: "
            f"its window lies {min(abs(a), abs(b)):.3g} sd from the mean"
        )
    return np.clip(x, low, high)  # rounding only: the draws lie in [low, high] to the last ulp


def sample_priors(priors: Mapping[str, tuple], size: int, seed: int) -> dict[str, np.ndarray]:
    """``size`` independent draws of each prior (seeded; sorted name order).

    Raises ValueError for an unknown kind, a degenerate prior, or draws outside the support.
    """
    rng = np.random.default_rng(seed)
    out = {}
    for name in sorted(priors):
        kind, args = _check(name, priors[name])
        x = _draw(kind, args, size, rng)
        low, high, closed = SUPPORT.get(name, (-np.inf, np.inf, False))
        bad = ~(((x >= low) if closed else (x > low)) & (x < high))
        if np.any(bad):
            raise InputError(
                f"the prior {name} ~ {describe_prior(priors[name])} puts {bad.sum()} of {size} "
                f"draws outside the support of {name} ({'[' if closed else '('}{low:g}, {high:g}); "
                "use a truncnormal, "
                "uniform or lognormal prior that stays inside it"
            )
        out[name] = x
    return out


def stated_priors_of(
    priors: Mapping[str, tuple | str] | Iterable[str] | None,
) -> dict[str, tuple]:
    """User priors as :mod:`soilstats.bayes.stated_priors` tuples, from tuples, the CLI's text
    forms (``{"c": "uniform:0:2000"}``) or its ``--prior`` strings (``["c=uniform:0:2000"]``)."""
    if priors is None:
        return {}
    if isinstance(priors, str):
        priors = [priors]
    if not isinstance(priors, Mapping):
        pairs = {}
        for item in priors:
            name, sep, form = str(item).partition("=")
            if not sep or not name.strip():
                raise InputError(
                    f"cannot read the prior {item!r}: write NAME=FORM, e.g. c=uniform:0:2000"
                )
            pairs[name.strip()] = form
        priors = pairs
    return {
        name: parse_stated_prior(spec) if isinstance(spec, str) else tuple(spec)
        for name, spec in priors.items()
    }
