"""The uncertain inputs of the wheel model, carried as stated priors instead of fixed values.

A wheel prediction rests on inputs that no plate test measures: where the normal stress peaks
and where the contact ends (the stress angles), the datum the sinkage is measured from, how
the sinkage exponent changes with slip, and the shear parameters.  Each is a prior with a
documented, sourced default (issue #43, item 2); a user's ``--prior NAME=KIND:ARGS`` replaces
it.  Every prior is a normal on the parameter's *sampling scale* (named below), optionally
truncated to [low, high], or a uniform on [low, high]: the calibration's least-squares start
reads each normal as one pseudo-observation, and the sampler uses the exact density.

=========  ======================  ==========================================================
name       default                 source
=========  ======================  ==========================================================
a0         N(0.30, 0.15) [0, 0.95] θm/θ1 at s = 0.  Wong & Reece (1967, Table 1, c1): loose
                                   sand 0.18, compact sand 0.43; Ishigami et al. (2007,
                                   Toyoura sand) 0.4; CMU's values tuned on these runs
                                   0.20–0.27 (wheel.md).  The prior spans all of them.
a1         N(0.30, 0.30) [−0.5, 1] the slope of θm/θ1 in s.  Wong & Reece c2 = 0.32;
                                   Ishigami 0.15; CMU 0.67–0.71.
b0         N(0, 0.30) [−0.9, 0.5]  θ2/θ1 at s = 0 (exit angle).  0: the classical exit at the
                                   bottom dead centre (Wong & Reece); CMU's tuned β = 0 value
                                   −0.48 (rebound behind the bottom dead centre).
b1         N(0, 0.30) [−1, 1]      slope of θ2/θ1 in s (CMU: 0 at β = 0).
datum_mm   N(0, 3) mm              error of the sinkage datum, added to the model's sinkage.
                                   CMU: the datum is assumed (31.5 mm below the start); during
                                   the entry the wheel rises 3.3 mm and settles within
                                   −3.1…+1.3 mm (IQR) of it (wheel.md, "Sinkage").
n1, n2     N(0, 0.5) [−1, 2]       slip-sinkage: exponent n + n1·s (s ≥ 0), n + n2·|s|
                                   (s < 0), Ding et al. (2011), as CMU's ``sigma.m``;
                                   centred on no slip-sinkage.
c_kPa      N(0.5, 1.0) [0, 5] kPa  cohesion of dry sand: 0–1 kPa (Wong 2008, Table 2.3;
                                   CMU's 1 kPa).
phi        N(30, 6) [10, 50] deg   friction angle of sand: 28–38° (Wong 2008, Table 2.3);
                                   CMU's 29°.
log_K      N(ln 0.015, 0.8)        shear deformation modulus K [m]: 0.01–0.025 m for sands
                                   (Wong 2008, Table 2.3); CMU's 0.021 m.
=========  ======================  ==========================================================

The defaults are deliberately wide: they state what the literature allows, so that the wheel
runs, where a user has them, decide.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...errors import InputError

__all__ = ["DEFAULT_INPUTS", "SHEAR_INPUTS", "WHEEL_INPUTS", "InputPrior", "input_priors"]


@dataclass(frozen=True)
class InputPrior:
    """A prior on one sampling-scale parameter: normal (``sd`` > 0) or uniform (``sd`` None).

    ``low``/``high`` truncate (a uniform needs both).  ``source`` says where it comes from.
    """

    name: str
    mean: float
    sd: float | None
    low: float = -math.inf
    high: float = math.inf
    source: str = ""
    unit: str = "-"

    def __post_init__(self) -> None:
        if not (self.low < self.high):
            raise InputError(f"prior of {self.name}: need low < high, got {self.low}, {self.high}")
        if self.sd is None and not (math.isfinite(self.low) and math.isfinite(self.high)):
            raise InputError(f"uniform prior of {self.name} needs finite bounds")
        if self.sd is not None and not self.sd > 0:
            raise InputError(f"prior of {self.name}: sd must be > 0, got {self.sd}")

    def log_pdf(self, x: np.ndarray) -> np.ndarray:
        """Log density (up to a constant shared by all x), −inf outside [low, high]."""
        x = np.asarray(x, float)
        inside = (x >= self.low) & (x <= self.high)
        if self.sd is None:
            return np.where(inside, 0.0, -np.inf)
        return np.where(inside, -0.5 * ((x - self.mean) / self.sd) ** 2, -np.inf)

    def start(self) -> float:
        """A starting value inside the support (the mean, clipped into it)."""
        lo = self.low if math.isfinite(self.low) else self.mean - 10.0
        hi = self.high if math.isfinite(self.high) else self.mean + 10.0
        return float(np.clip(self.mean, lo + 1e-3 * (hi - lo), hi - 1e-3 * (hi - lo)))

    def describe(self) -> str:
        bounds = ""
        if math.isfinite(self.low) or math.isfinite(self.high):
            bounds = f" on [{self.low:g}, {self.high:g}]"
        if self.sd is None:
            return f"{self.name} ~ uniform({self.low:g}, {self.high:g})"
        return f"{self.name} ~ normal({self.mean:g}, {self.sd:g}){bounds}"

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "kind": "uniform" if self.sd is None else "normal",
            "mean": self.mean,
            "sd": self.sd,
            "low": self.low,
            "high": self.high,
            "unit": self.unit,
            "source": self.source,
        }


_WR = "Wong & Reece (1967, Table 1)"
DEFAULT_INPUTS: dict[str, InputPrior] = {
    p.name: p
    for p in (
        InputPrior(
            "a0",
            0.30,
            0.15,
            0.0,
            0.95,
            f"{_WR} 0.18–0.43; Ishigami et al. 2007 0.4; CMU tuned 0.20–0.27",
        ),
        InputPrior(
            "a1",
            0.30,
            0.30,
            -0.5,
            1.0,
            f"{_WR} 0.32; Ishigami et al. 2007 0.15; CMU tuned 0.67–0.71",
        ),
        InputPrior(
            "b0",
            0.0,
            0.30,
            -0.9,
            0.5,
            "0: exit at the bottom dead centre (Wong & Reece 1967); CMU tuned −0.48 at β = 0",
        ),
        InputPrior("b1", 0.0, 0.30, -1.0, 1.0, "CMU: 0 at β = 0"),
        InputPrior(
            "datum_mm",
            0.0,
            3.0,
            -15.0,
            15.0,
            "assumed sinkage datum; CMU entry lift 3.3 mm, settles within −3.1…+1.3 mm (wheel.md)",
            "mm",
        ),
        InputPrior(
            "n1",
            0.0,
            0.5,
            -1.0,
            2.0,
            "slip-sinkage exponent n + n1·s, s ≥ 0 (Ding et al. 2011); centred on none",
        ),
        InputPrior(
            "n2",
            0.0,
            0.5,
            -1.0,
            2.0,
            "slip-sinkage exponent n + n2·|s|, s < 0 (Ding et al. 2011); centred on none",
        ),
        InputPrior(
            "c_kPa", 0.5, 1.0, 0.0, 5.0, "dry sand 0–1 kPa (Wong 2008, Table 2.3); CMU 1 kPa", "kPa"
        ),
        InputPrior(
            "phi", 30.0, 6.0, 10.0, 50.0, "sand 28–38° (Wong 2008, Table 2.3); CMU 29°", "deg"
        ),
        InputPrior(
            "log_K",
            math.log(0.015),
            0.8,
            math.log(1e-4),
            math.log(0.2),
            "sand 0.01–0.025 m (Wong 2008, Table 2.3); CMU 0.021 m",
            "ln m",
        ),
    )
}
#: The wheel-level inputs every calibration carries.
WHEEL_INPUTS: tuple[str, ...] = ("a0", "a1", "b0", "b1", "datum_mm", "n1", "n2")
#: The shear inputs (sampling scale), carried when drawbar pull is measured or priors given.
SHEAR_INPUTS: tuple[str, ...] = ("c_kPa", "phi", "log_K")

# A user's prior on c [Pa], phi [deg] or K [m], mapped to the sampling scale.
_USER_NAMES = {"c": "c_kPa", "phi": "phi", "K": "log_K", "datum_m": "datum_mm"}


def _from_user(name: str, spec: Sequence) -> InputPrior:
    kind, *args = spec
    args = [float(a) for a in args]
    target = _USER_NAMES.get(name, name)
    base = DEFAULT_INPUTS[target]
    scale = {"c_kPa": 1e-3, "datum_mm": 1e3}.get(target, 1.0)
    source = f"user prior {kind}({', '.join(f'{a:g}' for a in args)})"
    if target == "log_K":
        if kind == "lognormal":
            return InputPrior(
                target, math.log(args[0]), args[1], base.low, base.high, source, "ln m"
            )
        if kind == "uniform" and args[0] > 0:
            return InputPrior(
                target, 0.0, None, math.log(args[0]), math.log(args[1]), source, "ln m"
            )
        raise InputError(
            f"prior of K: use lognormal:MEDIAN:SIGMA_LOG or uniform:LOW:HIGH (m), got {kind}"
        )
    if kind == "normal":
        return InputPrior(
            target, args[0] * scale, args[1] * scale, base.low, base.high, source, base.unit
        )
    if kind == "truncnormal":
        return InputPrior(
            target,
            args[0] * scale,
            args[1] * scale,
            args[2] * scale,
            args[3] * scale,
            source,
            base.unit,
        )
    if kind == "uniform":
        return InputPrior(target, 0.0, None, args[0] * scale, args[1] * scale, source, base.unit)
    raise InputError(f"prior of {name}: use normal, truncnormal or uniform, got {kind!r}")


def input_priors(user: Mapping[str, Sequence] | None = None) -> dict[str, InputPrior]:
    """The defaults of :data:`DEFAULT_INPUTS` with the user's priors put in their place.

    ``user`` maps ``c`` [Pa], ``phi`` [deg], ``K`` [m], ``datum_m`` [m] or a sampling-scale
    name (``a0`` …) to a prior tuple as the CLI's ``--prior`` gives it.
    """
    out = dict(DEFAULT_INPUTS)
    for name, spec in (user or {}).items():
        target = _USER_NAMES.get(name, name)
        if target not in out:
            raise InputError(
                f"no wheel input named {name!r}; the calibration carries "
                f"{sorted(set(_USER_NAMES) | set(DEFAULT_INPUTS))}"
            )
        out[target] = _from_user(name, spec)
    return out
