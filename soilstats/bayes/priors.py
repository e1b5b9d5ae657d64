"""Priors of the posterior models: physics by default, overridable per parameter.

A prior here is a (possibly truncated, possibly improper) density on one parameter in the
parameter's own unit (φ in degrees).  The defaults only encode what physics forbids:

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

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

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


@dataclass(frozen=True)
class Prior:
    """Base class: a log-density on one parameter, vectorised over walkers."""

    lower: float = -np.inf
    upper: float = np.inf

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        """Log-density (up to a constant) at ``x``; ``-inf`` outside (lower, upper)."""
        raise NotImplementedError

    def _support(self, x: np.ndarray) -> np.ndarray:
        return (x > self.lower) & (x < self.upper)


@dataclass(frozen=True)
class Uniform(Prior):
    """Flat on the open interval (lower, upper); improper if either end is infinite."""

    closed_lower: bool = False  # include ``lower`` itself (c ≥ 0: cohesionless sand)

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        inside = self._support(x) | (self.closed_lower & (x == self.lower))
        return np.where(inside, 0.0, -np.inf)

    def __str__(self) -> str:
        return f"flat on {'[' if self.closed_lower else '('}{self.lower:g}, {self.upper:g})"


@dataclass(frozen=True)
class Normal(Prior):
    """Normal(mu, sd) truncated to (lower, upper): an informative prior, e.g. from a handbook."""

    mu: float = 0.0
    sd: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sd) and self.sd > 0):
            raise ValueError(f"Normal prior needs a finite sd > 0, got sd={self.sd!r}")

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        return np.where(self._support(x), -0.5 * ((x - self.mu) / self.sd) ** 2, -np.inf)

    def __str__(self) -> str:
        return f"normal({self.mu:g}, {self.sd:g}) on ({self.lower:g}, {self.upper:g})"


_POS = Uniform(0.0, np.inf)
_ANY = Uniform()
_C = Uniform(0.0, np.inf, closed_lower=True)
_PHI = Uniform(0.0, 90.0)

DEFAULT_PRIORS: dict[str, dict[str, Prior]] = {
    "bekker": {"kc": _ANY, "kphi": _POS, "n": _POS},
    "bernstein": {"k": _POS, "n": _POS},
    "reece": {"k1": _ANY, "k2": _POS, "n": _POS},
    "mohr-coulomb": {"c": _C, "phi": _PHI},
    "janosi": {"c": _C, "phi": _PHI, "K": _POS},
}


def resolve_priors(
    model_name: str, param_names: tuple[str, ...], priors: Mapping[str, object] | None
) -> tuple[Prior, ...]:
    """The prior of each parameter: the default, replaced where ``priors`` names one.

    Parameters
    ----------
    model_name : str
        Model name (key of :data:`DEFAULT_PRIORS`).
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
    chosen = dict(DEFAULT_PRIORS.get(model_name, {}))
    for name in param_names:
        chosen.setdefault(name, _ANY)
    for name, value in (priors or {}).items():
        if name not in param_names:
            raise ValueError(
                f"prior given for {name!r}, which is not a parameter of {model_name!r}; "
                f"its parameters are {list(param_names)}"
            )
        if value is None:
            chosen[name] = _ANY
        elif isinstance(value, Prior):
            chosen[name] = value
        elif isinstance(value, tuple) and len(value) == 2:
            lo, hi = (float(v) for v in value)
            if not lo < hi:
                raise ValueError(f"prior interval for {name!r} must have lower < upper: {value}")
            chosen[name] = Uniform(lo, hi)
        else:
            raise ValueError(
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
            mu, sd, *bounds = (float(p) for p in parts[1:])
            lo, hi = bounds or (-np.inf, np.inf)
            return Normal(lower=lo, upper=hi, mu=mu, sd=sd)
        if len(parts) == 2:
            lo, hi = float(parts[0]), float(parts[1])
            if lo < hi:
                return Uniform(lo, hi)
    except ValueError:
        pass
    raise ValueError(
        f"cannot read the prior {text!r}: write LO:HI (flat), normal:MU:SD or "
        "normal:MU:SD:LO:HI, e.g. 0.2:2 or normal:1.0:0.3:0:inf"
    )


def priors_from_items(items) -> dict[str, Prior]:
    """``["n=0.2:2", "kc=normal:0:5e4"]`` -> ``{"n": Prior, "kc": Prior}`` (``--prior``)."""
    out: dict[str, Prior] = {}
    for item in items or ():
        name, eq, spec = str(item).partition("=")
        if not eq or not name.strip():
            raise ValueError(f"--prior takes NAME=SPEC (e.g. n=0.2:2), got {item!r}")
        out[name.strip()] = parse_prior(spec)
    return out


def priors_from_toml(path, model_name: str) -> dict[str, Prior]:
    """The ``[MODEL]`` table of a TOML file: ``NAME = "SPEC"`` (as :func:`parse_prior`).

    A file may hold tables for several models (``[bekker]``, ``[janosi]``); a model without a
    table keeps its defaults. Unknown parameter names are refused by :func:`resolve_priors`.
    """
    import tomllib
    from pathlib import Path

    path = Path(path)
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise ValueError(f"cannot read the priors file {str(path)!r}: {err}") from None
    section = table.get(model_name, {})
    if not isinstance(section, dict):
        raise ValueError(f'{path}: [{model_name}] must be a table of NAME = "SPEC" entries')
    try:
        return {name: parse_prior(spec) for name, spec in section.items()}
    except ValueError as err:
        raise ValueError(f"{path}, [{model_name}]: {err}") from None
